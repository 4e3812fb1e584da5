"""Visual servoing core math: interaction matrices (sign convention), laws, joint map."""
import numpy as np
import pytest

from tudorvision.robot import T_base_ee, jacobian_ee, load_robot_params
from tudorvision.servo import (AdaptiveGain, GoalFeatures, LawConfig, SquareFeatures, default_T_ee_cam, hybrid_law,
                               hybrid_matrix, ibvs_law, joint_velocity, point_interaction, servo_command)
from tudorvision.servo.interaction import project_cam, seed_image_jacobian
from tudorvision.servo.joint_map import point_jacobian
from tudorvision.servo.laws import adaptive_gain, limit_velocity
from tudorvision.servo.joint_map import JointMapConfig

F = 525.0


def _features_of(p_cam, f=F, c=(320.0, 240.0)):
    """Ideal camera: square features (centroid = first point) from camera-frame points (5, 3)."""
    uv = project_cam(p_cam, f) + c
    return SquareFeatures(found=True, centroid_uv=uv[0], center_uv=uv[0], corners_uv=uv[1:],
                          depth_m=p_cam[:, 2].copy())


# --------------------------------------------------------------------------- interaction
def test_point_interaction_matches_finite_differences_of_a_static_point():
    rng = np.random.default_rng(0)
    for _ in range(20):
        P = rng.uniform([-0.3, -0.3, 0.5], [0.3, 0.3, 2.0])           # static point, camera frame at t = 0
        v = rng.normal(size=3)                                          # camera translation velocity
        h = 1e-6
        # the camera moves by v h, so the point's camera coordinates become P - v h
        xy0 = project_cam(P, F)
        num = (project_cam(P - v * h, F) - project_cam(P + v * h, F)) / (2 * h)
        L = point_interaction(xy0, P[2], F)
        assert np.allclose(L @ v, num, rtol=1e-6, atol=1e-6)
        # and the depth row is dZ/dt = -v_z
        assert np.isclose(((P - v * h)[2] - (P + v * h)[2]) / (2 * h), -v[2])


def test_seed_matrices_are_negatives_of_the_standard_ones():
    xy = np.array([[12.0, -7.0], [0.0, 0.0]])
    Z = np.array([0.8, 1.1])
    assert np.allclose(seed_image_jacobian(xy, Z, F), -point_interaction(xy, Z, F).reshape(-1, 3))
    # at the principal point L_c is the negative of [L_xy; 0 0 -1]
    L_full = np.vstack([point_interaction([0.0, 0.0], 0.9, F), [0, 0, -1.0]])
    assert np.allclose(hybrid_matrix(0.9, F), -L_full)


def test_hybrid_law_sign_moves_towards_the_goal():
    # square right of and farther than the goal: move right (+x) and forward (+z)
    v, e, _ = hybrid_law([340.0, 240.0, 0.9], [320.0, 240.0, 0.8], (320, 240), F, 1.0)
    assert v[0] > 0 and v[2] > 0 and abs(v[1]) < 1e-12
    assert np.allclose(e, [-20.0, 0.0, -0.1])


def test_interaction_rejects_bad_depth():
    with pytest.raises(ValueError, match="Z"):
        point_interaction([0.0, 0.0], 0.0, F)
    with pytest.raises(ValueError, match="Z"):
        hybrid_matrix(float("nan"), F)


# --------------------------------------------------------------------------- closed kinematic loops
def _square_world(size=0.1, z=0.0):
    h = size / 2
    return np.array([[0, 0, z], [-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]], float)


def _goal_for(c_goal, pts):
    return GoalFeatures(features=_features_of(pts - c_goal), f_px=F, principal_uv=np.array([320.0, 240.0]))


def _simulate(law: LawConfig, c0, c_goal, T=8.0, dt=0.005):
    """Camera translating (orientation fixed, looking along world z) towards a square on the plane z = 0.8 ahead."""
    pts = _square_world(z=0.8)
    goal = _goal_for(c_goal, pts)
    c = np.array(c0, float)
    log = []
    for k in range(int(T / dt)):
        cmd = servo_command(_features_of(pts - c), goal, law)
        assert cmd.ok
        log.append((k * dt, cmd.error.copy(), c.copy()))
        c = c + cmd.v_cam * dt
    return log


def test_hybrid_law_drives_an_ideal_camera_to_the_goal_with_exponential_decay():
    lam = 1.5
    law = LawConfig(law="hybrid", gain=AdaptiveGain(lambda_0=lam, lambda_inf=lam, slope_0=0.0), v_max_m_s=10.0)
    c_goal = np.zeros(3)
    log = _simulate(law, [0.05, -0.04, 0.15], c_goal)
    t = np.array([r[0] for r in log])
    ez = np.array([r[1][2] for r in log])
    # e_z obeys de/dt = -lambda e exactly (Euler steps)
    assert np.allclose(ez, ez[0] * (1 - lam * 0.005) ** np.arange(len(t)), rtol=1e-9, atol=1e-12)
    eu = np.array([r[1][0] for r in log])
    assert abs(eu[0]) > 10 and abs(eu[-1]) < 1e-3
    # late decay rate of the image error is lambda (coupling terms vanish at the goal)
    k1, k2 = int(3.0 / 0.005), int(5.0 / 0.005)
    rate = -np.log(abs(eu[k2]) / abs(eu[k1])) / (t[k2] - t[k1])
    assert rate == pytest.approx(lam, rel=0.02)
    assert np.linalg.norm(log[-1][2] - c_goal) < 1e-4


@pytest.mark.parametrize("mode", ["current", "desired", "mean"])
def test_classical_ibvs_with_four_points_converges(mode):
    law = LawConfig(law="ibvs", interaction=mode, gain=AdaptiveGain(lambda_0=1.0, lambda_inf=1.0, slope_0=0.0),
                    v_max_m_s=10.0)
    c_goal = np.array([0.0, 0.0, 0.0])
    log = _simulate(law, [0.08, 0.05, -0.2], c_goal, T=10.0)
    assert np.linalg.norm(log[-1][2] - c_goal) < 1e-4
    errs = [np.linalg.norm(r[2] - c_goal) for r in log]
    assert errs[-1] < 1e-3 * errs[0]


def test_ibvs_law_pseudo_inverse_matches_explicit_pinv():
    rng = np.random.default_rng(3)
    uv = rng.uniform(100, 500, (4, 2))
    uv_star = uv + rng.normal(0, 5, (4, 2))
    Z = rng.uniform(0.6, 1.0, 4)
    v, _ = ibvs_law(uv, Z, uv_star, Z, (320, 240), F, 0.7)
    L = point_interaction(uv - [320, 240], Z, F).reshape(-1, 3)
    assert np.allclose(v, -0.7 * np.linalg.pinv(L) @ (uv - uv_star).ravel())


# --------------------------------------------------------------------------- gain, limit, zero commands
def test_adaptive_gain_formula():
    l0, linf, s0 = 4.0, 0.5, 20.0
    assert adaptive_gain(0.0, l0, linf, s0) == pytest.approx(l0)
    assert adaptive_gain(1e6, l0, linf, s0) == pytest.approx(linf)
    h = 1e-7
    slope = (adaptive_gain(h, l0, linf, s0) - adaptive_gain(0.0, l0, linf, s0)) / h
    assert slope == pytest.approx(-s0, rel=1e-4)
    x = 0.03
    assert adaptive_gain(x, l0, linf, s0) == pytest.approx((l0 - linf) * np.exp(-s0 * x / (l0 - linf)) + linf)
    assert AdaptiveGain(lambda_0=2.0, lambda_inf=2.0, slope_0=5.0)(0.3) == 2.0
    with pytest.raises(ValueError, match="gain"):
        AdaptiveGain(lambda_0=-1.0)


def test_velocity_limit_keeps_direction():
    v = np.array([0.3, -0.4, 1.2])
    w = limit_velocity(v, 0.1)
    assert np.linalg.norm(w) == pytest.approx(0.1)
    assert np.allclose(w / np.linalg.norm(w), v / np.linalg.norm(v))
    assert np.allclose(limit_velocity([0.01, 0, 0], 0.1), [0.01, 0, 0])
    pts = _square_world(z=0.8)
    goal = _goal_for(np.zeros(3), pts)
    cmd = servo_command(_features_of(pts - [0.3, 0.2, -0.3]), goal, LawConfig(v_max_m_s=0.05))
    assert cmd.ok and np.linalg.norm(cmd.v_cam) == pytest.approx(0.05)


def test_zero_command_on_lost_features_or_invalid_depth():
    pts = _square_world(z=0.8)
    goal = _goal_for(np.zeros(3), pts)
    good = _features_of(pts - [0.02, 0.0, 0.0])
    assert servo_command(good, goal).ok
    lost = SquareFeatures.lost("gone")
    for law in ("hybrid", "ibvs"):
        c = servo_command(lost, goal, LawConfig(law=law))
        assert not c.ok and np.array_equal(c.v_cam, np.zeros(3))
    nan_c = SquareFeatures(found=True, centroid_uv=good.centroid_uv, center_uv=good.center_uv,
                           corners_uv=good.corners_uv, depth_m=np.r_[np.nan, good.depth_m[1:]])
    c = servo_command(nan_c, goal)
    assert not c.ok and not np.any(c.v_cam) and "depth" in c.reason
    nan_corner = SquareFeatures(found=True, centroid_uv=good.centroid_uv, center_uv=good.center_uv,
                                corners_uv=good.corners_uv, depth_m=np.r_[good.depth_m[:4], np.nan])
    assert servo_command(nan_corner, goal).ok                              # hybrid needs the centroid only
    c = servo_command(nan_corner, goal, LawConfig(law="ibvs"))
    assert not c.ok and not np.any(c.v_cam)
    with pytest.raises(ValueError, match="goal"):
        GoalFeatures(features=nan_c, f_px=F, principal_uv=np.array([320.0, 240.0]))


# --------------------------------------------------------------------------- joint map
def test_point_jacobian_matches_finite_differences():
    T_ee_cam = default_T_ee_cam(0.07)
    rng = np.random.default_rng(1)
    for _ in range(10):
        th = rng.uniform([-1, 0.1, -1.5], [1, 1.5, 1.5])
        J = point_jacobian(th, T_ee_cam[:3, 3])
        h = 1e-6
        num = np.zeros((3, 3))
        for j in range(3):
            d = np.zeros(3)
            d[j] = h
            num[:, j] = ((T_base_ee(th + d) @ T_ee_cam)[:3, 3] - (T_base_ee(th - d) @ T_ee_cam)[:3, 3]) / (2 * h)
        assert np.allclose(J, num, atol=1e-7)
    assert np.allclose(point_jacobian(th), jacobian_ee(th))


def test_joint_velocity_realises_the_camera_velocity():
    T_ee_cam = default_T_ee_cam()
    th = np.deg2rad([10.0, 5.0, -80.0])
    v_cam = np.array([0.01, -0.02, 0.015])
    cmd = joint_velocity(v_cam, th, T_ee_cam)
    assert cmd.ok
    R = (T_base_ee(th) @ T_ee_cam)[:3, :3]
    assert np.allclose(point_jacobian(th, T_ee_cam[:3, 3]) @ cmd.theta_dot, R @ v_cam, atol=1e-9)


def test_joint_velocity_stops_near_singularities_and_range_ends():
    p = load_robot_params()
    T = default_T_ee_cam(0.0)
    # straight up: theta1 cannot move the end effector (reach 0)
    cmd = joint_velocity([0.02, 0.0, 0.0], [0.0, np.pi / 2, 0.0], T)
    assert not cmd.ok and not np.any(cmd.theta_dot) and "singular" in cmd.reason
    # stretched arm (theta3 = 0) is singular too
    cmd = joint_velocity([0.0, 0.02, 0.0], [0.0, 0.3, 0.0], T)
    assert not cmd.ok and not np.any(cmd.theta_dot)
    # joint 3 at its lower end, asked to go further
    th = np.array([0.0, 0.2, p.joint_limits_rad[2, 0] + np.deg2rad(1.0)])
    v_base = jacobian_ee(th) @ np.array([0.0, 0.0, -0.2])
    R = (T_base_ee(th) @ T)[:3, :3]
    cmd = joint_velocity(R.T @ v_base, th, T)
    assert not cmd.ok and "joint 3" in cmd.reason and not np.any(cmd.theta_dot)
    # the opposite direction is fine
    assert joint_velocity(-R.T @ v_base, th, T).ok
    # huge camera velocities are scaled to the speed limits, never beyond
    cfg = JointMapConfig(speed_fraction=0.5)
    cmd = joint_velocity([5.0, 5.0, 5.0], np.deg2rad([0.0, 5.0, -80.0]), T, config=cfg)
    assert cmd.ok and np.all(np.abs(cmd.theta_dot) <= 0.5 * p.max_speed_rad_s + 1e-12)
    # damped near (not at) a singularity: bounded
    cmd = joint_velocity([0.0, 0.02, 0.0], [0.0, 0.3, 0.25], T)
    assert np.all(np.abs(cmd.theta_dot) <= 0.5 * p.max_speed_rad_s + 1e-12)
