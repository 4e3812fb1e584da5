"""The IIR variant of the static strain cancellation (section 2.2, equation 2.2.3)."""
from __future__ import annotations

import numpy as np
import pytest

from tudorvision.joint.damping import DampingConfig, StrainDamper
from tudorvision.joint.iir_filter import ExponentialStrainFilter


def _run(f, x):
    return np.array([f.step([v])[1][0] for v in x])


def test_double_exponential_smoothing_removes_steps_and_ramps_and_passes_fast_oscillations():
    fs, alpha = 100.0, 0.02
    t = np.arange(0, 20, 1 / fs)
    # figure 2.3's stimulus: step plus ramp from t = 2 s; the high-pass output returns to zero
    x = np.where(t >= 2, 1.0 + 0.5 * (t - 2), 0.0)
    out = _run(ExponentialStrainFilter([0.0], alpha=alpha), x)
    assert abs(out[t > 2][0]) > 0.9 and np.all(np.abs(out[t > 17]) < 0.01)
    # a 2 Hz oscillation passes with about unit gain once the estimate has settled
    y = _run(ExponentialStrainFilter([0.0], alpha=alpha), np.sin(2 * np.pi * 2 * t))
    assert np.ptp(y[t > 15]) == pytest.approx(2.0, rel=0.1)
    # analytic: (1 - G)^2 with G = alpha / (1 - (1 - alpha) z^-1)
    z1 = np.exp(-2j * np.pi * 2 / fs)
    g = alpha / (1 - (1 - alpha) * z1)
    assert np.ptp(y[t > 15]) / 2 == pytest.approx(abs(1 - g) ** 2, rel=0.03)


def test_decimated_iir_holds_its_estimate_and_the_damper_uses_it():
    f = ExponentialStrainFilter([0.0], alpha=0.5, decimation=3)
    mus = [f.step([1.0])[0][0] for _ in range(4)]
    assert mus[0] == mus[1] == mus[2] != mus[3]
    d = StrainDamper(DampingConfig(law="proportional", k_eps=(0, 100, 100), iir_alpha=0.02, decimation=20),
                     [0.0] * 4, 5e-4)
    assert isinstance(d.filter, ExponentialStrainFilter) and d.filter.decimation == 20
    with pytest.raises(ValueError, match="alpha"):
        ExponentialStrainFilter([0.0], alpha=0.0)
