"""Depth uncertainty calibration: recover the seed's sigma_z(z) from synthetic planar-target stacks."""
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.rgbd.depth_model import (calibrate_depth_model, depth_step_stats, fit_depth_model,
                                          plot_depth_model, read_depth_table_csv, write_depth_table_csv)
from tudorvision.rgbd.frames import Intrinsics
from tudorvision.sensors import KINECT_DEPTH_NOISE, DepthNoiseModel

K = Intrinsics(131.25, 131.25, 39.5, 29.5, 80, 60)     # Kinect optics at 1/8 resolution


def seed_sigma_m(z):
    """The seed's fit, written out independently: cm with z in m."""
    return (0.51 * z ** 3 - 2.1 * z ** 2 + 5.12 * z - 2.18) / 100.0


def bias_m(z):
    return 0.003 * z ** 2          # a made-up systematic depth error to recover


def target_stack(rng, z, n_frames=100, *, tilt=0.0):
    """Planar target (40 x 30 px) at distance z before a wall 1.5 m behind, mm rounding, 0 = invalid."""
    vv, uu = np.mgrid[: K.height, : K.width]
    plane = np.full(K.shape, z + bias_m(z)) + tilt * (uu - K.cx) / K.fx * z
    wall = np.full(K.shape, z + 1.5)
    on = (np.abs(uu - 40) < 20) & (np.abs(vv - 30) < 15)
    truth = np.where(on, plane, wall)
    sigma = seed_sigma_m(np.where(on, z, wall))       # noise of the true distance; bias is an offset
    noisy = truth + sigma * rng.standard_normal((n_frames,) + K.shape)
    noisy = np.rint(noisy * 1000.0) / 1000.0
    noisy[:, truth > 6.5] = 0.0               # sensor range (true depth, as the virtual lab)
    noisy[:, 0, :] = 0.0                      # a dead row
    return noisy, on


def test_sigma_model_recovered_within_10_percent(tmp_path):
    rng = np.random.default_rng(10)
    distances = np.array([0.6, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0])
    stacks = [target_stack(rng, z)[0] for z in distances]
    model, table = calibrate_depth_model(stacks, K, nominal_distances_m=distances)
    zz = np.linspace(0.6, 6.0, 100)
    rel = np.abs(model.sigma_m(zz) / seed_sigma_m(zz) - 1.0)
    assert rel.max() < 0.10
    assert [r.distance_m for r in table] == sorted(distances.tolist())
    for row in table:
        assert abs(row.sigma_m / seed_sigma_m(row.distance_m) - 1.0) < 0.05
        # the bias against the nominal distance is recovered to a small fraction of sigma
        assert abs(row.bias_m - bias_m(row.distance_m)) < 0.1 * seed_sigma_m(row.distance_m) + 1e-3
        assert 900 < row.n_pixels <= 40 * 30
    # CSV round trip with the documented columns
    path = write_depth_table_csv(tmp_path / "depth.csv", table)
    assert path.read_text().splitlines()[0] == "distance_m,sigma_m,bias_m,n_pixels"
    back = read_depth_table_csv(path)
    np.testing.assert_allclose([r.sigma_m for r in back], [r.sigma_m for r in table], rtol=1e-5)
    png = plot_depth_model(tmp_path / "depth.png", table, model)
    assert png.read_bytes()[:4] == b"\x89PNG"
    # serialisation of the model
    assert DepthNoiseModel.from_dict(model.as_dict()) == model


def test_roi_and_auto_region_agree_and_tilted_plane_has_no_bias():
    rng = np.random.default_rng(11)
    stack, on = target_stack(rng, 2.0, n_frames=60, tilt=0.3)
    auto = depth_step_stats(stack, K, nominal_distance_m=2.0)
    roi = depth_step_stats(stack, K, nominal_distance_m=2.0, roi=(22, 17, 58, 43))
    assert abs(auto.sigma_m / seed_sigma_m(2.0) - 1) < 0.08
    assert abs(roi.sigma_m / seed_sigma_m(2.0) - 1) < 0.08
    assert roi.n_pixels == 36 * 26
    # the tilt is absorbed by the plane fit; only the constant offset shows as bias
    assert abs(auto.bias_m - bias_m(2.0)) < 0.01
    assert auto.plane_rms_m < 0.01
    no_nominal = depth_step_stats(stack, K)
    assert np.isnan(no_nominal.bias_m) and abs(no_nominal.distance_m - 2.0 - bias_m(2.0)) < 0.01


def test_seed_model_values_and_fit():
    z = np.linspace(0.6, 6.0, 12)
    np.testing.assert_allclose(KINECT_DEPTH_NOISE.sigma_m(z), seed_sigma_m(z), rtol=1e-12)
    assert KINECT_DEPTH_NOISE.sigma_m(0.3) == KINECT_DEPTH_NOISE.floor_m      # cubic negative there
    m = fit_depth_model(z, seed_sigma_m(z))
    np.testing.assert_allclose(m.coeffs, [0.0051, -0.021, 0.0512, -0.0218], atol=1e-10)


def test_bad_calibration_input():
    rng = np.random.default_rng(12)
    with pytest.raises(TudorVisionError, match="at least 4 distinct distances"):
        fit_depth_model([1.0, 2.0, 3.0], [0.01, 0.02, 0.04])
    with pytest.raises(TudorVisionError, match="at least 2 frames"):
        depth_step_stats(np.ones((1,) + K.shape), K)
    with pytest.raises(TudorVisionError, match="no valid depth"):
        depth_step_stats(np.zeros((5,) + K.shape), K)
    with pytest.raises(ValueError, match=r"expected shape \(F, H, W\)"):
        depth_step_stats(np.ones(K.shape), K)
    stack, _ = target_stack(rng, 1.0, n_frames=5)
    with pytest.raises(TudorVisionError, match="need at least 100"):
        depth_step_stats(stack, K, roi=(10, 10, 15, 15))
    with pytest.raises(ValueError, match="roi"):
        depth_step_stats(stack, K, roi=(10, 10, 500, 15))
