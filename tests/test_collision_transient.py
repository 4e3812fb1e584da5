"""Threshold allowance for the soft links' inertial transient (joint.collision_transient)."""
import numpy as np
import pytest
from scipy.signal import lfilter

from tudorvision.joint.collision import CollisionMonitor, reaction_config
from tudorvision.joint.collision_transient import TRANSIENT_HOLD_S, TRANSIENT_TAU_S, TransientAllowance
from tudorvision.joint.strain_dynamics import N_PARAMS, StrainDynamicsModel

DT = 5e-4
I_CONST = np.array([[1e-4, 2e-5], [1e-5, 5e-5]])      # strain per rad/s^2


def test_allowance_matches_an_independent_filter_implementation():
    """Random planned speeds: the allowance is gain * held |u - lowpass(u)|, u = I a_ref (scipy oracle)."""
    rng = np.random.default_rng(4)
    n = 3000
    acc = np.repeat(rng.normal(0.0, 2.0, size=(n // 100, 2)), 100, axis=0)       # piecewise-constant accelerations
    dref = np.zeros((n, 3))
    dref[:, 1:] = np.cumsum(acc, axis=0) * DT
    gain = 1.3
    ta = TransientAllowance(DT, gain=gain)
    got = np.array([ta.step(I_CONST, d) for d in dref])
    a = np.vstack([np.zeros((1, 2)), np.diff(dref[:, 1:], axis=0) / DT])
    u = a @ I_CONST.T
    al = DT / (TRANSIENT_TAU_S + DT)
    hp = np.abs(u - lfilter([al], [1.0, al - 1.0], u, axis=0))
    want = np.empty_like(hp)
    held = np.zeros(2)
    for k in range(n):
        held = np.maximum(held * np.exp(-DT / TRANSIENT_HOLD_S), gain * hp[k])
        want[k] = held
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-15)


def test_allowance_is_the_change_of_inertial_strain_and_fades_in_steady_motion():
    ta = TransientAllowance(DT, gain=1.0)
    assert ta.step(I_CONST, (0.0, 0.3, 0.0)) == [0.0, 0.0]          # the first sample: no acceleration known
    speed = 0.3
    for _ in range(2000):                                              # constant speed: nothing
        assert ta.step(I_CONST, (0.0, speed, 0.0)) == [0.0, 0.0]
    speed += 2.0 * DT                                                  # joint 2 starts accelerating at 2 rad/s^2
    first = ta.step(I_CONST, (0.0, speed, 0.0))
    scale = 1.0 - DT / (TRANSIENT_TAU_S + DT)
    assert first == pytest.approx(list(2.0 * I_CONST[:, 0] * scale), rel=1e-12)
    for _ in range(int(0.6 / DT)):                                     # steady acceleration for 0.6 s
        speed += 2.0 * DT
        last = ta.step(I_CONST, (0.0, speed, 0.0))
    assert max(last) < 0.01 * max(first)
    with pytest.raises(ValueError, match="gain"):
        TransientAllowance(DT, gain=-1.0)


def _monitor(gain):
    chi = np.zeros((2, 2 * N_PARAMS))
    chi[:, :2] = I_CONST                       # constant inertia, no Coriolis, no gravity
    return CollisionMonitor(StrainDynamicsModel(chi=chi), [100e-6, 50e-6], 0.0, DT, reaction_config("none"),
                            k_i=2000.0, transient_gain=gain)


def _run(mon, planned_speed, strain2):
    """Arm at rest as measured (residual = strain through the observer's low-pass); returns detection time."""
    for k in range(planned_speed.size):
        mon.step([0.0, 0.5, 0.1], [0.0] * 3, [strain2[k], 0.0, 0.0, 0.0], [0.0, 0.5, 0.1],
                 [0.0, planned_speed[k], 0.0], [0.0] * 3)
        if mon.collision:
            return k * DT
    return None


def test_monitor_ignores_the_transient_of_a_replan_and_still_detects_a_contact_in_steady_motion():
    t = np.arange(0.0, 3.0, DT)
    # a re-plan at 1 s: joint 2's planned acceleration jumps to 2 rad/s^2 (u = 200 um/m at link 2),
    # and the soft link answers 10-40 ms later with a 150 um/m transient (1.5x the link-2 threshold)
    speed = np.where(t >= 1.0, 2.0 * (t - 1.0), 0.0)
    speed = np.minimum(speed, 0.8)                                     # then constant speed from 1.4 s
    strain = np.where((t >= 1.01) & (t < 1.04), 150e-6, 0.0)
    assert _run(_monitor(0.0), speed, strain) == pytest.approx(1.01, abs=0.002)    # fixed thresholds: false positive
    assert _run(_monitor(1.0), speed, strain) is None                               # widened in time: none
    # a contact at 2.5 s during steady motion: detected as with fixed thresholds
    contact = np.where(t >= 2.5, 150e-6, 0.0)
    fixed = _run(_monitor(0.0), speed, contact)
    assert fixed == pytest.approx(2.5, abs=0.002)
    assert _run(_monitor(1.0), speed, contact) == pytest.approx(fixed, abs=1e-9)


def test_setup_default_gain_follows_the_plant_and_the_served_folder_says_its_gain(tmp_path):
    from tudorvision._checks import TudorVisionError
    from tudorvision.cli.joint import collision_transient_gain
    from tudorvision.joint.collision_transient import SOFT_TRANSIENT_GAIN
    from tudorvision.lab.collision_experiments import CollisionSetup

    assert CollisionSetup().transient_gain == SOFT_TRANSIENT_GAIN > 0
    assert CollisionSetup(plant="stiff").transient_gain == 0.0
    assert CollisionSetup(plant="stiff", transient_gain=0.5).transient_gain == 0.5
    with pytest.raises(ValueError, match="transient_gain"):
        CollisionSetup(transient_gain=-1.0)
    meta = tmp_path / "collision.json"
    assert collision_transient_gain(str(meta)) == 0.0                      # no file: fixed thresholds
    meta.write_text('{"plant": "soft"}')
    assert collision_transient_gain(str(meta)) == 0.0                      # written before the key existed
    meta.write_text('{"transient_gain": 1.0}')
    assert collision_transient_gain(str(meta)) == 1.0
    for bad in ('{"transient_gain": -2}', '{"transient_gain": "x"}', "not json"):
        meta.write_text(bad)
        with pytest.raises(TudorVisionError, match="collision.json"):
            collision_transient_gain(str(meta))
