"""B.4 metrics against closed-form values."""
import numpy as np
import pytest

from tudorvision.joint.metrics import (ANGLE_BAND_RAD, damping_metrics, goodness_of_fit, iate, iats,
                                       normalise_metrics, nrmse, settling_time, spectral_amplitude)


def test_iate_of_constant_error_is_half_t_squared():
    t = np.linspace(0.0, 4.0, 4001)
    assert iate(t, np.full_like(t, 3.0), 1.0) == pytest.approx(2.0 * 4.0**2 / 2, rel=1e-6)
    assert iats(t, -np.ones_like(t)) == pytest.approx(8.0, rel=1e-6)


def test_settling_time_of_decaying_oscillation():
    t = np.arange(0, 20, 1e-3)
    x = 100e-6 * np.exp(-t / 2.0) * np.cos(2 * np.pi * 2 * t)
    ts = settling_time(t, x, band=15e-6)
    # envelope crosses the band at 2 ln(100/15) = 3.79 s; the last peak above it is before
    assert 3.3 < ts <= 2 * np.log(100 / 15) + 1e-3
    assert settling_time(t, 1e-3 * np.ones_like(t), band=15e-6, horizon_s=10.0) == 10.0
    assert settling_time(t, np.zeros_like(t), band=15e-6) == 0.0
    with pytest.raises(ValueError, match="band"):
        settling_time(t, x, band=0.0)


def test_spectral_amplitude_picks_the_frequency():
    t = np.arange(0, 10, 1e-3)
    x = 2.0 * np.sin(2 * np.pi * 2.5 * t) + 0.5 * np.sin(2 * np.pi * 10 * t)
    assert spectral_amplitude(t, x, 2.5) == pytest.approx(2.0, rel=1e-3)
    assert spectral_amplitude(t, x, 10.0) == pytest.approx(0.5, rel=1e-3)


def test_fit_metrics():
    ref = np.sin(np.linspace(0, 6, 100))
    assert goodness_of_fit(ref, ref) == 100.0
    assert nrmse(np.full(100, ref.mean()), ref) == pytest.approx(100.0)
    with pytest.raises(ValueError, match="constant"):
        nrmse(ref, np.ones(100))
    with pytest.raises(ValueError, match="shapes"):
        nrmse(ref, ref[:5])


def test_damping_metrics_and_normalisation():
    t = np.arange(0, 10, 2e-3)
    e = 100e-6 * np.exp(-t) * np.sin(2 * np.pi * 2 * t)
    th = np.where(t < 1.0, t, 1.0)
    m = damping_metrics(t, e, th, th, theta_goal=1.0, freq_hz=2.0)
    assert m["iate"] == 0.0 and m["joint_settling_s"] == pytest.approx(1.0, abs=3e-3)
    assert m["max_strain"] < 100e-6
    assert abs(m["final_joint_error_rad"]) < ANGLE_BAND_RAD
    n = normalise_metrics(m, m)
    assert n["iats"] == 100.0 and n["strain_settling_s"] == pytest.approx(10 * m["strain_settling_s"])
