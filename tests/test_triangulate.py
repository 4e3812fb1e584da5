"""Triangulation against synthetic projection truth and the numpy DLT oracle;
rolling-shutter compensation on a simulated fast-moving point."""
import cv2
import numpy as np
import pytest

from tudorvision.geometry import invert_transform, make_frame, transform_points
from tudorvision.io.calibration import Calibration, CameraModel, StereoExtrinsics
from tudorvision.stereo.triangulate import (StereoRig, compensate_rolling_shutter, projection_matrices,
                                            rolling_shutter_times, triangulate_dlt,
                                            triangulate_points, triangulate_spheres,
                                            triangulate_stereo, undistort_points)

LINE_TIME = 0.018 / 480      # read-out of 480 rows in 18 ms
K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])
DIST_L = np.array([-0.21, 0.07, 4e-4, -3e-4, -0.01])
DIST_R = np.array([-0.19, 0.05, -2e-4, 5e-4, 0.0])


def _camera_pose(pos, target=(0.0, 0.0, 0.6)):
    pos = np.asarray(pos, float)
    z = np.asarray(target, float) - pos
    return make_frame(pos, z, np.cross(z, [0.0, 0.0, 1.0]))   # x right, y down


T_BASE_LEFT = _camera_pose([-1.5, -2.4, 2.7])
T_BASE_RIGHT = _camera_pose([1.5, -2.4, 2.7])
T_RIGHT_LEFT = invert_transform(T_BASE_RIGHT) @ T_BASE_LEFT


def _calibration(rectify=False, line_time=LINE_TIME):
    R, T = T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3]
    kw = {}
    if rectify:
        R1, R2, P1, P2, Q, *_ = cv2.stereoRectify(K, DIST_L, K, DIST_R, (640, 480), R, T.reshape(3, 1),
                                                  flags=cv2.CALIB_ZERO_DISPARITY, alpha=-1)
        kw = dict(R1=R1, R2=R2, P1=P1, P2=P2, Q=Q)
    return Calibration(
        cameras={"left": CameraModel(K=K, dist=DIST_L, width=640, height=480, line_time_s=line_time),
                 "right": CameraModel(K=K, dist=DIST_R, width=640, height=480, line_time_s=line_time)},
        stereo=StereoExtrinsics(R=R, T=T, **kw))


def _project(points_base, T_base_cam, dist):
    p_cam = transform_points(invert_transform(T_base_cam), points_base)
    uv, _ = cv2.projectPoints(p_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return uv.reshape(-1, 2)


def _workspace_points(rng, n):
    r = rng.uniform(0.1, 0.84, n)
    a = rng.uniform(-np.pi, np.pi, n)
    return np.column_stack([r * np.cos(a), r * np.sin(a), rng.uniform(0.0, 1.2, n)])


def test_cv2_triangulation_matches_numpy_dlt_oracle():
    rng = np.random.default_rng(10)
    X = rng.uniform([-1, -1, 2], [1, 1, 5], size=(200, 3))
    P1, P2 = projection_matrices(K, K, T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3])

    def proj(P):
        h = np.c_[X, np.ones(len(X))] @ P.T
        return h[:, :2] / h[:, 2:]

    a, b = proj(P1), proj(P2)
    assert np.abs(triangulate_points(a, b, P1, P2) - X).max() < 1e-8
    assert np.abs(triangulate_dlt(a, b, P1, P2) - X).max() < 1e-8
    an = a + rng.normal(scale=0.25, size=a.shape)
    bn = b + rng.normal(scale=0.25, size=b.shape)
    ours, oracle = triangulate_points(an, bn, P1, P2), triangulate_dlt(an, bn, P1, P2)
    err = np.linalg.norm(ours - X, axis=1)
    assert 1e-5 < np.median(err) < 5e-3          # noise really moved the points
    assert np.abs(ours - oracle).max() < 1e-9   # same estimator, independent implementation


@pytest.mark.parametrize("method", ["normalized", "rectified"])
@pytest.mark.parametrize("stored_rectification", [False, True])
def test_stereo_triangulation_recovers_truth_with_distortion(method, stored_rectification):
    rng = np.random.default_rng(11)
    X_base = _workspace_points(rng, 300)
    cal = _calibration(rectify=stored_rectification)
    uv_l, uv_r = _project(X_base, T_BASE_LEFT, DIST_L), _project(X_base, T_BASE_RIGHT, DIST_R)
    assert np.all((uv_l > 0) & (uv_l < [640, 480]))    # the rig sees the workspace
    X_left = triangulate_stereo(uv_l, uv_r, cal, method=method)
    truth_left = transform_points(invert_transform(T_BASE_LEFT), X_base)
    assert np.abs(X_left - truth_left).max() < 1e-6


@pytest.mark.parametrize("method", ["normalized", "rectified"])
def test_stereo_rig_matches_triangulate_stereo_and_a_projected_epipolar_oracle(method):
    rng = np.random.default_rng(15)
    X_base = _workspace_points(rng, 40)
    cal = _calibration()
    uv_l = _project(X_base, T_BASE_LEFT, DIST_L) + rng.normal(scale=0.3, size=(40, 2))
    uv_r = _project(X_base, T_BASE_RIGHT, DIST_R)
    uv_r[:, 1] += rng.uniform(-5.0, 5.0, 40)            # off the epipolar line by a known few pixels
    uv_l[7] = np.nan
    rig = StereoRig(cal, method=method)
    got = rig.triangulate(uv_l, uv_r)
    want = triangulate_stereo(uv_l, uv_r, cal, method=method)
    assert np.isnan(got[7]).all() and np.isfinite(np.delete(got, 7, axis=0)).all()
    assert np.abs(np.delete(got - want, 7, axis=0)).max() < 1e-12
    # oracle: the left ray's points at two depths projected into the ideal right image give the line
    und_l = undistort_points(uv_l, K, DIST_L)
    und_r = undistort_points(uv_r, K, DIST_R, P=K)
    R, T = T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3]
    epi = rig.epipolar_px(uv_l, uv_r)
    assert np.isnan(epi[7])
    for i in np.flatnonzero(np.isfinite(und_l[:, 0])):
        ray = np.r_[und_l[i], 1.0]
        a, b = ((K @ (R @ (z * ray) + T)) for z in (1.0, 6.0))
        a, b = a[:2] / a[2], b[:2] / b[2]
        d = b - a
        dist = abs(d[0] * (und_r[i, 1] - a[1]) - d[1] * (und_r[i, 0] - a[0])) / np.hypot(*d)
        assert abs(epi[i] - dist) < 1e-6
    assert np.nanmax(epi) > 2.0                          # the offsets really moved the points off the lines
    with pytest.raises(ValueError, match="method"):
        StereoRig(cal, method="fast")


def test_stereo_rig_memo_gives_the_uncached_result_and_uses_remembered_points():
    rng = np.random.default_rng(16)
    cal = _calibration()
    X_base = _workspace_points(rng, 60)
    uv_l = _project(X_base, T_BASE_LEFT, DIST_L) + rng.normal(scale=0.3, size=(60, 2))
    uv_r = _project(X_base, T_BASE_RIGHT, DIST_R) + rng.normal(scale=0.3, size=(60, 2))
    rig, fresh = StereoRig(cal), StereoRig(cal)
    rounds = []
    for _ in range(2):                            # first call computes and memoises, second reads the memo
        got = []
        for i in range(0, 60, 3):                 # a frame's few points per call
            got.append(rig.triangulate(uv_l[i:i + 3], uv_r[i:i + 3]))
            assert np.abs(got[-1] - triangulate_stereo(uv_l[i:i + 3], uv_r[i:i + 3], cal)).max() < 1e-12
            assert np.array_equal(rig.epipolar_px(uv_l[i:i + 3], uv_r[i:i + 3]),
                                  StereoRig(cal).epipolar_px(uv_l[i:i + 3], uv_r[i:i + 3]))
        rounds.append(np.concatenate(got))
    assert np.array_equal(rounds[0], rounds[1])
    assert len(rig._memo[0]) == 60 and len(rig._memo[1]) == 60
    # points remembered with their normalised coordinates are triangulated from those (the oracle: the
    # DLT on the normalised points themselves), not from undistorting the pixels again
    xl, xr = undistort_points(uv_l[:2], K, DIST_L), undistort_points(uv_r[:2], K, DIST_R)
    xl_moved = xl + [[1e-4, -2e-4], [0.0, 3e-4]]
    rig.remember(uv_l[:2], xl_moved, 0)
    P2 = np.hstack([T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3:]])
    want = triangulate_dlt(xl_moved, xr, np.hstack([np.eye(3), np.zeros((3, 1))]), P2)
    assert np.abs(rig.triangulate(uv_l[:2], uv_r[:2]) - want).max() < 1e-9
    assert np.abs(fresh.triangulate(uv_l[:2], uv_r[:2]) - want).max() > 1e-5   # the move was real
    # a memo that outgrows its size starts again instead of growing without bound
    many = rng.uniform([0, 0], [640, 480], size=(5000, 2))
    for i in range(0, 5000, 4):
        rig.epipolar_px(many[i:i + 4], many[i:i + 4])
    assert len(rig._memo[0]) <= 4096 + 8


def test_noise_gives_millimetre_level_errors_in_workspace():
    rng = np.random.default_rng(12)
    X_base = _workspace_points(rng, 2000)
    cal = _calibration()
    uv_l = _project(X_base, T_BASE_LEFT, DIST_L) + rng.normal(scale=0.25, size=(2000, 2))
    uv_r = _project(X_base, T_BASE_RIGHT, DIST_R) + rng.normal(scale=0.25, size=(2000, 2))
    X = transform_points(T_BASE_LEFT, triangulate_stereo(uv_l, uv_r, cal))
    rms = np.sqrt(np.mean(np.sum((X - X_base) ** 2, axis=1)))
    # 0.25 px at 3.5 m with f = 700 px is 1.25 mm per image axis; the
    # convergent 3 m baseline gives 2-3 mm 3D RMS (the seed reports 2 mm)
    assert 1e-3 < rms < 4e-3


def test_missing_view_gives_nan_never_single_view_point():
    rng = np.random.default_rng(13)
    X_base = _workspace_points(rng, 6)
    uv_l, uv_r = _project(X_base, T_BASE_LEFT, DIST_L), _project(X_base, T_BASE_RIGHT, DIST_R)
    uv_l[1] = np.nan
    uv_r[3] = np.nan
    uv_l[5, 0] = np.nan
    for method in ("normalized", "rectified"):
        X = triangulate_stereo(uv_l, uv_r, _calibration(), method=method)
        assert np.isnan(X[[1, 3, 5]]).all()
        assert np.isfinite(X[[0, 2, 4]]).all()
    P1, P2 = projection_matrices(K, K, T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3])
    assert np.isnan(triangulate_dlt(uv_l, uv_r, P1, P2)[[1, 3, 5]]).all()
    assert np.isnan(triangulate_points(np.full((2, 2), np.nan), uv_r[:2], P1, P2)).all()


def test_spheres_midpoint_flags_and_base_frame():
    rng = np.random.default_rng(14)
    red, green = _workspace_points(rng, 5), _workspace_points(rng, 5)
    uv_l = {"red": _project(red, T_BASE_LEFT, DIST_L), "green": _project(green, T_BASE_LEFT, DIST_L)}
    uv_r = {"red": _project(red, T_BASE_RIGHT, DIST_R), "green": _project(green, T_BASE_RIGHT, DIST_R)}
    uv_r["green"][2] = np.nan                      # green lost in the right camera
    res = triangulate_spheres(uv_l, uv_r, _calibration(), T_base_left=T_BASE_LEFT)
    assert res.frame == "base"
    assert res.sphere_valid["red"].all()
    assert res.sphere_valid["green"].tolist() == [True, True, False, True, True]
    assert res.ee_valid.tolist() == [True, True, False, True, True]
    assert np.isnan(res.ee[2]).all() and np.isnan(res.spheres["green"][2]).all()
    ok = res.ee_valid
    assert np.abs(res.ee[ok] - (red[ok] + green[ok]) / 2).max() < 1e-6
    assert np.abs(res.spheres["red"] - red).max() < 1e-6
    left = triangulate_spheres(uv_l, uv_r, _calibration())
    assert left.frame == "left"
    assert np.allclose(transform_points(T_BASE_LEFT, left.ee[ok]), res.ee[ok])


def test_bad_arguments_name_the_argument():
    cal = _calibration()
    with pytest.raises(ValueError, match="method"):
        triangulate_stereo([[1.0, 2.0]], [[1.0, 2.0]], cal, method="midpoint")
    with pytest.raises(ValueError, match="uv_right: expected shape"):
        triangulate_stereo(np.zeros((3, 2)), np.zeros((2, 2)), cal)
    with pytest.raises(ValueError, match="uv_right: expected the same"):
        triangulate_spheres({"red": np.zeros((1, 2))}, {"green": np.zeros((1, 2))}, cal)
    with pytest.raises(ValueError, match="calibration: has no stereo"):
        triangulate_stereo([[1.0, 2.0]], [[1.0, 2.0]], Calibration(cameras=dict(cal.cameras)))
    with pytest.raises(ValueError, match="P_left"):
        triangulate_points([[0, 0]], [[0, 0]], np.eye(3), np.eye(3, 4))
    with pytest.raises(ValueError, match="t_frame: timestamps must increase"):
        compensate_rolling_shutter([0.0, 0.0], np.zeros((2, 2)), 1e-5)


def test_undistort_to_pixels_round_trip():
    rng = np.random.default_rng(15)
    X = transform_points(invert_transform(T_BASE_LEFT), _workspace_points(rng, 50))
    uv = _project(transform_points(T_BASE_LEFT, X), T_BASE_LEFT, DIST_L)
    ideal = X[:, :2] / X[:, 2:] * 700.0 + [319.5, 239.5]
    assert np.abs(undistort_points(uv, K, DIST_L, P=K) - ideal).max() < 1e-4
    assert np.abs(undistort_points(uv, K, DIST_L) - X[:, :2] / X[:, 2:]).max() < 1e-6


# ----------------------------------------------------------------------------- rolling shutter
def _moving_point(t):
    """A fast end-effector-like motion: 0.84 m circle at 6.5 rad/s (5.5 m/s) plus a vertical bob."""
    t = np.asarray(t, float)
    w = 5.5 / 0.84
    return np.stack([0.84 * np.cos(w * t), 0.84 * np.sin(w * t), 0.7 + 0.3 * np.sin(3.0 * t)], axis=-1)


def _rolling_shutter_capture(t_frame, T_base_cam, dist):
    """Pixel track and capture time: the moving point's projection hits its own row."""
    tc = np.array(t_frame, float)
    for _ in range(30):   # fixed point t = t_frame + v(t) * line_time, contraction ~ 0.1
        uv = _project(_moving_point(tc), T_base_cam, dist)
        tc_new = t_frame + uv[:, 1] * LINE_TIME
        if np.abs(tc_new - tc).max() < 1e-13:
            break
        tc = tc_new
    uv = _project(_moving_point(tc), T_base_cam, dist)
    assert np.abs(t_frame + uv[:, 1] * LINE_TIME - tc).max() < 1e-11
    return uv, tc


def test_rolling_shutter_times():
    assert np.allclose(rolling_shutter_times([1.0], [480.0], LINE_TIME), 1.018)
    with pytest.raises(ValueError, match="line_time_s"):
        rolling_shutter_times([1.0], [2.0], -1.0)


def test_rolling_shutter_compensation_reduces_fast_motion_error():
    t = np.arange(50) * 0.02                       # 50 Hz, both cameras triggered together
    uv_l, tc_l = _rolling_shutter_capture(t, T_BASE_LEFT, DIST_L)
    uv_r, tc_r = _rolling_shutter_capture(t, T_BASE_RIGHT, DIST_R)
    assert np.abs(tc_l - tc_r).max() > 1e-3         # the two views are really at different instants
    truth = _moving_point(t)
    cal = _calibration()
    raw = transform_points(T_BASE_LEFT, triangulate_stereo(uv_l, uv_r, cal))
    cl, ok_l = compensate_rolling_shutter(t, uv_l, LINE_TIME)
    cr, ok_r = compensate_rolling_shutter(t, uv_r, LINE_TIME)
    assert ok_l.all() and ok_r.all()
    comp = transform_points(T_BASE_LEFT, triangulate_stereo(cl, cr, cal))
    err_raw = np.sqrt(np.mean(np.sum((raw - truth) ** 2, axis=1)))
    err_comp = np.sqrt(np.mean(np.sum((comp - truth) ** 2, axis=1)))
    assert err_raw > 0.01                            # centimetres without compensation
    assert err_comp < 0.01 * err_raw and err_comp < 2e-4
    # the same through triangulate_spheres with timestamps
    res = triangulate_spheres({"s": uv_l}, {"s": uv_r}, cal, T_base_left=T_BASE_LEFT, t_left=t, t_right=t)
    assert np.allclose(res.ee, comp, atol=1e-9)


def test_rolling_shutter_compensation_with_gaps_and_isolated_samples():
    t = np.arange(20) * 0.02
    uv, _ = _rolling_shutter_capture(t, T_BASE_LEFT, DIST_L)
    uv[5] = np.nan
    uv[10:13] = np.nan
    uv[14:20] = np.nan                             # sample 13 is isolated
    out, done = compensate_rolling_shutter(t, uv, LINE_TIME)
    assert np.isnan(out[[5, 10, 11, 12]]).all()    # missing stays missing
    assert not done[13] and np.array_equal(out[13], uv[13])
    assert done[[0, 4, 6, 9]].all()
    ideal = _project(_moving_point(t), T_BASE_LEFT, DIST_L)
    good = done & np.isfinite(out[:, 0])
    assert np.abs(out[good] - ideal[good]).max() < 0.5 < np.abs(uv[good] - ideal[good]).max()
