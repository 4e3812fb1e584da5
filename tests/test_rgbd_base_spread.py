"""The sweep calibration's bootstrap spread against the scatter of the estimate over noise draws (an oracle)."""
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.geometry import invert_transform
from tudorvision.rgbd.base_calib import base_frame_from_theta2_sweep
from tudorvision.rgbd.base_spread import sweep_calibration_spread

R_M = 0.84


def _sweep(rng, sigma_m, step_deg=10.0):
    """A half-circle sweep seen from 5 m (the circle plane tilted 30 deg from the view) and 6 vertical samples."""
    th = np.radians(np.arange(0.0, 180.0 + 1e-9, step_deg))
    a = np.radians(30.0)
    x_b, z_b = np.array([1.0, 0.0, 0.0]), np.array([0.0, -np.cos(a), np.sin(a)])   # in-plane axes, camera frame
    centre = np.array([0.1, 0.2, 5.0])
    pts = centre + R_M * (np.cos(th)[:, None] * x_b + np.sin(th)[:, None] * z_b)
    vert = np.repeat((centre + R_M * z_b)[None], 6, axis=0)
    return th, pts + rng.normal(0.0, sigma_m, pts.shape), vert + rng.normal(0.0, sigma_m, vert.shape)


@pytest.mark.parametrize("sigma_m", [0.004, 0.012])
def test_bootstrap_spread_matches_the_scatter_over_noise_draws(sigma_m):
    rng = np.random.default_rng(7)
    origins = []
    for _ in range(40):
        th, pts, vert = _sweep(rng, sigma_m)
        T, _ = base_frame_from_theta2_sweep(pts, vert, theta2_rad=th, origin="joint2")
        origins.append(invert_transform(T)[:3, 3])
    sd_mc = np.std(origins, axis=0)
    th, pts, vert = _sweep(rng, sigma_m)
    T, _ = base_frame_from_theta2_sweep(pts, vert, theta2_rad=th, origin="joint2")
    s = sweep_calibration_spread(T, pts, vert, th, n_boot=80, rng=np.random.default_rng(1), origin="joint2")
    assert s["n_boot"] + s["n_failed"] == 80 and s["n_boot"] >= 70
    ratio = np.linalg.norm(s["translation_sd_m"]) / np.linalg.norm(sd_mc)
    assert 0.6 < ratio < 1.6, (s["translation_sd_m"], sd_mc)
    # the p95 of the displacement against its RMS: 1.6 for an isotropic 3-D normal, 2.0 along one axis
    assert 1.0 < s["translation_p95_m"] / np.linalg.norm(sd_mc) < 2.5


def test_bootstrap_spread_grows_with_the_noise_and_repeats():
    rng = np.random.default_rng(3)
    th, pts, vert = _sweep(rng, 0.003)
    noise = rng.normal(0.0, 1.0, pts.shape)
    out = []
    for k in (1.0, 4.0):
        p = pts + (k - 1.0) * 0.003 * noise
        T, _ = base_frame_from_theta2_sweep(p, vert, theta2_rad=th)
        out.append(sweep_calibration_spread(T, p, vert, th, n_boot=30))
    # the sweep's noise four times (the vertical samples' kept): the spread grows, less than fourfold
    assert 1.5 < out[1]["translation_p95_m"] / out[0]["translation_p95_m"] < 4.5
    assert out[1]["rotation_p95_deg"] > out[0]["rotation_p95_deg"]
    T, _ = base_frame_from_theta2_sweep(pts, vert, theta2_rad=th)
    assert sweep_calibration_spread(T, pts, vert, th, n_boot=30) == out[0]          # seeded: a report repeats


def test_bootstrap_spread_bad_arguments():
    rng = np.random.default_rng(0)
    th, pts, vert = _sweep(rng, 0.003)
    T, _ = base_frame_from_theta2_sweep(pts, vert, theta2_rad=th)
    with pytest.raises(ValueError, match="n_boot"):
        sweep_calibration_spread(T, pts, vert, th, n_boot=5)
    with pytest.raises(ValueError, match="mirror"):
        sweep_calibration_spread(T, pts, vert, None, mirror=True)
    with pytest.raises(ValueError, match="theta2_rad"):
        sweep_calibration_spread(T, pts, vert, th[:-1])
    with pytest.raises(TudorVisionError, match="no valid"):
        sweep_calibration_spread(T, pts, np.full((3, 3), np.nan), th)
