"""Damping core: static strain cancellation, damping laws, closed loop on the simulated arm."""
import math

import numpy as np
import pytest
from scipy import signal

from tudorvision.joint.damping import (DampingConfig, SosFilter, StaticStrainFilter, StrainDamper,
                                       default_damping_config, half_integrator_sos, highpass_response,
                                       moving_average_fir, pade_p55, proportional_feedback, static_strain_fir)


# --------------------------------------------------------------- static strain cancellation
@pytest.mark.parametrize("freq_hz", [0.7, 2.3, 9.0])
def test_filter_matches_analytic_frequency_response(freq_hz):
    """Steady-state gain and phase of the running filter equal (1 - M)^2 at e^{jw}."""
    fs, n = 2000.0, 1000
    k = np.arange(int(6 * fs))
    x = 1e-4 * np.sin(2 * np.pi * freq_hz * k / fs)
    f = StaticStrainFilter([0.0], n_window=n)
    y = np.array([f.step([v])[1][0] for v in x])
    H = highpass_response([freq_hz], n, fs)[0]
    expect = 1e-4 * np.abs(H) * np.sin(2 * np.pi * freq_hz * k / fs + np.angle(H))
    tail = k > 2 * n + 10
    assert np.max(np.abs(y[tail] - expect[tail])) < 1e-9


def test_fir_coefficients_frequency_response():
    b = static_strain_fir(50)
    w, h = signal.freqz(b, worN=np.linspace(0.01, 3.0, 50))
    H = highpass_response(w * 100.0 / (2 * np.pi), 50, 100.0)
    np.testing.assert_allclose(1.0 - h, H, atol=1e-12)
    # 40 dB/decade edge: a tenfold lower frequency attenuates about 100 times
    lo = np.abs(highpass_response([0.01, 0.1], 50, 100.0))
    assert 90 < lo[1] / lo[0] < 110


def test_filter_removes_constant_and_ramp():
    fs, n = 2000.0, 200
    t = np.arange(3000) / fs
    eps = 3e-4 + 2e-4 * t
    f = StaticStrainFilter([eps[0]], n_window=n)
    out = np.array([f.step([v])[1][0] for v in eps])
    assert np.max(np.abs(out[2 * n:])) < 1e-12          # double zero at DC
    assert np.max(np.abs(out[:2 * n])) > 1e-6            # while the windows fill, the lag shows


def test_decimated_filter_is_the_100hz_filter():
    rng = np.random.default_rng(3)
    x100 = np.cumsum(rng.normal(size=300)) * 1e-5
    f = StaticStrainFilter([0.0], n_window=50, decimation=20)
    out = []
    for v in x100:
        for _ in range(20):
            out.append(f.step([v])[0][0])
    mu = np.array(out)[::20]
    ref = signal.lfilter(static_strain_fir(50), [1.0], x100)     # zero initial state = filled with 0
    np.testing.assert_allclose(mu, ref, atol=1e-15)


def test_filter_arguments():
    with pytest.raises(ValueError, match="n_window"):
        StaticStrainFilter([0.0], n_window=0)
    with pytest.raises(ValueError, match="n_window"):
        moving_average_fir(0)


# --------------------------------------------------------------- laws
def test_proportional_sign_and_units():
    np.testing.assert_allclose(proportional_feedback([2e-4, -1e-4, 0.0], [100.0, 100.0, 1.0]), [-0.02, 0.01, 0.0])


def test_pade_p55_approximates_half_integrator_on_band():
    ds, dt = 2 * np.pi * 3.0, 5e-4
    sos = half_integrator_sos(ds, dt)
    f = np.geomspace(0.5, 20.0, 25)
    _, h = signal.sosfreqz(sos, worN=2 * np.pi * f * dt)
    ref = 1.0 / np.sqrt(1j * 2 * np.pi * f)
    err_db = 20 * np.log10(np.abs(h) / np.abs(ref))
    assert np.max(np.abs(err_db)) < 0.1
    assert np.max(np.abs(np.degrees(np.angle(h)) + 45.0)) < 1.0
    # far outside the band the approximant departs (finite DC gain): the test can fail
    _, h0 = signal.sosfreqz(sos, worN=[2 * np.pi * 0.01 * dt])
    assert abs(20 * np.log10(abs(h0[0]) * math.sqrt(2 * np.pi * 0.01))) > 3.0
    num, den = pade_p55(ds)
    assert np.all(np.real(np.roots(den)) < 0)
    with pytest.raises(ValueError, match="shift"):
        pade_p55(0.0)


def test_sos_filter_matches_scipy():
    sos = half_integrator_sos(10.0, 1e-3)
    x = np.random.default_rng(0).normal(size=500)
    f = SosFilter(sos)
    y = [f.step(v) for v in x]
    np.testing.assert_allclose(y, signal.sosfilt(sos, x), rtol=1e-10, atol=1e-12)


def test_damper_laws_outputs():
    k = (0.0, 100.0, 50.0)
    e = [1e-4, 0.0, -2e-4, 0.0]
    p = StrainDamper(DampingConfig(law="proportional", k_eps=k, n_window=10), [0.0] * 4, 1e-3)
    dv, dth = p.step(e)
    assert dth == [0.0, 0.0, 0.0] and dv[0] == 0.0
    assert dv[1] < 0 < dv[2]                       # -k eps_tilde with link-2 and link-3 root gauges
    i = StrainDamper(DampingConfig(law="integral", k_eps=k, n_window=10), [0.0] * 4, 1e-3)
    outs = [i.step(e)[1][1] for _ in range(3)]
    assert outs[0] < 0 and outs[2] < outs[1] < outs[0]        # integrates
    assert i.pd_scale == 0.5 and p.pd_scale == 1.0
    h = StrainDamper(DampingConfig(law="half_integrator", k_eps=k, n_window=10), [0.0] * 4, 1e-3)
    assert h.step(e)[1][1] < 0
    off = StrainDamper(default_damping_config("off"), [0.0] * 4, 1e-3)
    assert off.step(e) == ([0.0] * 3, [0.0] * 3)
    with pytest.raises(ValueError, match="law"):
        DampingConfig(law="pid")
    with pytest.raises(ValueError, match="k_eps"):
        DampingConfig(law="proportional", k_eps=(1.0, 2.0))


def test_coulomb_friction_switch_of_the_plant_sticks_or_slides():
    """PlantConfig(coulomb_friction=False) (the chapter-8 diagnostic) removes sticking, keeps the rest."""
    from tudorvision.robot import load_robot_params
    from tudorvision.sim.arm import ElasticArm, PlantConfig
    p = load_robot_params()
    moved = {}
    for coulomb in (True, False):
        cfg = PlantConfig(gravity=False, elastic=False, coulomb_friction=coulomb)
        arm = ElasticArm([0.0, 1.0, 0.0], params=p, config=cfg)
        k_m = arm.kM[1]
        tau = 0.5 * float(p.gear_ratio[1] * min(p.coulomb_pos_Nm[1], p.coulomb_neg_Nm[1]))  # half the breakaway
        for _ in range(400):
            arm.step([0.0, tau / k_m, 0.0])
        moved[coulomb] = arm.theta[1] - 1.0
    assert moved[True] == 0.0                 # below breakaway: the joint sticks
    assert moved[False] > 1e-4                # without Coulomb friction the same torque turns it


# --------------------------------------------------------------- model-assisted static strain cancellation
class _QuasiStaticModel:
    """Root strains of a known linear quasi-static law, ``a sin(theta2) + b ddtheta2`` (links 2, 3)."""

    def __init__(self, a=(4e-4, 1e-4), b=(3e-5, -2e-5)):
        self.a, self.b = np.asarray(a), np.asarray(b)
        self.calls = []

    def predict(self, theta, dtheta, ddtheta, payload_kg):
        th, ddth = np.asarray(theta), np.asarray(ddtheta)
        self.calls.append((th.copy(), np.asarray(dtheta).copy(), ddth.copy(), payload_kg))
        return np.sin(th[:, 1:2]) * self.a + ddth[:, 1:2] * self.b


def _motion(n, dt):
    """Smooth 0 -> 0.8 rad move of joint 2 (cosine velocity profile over 0.6 s), then rest."""
    t = np.arange(n) * dt
    T = 0.6
    tau = np.clip(t / T, 0.0, 1.0)
    th2 = 0.8 * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi))
    dth2 = np.where(t < T, 0.8 / T * (1 - np.cos(2 * np.pi * tau)), 0.0)
    ddth2 = np.where(t < T, 0.8 / T * (2 * np.pi / T) * np.sin(2 * np.pi * tau), 0.0)
    return th2, dth2, ddth2


def test_model_assisted_cancellation_removes_the_quasi_static_strain():
    """Strain = the model's quasi-static strain + an oscillation: with the model the filter output is
    the oscillation from the start (oracle: the same filter applied to the oscillation alone), without
    it the quasi-static change leaks through for the filter's 2N samples."""
    dt, n = 1e-3, 3000
    th2, dth2, ddth2 = _motion(n, dt)
    osc = 2e-5 * np.sin(2 * np.pi * 2.5 * np.arange(n) * dt)
    model = _QuasiStaticModel()
    ref = [([0.0, th2[k], 0.0], [0.0, dth2[k], 0.0], [0.0, ddth2[k], 0.0]) for k in range(n)]
    q = model.predict(np.array([r[0] for r in ref]), None, np.array([r[2] for r in ref]), 0.3)
    model.calls.clear()
    strain = np.zeros((n, 4))
    strain[:, 0] = 1e-4 + q[:, 0] + osc
    strain[:, 2] = -5e-5 + q[:, 1] - osc
    cfg = DampingConfig(law="proportional", k_eps=(0.0, 100.0, 100.0), n_window=200)
    plain = StrainDamper(cfg, strain[0], dt)
    assisted = StrainDamper(cfg, strain[0], dt, strain_model=model, payload_kg=0.3)
    oracle = StaticStrainFilter([0.0, 0.0], n_window=200)
    e_plain, e_ass, e_or, dv_ass = [], [], [], []
    for k in range(n):
        plain.step(strain[k], ref[k])                                    # no model: reference ignored
        e_plain.append(plain.eps_tilde[0])
        dv, _ = assisted.step(strain[k], ref[k])
        e_ass.append(assisted.eps_tilde[0])
        dv_ass.append(dv)
        e_or.append(oracle.step([osc[k], -osc[k]])[1])
    e_plain, e_ass, e_or = np.array(e_plain), np.array(e_ass), np.array(e_or)
    np.testing.assert_allclose(e_ass, e_or[:, 0], atol=1e-12)
    np.testing.assert_allclose(assisted.eps_tilde[2], e_or[-1, 1], atol=1e-12)
    assert np.max(np.abs(e_plain - e_or[:, 0])) > 5e-5             # the quasi-static change leaks
    assert dv_ass[-1][1] == pytest.approx(-100.0 * e_ass[-1])        # the law acts on the assisted signal
    # the model saw the cascade's reference and the payload at every step
    assert len(model.calls) == n and model.calls[7][3] == 0.3
    np.testing.assert_array_equal(model.calls[7][2], [ref[7][2]])


def test_model_assisted_damper_checks_and_falls_back_without_reference():
    cfg = DampingConfig(law="proportional", k_eps=(0.0, 100.0, 100.0), n_window=10)
    with pytest.raises(TypeError, match="strain_model"):
        StrainDamper(cfg, [0.0] * 4, 1e-3, strain_model=object())
    with pytest.raises(ValueError, match="payload_kg"):
        StrainDamper(cfg, [0.0] * 4, 1e-3, strain_model=_QuasiStaticModel(), payload_kg=-1.0)
    a = StrainDamper(cfg, [0.0] * 4, 1e-3, strain_model=_QuasiStaticModel())
    b = StrainDamper(cfg, [0.0] * 4, 1e-3)
    e = [1e-4, 0.0, -2e-4, 0.0]
    assert a.step(e) == b.step(e)                                    # no reference: the plain filter


def test_controlled_arm_passes_its_reference_to_the_damper():
    """ControlledArm hands the planned (theta, dtheta, ddtheta) to a damper with a strain model."""
    from tudorvision.robot import load_robot_params
    from tudorvision.sim.arm import ElasticArm, PlantConfig
    from tudorvision.joint.controlled import ControlledArm
    p = load_robot_params()
    arm = ElasticArm([0.0, 0.3, 0.0], params=p, config=PlantConfig())
    ca = ControlledArm(arm)
    model = _QuasiStaticModel()
    ca.set_damper(StrainDamper(DampingConfig(law="proportional", k_eps=(0.0, 10.0, 10.0)), arm.measured_strain(),
                               arm.config.dt, strain_model=model, payload_kg=0.35))
    ca.set_goal([0.0, 0.5, 0.0])
    for _ in range(200):
        ca.step()
    th, dth, ddth, m = model.calls[-1]
    planned = ca._planner.sample_scalar(arm.t - arm.config.dt)
    np.testing.assert_allclose(th[0], ca.theta_ref)
    np.testing.assert_allclose(dth[0], ca.dtheta_ref)
    np.testing.assert_allclose(ddth[0], planned[2], atol=1e-12)
    assert ddth[0][1] > 0 and m == 0.35                              # accelerating toward the goal
    # velocity mode: the acceleration is the ramp of the commanded velocity
    ca.set_velocity([0.0, -0.2, 0.0])
    ca.step()
    assert model.calls[-1][2][0][1] < 0


class _PredictOnly:
    """The identified model seen through ``predict`` alone (a user's own model has no ``predict_one``)."""

    def __init__(self, model):
        self.model = model

    def predict(self, theta, dtheta, ddtheta, payload_kg):
        return self.model.predict(theta, dtheta, ddtheta, payload_kg)


def test_model_assisted_damper_takes_the_identified_models_fast_path_with_the_same_output():
    """The identified model's one-sample path and a model with only ``predict`` damp identically, bit for bit."""
    from tudorvision.joint.strain_dynamics import StrainDynamicsModel
    dt, n = 1e-3, 1500
    th2, dth2, ddth2 = _motion(n, dt)
    rng = np.random.default_rng(3)
    model = StrainDynamicsModel(chi=rng.normal(0.0, 1e-4, (2, 32)))
    cfg = DampingConfig(law="proportional", k_eps=(0.0, 100.0, 100.0), n_window=100)
    strain = rng.normal(0.0, 2e-5, (n, 4))
    fast = StrainDamper(cfg, strain[0], dt, strain_model=model, payload_kg=0.2)
    slow = StrainDamper(cfg, strain[0], dt, strain_model=_PredictOnly(model), payload_kg=0.2)
    assert fast._predict_one is not None and slow._predict_one is None
    for k in range(n):
        ref = ([0.0, th2[k], -0.3 * th2[k]], [0.0, dth2[k], -0.3 * dth2[k]], [0.0, ddth2[k], -0.3 * ddth2[k]])
        assert fast.step(strain[k], ref) == slow.step(strain[k], ref)
        if k == n // 2:
            fast.set_payload(0.35)
            slow.set_payload(0.35)
    assert fast.eps_tilde == slow.eps_tilde
