"""The overshoot lead of the catching agent: the net target moved back along its move (issue 18).

A net that arrives shortly before the ball is still carried past its goal along the move; the agent
may aim short by what it expects (``DemoOptions.overshoot_lead_m``, off by default).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _catch_stubs import LayerStub, identity_ik_agent
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.profile import overshoot_lead_target

READY = np.array([0.0, 0.0, 1.07])

coord = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(dx=coord, dz=coord, lead=st.floats(0.0, 0.05), margin=st.floats(-1.0, 1.0), fade=st.floats(0.05, 1.0),
       full=st.floats(0.05, 0.5))
def test_the_lead_moves_the_target_back_along_the_move_by_the_stated_amount(dx, dz, lead, margin, fade, full):
    target = READY + [0.0, dx, dz]
    got = overshoot_lead_target(target, READY, lead, margin, fade_s=fade, full_move_m=full)
    move = target - READY
    length = float(np.linalg.norm(move))
    # an independent statement of the rule: the share of the lead by move length and by time margin
    share_len = min(length / full, 1.0)
    share_time = float(np.clip((fade - margin) / fade, 0.0, 1.0))
    want = min(lead * share_len * share_time, 0.5 * length)
    if length <= 1e-9:  # no move (under a nanometre, the documented floor): nothing to lead
        want = 0.0
    back = target - got
    assert np.linalg.norm(back) == pytest.approx(want, abs=1e-12)
    if want > 1e-9:     # straight back towards where the move starts
        assert np.allclose(np.cross(back, move), 0.0, atol=1e-12) and float(back @ move) > 0.0


def test_no_lead_when_the_net_arrives_early_or_the_lead_is_off():
    target = READY + [0.0, 0.4, -0.2]
    assert np.array_equal(overshoot_lead_target(target, READY, 0.012, 0.25), target)      # at the fade time
    assert np.array_equal(overshoot_lead_target(target, READY, 0.012, 0.6), target)
    assert np.array_equal(overshoot_lead_target(target, READY, 0.0, -0.1), target)
    assert np.array_equal(overshoot_lead_target(READY, READY, 0.012, 0.0), READY)          # no move: no direction
    # arriving at the crossing or late: the full lead (for a long move), not more
    assert np.linalg.norm(target - overshoot_lead_target(target, READY, 0.012, -0.3)) == pytest.approx(0.012)


@pytest.mark.parametrize("kw", [{"overshoot_lead_m": -0.01}, {"overshoot_lead_m": 0.2}, {"overshoot_fade_s": 0.0},
                                {"overshoot_full_move_m": -1.0}])
def test_demo_options_refuse_an_impossible_lead(kw):
    with pytest.raises(ValueError, match="overshoot_lead_m"):
        DemoOptions(**kw)


@pytest.mark.parametrize("lead", [0.0, 0.02])
def test_the_agent_sends_the_target_moved_back_only_when_the_net_arrives_late(monkeypatch, lead):
    goal = np.deg2rad([0.0, 20.0, 70.0])
    sent = {}
    for name, t_cross in (("tight", 0.05), ("early", 30.0)):
        layer = LayerStub()
        agent = identity_ik_agent(layer, monkeypatch, (0.0, 60.0, 60.0), overshoot_lead_m=lead)
        agent.begin_throw(0)
        agent.return_to_ready(0.0)                      # the arm rests at the ready pose: the mirror knows it
        agent._intercept(5.0, SimpleNamespace(p_base=goal, t_cross=5.0 + t_cross), layer.theta)
        sent[name] = layer.sent[-1]
    assert np.allclose(sent["early"], goal)              # arrives long before the crossing: no lead
    ready = np.deg2rad([0.0, 60.0, 60.0])
    # the move (0.72 rad here, in the stub's joint-angle "metres") is longer than the full-lead move
    assert np.allclose(sent["tight"], overshoot_lead_target(goal, ready, lead, -1.0))
    assert np.linalg.norm(sent["tight"] - goal) == pytest.approx(lead)
