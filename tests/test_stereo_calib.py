"""Stereo checkerboard calibration on synthetic image pairs rendered with known cameras."""
import functools

import cv2
import numpy as np
import pytest

from tudorvision.cli import main
from tudorvision.geometry import make_frame, rotation_angle
from tudorvision.io.calibration import load_calibration
from tudorvision.io.formats import load_opencv_stereo, load_ros_camera_info
from tudorvision.stereo.calibrate import (board_object_points, calibrate_stereo,
                                          calibrate_stereo_from_images, detect_board_pairs,
                                          find_board_corners, parse_board, plot_view_errors)

SIZE = (640, 480)
BOARD = (9, 6)
SQUARE = 0.025
K_L = np.array([[690.0, 0.0, 322.0], [0.0, 690.0, 236.0], [0.0, 0.0, 1.0]])
K_R = np.array([[705.0, 0.0, 316.0], [0.0, 705.0, 243.0], [0.0, 0.0, 1.0]])
D_L = np.array([-0.12, 0.05, 0.0, 0.0, 0.0])
D_R = np.array([-0.10, 0.03, 0.0, 0.0, 0.0])
_CRIT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-12)


def _rig():
    """Right camera 0.15 m to the right of the left one, turned 4 deg inward."""
    c_right = np.array([0.15, 0.0, 0.0])
    a = np.deg2rad(-4.0)
    R_left_right = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    R = R_left_right.T                      # x_right = R x_left + T
    return R, -R @ c_right


R_TRUE, T_TRUE = _rig()


@functools.lru_cache(maxsize=None)
def _texture(px=24):
    cols, rows = BOARD[0] + 1, BOARD[1] + 1
    tex = np.full(((rows + 2) * px, (cols + 2) * px), 235, np.uint8)
    for j in range(rows):
        for k in range(cols):
            if (j + k) % 2 == 0:
                tex[(j + 1) * px:(j + 2) * px, (k + 1) * px:(k + 2) * px] = 25
    return tex, px


@functools.lru_cache(maxsize=None)
def _pixel_rays(K_bytes, D_bytes):
    K = np.frombuffer(K_bytes).reshape(3, 3)
    D = np.frombuffer(D_bytes)
    u, v = np.meshgrid(np.arange(SIZE[0], dtype=np.float64), np.arange(SIZE[1], dtype=np.float64))
    uv = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    xy = cv2.undistortPoints(uv, K, D, None, None, None, _CRIT).reshape(-1, 2)
    return np.column_stack([xy, np.ones(len(xy))])


def _render(K, D, R_cam_board, t_cam_board, rng):
    """Image of the board seen by a distorted camera: per pixel, intersect its ray with the board."""
    tex, px = _texture()
    rays = _pixel_rays(K.tobytes(), D.tobytes())
    H = np.column_stack([R_cam_board[:, 0], R_cam_board[:, 1], t_cam_board])   # board plane -> ray
    b = rays @ np.linalg.inv(H).T
    xb, yb = b[:, 0] / b[:, 2], b[:, 1] / b[:, 2]
    # inner corner (0, 0) sits at the boundary between texture pixels 2px-1 and 2px
    mapx = (2 * px - 0.5 + xb / SQUARE * px).reshape(SIZE[1], SIZE[0]).astype(np.float32)
    mapy = (2 * px - 0.5 + yb / SQUARE * px).reshape(SIZE[1], SIZE[0]).astype(np.float32)
    img = cv2.remap(tex, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128)
    img = cv2.GaussianBlur(img, (0, 0), 0.7).astype(np.float64)
    img += rng.normal(scale=2.0, size=img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def _project(K, D, R, t, obj):
    uv, _ = cv2.projectPoints(obj.astype(np.float64), cv2.Rodrigues(R)[0], t, K, D)
    return uv.reshape(-1, 2)


def _board_poses(rng, n, K_right=K_R, D_right=D_R):
    obj = board_object_points(BOARD, SQUARE)
    centre = obj.mean(axis=0)
    poses = []
    while len(poses) < n:
        z = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), -1.0])     # board normal toward camera
        T = make_frame([0, 0, 0], -z, [np.cos(rng.uniform(-0.3, 0.3)), np.sin(rng.uniform(-0.3, 0.3)), 0])
        R = T[:3, :3]
        dist = rng.uniform(0.45, 0.75)
        target = np.array([rng.uniform(-0.08, 0.12), rng.uniform(-0.06, 0.06), dist])
        t = target - R @ centre
        ok = True
        for K, D, Rc, tc in ((K_L, D_L, R, t), (K_right, D_right, R_TRUE @ R, R_TRUE @ t + T_TRUE)):
            uv = _project(K, D, Rc, tc, obj)
            if not np.all((uv > 30) & (uv < np.array(SIZE) - 30)):
                ok = False
        if ok:
            poses.append((R, t))
    return poses


def _write_pairs(tmp_path, n, seed=0, blank=(), K_right=K_R, D_right=D_R):
    rng = np.random.default_rng(seed)
    left, right = [], []
    for i, (R, t) in enumerate(_board_poses(rng, n, K_right, D_right)):
        il = _render(K_L, D_L, R, t, rng)
        ir = _render(K_right, D_right, R_TRUE @ R, R_TRUE @ t + T_TRUE, rng)
        if i in blank:
            ir = np.full_like(ir, 128)
        lp, rp = tmp_path / f"left{i:02d}.png", tmp_path / f"right{i:02d}.png"
        cv2.imwrite(str(lp), il)
        cv2.imwrite(str(rp), ir)
        left.append(lp)
        right.append(rp)
    return left, right


def test_parse_board_and_object_points():
    assert parse_board("9X6") == (9, 6)
    with pytest.raises(ValueError, match="board"):
        parse_board("9-6")
    obj = board_object_points((9, 6), 0.025)
    assert obj.shape == (54, 3) and np.allclose(obj[9], [0, 0.025, 0])
    with pytest.raises(ValueError, match="square_m"):
        board_object_points((9, 6), 0.0)


def test_rendered_corners_are_found_at_their_true_positions():
    rng = np.random.default_rng(1)
    R, t = _board_poses(rng, 1)[0]
    img = _render(K_L, D_L, R, t, rng)
    corners = find_board_corners(img, BOARD)
    truth = _project(K_L, D_L, R, t, board_object_points(BOARD, SQUARE))
    assert corners is not None
    assert np.sqrt(np.mean(np.sum((corners - truth) ** 2, axis=1))) < 0.1
    assert find_board_corners(np.full((480, 640), 128, np.uint8), BOARD) is None


def test_calibration_recovers_synthetic_rig(tmp_path):
    left, right = _write_pairs(tmp_path, 12, seed=2, blank=(3,))
    res = calibrate_stereo_from_images(left, right, BOARD, SQUARE)
    assert len(res.views) == 11 and len(res.skipped) == 1
    assert "right03.png" in res.skipped[0][1] and "not found" in res.skipped[0][1]
    assert res.rms_px < 0.2 and res.per_view_rms_px.shape == (11, 2)
    assert res.epipolar_error_px < 0.3
    cal = res.calibration
    for name, K, D in (("left", K_L, D_L), ("right", K_R, D_R)):
        cam = cal.camera(name)
        assert abs(cam.fx / K[0, 0] - 1) < 0.003 and abs(cam.fy / K[1, 1] - 1) < 0.003
        assert abs(cam.cx - K[0, 2]) < 1.5 and abs(cam.cy - K[1, 2]) < 1.5
        assert abs(cam.dist[0] - D[0]) < 0.03
    st = cal.stereo
    assert abs(st.baseline_m - 0.15) < 5e-4
    assert np.rad2deg(rotation_angle(st.R.T @ R_TRUE)) < 0.05
    assert st.has_rectification
    # rectification: corresponding corners land on the same rectified row
    det = detect_board_pairs(left[:2], right[:2], BOARD)
    ra = cv2.undistortPoints(det.corners_left[0].reshape(-1, 1, 2), cal.camera("left").K,
                             cal.camera("left").dist, R=st.R1, P=st.P1).reshape(-1, 2)
    rb = cv2.undistortPoints(det.corners_right[0].reshape(-1, 1, 2), cal.camera("right").K,
                             cal.camera("right").dist, R=st.R2, P=st.P2).reshape(-1, 2)
    assert np.abs(ra[:, 1] - rb[:, 1]).max() < 0.5
    assert "overall RMS" in res.summary()
    png = plot_view_errors(res, tmp_path / "errors.png")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_opencv_sample_mode_agrees_with_default(tmp_path):
    # a rig that fits the sample's model: same focal length, no tangential distortion
    K_right = np.array([[690.0, 0.0, 316.0], [0.0, 690.0, 243.0], [0.0, 0.0, 1.0]])
    left, right = _write_pairs(tmp_path, 8, seed=3, K_right=K_right, D_right=D_L)
    det = detect_board_pairs(left, right, BOARD)
    obj = board_object_points(BOARD, SQUARE)
    a = calibrate_stereo(obj, det.corners_left, det.corners_right, det.image_size)
    b = calibrate_stereo(obj, det.corners_left, det.corners_right, det.image_size, mode="opencv-sample")
    assert b.calibration.camera("left").fx == pytest.approx(b.calibration.camera("right").fx)
    assert b.calibration.camera("left").dist[2:].tolist() == [0.0, 0.0, 0.0]
    for res in (a, b):
        assert abs(res.calibration.camera("left").fx / 690.0 - 1) < 0.005
        assert abs(res.calibration.stereo.baseline_m - 0.15) < 1e-3
    assert b.rms_px < 0.2 and np.isnan(b.rms_left_px) and b.mode == "opencv-sample"
    with pytest.raises(ValueError, match="mode"):
        calibrate_stereo(obj, det.corners_left, det.corners_right, det.image_size, mode="fast")


def test_cli_writes_all_outputs(tmp_path, capsys):
    imgs = tmp_path / "imgs"
    imgs.mkdir()
    left, right = _write_pairs(imgs, 6, seed=4, blank=(5,))
    out = tmp_path / "cal.yaml"
    rc = main(["calib", "stereo", "--dir", str(imgs), "--board", "9x6", "--square", str(SQUARE),
               "--out", str(out), "--plot", str(tmp_path / "err.png"), "--export-ros", str(tmp_path / "ros"),
               "--export-opencv", str(tmp_path / "cv"), "--line-time", "3.75e-5"])
    text = capsys.readouterr()
    assert rc == 0, text.err
    assert "skipped" in text.out and "right05.png" in text.out
    cal = load_calibration(out)
    assert cal.stereo is not None and abs(cal.stereo.baseline_m - 0.15) < 0.003
    assert cal.camera("left").line_time_s == pytest.approx(3.75e-5)
    ros = load_ros_camera_info(tmp_path / "ros" / "right.yaml")
    assert np.allclose(ros.P, cal.stereo.P2) and np.allclose(ros.camera.K, cal.camera("right").K)
    cv = load_opencv_stereo(tmp_path / "cv" / "intrinsics.yml", tmp_path / "cv" / "extrinsics.yml")
    assert cv.stereo.allclose(cal.stereo, atol=1e-9)
    for name in ("left", "right"):
        assert np.allclose(cv.camera(name).K, cal.camera(name).K)
        assert np.allclose(cv.camera(name).dist, cal.camera(name).dist)
        assert cv.camera(name).size == SIZE
    assert (tmp_path / "err.png").exists()
    # the same through explicit lists
    rc = main(["calib", "stereo", "--left", ",".join(map(str, left[:5])), "--right",
               ",".join(map(str, right[:5])), "--square", str(SQUARE), "--out", str(tmp_path / "b.yaml")])
    assert rc == 0


def test_cli_too_few_views_is_one_line_error(tmp_path, capsys):
    imgs = tmp_path / "imgs"
    imgs.mkdir()
    _write_pairs(imgs, 3, seed=5, blank=(0, 1))
    rc = main(["calib", "stereo", "--dir", str(imgs), "--square", str(SQUARE), "--out", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and "too few valid checkerboard views: 1" in err
    rc = main(["calib", "stereo", "--dir", str(tmp_path / "nothing"), "--out", str(tmp_path / "c.yaml")])
    assert rc == 2
    rc = main(["calib", "stereo", "--left", "a.png", "--right", "a.png,b.png", "--out", str(tmp_path / "c.yaml")])
    assert rc == 2 and "right" in capsys.readouterr().err
