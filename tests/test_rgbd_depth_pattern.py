"""The depth camera's fixed pattern, calibrated from flat-wall frames (rgbd.depth_pattern).

Oracles: a known inverse-depth pattern on exact planes (recovered up to its affine part, which planes
cannot show); the lab's sensor unit, whose pattern the lab knows and perception does not; the OpenCV
YAML file read back; points and images corrected alike."""
from pathlib import Path

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.rgbd.depth_pattern import (DepthPatternCorrection, calibrate_depth_pattern,
                                            plane_residual_inv_depth, read_depth_pattern, write_depth_pattern)
from tudorvision.rgbd.frames import Intrinsics

H, W = 96, 128
VV, UU = np.mgrid[0:H, 0:W].astype(float)


def _affine_free(c):
    A = np.stack([np.ones(c.size), UU.ravel(), VV.ravel()], 1)
    return c - (A @ np.linalg.lstsq(A, c.ravel(), rcond=None)[0]).reshape(c.shape)


def _plane_inv(a, b, c):
    return a + b * UU + c * VV


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_known_pattern_is_recovered_from_tilted_planes_up_to_its_affine_part(seed):
    rng = np.random.default_rng(seed)
    kx, ky, ph = rng.uniform(0.03, 0.08, 2).tolist() + [rng.uniform(0, 6)]
    c = 1.5e-3 * np.sin(kx * UU + ph) * np.cos(ky * VV) + 4e-4 + 2e-6 * UU      # with an affine part
    frames = []
    for k in range(6):
        inv = _plane_inv(rng.uniform(0.2, 0.45), rng.uniform(-4e-4, 4e-4), rng.uniform(-4e-4, 4e-4))
        z = 1.0 / (inv + c)
        z[rng.uniform(size=z.shape) < 0.05] = 0.0                               # invalid pixels
        if k == 0:
            z[10:30, 20:50] = 0.8                                                # a box in front of the wall
        frames.append(z)
    corr = calibrate_depth_pattern(frames, step_px=4)
    assert corr.n_frames == 6 and corr.image_size == (W, H)
    err = corr.field() - _affine_free(c)
    # the grid's bilinear step and the wrapped-in box cost a little; the affine part is not there to find
    assert np.sqrt(np.mean(err ** 2)) < 0.08 * np.sqrt(np.mean(_affine_free(c) ** 2))
    # applied to a frame of the wall: the plane comes back, up to a plane (the unobservable affine part)
    flat = corr.apply(frames[1])
    r, frac = plane_residual_inv_depth(flat)
    r0, _ = plane_residual_inv_depth(frames[1])
    assert frac > 0.9 and np.nanstd(r) < 0.15 * np.nanstd(r0)


def test_the_lab_sensor_pattern_is_removed_at_5_m():
    """The lab's Kinect (noise and its fixed pattern) before a wall: 30 frames calibrate the pattern; at 5 m
    it moves depths by about 4 cm RMS, after the correction by a few millimetres."""
    from tudorvision.lab.depth_wall import render_wall_frames, wall_depth_m
    from tudorvision.sim.depth_sensor import DepthSensorModel, pattern_field

    K = np.array([[262.5, 0, 159.5], [0, 262.5, 119.5], [0, 0, 1]])
    for unit in (3, 4):
        m = DepthSensorModel(pattern_seed=unit)
        corr = calibrate_depth_pattern(render_wall_frames(K, 320, 240, m, np.random.default_rng(unit)))
        c = pattern_field(m, 240, 320)
        z = 5.0
        before = np.sqrt(np.mean((1 / (1 / z + c) - z) ** 2))
        after = np.sqrt(np.mean((corr.apply(1 / (1 / z + c)) - z) ** 2))
        assert 0.03 < before < 0.05 and after < 0.15 * before
    # a wall seen at a slant is a plane too
    zt = wall_depth_m(K, 320, 240, 3.0, [0.2, -0.1, 0.97])
    assert np.all(np.isfinite(zt)) and zt.max() - zt.min() > 0.3


def test_points_are_corrected_as_the_image_is():
    rng = np.random.default_rng(5)
    grid = rng.normal(0, 1e-3, (12, 16))
    corr = DepthPatternCorrection(grid, 8, (W, H))
    K = Intrinsics(100.0, 100.0, 63.5, 47.5, W, H)
    z_img = np.full((H, W), 4.0)
    fixed = corr.apply(z_img)
    for u, v in ((10, 10), (64, 40), (120, 90)):
        p = np.array([(u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0]) * 4.0
        q = corr.correct_points(p, K)
        assert abs(q[2] - fixed[v, u]) < 1e-9 and np.allclose(q[:2] / q[2], p[:2] / p[2])
    pts = corr.correct_points(np.array([[0.0, 0.0, 4.0], [0.1, 0.1, 3.0]]), K)
    assert pts.shape == (2, 3)
    # crops: the same correction at their place in the image
    np.testing.assert_allclose(corr.apply(z_img[20:40, 30:70], origin_px=(20, 30)), fixed[20:40, 30:70])
    with pytest.raises(ValueError, match="does not fit"):
        corr.apply(z_img[:10, :10], origin_px=(90, 0))
    # invalid depths stay invalid
    z = z_img.copy()
    z[0, 0], z[1, 1] = 0.0, np.nan
    out = corr.apply(z)
    assert out[0, 0] == 0.0 and np.isnan(out[1, 1])


def test_file_round_trip_and_hostile_files(tmp_path):
    corr = DepthPatternCorrection(np.random.default_rng(0).normal(0, 1e-3, (3, 4)), 5, (20, 15), 7)
    path = write_depth_pattern(tmp_path / "p.yaml", corr)
    back = read_depth_pattern(path)
    assert np.array_equal(back.grid_inv_m, corr.grid_inv_m) and back.step_px == 5 and back.image_size == (20, 15)
    assert back.n_frames == 7
    with pytest.raises(TudorVisionError, match="no such depth pattern file"):
        read_depth_pattern(tmp_path / "missing.yaml")
    other = tmp_path / "other.yaml"
    other.write_text("%YAML:1.0\n---\nkind: camera\n")
    with pytest.raises(TudorVisionError, match="not a depth pattern file"):
        read_depth_pattern(other)
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(path.read_text().replace("image_width: 20", "image_width: 99"))
    with pytest.raises(TudorVisionError, match=r"wrong\.yaml: grid_inv_m"):
        read_depth_pattern(wrong)
    junk = tmp_path / "junk.yaml"
    junk.write_bytes(b"\x00\xff not yaml [[[")
    with pytest.raises(TudorVisionError, match="junk.yaml"):
        read_depth_pattern(junk)
    with pytest.raises(ValueError, match="grid_inv_m"):
        DepthPatternCorrection(np.full((3, 4), np.nan), 5, (20, 15))


def test_frames_without_a_plane_are_refused_in_one_line():
    rng = np.random.default_rng(0)
    clutter = [rng.uniform(1.0, 5.0, (H, W)) for _ in range(3)]       # no plane anywhere
    with pytest.raises(TudorVisionError, match="point the camera at a flat wall"):
        calibrate_depth_pattern(clutter)
    with pytest.raises(TudorVisionError, match="no frames"):
        calibrate_depth_pattern([])
    with pytest.raises(TudorVisionError, match="frame 1: shape"):
        calibrate_depth_pattern([np.full((H, W), 2.0), np.full((H, W + 1), 2.0)])


REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata" / "rgbd_kinect_room" / "depth"


@pytest.mark.skipif(not REAL.is_dir(), reason="the real Kinect frames (../shared/realdata/rgbd_kinect_room) are absent")
def test_a_real_kinects_pattern_calibrated_from_three_floors_flattens_the_fourth():
    """Real data: the floors of three real Kinect frames (the camera moving between them) calibrate the pattern;
    removed from the fourth frame's floor, its residual from a plane (16 px blocks) drops by a quarter or more
    (the floor's own unevenness and the noise stay; benchmarks/bench_depth_pattern_real.py: 23-46 %)."""
    import cv2

    floors = {}
    for i, r0 in ((2, 300), (3, 300), (4, 330), (5, 330)):
        d = cv2.imread(str(REAL / f"{i}.pgm"), cv2.IMREAD_UNCHANGED).astype(float) / 1000.0
        region = np.zeros(d.shape, bool)
        region[r0:470, 40:560] = True
        z = np.where(region, d, 0.0)
        res, _ = plane_residual_inv_depth(z, max_dev_m=0.03)
        floors[i] = np.where(np.isfinite(res), z, 0.0)

    def block_rms(z):
        res, _ = plane_residual_inv_depth(z, max_dev_m=0.03)
        b = res.reshape(30, 16, 40, 16)
        n = np.isfinite(b).sum(axis=(1, 3))
        with np.errstate(invalid="ignore"):
            m = np.nansum(b, axis=(1, 3)) / n
        return float(np.sqrt(np.mean(m[n >= 128] ** 2)))

    corr = calibrate_depth_pattern([floors[j] for j in (2, 3, 4)], step_px=16, min_plane_fraction=0.05,
                                   min_samples=64)
    assert corr.n_frames == 3
    before, after = block_rms(floors[5]), block_rms(corr.apply(floors[5]))
    assert after < 0.75 * before
