"""Collision core: identification, momentum residual, isolation, reaction admittance."""
import numpy as np
import pytest

from tudorvision.joint.collision import (Admittance, CollisionMonitor, MomentumObserver, ReactionConfig, isolate,
                                         reaction_config, thresholds_from_residuals)
from tudorvision.joint.strain_dynamics import (N_PARAMS, StrainDynamicsModel, aprbs, derivatives, fit_report,
                                               fit_strain_dynamics, regressor, regressor_payload)


def _true_model(rng):
    chi = rng.normal(0.0, 1.0, size=(2, 2 * N_PARAMS)) * 1e-5
    chi[:, 7:16] *= 10.0                      # gravity terms dominate, as on the arm
    return StrainDynamicsModel(chi=chi)


def _trajectory(t):
    """Smooth joint motion with analytic derivatives (joint 1 at rest)."""
    w = np.array([0.0, 1.3, 2.1])
    amp = np.array([0.0, 0.6, 0.8])
    off = np.array([0.0, 0.9, -0.2])
    th = off + amp * np.sin(w * t[:, None])
    d = amp * w * np.cos(w * t[:, None])
    dd = -amp * w**2 * np.sin(w * t[:, None])
    return th, d, dd


def test_least_squares_recovers_known_coefficients():
    rng = np.random.default_rng(1)
    true = _true_model(rng)
    n = 4000
    th = rng.uniform([0, -0.2, -1.5], [0, 3.2, 1.5], size=(n, 3))
    d = rng.uniform(-1.2, 1.2, size=(n, 3))
    dd = rng.uniform(-4.0, 4.0, size=(n, 3))
    m = rng.choice([0.05, 0.15, 0.25, 0.35, 0.45], size=n)
    eps = true.predict(th, d, dd, m) + rng.normal(0.0, 1e-8, size=(n, 2))
    est = fit_strain_dynamics(th, d, dd, eps, m)
    np.testing.assert_allclose(est.chi, true.chi, atol=2e-8)
    rep = fit_report(est, th, d, dd, eps, m)
    assert min(rep.fit_pct) > 99.0 and max(rep.rmse) < 2e-8
    with pytest.raises(ValueError, match="samples"):
        fit_strain_dynamics(th[:5], d[:5], dd[:5], eps[:5], m[:5])


def test_regressor_shapes_and_errors():
    z = np.zeros((4, 3))
    assert regressor(z, z, z).shape == (4, N_PARAMS)
    assert regressor_payload(z, z, z, 0.3).shape == (4, 2 * N_PARAMS)
    with pytest.raises(ValueError, match="dtheta"):
        regressor(z, np.zeros((3, 3)), z)


def test_derivatives_of_a_sine():
    t = np.arange(0, 3, 5e-4)
    th, d, dd = _trajectory(t)
    de, dde = derivatives(t, th)
    inner = slice(100, -100)
    np.testing.assert_allclose(de[inner], d[inner], atol=1e-5)
    np.testing.assert_allclose(dde[inner], dd[inner], atol=1e-2)


def test_momentum_residual_tracks_collision_strain():
    """Model-consistent strains give a zero residual; a collision strain appears through K_I / (s + K_I)."""
    rng = np.random.default_rng(2)
    model = _true_model(rng)
    dt, k_i = 5e-4, 80.0
    t = np.arange(0, 2.0, dt)
    th, d, dd = _trajectory(t)
    eps = model.predict(th, d, dd, 0.3)
    eps_c = np.where(t >= 1.0, 40e-6, 0.0)
    eps[:, 1] += eps_c                          # a push on link 3
    obs = MomentumObserver(model, 0.3, k_i=k_i, dt=dt)
    r = np.array([obs.step(th[k], d[k], eps[k]) for k in range(t.size)])
    assert np.max(np.abs(r[t < 1.0])) < 1e-7    # no false residual from the motion
    k = np.searchsorted(t, 1.0 + 1.0 / k_i)
    assert r[k, 1] == pytest.approx(40e-6 * (1 - np.exp(-1)), rel=0.03)
    assert r[-1, 1] == pytest.approx(40e-6, rel=1e-3)
    assert abs(r[-1, 0]) < 1e-7                 # the other link stays quiet
    assert isolate(r[-1], [5e-6, 5e-6]) == (3, 1)
    with pytest.raises(ValueError, match="k_i"):
        MomentumObserver(model, 0.3, k_i=0.0, dt=dt)


def test_isolation_prefers_last_link_and_sign():
    assert isolate([-9e-6, 0.0], [4e-6, 4e-6]) == (2, -1)
    assert isolate([9e-6, 6e-6], [4e-6, 4e-6]) == (3, 1)


def test_thresholds_six_sigma():
    r = np.random.default_rng(5).normal(0, 2e-6, size=(50000, 2))
    np.testing.assert_allclose(thresholds_from_residuals(r), 12e-6, rtol=0.02)


def test_admittance_first_order_and_strategies():
    c = ReactionConfig(strategy="reflex", m_r=0.1, f_r=0.5, k_r=0.0, k_or=2.0, v_max=10.0)
    a = Admittance(c, 1e-3)
    v = [a.step(0.1) for _ in range(3000)]
    tau_s = c.m_r / c.f_r
    assert v[int(tau_s / 1e-3) - 1] == pytest.approx(0.4 * (1 - np.exp(-1)), rel=0.02)
    assert v[-1] == pytest.approx(0.4, rel=1e-3)           # k_or tau / f_r
    spring = Admittance(ReactionConfig(strategy="reflex", m_r=0.1, f_r=0.5, k_r=2.0), 1e-3)
    x = [spring.step(0.1) for _ in range(20000)]
    assert abs(x[-1]) < 1e-4 and spring.x == pytest.approx(0.05, rel=1e-2)   # settles at tau / k_r
    assert reaction_config("interaction").k_or == 1.0 and reaction_config("reflex").k_or > 1.0
    with pytest.raises(ValueError, match="strategy"):
        ReactionConfig(strategy="run")
    with pytest.raises(ValueError, match="m_r"):
        ReactionConfig(m_r=0.0)


def test_monitor_replaces_velocity_reference():
    model = StrainDynamicsModel(chi=np.zeros((2, 2 * N_PARAMS)))
    th, d = [0.0, 0.5, 0.1], [0.0, 0.0, 0.0]
    for strategy, expect_move in (("stop", False), ("reflex", True), ("none", None)):
        mon = CollisionMonitor(model, [5e-6, 5e-6], 0.3, 1e-3, reaction_config(strategy), k_i=200.0)
        outs = [mon.step(th, d, [0.0, 0.0, 30e-6, 0.0], [1.0, 1.0, 1.0], [0.5, 0.5, 0.5], [0.0, 0.01, 0.0])
                for _ in range(100)]
        assert mon.collision and mon.link == 3 and mon.direction == 1
        assert mon.detected_at < 0.01
        if strategy == "none":
            assert outs[-1] is None
            continue
        th_ref, dth_ref, extra = outs[-1]
        assert th_ref == th and dth_ref == [0.0, 0.0, 0.0]
        assert extra[1] == pytest.approx(0.01)                 # damping input kept
        if expect_move:
            assert extra[2] < -1e-3                            # tension on top: retreat toward lower theta3
        else:
            assert extra[2] == 0.0
        mon.reset()
        assert not mon.collision


def test_aprbs_levels_in_range():
    t, lv = aprbs(np.random.default_rng(0), 30.0, [0.1, -1.0], [2.0, 1.0])
    assert np.all(lv >= [0.1, -1.0]) and np.all(lv <= [2.0, 1.0]) and t[-1] < 30.0


def _monitor_on(strain_rows, dt=5e-4, window=0.015):
    """Run a monitor with a zero model (residual = strain through K_I / (s + K_I)) over strain samples."""
    mon = CollisionMonitor(StrainDynamicsModel(chi=np.zeros((2, 2 * N_PARAMS))), [10e-6, 10e-6], 0.3, dt,
                           reaction_config("none"), k_i=2000.0, isolation_window_s=window)
    th, d = [0.0, 0.5, 0.1], [0.0, 0.0, 0.0]
    for row in strain_rows:
        mon.step(th, d, row, th, d, [0.0, 0.0, 0.0])
    return mon


def test_isolation_window_separates_link2_impact_transient_from_link3_contact():
    dt = 5e-4
    t = np.arange(0.0, 0.1, dt)
    rng = np.random.default_rng(11)
    for _ in range(5):
        amp2, amp3, t0 = rng.uniform(30e-6, 80e-6), rng.uniform(20e-6, 60e-6), rng.uniform(0.01, 0.03)
        on = t >= t0
        # link-2 impact: persistent link-2 load, link-3 transient one way (~6 ms) then the other
        e3 = np.where(on & (t < t0 + 0.006), amp3, np.where(on & (t < t0 + 0.03), -amp3, 0.0))
        link2 = np.stack([np.where(on, amp2, 0.0), np.zeros_like(t), e3, np.zeros_like(t)], axis=1)
        mon = _monitor_on(link2, dt)
        assert mon.collision and mon.isolated and (mon.link, mon.direction) == (2, 1)
        assert mon.detected_at == pytest.approx(t0, abs=2e-3)
        plain = _monitor_on(link2, dt, window=0.0)               # the plain rule at first violation: link 3
        assert plain.isolated and plain.link == 3
        # link-3 contact: both roots loaded with one sign for the contact duration
        link3 = np.stack([np.where(on, amp2, 0.0), np.zeros_like(t), np.where(on, -amp3, 0.0),
                          np.zeros_like(t)], axis=1)
        mon = _monitor_on(link3, dt)
        assert mon.isolated and (mon.link, mon.direction) == (3, -1)
    with pytest.raises(ValueError, match="isolation_window_s"):
        _monitor_on([], window=-1.0)


def test_monitor_arms_after_the_given_time():
    rows = np.tile([0.0, 0.0, 30e-6, 0.0], (200, 1))              # a violation from the second sample
    mon = CollisionMonitor(StrainDynamicsModel(chi=np.zeros((2, 2 * N_PARAMS))), [10e-6, 10e-6], 0.3, 5e-4,
                           reaction_config("none"), k_i=2000.0, armed_after_s=0.05)
    for row in rows:
        mon.step([0.0, 0.5, 0.1], [0.0] * 3, row, [0.0] * 3, [0.0] * 3, [0.0] * 3)
        if mon.collision:
            break
    assert mon.detected_at == pytest.approx(0.0505, abs=1e-9)    # the first armed sample (k_i dt = 1)


def test_detection_highpass_removes_slow_unmodelled_strain_and_keeps_contact_onset():
    """Residual of a zero model = strain; a 1.5 Hz oscillation is attenuated, a step onset passes."""
    dt, fc = 5e-4, 5.0
    t = np.arange(0.0, 3.0, dt)
    zero = StrainDynamicsModel(chi=np.zeros((2, 2 * N_PARAMS)))

    def run(rows, hp):
        mon = CollisionMonitor(zero, [np.inf, np.inf], 0.3, dt, reaction_config("none"), k_i=2000.0,
                               detect_highpass_hz=hp)
        out = []
        for row in rows:
            mon.step([0.0, 0.5, 0.1], [0.0] * 3, row, [0.0] * 3, [0.0] * 3, [0.0] * 3)
            out.append(mon.residual[1])
        return np.asarray(out)

    osc = np.zeros((t.size, 4))
    osc[:, 0] = 100e-6 * np.sin(2 * np.pi * 1.5 * t)
    tail = t > 1.0
    ratio = np.abs(run(osc, fc)[tail]).max() / np.abs(run(osc, 0.0)[tail]).max()
    # first-order high-pass gain at 1.5 Hz: (f/fc) / sqrt(1 + (f/fc)^2) = 0.287
    assert ratio == pytest.approx(0.287, abs=0.02)
    step = np.zeros((t.size, 4))
    step[t >= 1.0, 0] = 100e-6
    r = run(step, fc)
    k = np.searchsorted(t, 1.005)                 # 5 ms after onset: exp(-2 pi fc 5 ms) = 0.855 remains
    assert r[k] == pytest.approx(100e-6 * np.exp(-2 * np.pi * fc * 0.005), rel=0.05)
    assert abs(r[-1]) < 1e-6                      # a sustained load fades from the detection residual
    with pytest.raises(ValueError, match="detect_highpass_hz"):
        CollisionMonitor(zero, [1e-5, 1e-5], 0.3, dt, detect_highpass_hz=-1.0)


def test_input_lag_keeps_model_consistent_residual_small():
    """With all inputs through the same first-order filter, a model-consistent motion gives a small residual."""
    rng = np.random.default_rng(5)
    model = _true_model(rng)
    dt, td = 5e-4, 0.003
    t = np.arange(0, 2.0, dt)
    th, d, dd = _trajectory(t)
    eps = model.predict(th, d, dd, 0.3)
    a = dt / (td + dt)
    d_f = np.zeros_like(d)                      # the cascade's filtered velocity
    d_f[0] = d[0]
    for k in range(1, t.size):
        d_f[k] = d_f[k - 1] + a * (d[k] - d_f[k - 1])
    res = {}
    for lag in (0.0, td):
        obs = MomentumObserver(model, 0.3, k_i=100.0, dt=dt, input_lag_s=lag)
        res[lag] = np.array([obs.step(th[k], d_f[k], eps[k]) for k in range(t.size)])
    assert np.abs(res[td][t > 0.2]).max() < 0.5 * np.abs(res[0.0][t > 0.2]).max()
    with pytest.raises(ValueError, match="input_lag_s"):
        MomentumObserver(model, 0.3, dt=dt, input_lag_s=-1.0)
