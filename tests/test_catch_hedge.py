"""A first intercept setpoint hedged where the IK is steep (issue 18, ``DemoOptions.first_hedge_sigma``).

:func:`hedged_goal` moves a joint whose plausible goals spread widely only to the near edge of their range;
the agent feeds it the goals of the first estimate moved along its covariance's principal directions.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _catch_stubs import LayerStub, identity_ik_agent
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.profile import hedged_goal

angles = st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3)


@settings(max_examples=80, deadline=None)
@given(goal=angles, plausible=st.lists(angles, min_size=0, max_size=4), now=angles, spread=st.floats(0.0, 0.5))
def test_a_hedged_joint_goes_to_the_nearest_plausible_goal_and_the_others_to_the_goal(goal, plausible, now, spread):
    got = hedged_goal(goal, np.reshape(plausible, (-1, 3)), now, spread)
    for j in range(3):
        values = [goal[j]] + [p[j] for p in plausible]
        lo, hi = min(values), max(values)
        if (hi - lo) / 2 <= spread:
            assert got[j] == goal[j]
            continue
        assert lo <= got[j] <= hi
        # nearest to where the joint is: no plausible goal is closer, and the goal itself is never closer
        assert abs(got[j] - now[j]) <= min(abs(v - now[j]) for v in values) + 1e-12
        if lo <= now[j] <= hi:
            assert got[j] == now[j]


def _first_setpoint(monkeypatch, **options):
    layer = LayerStub()
    agent = identity_ik_agent(layer, monkeypatch, (0.0, 60.0, 60.0), overshoot_lead_m=0.0, **options)
    agent.begin_throw(0)
    agent.return_to_ready(0.0)
    goal = np.deg2rad([0.0, 50.0, 80.0])
    # the estimate's covariance: joint 2's direction 1 deg, joint 3's 15 deg (the "steep" one)
    cov = np.diag(np.deg2rad([0.0, 1.0, 15.0]) ** 2)
    it = SimpleNamespace(p_base=goal, t_cross=30.0, cov_base=cov, sigma_m=float(np.deg2rad(15.0)))
    agent._intercept(5.0, it, layer.theta)
    first = np.asarray(layer.sent[-1])
    refined = SimpleNamespace(p_base=goal + np.deg2rad([0.0, 0.0, 2.0]), t_cross=30.0, cov_base=cov,
                              sigma_m=it.sigma_m)
    agent._intercept(5.5, refined, layer.theta)
    return first, np.asarray(layer.sent[-1]), agent.log.hedged, goal


def test_the_agent_hedges_the_steep_joint_of_its_first_setpoint_only(monkeypatch):
    first, second, hedged, goal = _first_setpoint(monkeypatch, first_hedge_sigma=1.0,
                                                  first_hedge_min_rad=float(np.deg2rad(5.0)))
    assert hedged == 1
    assert first[1] == pytest.approx(goal[1])                         # 1 deg of spread: straight to the goal
    # joint 3 from 60 deg towards 80 +- 15: only to 65, the near edge of what the estimate allows
    assert np.rad2deg(first[2]) == pytest.approx(65.0, abs=1e-6)
    assert np.rad2deg(second[2]) == pytest.approx(82.0, abs=1e-6)     # a refinement goes to its estimate


def test_without_the_option_the_first_setpoint_goes_to_the_estimate(monkeypatch):
    first, _, hedged, goal = _first_setpoint(monkeypatch)
    assert hedged == 0 and np.allclose(first, goal)


@pytest.mark.parametrize("kw", [{"first_hedge_sigma": -0.1}, {"first_hedge_sigma": float("nan")},
                                {"first_hedge_min_rad": 4.0}])
def test_demo_options_refuse_an_impossible_hedge(kw):
    with pytest.raises(ValueError, match="first_hedge"):
        DemoOptions(**kw)
