"""Ball EKF, intercept and ballistic peer (section 9.3)."""
import numpy as np
import pytest

from tudorvision.catch import (BallEKF, BallModel, BallisticPredictor, EKFOptions, init_from_detections,
                               plane_crossing, propagate, reachable_solutions, update, working_plane_normal)
from tudorvision.catch.ball_model import ball_dynamics, dynamics_jacobian
from tudorvision.catch.intercept import InterceptOptions, InterceptPlanner
from tudorvision.robot import fk_ee
from tudorvision.lab.record import random_throw, throw_trajectory

CAM = np.array([0.0, -6.8, 2.0])


def _numjac(f, x, eps=1e-6):
    x = np.asarray(x, float)
    J = np.zeros((len(f(x)), len(x)))
    for i in range(len(x)):
        d = np.zeros_like(x); d[i] = eps
        J[:, i] = (f(x + d) - f(x - d)) / (2 * eps)
    return J


def test_dynamics_and_transition_jacobians_match_finite_differences():
    rng = np.random.default_rng(1)
    m = BallModel(drag_k_per_m=0.012)
    for _ in range(5):
        x = np.concatenate([rng.normal(size=3), rng.normal(size=3) * 4 + [0, 6, 2]])
        np.testing.assert_allclose(dynamics_jacobian(x, m), _numjac(lambda s: ball_dynamics(s, m), x), atol=1e-6)
        _, F = propagate(x, 0.2, m)
        Fn = _numjac(lambda s: propagate(s, 0.2, m, jacobian=False), x)
        np.testing.assert_allclose(F, Fn, atol=1e-6)
        assert np.abs(F[3:, 3:] - np.eye(3)).max() > 1e-3      # drag couples the velocities


def test_drag_free_limit_is_the_parabola():
    x0 = np.array([0.1, -5.0, 1.6, 0.2, 6.0, 3.0])
    for dt in (0.1, 0.45, 1.0):
        x = propagate(x0, dt, BallModel(drag_k_per_m=0.0), jacobian=False)
        p = x0[:3] + x0[3:] * dt + 0.5 * np.array([0, 0, -9.81]) * dt ** 2
        np.testing.assert_allclose(x[:3], p, atol=1e-10)
        np.testing.assert_allclose(x[3:], x0[3:] + np.array([0, 0, -9.81]) * dt, atol=1e-10)


def test_propagation_matches_the_simulator_flight():
    p0, v0 = np.array([0.0, -6.0, 1.7]), np.array([0.1, 6.5, 2.5])
    t, p, v = throw_trajectory(p0, v0, duration_s=0.9)
    x = propagate(np.r_[p0, v0], 0.9, BallModel(), jacobian=False)
    np.testing.assert_allclose(x[:3], p[-1], atol=1e-6)


def _meas_cov(p_base, rng=None):
    """Detector-like covariance: sigma along the viewing ray from the camera, small across."""
    r = p_base - CAM
    z = np.linalg.norm(r)
    r /= z
    s_along = 0.0135 * z ** 2 / 8        # ~ sigma_z(z) / sqrt(pixels)
    s_lat = 1.0 * z / 525
    return s_along ** 2 * np.outer(r, r) + s_lat ** 2 * (np.eye(3) - np.outer(r, r))


def _flight(rng, n_frames_max=40):
    p0, v0 = random_throw(rng)
    t, p, v = throw_trajectory(p0, v0, duration_s=1.6)
    i_cross = int(np.argmax(p[:, 1] > 0))
    # crossing by interpolation
    a = -p[i_cross - 1, 1] / (p[i_cross, 1] - p[i_cross - 1, 1])
    t_cross = t[i_cross - 1] + a * (t[i_cross] - t[i_cross - 1])
    p_cross = p[i_cross - 1] + a * (p[i_cross] - p[i_cross - 1])
    tf = np.arange(1, n_frames_max) / 30.0 + 0.01
    tf = tf[tf < t_cross]
    pf = np.array([[np.interp(s, t, p[:, j]) for j in range(3)] for s in tf])
    keep = np.linalg.norm(pf - CAM, axis=1) < 4.5     # visible within 4.5 m of the wall camera
    return tf[keep], pf[keep], t_cross, p_cross, (t, p, v)


def test_prediction_error_and_nees_on_noisy_dragged_flights():
    rng = np.random.default_rng(7)
    errs, errs_bal, nees = [], [], []
    for _ in range(25):
        tf, pf, t_cross, p_cross, (t, p, v) = _flight(rng)
        ekf = BallEKF()
        matched = BallEKF(EKFOptions(q_m2_s3=0.0))     # the simulator's flight is exactly the model
        bal = BallisticPredictor(working_plane_normal(0.0))
        last = None
        for ti, pi in zip(tf, pf):
            if ti > t_cross - 0.3:      # 300 ms before the crossing
                break
            R = _meas_cov(pi)
            z = rng.multivariate_normal(pi, R)
            ekf.step(ti, z, R)
            matched.step(ti, z, R)
            bal.add(ti, z)
            last = ti
        c = plane_crossing(ekf.x, ekf.P, working_plane_normal(0.0))
        errs.append(np.linalg.norm(c.p_base - p_cross))
        errs_bal.append(np.linalg.norm(bal.predict()[1] - p_cross))
        x_true = np.array([np.interp(last, t, a[:, j]) for a in (p, v) for j in range(3)])
        e = matched.x - x_true
        nees.append(float(e @ np.linalg.solve(matched.P, e)))
    assert np.median(errs) < 0.02
    assert np.median(errs) < 0.5 * np.median(errs_bal)    # the drag model beats the drag-free peer
    assert 6 * 0.6 < np.mean(nees) < 6 * 1.5               # consistent (chi-square, 6 dof, 25 runs)


def test_gating_rejects_an_outlier_and_keeps_the_estimate():
    rng = np.random.default_rng(3)
    tf, pf, *_ = _flight(rng)
    ekf = BallEKF()
    for ti, pi in zip(tf[:8], pf[:8]):
        ekf.step(ti, pi, _meas_cov(pi))
    x_before = ekf.x
    out = ekf.step(tf[8], pf[8] + [0.4, 0.0, 0.3], _meas_cov(pf[8]))
    assert out == "rejected"
    assert ekf.last_nis > ekf.options.gate_nis
    assert np.linalg.norm(ekf.x[:3] - pf[8]) < 0.05      # predicted, not pulled to the outlier
    assert ekf.step(tf[9], pf[9], _meas_cov(pf[9])) == "accepted"
    assert x_before is not None


def test_reset_on_a_new_throw():
    rng = np.random.default_rng(4)
    tf1, pf1, *_ = _flight(rng)
    tf2, pf2, *_ = _flight(rng)
    ekf = BallEKF()
    for ti, pi in zip(tf1, pf1):
        ekf.step(ti, pi, _meas_cov(pi))
    assert ekf.throw_id == 0
    t0 = tf1[-1] + 0.6       # after a pause: the gap starts a new throw
    states = [ekf.step(t0 + ti, pi, _meas_cov(pi)) for ti, pi in zip(tf2, pf2)]
    assert states[0] == "restarted" and "initialised" in states
    assert ekf.throw_id == 1
    assert np.linalg.norm(ekf.x[:3] - pf2[-1]) < 0.03
    # without a gap: consecutive gated detections restart the filter too
    ekf2 = BallEKF(EKFOptions(max_gap_s=10.0))
    for ti, pi in zip(tf1[:6], pf1[:6]):
        ekf2.step(ti, pi, _meas_cov(pi))
    states = [ekf2.step(tf1[5] + 0.02 * (i + 1), pf2[i], _meas_cov(pf2[i])) for i in range(8)]
    assert "restarted" in states and ekf2.throw_id == 1


def test_a_gap_in_the_flight_continues_the_throw_when_the_ball_fits():
    """The ball out of view for 0.3 s (a lob above the image) and back: the same throw, not a new one.

    Oracle: a filter that never starts a new throw on a gap (``max_gap_s`` beyond the gap) fed the
    same detections: identical states. With coasting off (``max_coast_s=0``) the gap restarts the
    filter as before; a detection after the gap that does not fit the flight restarts it too.
    """
    rng = np.random.default_rng(11)
    tf, pf, *_ = _flight(rng)
    noisy = pf + rng.normal(scale=0.002, size=pf.shape)
    seen = (tf < tf[2] + 1e-9) | (tf > tf[2] + 0.27)      # frames 3.. hidden for 0.3 s
    k = 3                                                   # the first detection after the gap
    assert tf[seen][k] - tf[seen][k - 1] > EKFOptions().max_gap_s and len(tf[seen]) >= k + 2
    coast, plain, old = BallEKF(EKFOptions(n_init=2)), BallEKF(EKFOptions(n_init=2, max_gap_s=1.0)), \
        BallEKF(EKFOptions(n_init=2, max_coast_s=0.0))
    states = {"coast": [], "old": []}
    for ti, pi in zip(tf[seen], noisy[seen]):
        states["coast"].append(coast.step(ti, pi, _meas_cov(pi)))
        plain.step(ti, pi, _meas_cov(pi))
        states["old"].append(old.step(ti, pi, _meas_cov(pi)))
    assert states["coast"][k] == "accepted" and "restarted" not in states["coast"] and coast.throw_id == 0
    np.testing.assert_allclose(coast.x, plain.x, rtol=0, atol=1e-12)
    assert states["old"][k] == "restarted" and old.throw_id == 1
    # a detection after the gap 0.5 m off the flight starts a new throw
    off = BallEKF(EKFOptions(n_init=2))
    for ti, pi in zip(tf[seen][:k], noisy[seen][:k]):
        off.step(ti, pi, _meas_cov(pi))
    t4, p4 = tf[seen][k], noisy[seen][k] + [0.5, 0.0, 0.0]
    assert off.step(t4, p4, _meas_cov(p4)) == "restarted"
    # beyond max_coast_s even a fitting detection starts a new throw
    late = BallEKF(EKFOptions(n_init=2, max_coast_s=0.28))
    for ti, pi in zip(tf[seen][:k], noisy[seen][:k]):
        late.step(ti, pi, _meas_cov(pi))
    assert late.step(tf[seen][k], noisy[seen][k], _meas_cov(noisy[seen][k])) == "restarted"
    with pytest.raises(ValueError, match="max_coast_s"):
        EKFOptions(max_coast_s=-1.0)


def test_init_and_update_reject_bad_input():
    with pytest.raises(ValueError, match="at least 2"):
        init_from_detections([0.0], np.zeros((1, 3)), np.eye(3)[None])
    with pytest.raises(ValueError, match="increasing"):
        init_from_detections([0.0, 0.0], np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)))
    with pytest.raises(ValueError, match="z"):
        update(np.zeros(6), np.eye(6), [1.0, 2.0], np.eye(3))
    with pytest.raises(ValueError, match="drag_k_per_m"):
        BallModel(drag_k_per_m=-1.0)


def test_plane_crossing_matches_an_analytic_case_in_a_rotated_plane():
    th1 = 0.4
    n = working_plane_normal(th1)
    x0 = np.array([0.2, -3.0, 1.5, 0.3, 5.0, 2.0])
    m = BallModel(drag_k_per_m=0.0)
    c = plane_crossing(x0, np.eye(6) * 1e-4, n, model=m, q_m2_s3=0.0)
    dt = -(n @ x0[:3]) / (n @ x0[3:])
    p = x0[:3] + x0[3:] * dt + 0.5 * np.array([0, 0, -9.81]) * dt ** 2
    assert c.dt_s == pytest.approx(dt, abs=1e-9)
    np.testing.assert_allclose(c.p_base, p, atol=1e-8)
    assert abs(n @ c.cov_base @ n) < 1e-12 * np.trace(c.cov_base) + 1e-15   # within the plane
    assert plane_crossing(x0 * [1, 1, 1, 1, -1, 1], np.eye(6), n, model=m) is None   # flying away


def test_reachability_and_release_policy():
    assert len(reachable_solutions(fk_ee([0.0, 1.2, 0.6]), 0.0)) == 2
    assert len(reachable_solutions([0.0, 0.0, 1.5], 0.0)) == 0       # above the reach
    assert len(reachable_solutions(fk_ee([0.5, 1.0, 0.3]), 0.0)) == 0   # not in the plane at theta1 = 0
    planner = InterceptPlanner(InterceptOptions(release_sigma_m=0.02))
    x = np.array([0.1, -2.0, 1.3, 0.0, 6.0, 1.0])
    assert not planner.update(0.0, x, np.eye(6) * 0.01).send          # too uncertain
    it = planner.update(0.1, x, np.eye(6) * 1e-6)
    assert it.reachable and it.send
    assert not planner.update(0.13, x, np.eye(6) * 1e-6).send         # same intercept: no resend
    x_high = x.copy(); x_high[5] = 4.0
    assert not planner.update(0.2, x_high, np.eye(6) * 1e-6).reachable
