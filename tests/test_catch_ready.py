"""The catching agent between throws and at the edge of the reach.

* The ready move after a fast intercept move waits while its re-plan would carry a joint past its
  range (the layer's range fault used to stop the arm over and over, and the next throw found it
  still on its way back).
* A crossing estimated a little beyond full stretch is released: the net, pulled in, still takes it.
"""
from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from _catch_stubs import LayerStub, identity_ik_agent
from tudorvision.lab.catch.options import DemoOptions


def test_path_range_is_the_planners_replan():
    """Oracle: the layer's planner itself, re-planned from the braking state to a goal the other way."""
    from tudorvision.joint.planner import plan_motion
    from tudorvision.lab.catch.agent import ReferenceMirror

    v, a = 1.6, 7.0
    start, goal = np.deg2rad([0.0, 60.0, 60.0]), np.deg2rad([0.0, -4.0, 60.0])
    back = np.deg2rad([0.0, 57.0, 57.0])
    m = ReferenceMirror(v, a)
    m.sent(goal, 0.0, theta_now=start)
    first = plan_motion(start, goal, v_max=v, a_max=a)
    t_brake = first.t_acc[1] + first.t_cruise[1] + 0.3 * first.t_dec[1]
    th, dth, _ = first.sample(t_brake)
    replan = plan_motion(th, back, v_max=v, a_max=a, dtheta_start=dth)
    path = replan.sample(np.linspace(0.0, replan.duration_s, 4000))[0]
    lo, hi = m.path_range_rad(back, t_brake)
    assert np.allclose(lo, path.min(axis=0), atol=2e-4) and np.allclose(hi, path.max(axis=0), atol=2e-4)
    assert lo[1] < goal[1] - np.deg2rad(2.0)            # braking anew, joint 2 passes the old goal
    # at rest the path is the straight span between where it stands and the goal
    lo, hi = m.path_range_rad(back, first.duration_s + 1.0)
    assert np.allclose(lo, np.minimum(goal, back)) and np.allclose(hi, np.maximum(goal, back))


def _agent(layer, monkeypatch):
    return identity_ik_agent(layer, monkeypatch, (0.0, 57.0, 57.0))


def test_ready_move_waits_while_its_replan_would_leave_a_joint_range(monkeypatch):
    layer = LayerStub()
    agent = _agent(layer, monkeypatch)
    agent.begin_throw(0)
    low = np.deg2rad([0.0, -4.0, 60.0])                   # joint 2 at its setpoint margin (range -14 deg)
    agent._intercept(0.0, SimpleNamespace(p_base=low, t_cross=10.0), layer.theta)
    assert len(layer.sent) == 1 and np.allclose(layer.sent[0], low)
    m = agent.mirror.motion
    # early, still accelerating: turning back stays inside the range, the ready move goes out at once
    agent.return_to_ready(0.1)
    assert len(layer.sent) == 2 and np.allclose(layer.sent[-1], agent.ready_point_base)
    # a fresh throw; braking hard near the margin: the re-plan would pass it, the ready move waits
    agent.begin_throw(1)
    agent._intercept(0.2, SimpleNamespace(p_base=low, t_cross=10.0), layer.theta)
    m = agent.mirror.motion
    t_brake = m.t0 + m.t_acc[1] + m.t_cruise[1] + 0.4 * m.t_dec[1]
    lo, _ = agent.mirror.path_range_rad(agent.ready_point_base, t_brake)
    assert lo[1] < np.deg2rad(-4.0)                       # what the wait avoids
    agent.return_to_ready(t_brake)
    assert len(layer.sent) == 3 and agent._ready_goal is not None
    # it goes out from the frame where the motion has ended (wait's and step's per-frame check)
    agent._send_ready(m.t0 + m.duration_s + 0.01)
    assert len(layer.sent) == 4 and np.allclose(layer.sent[-1], agent.ready_point_base)
    assert agent._ready_goal is None


def test_an_intercept_supersedes_a_waiting_ready_move(monkeypatch):
    layer = LayerStub()
    agent = _agent(layer, monkeypatch)
    agent.begin_throw(0)
    low = np.deg2rad([0.0, -4.0, 60.0])
    agent._intercept(0.0, SimpleNamespace(p_base=low, t_cross=10.0), layer.theta)
    m = agent.mirror.motion
    t_brake = m.t0 + m.t_acc[1] + m.t_cruise[1] + 0.4 * m.t_dec[1]
    agent.return_to_ready(t_brake)
    assert agent._ready_goal is not None
    agent.begin_throw(1)
    other = np.deg2rad([0.0, 20.0, 70.0])
    agent._intercept(m.t0 + m.duration_s + 0.05, SimpleNamespace(p_base=other, t_cross=20.0), layer.theta)
    assert agent._ready_goal is None and np.allclose(layer.sent[-1], other)
    agent._send_ready(m.t0 + m.duration_s + 0.1)
    assert np.allclose(layer.sent[-1], other)             # nothing else went out


@pytest.mark.parametrize("catch_deg", [(0.0, 48.0, 63.0), (0.0, 30.0, 75.0)])
def test_a_shaped_return_takes_the_least_swing_that_ends_before_the_weighing(monkeypatch, catch_deg):
    """``ready_shaping``: the return's profile is the choice over speeds x READY_ACCELS, brute-forced here.

    From the nearer catching pose some profiles end before the pause's weighing window; from the farther
    one none does, and the return takes the one that ends first (the demo's).
    """
    from tudorvision.lab.catch.agent import READY_ACCELS, READY_SETTLE_S, WEIGH_WINDOW_S
    from tudorvision.lab.catch.profile import SPEED_CANDIDATES

    for shaping in (False, True):
        layer = LayerStub(theta_deg=(0.0, 57.0, 57.0))
        agent = identity_ik_agent(layer, monkeypatch, (0.0, 57.0, 57.0), overshoot_lead_m=0.0,
                                  ready_shaping=shaping)
        agent.begin_throw(0)
        catch = np.deg2rad(catch_deg)
        agent._intercept(0.0, SimpleNamespace(p_base=catch, t_cross=0.9), layer.theta)
        t = 1.0                                                  # after the crossing, the intercept move over
        m = copy.deepcopy(agent.mirror)                          # the mirror as it is before the return
        agent.return_to_ready(t)
        assert len(layer.sent) == 2 and np.allclose(layer.sent[-1], agent.ready_point_base)
        v, a = layer.profiles[-1]
        if not shaping:
            assert (v, a) == (pytest.approx(agent.max_speed), pytest.approx(agent.max_accel))
            continue
        deadline = t + agent.options.gap_s - WEIGH_WINDOW_S - READY_SETTLE_S
        f = agent._modes(agent.ready_point_base)
        r, t_end = m.residual_rad(agent.ready_point_base, t, f, v_max=v, a_max=a)
        tried = [m.residual_rad(agent.ready_point_base, t, f, v_max=c * agent.max_speed, a_max=ca * agent.max_accel)
                 for ca in READY_ACCELS for c in SPEED_CANDIDATES]
        in_time = [r2 for r2, t2 in tried if t2 <= deadline]
        if catch_deg[1] > 40.0:
            assert in_time and t_end <= deadline and min(in_time) >= 0.98 * r - 1e-12
            assert r < m.residual_rad(agent.ready_point_base, t, f)[0]     # less swing than the demo's profile
        else:
            assert not in_time and t_end == pytest.approx(min(t2 for _, t2 in tried))
            assert (v, a) == (pytest.approx(agent.max_speed), pytest.approx(agent.max_accel))


def test_a_crossing_just_beyond_full_stretch_is_reachable_within_the_tolerance():
    from tudorvision.catch.intercept import InterceptOptions, InterceptPlanner
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    reach = p.link2_length_m + p.link3_length_m
    u = np.array([np.cos(np.deg2rad(60.0)), 0.0, np.sin(np.deg2rad(60.0))])   # up and forward
    shoulder = np.array([0.0, 0.0, p.link1_height_m])
    strict = InterceptPlanner(InterceptOptions(), params=p)
    tolerant = InterceptPlanner(InterceptOptions(reach_tol_m=0.015), params=p)
    for d, strict_ok, tolerant_ok in [(reach - 0.01, True, True), (reach + 0.01, False, True),
                                      (reach + 0.02, False, False)]:
        q = shoulder + d * u
        assert strict._reachable(q) is strict_ok and tolerant._reachable(q) is tolerant_ok, d
    # the tolerance does not widen the joint ranges: behind and below (joint 2 at 200 deg) stays unreachable
    behind = shoulder + (reach + 0.01) * np.array([-np.cos(np.deg2rad(20.0)), 0.0, -np.sin(np.deg2rad(20.0))])
    assert not tolerant._reachable(behind)
    for bad in (-0.01, float("nan")):
        try:
            InterceptOptions(reach_tol_m=bad)
        except ValueError as e:
            assert "reach_tol_m" in str(e)
        else:
            raise AssertionError(bad)


def test_the_inner_edge_of_the_reach_is_where_the_elbow_runs_out_of_range():
    """Oracle: the rigid IK at ``inner_reach_m`` has joint 3 exactly at its range less the margin; nearer
    crossings are pulled out radially (not sideways) onto that circle, farther ones are left alone."""
    from tudorvision.catch.intercept import inner_reach_m, net_target, reachable_solutions
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    margin = np.deg2rad(3.0)
    d_in = inner_reach_m(p, margin)
    shoulder = np.array([0.0, 0.0, p.link1_height_m])
    u = np.array([np.cos(np.deg2rad(70.0)), 0.0, np.sin(np.deg2rad(70.0))])
    sols = reachable_solutions(shoulder + d_in * u, 0.0, p)
    assert len(sols) == 2 and np.allclose(np.sort(np.abs(sols[:, 2])), p.joint_limits_rad[2][1] - margin)
    # 1 mm nearer: no solution keeps the margin on either elbow branch
    assert len(reachable_solutions(shoulder + (d_in - 0.001) * u, 0.0, p, margin_rad=margin + 1e-9)) == 0
    for d in (0.30, 0.50, d_in - 0.001):
        q = net_target(shoulder + d * u, 0.0, p, reach_margin_m=0.03, inner_reach_m=d_in)
        assert np.linalg.norm(q - shoulder) == pytest.approx(d_in, abs=1e-9)
        assert np.allclose((q - shoulder) / d_in, u)
    for d in (d_in + 0.001, 0.7):
        assert np.allclose(net_target(shoulder + d * u, 0.0, p, reach_margin_m=0.03, inner_reach_m=d_in),
                           shoulder + d * u)
    assert np.allclose(net_target(shoulder + 0.3 * u, 0.0, p), shoulder + 0.3 * u)     # default: no pull


def test_the_planner_releases_estimates_just_inside_the_inner_edge():
    from tudorvision.catch.intercept import InterceptOptions, InterceptPlanner, inner_reach_m
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    d_in = inner_reach_m(p, np.deg2rad(3.0))
    shoulder = np.array([0.0, 0.0, p.link1_height_m])
    u = np.array([np.cos(np.deg2rad(100.0)), 0.0, np.sin(np.deg2rad(100.0))])
    # the planner's own 2 deg range margin: without the inner edge, 1 cm inside it is unreachable
    plain = InterceptPlanner(InterceptOptions(reach_tol_m=0.015), params=p)
    inner = InterceptPlanner(InterceptOptions(reach_tol_m=0.015, inner_reach_m=d_in), params=p)
    for d, plain_ok, inner_ok in [(d_in + 0.005, True, True), (d_in - 0.01, False, True), (d_in - 0.02, False, False)]:
        q = shoulder + d * u
        assert plain._reachable(q) is plain_ok and inner._reachable(q) is inner_ok, d
    with pytest.raises(ValueError, match="inner_reach_m"):
        InterceptOptions(inner_reach_m=-0.1)
    # a tolerance of its own inside the inner edge (the net sits on that circle: no reach margin there),
    # the outer edge's unchanged
    wide = InterceptPlanner(InterceptOptions(reach_tol_m=0.015, inner_reach_m=d_in, inner_reach_tol_m=0.045),
                            params=p)
    for d, ok in [(d_in - 0.02, True), (d_in - 0.044, True), (d_in - 0.05, False)]:
        assert wide._reachable(shoulder + d * u) is ok, d
    l23 = p.link2_length_m + p.link3_length_m
    for d, ok in [(l23 + 0.014, True), (l23 + 0.02, False)]:
        assert wide._reachable(shoulder + d * u) is ok and inner._reachable(shoulder + d * u) is ok, d
    with pytest.raises(ValueError, match="inner_reach_tol_m"):
        InterceptOptions(inner_reach_tol_m=-0.01)


def test_the_demos_inner_edge_follows_joint_3s_setpoint_margin():
    from tudorvision.catch.intercept import inner_reach_m
    from tudorvision.lab.catch.agent import demo_inner_reach_m
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    assert demo_inner_reach_m(DemoOptions(), p) == pytest.approx(0.546, abs=0.001)       # 102 - 3 deg
    wider = DemoOptions(setpoint_margin_rad=tuple(np.deg2rad([10.0, 10.0, 12.0])))
    assert demo_inner_reach_m(wider, p) == pytest.approx(inner_reach_m(p, np.deg2rad(12.0)))
    assert demo_inner_reach_m(wider, p) > demo_inner_reach_m(DemoOptions(), p)
    assert demo_inner_reach_m(DemoOptions(inner_pull=False), p) == 0.0


@pytest.mark.parametrize("tol_m, interval_s", [(0.02, 0.2), (0.015, 0.2), (0.01, 0.1)])
def test_the_demos_refinement_rule_reaches_the_planner(tol_m, interval_s):
    """A refinement goes out when the crossing moved more than ``refine_tol_m`` and ``refine_interval_s`` passed.

    Oracle: the crossing of a flight shifted sideways by ``d`` moves by ``d`` in the working plane (the
    normal is the base y axis, the flight model does not depend on x).
    """
    from tudorvision.catch.ekf import BallModel
    from tudorvision.catch.intercept import InterceptPlanner
    from tudorvision.lab.catch.run import demo_intercept_options
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    o = DemoOptions(refine_tol_m=tol_m, refine_interval_s=interval_s)
    io = demo_intercept_options(o, p)
    assert (io.refine_tol_m, io.min_interval_s, io.release_sigma_m) == (tol_m, interval_s, o.release_sigma_m)
    planner = InterceptPlanner(io, model=BallModel(drag_k_per_m=o.drag_k_per_m), params=p)
    P = np.diag([1e-6] * 3 + [1e-6] * 3)

    def state(dx_m):
        return np.array([0.2 + dx_m, -3.0, 1.3, 0.0, 5.0, 2.5])

    first = planner.update(0.0, state(0.0), P)
    assert first.reachable and first.send
    for dt, dx, expect in [(interval_s / 2, 1.5 * tol_m, False),        # moved enough, too early
                           (interval_s, 0.8 * tol_m, False),            # late enough, moved too little
                           (interval_s, 1.2 * tol_m, True)]:            # both
        it = planner.update(dt, state(dx), P)
        moved = np.linalg.norm(it.p_base - first.p_base)
        assert moved == pytest.approx(dx, abs=1e-6)
        assert bool(it.send) is expect, (dt, dx)


def test_a_much_sharper_estimate_refines_before_the_interval():
    """``refine_sharper``: inside ``min_interval_s`` a refinement goes out only when the estimate's standard
    deviation fell to at most that fraction of the released one's (and it moved more than ``refine_tol_m``).

    The crossing's sigma is read back from the planner (process noise adds to the state's), so the oracle is
    the rule itself on the measured ratios, with cases chosen clearly on each side of it.
    """
    from tudorvision.catch.ekf import BallModel
    from tudorvision.catch.intercept import InterceptOptions, InterceptPlanner
    from tudorvision.robot import load_robot_params

    p = load_robot_params()

    def state(dx_m):
        return np.array([0.2 + dx_m, -3.0, 1.3, 0.0, 5.0, 2.5])

    def P(sd_m):
        return np.diag([sd_m ** 2] * 3 + [(2.0 * sd_m) ** 2] * 3)

    for sharper in (0.0, 0.5):
        planner = InterceptPlanner(InterceptOptions(release_sigma_m=0.5, refine_tol_m=0.02, min_interval_s=0.2,
                                                    refine_sharper=sharper),
                                   model=BallModel(drag_k_per_m=0.012), params=p)
        first = planner.update(0.0, state(0.0), P(0.05))
        assert first.send and first.sigma_m > 0.05
        a = planner.update(0.033, state(0.05), P(0.04))        # a little sharper, moved 5 cm: waits
        assert a.sigma_m > 0.7 * first.sigma_m and not a.send
        b = planner.update(0.066, state(0.01), P(0.01))        # much sharper, moved 1 cm: nothing to correct
        assert b.sigma_m < 0.4 * first.sigma_m and not b.send
        c = planner.update(0.1, state(0.05), P(0.01))          # much sharper, moved 5 cm
        assert c.sigma_m < 0.4 * first.sigma_m
        assert bool(c.send) is (sharper > 0.0)
    with pytest.raises(ValueError, match="refine_sharper"):
        InterceptOptions(refine_sharper=1.0)
    with pytest.raises(ValueError, match="refine_sharper"):
        DemoOptions(refine_sharper=-0.1)
