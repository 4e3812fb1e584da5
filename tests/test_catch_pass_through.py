"""Pass-through goals of the catching agent: a joint too late to stop at its goal passes it moving (issue 18).

:meth:`ReferenceMirror.pass_through_goal` extends each late joint's goal so that the layer's re-plan is at
the original goal at the pass time; ``DemoOptions.pass_through`` makes the agent send such goals for moves
that cannot stop before the crossing.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _catch_stubs import LayerStub, identity_ik_agent
from tudorvision.joint.planner import plan_motion
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.profile import ReferenceMirror

V, A = 1.2, 6.0
LO, HI = np.full(3, -3.0), np.full(3, 3.0)


def _mirror(theta0, moving_goal=None, t_sent=0.0):
    m = ReferenceMirror(V, A)
    m.reset(theta0, 0.0)
    if moving_goal is not None:                   # the arm already on its way somewhere
        m.sent(moving_goal, t_sent)
    return m


@settings(max_examples=60, deadline=None)
@given(start=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3),
       goal=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3),
       moving=st.one_of(st.none(), st.lists(st.floats(-2.5, 2.5), min_size=3, max_size=3)),
       frac=st.floats(0.3, 1.2))
def test_late_joints_pass_their_goal_at_the_pass_time_and_the_others_keep_it(start, goal, moving, frac):
    m = _mirror(np.array(start), None if moving is None else np.array(moving))
    t = 0.2
    g = np.array(goal)
    stop = m.plan(g, t)
    t_pass = t + frac * stop.duration_s
    got, late = m.pass_through_goal(g, t, t_pass, LO, HI)
    assert np.all(got >= LO - 1e-12) and np.all(got <= HI + 1e-12)
    assert np.array_equal(got[~late], g[~late])
    th, dth = m.state(t)
    way = np.sign(g - th)
    # independently: where the layer's plan (from the mirrored state) to the stop goal is at the pass time
    at_stop = plan_motion(th, g, v_max=V, a_max=A, dtheta_start=dth, t0=t).sample(t_pass)[0]
    assert np.array_equal(late, (way != 0) & ((g - at_stop) * way > 1e-9))
    at = plan_motion(th, got, v_max=V, a_max=A, dtheta_start=dth, t0=t).sample(t_pass)[0]
    farthest = plan_motion(th, np.where(way > 0, HI, LO), v_max=V, a_max=A, dtheta_start=dth, t0=t).sample(t_pass)[0]
    for j in np.flatnonzero(late):
        # moved beyond the goal along the way, never back
        assert (got[j] - g[j]) * way[j] >= 0.0
        if (farthest[j] - g[j]) * way[j] >= 1e-3:          # the goal can be passed in time: it is, to a millirad
            assert (at[j] - g[j]) * way[j] == pytest.approx(0.0, abs=2e-3)


def test_a_joint_that_cannot_get_there_in_time_goes_as_far_as_it_can():
    m = _mirror(np.zeros(3))
    g, late = m.pass_through_goal([0.0, 1.0, 0.0], 0.0, 0.8, LO, HI)     # at most 0.24 + 0.4 * 1.2 rad by 0.8 s
    assert late.tolist() == [False, True, False]
    reach = m.plan(g, 0.0).sample(0.8)[0][1]
    best = max(m.plan([0.0, float(e), 0.0], 0.0).sample(0.8)[0][1] for e in np.linspace(1.0, 3.0, 201))
    assert reach < 1.0 and reach == pytest.approx(best, abs=2e-3)


def test_a_bound_at_the_goal_leaves_the_joint_to_stop_there():
    m = _mirror(np.zeros(3))
    g, late = m.pass_through_goal([0.0, 1.0, 0.0], 0.0, 1.0, LO, [3.0, 1.0, 3.0])
    assert late[1] and g[1] == pytest.approx(1.0)


@pytest.mark.parametrize("on", [False, True])
def test_the_agent_passes_through_only_moves_that_cannot_stop_before_the_crossing(monkeypatch, on):
    goal = np.deg2rad([0.0, 20.0, 70.0])
    sent = {}
    for name in ("tight", "early"):
        layer = LayerStub()
        agent = identity_ik_agent(layer, monkeypatch, (0.0, 60.0, 60.0), pass_through=on, overshoot_lead_m=0.0)
        agent.begin_throw(0)
        agent.return_to_ready(0.0)
        fast = max(agent.max_speed, agent.late_speed)
        stop_s = agent.mirror.plan(goal, 5.0, fast).duration_s
        t_cross = 5.0 + (0.75 * stop_s if name == "tight" else 30.0)
        agent._intercept(5.0, SimpleNamespace(p_base=goal, t_cross=t_cross), layer.theta)
        sent[name] = (np.asarray(layer.sent[-1]), agent.log.passed, agent.mirror, t_cross)
    assert np.allclose(sent["early"][0], goal) and sent["early"][1] == 0
    tight, passed, mirror, t_cross = sent["tight"]
    if not on:
        assert passed == 0 and np.allclose(tight, goal)
        return
    assert passed == 1
    # joint 2 moves 40 deg down: too far to stop in time, so its goal lies beyond, further down, and the
    # layer's reference (the mirror's, which the send updated) passes 20 deg at the crossing
    assert tight[1] < goal[1] - 1e-3
    assert mirror.state(t_cross)[0][1] == pytest.approx(goal[1], abs=2e-3)
    stop = plan_motion(np.deg2rad([0.0, 60.0, 60.0]), goal, v_max=max(agent.max_speed, agent.late_speed),
                       a_max=agent.max_accel, t0=5.0)
    assert stop.sample(t_cross)[0][1] > goal[1] + np.deg2rad(1.0)      # braking to a stop, it would still be above
    assert tight[2] == pytest.approx(goal[2])            # joint 3's 10 deg fit in time


@pytest.mark.parametrize("kw", [{"pass_lead_s": 0.5}, {"pass_margin_s": -1.0}, {"pass_lead_s": float("nan")}])
def test_demo_options_refuse_an_impossible_pass_timing(kw):
    with pytest.raises(ValueError, match="pass_lead_s"):
        DemoOptions(**kw)
