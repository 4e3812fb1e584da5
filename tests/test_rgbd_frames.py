"""RGB-D frames and point clouds: back-projection, depth conversion, Open3D, PLY, real frames."""
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.geometry import fit_plane
from tudorvision.rgbd.cloud import (cloud_from_rgbd, colored_points_cam_from_rgbd, points_colors_from_cloud,
                                    read_ply, write_ply)
from tudorvision.rgbd.frames import (Intrinsics, organized_points_cam_from_depth, points_cam_from_depth,
                                     rays_cam_from_uv, uv_from_points_cam)
from tudorvision.sensors import depth_m_from_raw, raw_from_depth_m

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"
K_KINECT = Intrinsics(525.0, 523.0, 319.5, 241.0, 640, 480)


def _random_points(rng, n, K):
    z = rng.uniform(0.6, 6.0, n)
    u = rng.uniform(0, K.width - 1, n)
    v = rng.uniform(0, K.height - 1, n)
    return np.stack([(u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z], axis=1)


def test_back_projection_inverts_opencv_projection():
    rng = np.random.default_rng(1)
    K = K_KINECT
    pts = _random_points(rng, 3000, K)
    # independent projection: OpenCV
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K.matrix, None)
    uv = uv.reshape(-1, 2)
    ui, vi = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
    ok = (ui >= 0) & (ui < K.width) & (vi >= 0) & (vi < K.height)
    # rasterise (keep the nearest point per pixel, z-buffer)
    depth = np.full(K.shape, np.inf)
    np.minimum.at(depth, (vi[ok], ui[ok]), pts[ok, 2])
    depth[~np.isfinite(depth)] = np.nan
    back = points_cam_from_depth(depth, K)
    assert len(back) == np.isfinite(depth).sum()
    # re-projecting with OpenCV lands exactly on integer pixel centres with the rasterised depth
    uv_back, _ = cv2.projectPoints(back, np.zeros(3), np.zeros(3), K.matrix, None)
    uv_back = uv_back.reshape(-1, 2)
    np.testing.assert_allclose(uv_back, np.rint(uv_back), atol=1e-6)
    np.testing.assert_allclose(back[:, 2], depth[np.rint(uv_back[:, 1]).astype(int),
                                                  np.rint(uv_back[:, 0]).astype(int)])
    # each back-projected point lies within half a pixel footprint of its source point
    src = {(a, b): p for a, b, p in zip(vi[ok], ui[ok], pts[ok]) if p[2] == depth[a, b]}
    vv, uu = np.nonzero(np.isfinite(depth))
    err = np.array([np.linalg.norm(back[i] - src[(vv[i], uu[i])]) for i in range(len(back))])
    assert np.all(err <= 0.5 * np.sqrt(2) * back[:, 2] / min(K.fx, K.fy) + 1e-12)
    # own projection agrees with OpenCV
    np.testing.assert_allclose(uv_from_points_cam(pts, K), uv, atol=1e-9)


def test_organized_and_rays_consistent():
    rng = np.random.default_rng(2)
    K = Intrinsics(300.0, 310.0, 80.0, 60.0, 160, 120)
    depth = rng.uniform(0.5, 4.0, K.shape)
    depth[rng.random(K.shape) < 0.2] = np.nan
    org = organized_points_cam_from_depth(depth, K)
    flat = points_cam_from_depth(depth, K)
    np.testing.assert_allclose(org[np.isfinite(depth)], flat, rtol=1e-12, atol=1e-15)
    assert np.all(np.isnan(org[~np.isfinite(depth)]))
    vv, uu = np.nonzero(np.isfinite(depth))
    rays = rays_cam_from_uv(np.stack([uu, vv], 1), K)
    np.testing.assert_allclose(rays * (flat[:, 2] / rays[:, 2])[:, None], flat, atol=1e-12)
    mask = np.zeros(K.shape, bool)
    mask[10:20, 30:40] = True
    assert len(points_cam_from_depth(depth, K, mask=mask)) == (mask & np.isfinite(depth)).sum()


def test_depth_raw_round_trip_and_scale_check():
    rng = np.random.default_rng(3)
    d = rng.uniform(0.6, 6.0, (48, 64))
    d[0, :5] = np.nan
    raw = raw_from_depth_m(d, 1000.0, out_of_range="raise")
    assert raw.dtype == np.uint16 and np.all(raw[0, :5] == 0)
    back = depth_m_from_raw(raw, 1000.0, dtype=np.float64, check_range=True)
    np.testing.assert_allclose(back[1:], d[1:], atol=0.5e-3)
    assert np.all(np.isnan(back[0, :5]))
    tum = raw_from_depth_m(d, 5000.0, out_of_range="raise")
    back_tum = depth_m_from_raw(tum, 5000.0, dtype=np.float64, check_range=True)
    np.testing.assert_allclose(back_tum[1:], d[1:], atol=0.1e-3)
    # wrong scale: millimetre data read as metres -> implausible, with a hint
    with pytest.raises(TudorVisionError, match=r"implausible median depth.*depth_scale=1000"):
        depth_m_from_raw(raw, 1.0, dtype=np.float64, check_range=True)
    with pytest.raises(TudorVisionError, match="implausible"):
        depth_m_from_raw(tum, 1.0e6, dtype=np.float64, check_range=True)
    assert np.isfinite(depth_m_from_raw(raw, 1.0, dtype=np.float64)).any()


def test_bad_depth_input():
    zeros = np.zeros((48, 64), np.uint16)
    with pytest.raises(TudorVisionError, match="no valid pixel"):
        depth_m_from_raw(zeros, 1000.0, dtype=np.float64, check_range=True)
    with pytest.raises(TudorVisionError, match="no valid pixel"):
        points_cam_from_depth(np.full((480, 640), np.nan), K_KINECT)
    with pytest.raises(ValueError, match="does not match the intrinsics"):
        points_cam_from_depth(np.ones((10, 10)), K_KINECT)
    with pytest.raises(ValueError, match="depth_scale"):
        depth_m_from_raw(zeros + 1000, 0.0, dtype=np.float64, check_range=True)
    with pytest.raises(ValueError, match="positive focal length"):
        Intrinsics(0.0, 1.0, 0.0, 0.0, 10, 10)


def _synthetic_rgbd(rng, K):
    vv, uu = np.mgrid[: K.height, : K.width]
    depth = 2.0 + 0.002 * uu + 0.001 * vv + rng.normal(0, 0.01, K.shape)
    depth[rng.random(K.shape) < 0.1] = 0
    raw = raw_from_depth_m(np.where(depth > 0, depth, np.nan), 1000.0)
    color = rng.integers(0, 256, K.shape + (3,), dtype=np.uint8)
    return color, raw


def test_open3d_cloud_equals_numpy_back_projection():
    pytest.importorskip("open3d")
    rng = np.random.default_rng(4)
    K = Intrinsics(200.0, 201.0, 79.5, 60.3, 160, 120)
    color, raw = _synthetic_rgbd(rng, K)
    pcd = cloud_from_rgbd(color, raw, K, depth_scale=1000.0, depth_trunc=2.8)
    pts_o3d, col_o3d = points_colors_from_cloud(pcd)
    depth = depth_m_from_raw(raw, 1000.0, dtype=np.float64, check_range=True)
    pts_np, col_np = colored_points_cam_from_rgbd(color, depth, K, depth_trunc=2.8)
    assert len(pts_o3d) == len(pts_np) > 1000
    np.testing.assert_allclose(pts_o3d, pts_np, atol=1e-5)
    np.testing.assert_allclose(col_o3d, col_np, atol=1e-6)
    # depth-only cloud
    pts_d, cols_d = points_colors_from_cloud(cloud_from_rgbd(None, raw, K, depth_scale=1000.0, depth_trunc=2.8))
    assert cols_d is None
    np.testing.assert_allclose(pts_d, pts_np, atol=1e-5)
    with pytest.raises(TudorVisionError, match="no valid depth"):
        cloud_from_rgbd(color, np.zeros_like(raw), K, depth_scale=1000.0)


def test_ply_round_trip(tmp_path):
    pytest.importorskip("open3d")
    rng = np.random.default_rng(5)
    pts = rng.uniform(-3, 3, (500, 3))
    cols = rng.uniform(0, 1, (500, 3))
    path = write_ply(tmp_path / "cloud.ply", pts, cols)
    p2, c2 = read_ply(path)
    np.testing.assert_allclose(p2, pts, atol=1e-6)
    np.testing.assert_allclose(c2, cols, atol=1.0 / 255 + 1e-9)   # PLY stores 8-bit colours
    p3, c3 = read_ply(write_ply(tmp_path / "plain.ply", pts, binary=False))
    assert c3 is None
    np.testing.assert_allclose(p3, pts, atol=1e-5)   # ASCII keeps 6 significant digits
    with pytest.raises(FileNotFoundError):
        read_ply(tmp_path / "missing.ply")
    with pytest.raises(ValueError, match="colors"):
        write_ply(tmp_path / "bad.ply", pts, cols[:10])


def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"real data not available: {path} (see ../shared/realdata/SOURCES.md)")
    return path


def test_real_tum_desk_plane_residual():
    folder = _need(REALDATA / "rgbd_tum_desk")
    raw = cv2.imread(str(folder / "1_depth.png"), cv2.IMREAD_UNCHANGED)
    K = Intrinsics(520.9, 521.0, 325.1, 249.7, 640, 480)
    depth = depth_m_from_raw(raw, 5000.0, dtype=np.float64, check_range=True)
    mask = np.zeros(K.shape, bool)
    mask[330:381, 90:201] = True
    pts = points_cam_from_depth(depth, K, mask=mask)
    assert len(pts) > 3000
    plane = fit_plane(pts)
    resid = (pts - plane.centroid) @ plane.normal
    assert 1.1 < float(np.median(pts[:, 2])) < 1.35
    assert 1.0e-3 < float(np.std(resid)) < 2.6e-3      # SOURCES.md: about 1.8 mm


def test_real_kinect_room_cloud_span():
    folder = _need(REALDATA / "rgbd_kinect_room")
    raw = cv2.imread(str(folder / "depth" / "1.pgm"), cv2.IMREAD_UNCHANGED)
    color = cv2.cvtColor(cv2.imread(str(folder / "color" / "1.png")), cv2.COLOR_BGR2RGB)
    K = Intrinsics(518.0, 519.0, 325.5, 253.5, 640, 480)
    depth = depth_m_from_raw(raw, 1000.0, dtype=np.float64, check_range=True)
    pts, cols = colored_points_cam_from_rgbd(color, depth, K)
    assert 0.6 < len(pts) / (640 * 480) < 0.8
    assert abs(pts[:, 2].min() - 0.95) < 0.02 and abs(pts[:, 2].max() - 9.8) < 0.1
    assert cols.shape == pts.shape
    # wrong scale is caught on real data too
    with pytest.raises(TudorVisionError, match="did you mean depth_scale=1000"):
        depth_m_from_raw(raw, 1.0, dtype=np.float64, check_range=True)
