"""The working plane chosen per throw (issue 18, ``DemoOptions.yaw_max_rad``).

Joint 1 turns the plane the arm catches in when the fixed plane's intercept cannot be reached in time:
the planner's crossing of a turned plane against the analytic crossing of a drag-free flight, the choice
rule against its stated properties, the agent's use of it, and the ring scored where joint 1 really is.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _catch_stubs import LayerStub, identity_ik_agent
from tudorvision.catch.ball_model import BallModel
from tudorvision.catch.intercept import InterceptOptions, InterceptPlanner, reachable_solutions, working_plane_normal
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.planes import choose_plane, plane_candidates

G = np.array([0.0, 0.0, -9.81])


def test_candidates_start_at_the_fixed_plane_and_grow_both_ways():
    c = np.degrees(plane_candidates(np.radians(30.0), np.radians(10.0)))
    assert np.allclose(c, [0.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0])
    assert plane_candidates(0.0, 0.1).tolist() == [0.0]
    with pytest.raises(ValueError, match="plane_candidates"):
        plane_candidates(0.5, 0.0)


slack_values = st.one_of(st.none(), st.floats(-1.0, 1.0))


@settings(max_examples=200, deadline=None)
@given(slacks=st.lists(slack_values, min_size=1, max_size=8), margin=st.floats(-0.3, 0.3),
       gain=st.floats(0.0, 0.2))
def test_the_choice_keeps_the_fixed_plane_unless_another_gains_and_takes_the_first_in_time(slacks, margin, gain):
    cands = [float(i) for i in range(len(slacks))]            # index order = preference order
    table = dict(zip(cands, slacks))
    got = choose_plane(cands, table.get, margin, gain)
    first = slacks[0]
    others = [(c, s) for c, s in zip(cands[1:], slacks[1:]) if s is not None]
    eligible = [(c, s) for c, s in others if first is None or s >= first + gain]
    if first is not None and first >= margin:
        assert got == (0.0, first)
        return
    if not eligible:
        assert got == (None if first is None else (0.0, first))
        return
    c, s = got
    assert table[c] == s and (c, s) in eligible
    in_time = [e for e in eligible if e[1] >= margin]
    if in_time:
        assert (c, s) == in_time[0]                           # the smallest turn that is in time
    else:
        assert s == max(e[1] for e in eligible)                # none in time: the roomiest


def _drag_free_planner(**kw):
    o = InterceptOptions(release_sigma_m=10.0, **kw)
    return InterceptPlanner(o, model=BallModel(drag_k_per_m=0.0), q_m2_s3=1e-9)


@pytest.mark.parametrize("theta1_deg", [-30.0, -10.0, 0.0, 20.0])
def test_a_turned_plane_is_crossed_where_the_parabola_crosses_it(theta1_deg):
    x = np.array([0.35, -4.0, 1.6, -0.05, 7.0, 1.5])
    P = np.diag([1e-6] * 3 + [1e-6] * 3)
    pl = _drag_free_planner()
    it = pl.on_plane(2.0, x, P, np.radians(theta1_deg))
    n = working_plane_normal(np.radians(theta1_deg))
    # n has no vertical part, so n . p(t) is linear in t
    dt = -float(n @ x[:3]) / float(n @ x[3:])
    p = x[:3] + x[3:] * dt + 0.5 * G * dt ** 2
    assert it.t_cross == pytest.approx(2.0 + dt, abs=1e-6)
    assert np.allclose(it.p_base, p, atol=1e-6)
    assert it.reachable == (len(reachable_solutions(p, np.radians(theta1_deg), margin_rad=np.radians(2.0))) > 0)
    assert not it.send and pl.theta1_rad == 0.0 and pl.released is None     # the planner is unchanged


def test_a_plane_taken_for_the_throw_holds_until_the_next_throw():
    x = np.array([0.35, -4.0, 1.6, -0.05, 7.0, 1.5])
    P = np.diag([1e-6] * 6)
    pl = _drag_free_planner(refine_tol_m=0.02)
    assert pl.update(0.0, x, P).send
    turned = pl.on_plane(0.0, x, P, np.radians(-20.0))
    pl.use_plane(np.radians(-20.0), turned)
    assert pl.released.send and np.allclose(pl.released.p_base, turned.p_base)
    later = pl.update(0.05, x, P)                              # the same flight: on the turned plane, no refinement
    assert abs(float(working_plane_normal(np.radians(-20.0)) @ later.p_base)) < 1e-6 and not later.send
    pl.reset()
    assert pl.theta1_rad == 0.0 and abs(float(pl.update(0.1, x, P).p_base[1])) < 1e-6


class _Perception:
    """Intercepts per plane for the agent: the fixed plane needs a long joint-2 move, -20 deg a short one."""

    def __init__(self, goals):
        self.goals, self.used = goals, []

    def on_plane(self, t, theta1_rad):
        key = round(float(np.degrees(theta1_rad)))
        if key not in self.goals:
            return None
        return SimpleNamespace(t=t, t_cross=t + 0.8, p_base=np.radians(self.goals[key]), reachable=True,
                               cov_base=np.zeros((3, 3)), sigma_m=0.05)

    def use_plane(self, theta1_rad, released):
        self.used.append(float(theta1_rad))


def _agent(monkeypatch, goals, **options):
    layer = LayerStub((0.0, 60.0, 60.0))
    agent = identity_ik_agent(layer, monkeypatch, (0.0, 60.0, 60.0), overshoot_lead_m=0.0, **options)
    agent.perception = _Perception(goals)
    agent.begin_throw(0)
    return layer, agent


# identity IK: an intercept's "p_base" is its joint goal, joint 1 the plane's angle
# (the layer's sin^2 profile from (0, 60, 60) deg: 1.10 / 1.10 / 0.78 / 0.63 s against 0.7 s to the deadline)
GOALS = {0: (0.0, 0.0, 95.0), 10: (10.0, 0.0, 95.0), -10: (-10.0, 30.0, 85.0), -20: (-20.0, 55.0, 65.0)}


def test_the_agent_turns_to_the_smallest_plane_it_reaches_in_time_and_back_for_the_ready_move(monkeypatch):
    layer, agent = _agent(monkeypatch, GOALS, yaw_max_rad=float(np.radians(20.0)),
                          yaw_step_rad=float(np.radians(10.0)), yaw_margin_s=0.0)
    it = agent.perception.on_plane(1.0, 0.0)
    agent._intercept(1.0, it, layer.theta)
    sent = np.degrees(layer.sent[-1])
    assert np.allclose(sent, GOALS[-20]) and agent.log.yaw_rad == pytest.approx(np.radians(-20.0))
    assert agent.perception.used == [pytest.approx(np.radians(-20.0))] and agent.ik.theta1_rad == agent.log.yaw_rad
    # a refinement stays on that plane; the ready move goes back to the fixed one
    agent._intercept(1.3, SimpleNamespace(**{**vars(it), "p_base": np.radians([-20.0, 48.0, 75.0])}), layer.theta)
    assert agent.perception.used == [pytest.approx(np.radians(-20.0))]
    agent.return_to_ready(2.0)
    assert agent.ik.theta1_rad == 0.0
    agent.begin_throw(1)
    assert agent.ik.theta1_rad == 0.0


def test_without_a_plane_in_time_the_agent_takes_the_roomiest(monkeypatch):
    layer, agent = _agent(monkeypatch, GOALS, yaw_max_rad=float(np.radians(10.0)),
                          yaw_step_rad=float(np.radians(10.0)), yaw_margin_s=0.0)
    agent._intercept(1.0, agent.perception.on_plane(1.0, 0.0), layer.theta)
    assert np.allclose(np.degrees(layer.sent[-1]), GOALS[-10]) and np.degrees(agent.log.yaw_rad) == pytest.approx(-10)


def test_the_agent_keeps_the_fixed_plane_in_time_or_without_the_option(monkeypatch):
    near = {0: (0.0, 55.0, 65.0), -10: (-10.0, 58.0, 62.0)}
    layer, agent = _agent(monkeypatch, near, yaw_max_rad=float(np.radians(20.0)),
                          yaw_step_rad=float(np.radians(10.0)))
    agent._intercept(1.0, agent.perception.on_plane(1.0, 0.0), layer.theta)
    assert np.allclose(np.degrees(layer.sent[-1]), near[0]) and agent.log.yaw_rad == 0.0
    layer, agent = _agent(monkeypatch, GOALS)
    agent._intercept(1.0, agent.perception.on_plane(1.0, 0.0), layer.theta)
    assert np.allclose(np.degrees(layer.sent[-1]), GOALS[0]) and agent.perception.used == []


def _score(ring_theta1_deg, offset_x_m, yaw_deg=0.0):
    """A ball flying along +y through (0.3 + offset, 0, 1.0) m; the net at (0.3, 0, 1.0), its ring turned."""
    from tudorvision.lab.catch.scenario import Throw
    from tudorvision.lab.catch.score import score_throw
    from tudorvision.robot import load_robot_params

    tt = np.arange(0.0, 1.0, 1e-3)
    pts = np.column_stack([np.full_like(tt, 0.3 + offset_x_m), 7.0 * (tt - 0.9), np.full_like(tt, 1.0)])
    throw = Throw(index=0, t_release_s=0.0, times_s=tt, points_base=pts, t_cross_rel_s=0.9,
                  p_cross_base=pts[900], t_cross_s=0.9, ball_radius_m=0.045)
    x = 0.3 + offset_x_m      # the agent's estimate: where the ball crosses its (turned) plane through the base axis
    estimate = np.array([x, x * np.tan(np.radians(yaw_deg)), 1.0])
    log = SimpleNamespace(detections=20, last_intercept=SimpleNamespace(p_base=estimate), last_ballistic_base=None,
                          t_first_setpoint_s=0.4, t_arrived_s=0.7, payload_est_kg=0.0, yaw_rad=np.radians(yaw_deg))
    return score_throw(throw, log, net_at_cross=np.array([0.3, 0.0, 1.0]), theta_at_release=np.radians([0, 60, 60]),
                       payload_true_kg=0.0, options=DemoOptions(), params=load_robot_params(), theta1_rad=0.0,
                       max_speed=1.0, max_accel=5.0, frame_rate_hz=30.0,
                       ring_theta1_rad=None if ring_theta1_deg is None else np.radians(ring_theta1_deg))


def test_a_turned_ring_is_narrower_for_a_ball_that_keeps_its_course():
    # 4 cm off: inside R - r = 4.5 cm facing the ball; the ring turned 30 deg lets a ball through only within
    # R - r / cos 30 = 3.80 cm of its centre in its plane, and this one crosses it 4 / cos 30 = 4.62 cm off
    assert _score(None, 0.04).caught and _score(0.0, 0.04).caught
    turned = _score(30.0, 0.04, yaw_deg=30.0)
    assert not turned.caught and turned.rim_contact and turned.yaw_deg == pytest.approx(30.0)
    # judged against the turned plane's true crossing, the estimate was right: a rim miss, not a prediction error
    assert turned.reason == "ball hit the rim" and turned.pred_error_m == pytest.approx(0.0, abs=1e-9)
    assert turned.ring_offset_m == pytest.approx(0.04 / np.cos(np.radians(30.0)), abs=1e-4)
    assert _score(30.0, 0.03).caught and _score(30.0, 0.0).caught


@pytest.mark.parametrize("kw", [{"yaw_max_rad": -0.1}, {"yaw_max_rad": 2.0}, {"yaw_step_rad": 0.0},
                                {"yaw_margin_s": float("nan")}, {"yaw_min_gain_s": -0.01}])
def test_demo_options_refuse_an_impossible_plane_choice(kw):
    with pytest.raises(ValueError, match="yaw_"):
        DemoOptions(**kw)


def test_the_demo_turns_joint_1_for_a_throw_low_on_the_right(tmp_path):
    """End to end (``catch demo --yaw-max-deg``): the demo's first throw of seed 0 crosses the fixed plane low on
    the right (x 0.41 m, z 0.70 m), where joint 2 cannot swing down in time; the agent turns the plane towards
    the thrower on that side (joint 1 negative) and says so in throws.csv and summary.json."""
    import csv
    import json

    from tudorvision.cli import main

    out = tmp_path / "d"
    assert main(["catch", "demo", "--throws", "1", "--no-render", "--no-rerun", "--yaw-max-deg", "34",
                 "--out", str(out)]) == 0
    row = next(csv.DictReader((out / "throws.csv").open()))
    assert float(row["x_cross_true_m"]) > 0.35 and float(row["z_cross_true_m"]) < 0.8
    assert -34.0 <= float(row["yaw_deg"]) <= -10.0
    # the net is judged against where the ball crossed the turned plane (23 cm from the fixed plane's crossing)
    assert float(row["miss_m"]) < 0.1 and float(row["pred_error_m"]) < 0.05
    s = json.loads((out / "summary.json").read_text())
    assert s["throws_on_a_turned_plane"] == 1 and s["yaw_max_rad"] == pytest.approx(np.radians(34.0))
