"""The theta1 ("yaw") sweep that corrects the base frame's tilt towards the camera (issue 18's wall camera).

Oracles: an analytic ring of points under a known tilt, and the lab's ground truth for rendered sweeps (the
perception side never sees it)."""
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.geometry import invert_transform
from tudorvision.lab.disc_sweep import DiscSweepParams, render_disc_sweep
from tudorvision.rgbd.disc3d import Disc3DOptions
from tudorvision.rgbd.frames import Intrinsics
from tudorvision.rgbd.yaw_sweep import measure_yaw_sweep, refine_tilt_from_yaw
from tudorvision.robot.kinematics import T_base_ee


def _rot(axis, deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _euler_base(R_err):
    """Small rotation error as angles about base x, y, z, degrees."""
    return np.degrees([R_err[2, 1], R_err[0, 2], R_err[1, 0]])


@pytest.mark.parametrize("seed", range(5))
def test_a_tilt_about_base_x_is_removed_and_nothing_else_turns(seed):
    rng = np.random.default_rng(seed)
    T_true = np.eye(4)                                   # camera 6 m in front of the base, looking at it, rolled
    T_true[:3, :3] = _rot(2, rng.uniform(-10, 10)) @ np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]) \
        @ _rot(0, -8.0)
    T_true[:3, 3] = [rng.uniform(-0.3, 0.3), -6.0, 2.0]
    th1 = np.radians(np.repeat(np.arange(-45.0, 45.1, 7.5), 4))
    th = np.c_[th1, np.full_like(th1, np.radians(45.0)), np.zeros_like(th1)]
    ring_base = T_base_ee(th)[:, :3, 3] + [0.0, 0.0, -0.03]             # a uniform sag keeps it horizontal
    pts_cam = (invert_transform(T_true) @ np.c_[ring_base, np.ones(len(th))].T).T[:, :3]
    pts_cam += rng.normal(0.0, 0.001, pts_cam.shape)
    pts_cam[3] = [np.nan] * 3                                            # a lost frame
    pts_cam[7] += [0.0, 0.0, 0.4]                                        # an outlier
    tilt, heading = rng.uniform(-1.0, 1.0), rng.uniform(-0.5, 0.5)
    T0 = T_true.copy()
    T0[:3, :3] = _rot(0, tilt) @ _rot(2, heading) @ T_true[:3, :3]      # the first estimate's errors
    pivot_cam = pts_cam[10]
    T1, info = refine_tilt_from_yaw(T0, pts_cam, pivot_cam=pivot_cam)
    e0, e1 = _euler_base(T0[:3, :3] @ T_true[:3, :3].T), _euler_base(T1[:3, :3] @ T_true[:3, :3].T)
    se = info["yaw_tilt_std_deg"]
    assert abs(e0[0] - tilt) < 0.01 and abs(e1[0]) < 4 * se             # the tilt about x is gone (to its noise)
    assert abs(e1[2] - e0[2]) < 0.01 and abs(e1[1] - e0[1]) < 0.01       # heading and roll untouched
    assert abs(info["yaw_tilt_correction_deg"] + tilt) < 4 * se + 0.01
    assert len(th) - 5 <= info["yaw_points_used"] <= len(th) - 2        # the outlier and the lost frame left out
    assert 0.005 < se < 0.05
    p0, p1 = T0 @ np.r_[pivot_cam, 1.0], T1 @ np.r_[pivot_cam, 1.0]
    assert np.allclose(p0, p1, atol=1e-12)                               # turned about the pivot


@pytest.mark.parametrize("seed", range(3))
def test_depth_scatter_along_the_rays_does_not_tilt_the_plane_with_the_kinematics(seed):
    """The camera looks 8 deg down, so a disc centre moved along its ray moves in height too: 60 mm of depth scatter
    (a Kinect at 6 m) pulls a least-squares plane through the measured points towards the rays' slope by about
    0.4 deg. With ``theta_rad`` the depths come from the arc (its radius scaled to the points: the elastic links
    bend out, here by 5 %) and the tilt is found to within 0.1 deg (the scale's own noise is what is left)."""
    rng = np.random.default_rng(seed)
    T_true = np.eye(4)
    T_true[:3, :3] = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]) @ _rot(0, -8.0)
    T_true[:3, 3] = [0.1, -6.0, 2.0]
    th1 = np.radians(np.linspace(-45.0, 45.0, 400))
    th = np.c_[th1, np.full_like(th1, np.radians(45.0)), np.zeros_like(th1)]
    rigid = T_base_ee(th)[:, :3, 3]
    ring_base = np.c_[1.05 * rigid[:, :2], rigid[:, 2] - 0.03]          # bent out 5 % and down 3 cm
    pts_cam = (invert_transform(T_true) @ np.c_[ring_base, np.ones(len(th))].T).T[:, :3]
    rays = pts_cam / np.linalg.norm(pts_cam, axis=1, keepdims=True)
    pts_cam += rays * rng.normal(0.0, 0.06, (len(th), 1)) + rng.normal(0.0, 0.002, pts_cam.shape)
    T0 = T_true.copy()
    T0[:3, :3] = _rot(0, 0.5) @ T_true[:3, :3]
    pivot = pts_cam.mean(axis=0)
    T_meas, info_meas = refine_tilt_from_yaw(T0, pts_cam, pivot_cam=pivot)
    T_kin, info = refine_tilt_from_yaw(T0, pts_cam, pivot_cam=pivot, theta_rad=th)
    err_meas = _euler_base(T_meas[:3, :3] @ T_true[:3, :3].T)[0]
    err_kin = _euler_base(T_kin[:3, :3] @ T_true[:3, :3].T)[0]
    assert abs(err_meas) > 0.25                                          # the measured depths tilt the plane
    assert abs(err_kin) < 0.1 and abs(err_kin) < abs(err_meas) / 4     # (seeds 0-2: 0.36-0.50 against 0.01-0.08)
    assert info["yaw_depth_from"] == "kinematics" and info_meas["yaw_depth_from"] == "measured"
    assert info["yaw_radius_scale"] == pytest.approx(1.05, abs=0.01)
    with pytest.raises(ValueError, match="theta_rad"):
        refine_tilt_from_yaw(T0, pts_cam, theta_rad=th[:10])


def test_too_few_points_or_too_little_spread_is_refused():
    a = np.radians(np.arange(-45.0, 45.1, 15.0))
    ring = np.c_[0.6 * np.cos(a), 0.6 * np.sin(a), np.full_like(a, 0.9)]
    with pytest.raises(TudorVisionError, match="valid disc centres"):
        refine_tilt_from_yaw(np.eye(4), ring[:4])
    narrow = np.radians(np.linspace(-5.0, 5.0, 8))
    ring = np.c_[0.6 * np.cos(narrow), 0.6 * np.sin(narrow), np.full_like(narrow, 0.9)]
    with pytest.raises(TudorVisionError, match="turn joint 1 further"):
        refine_tilt_from_yaw(np.eye(4), ring)
    with pytest.raises(ValueError, match="T_base_cam"):
        refine_tilt_from_yaw(np.eye(3), ring)


@pytest.fixture(scope="module")
def yaw_sweep():
    p = DiscSweepParams(camera_distance_m=4.5, camera_height_m=1.8, theta2_deg=(30.0, 90.0, 150.0),
                        frames_per_pose=2, n_vertical=2, yaw_theta1_deg=(-45.0, -15.0, 15.0, 45.0),
                        yaw_theta2_deg=45.0, yaw_frames_per_pose=2)
    return render_disc_sweep(p, np.random.default_rng(3), width=320, height=240)


def test_the_lab_renders_the_yaw_poses_after_the_vertical_posture(yaw_sweep):
    sw = yaw_sweep
    assert sw.yaw.sum() == 8 and not np.any(sw.yaw & sw.vertical) and np.all(sw.yaw[-8:])
    assert np.allclose(np.degrees(sw.theta_rad[sw.yaw, 0]), np.repeat([-45.0, -15.0, 15.0, 45.0], 2))
    centres_base = (sw.T_base_cam @ np.c_[sw.disc_centres_cam, np.ones(len(sw.yaw))].T).T[sw.yaw, :3]
    assert np.ptp(centres_base[:, 2]) < 1e-6            # one height: a horizontal circle about base z
    rigid = T_base_ee(sw.theta_rad[sw.yaw])[:, :3, 3]
    assert np.allclose(np.arctan2(centres_base[:, 1], centres_base[:, 0]), sw.theta_rad[sw.yaw, 0], atol=1e-6)
    assert np.max(np.linalg.norm(centres_base - rigid, axis=1)) < 0.1   # the elastic arm's sag only


def test_the_disc_is_found_in_every_yaw_frame_from_a_first_estimate(yaw_sweep):
    sw = yaw_sweep
    K = Intrinsics.from_matrix(sw.K, 320, 240)
    T0 = sw.T_base_cam.copy()
    T0[:3, :3] = _rot(0, 0.8) @ _rot(2, -0.6) @ T0[:3, :3]              # a first estimate, about a degree off
    T0[:3, 3] += [0.01, -0.01, 0.005]
    pts, skipped = measure_yaw_sweep(sw.depth_m[sw.yaw], K, T0, sw.theta_rad[sw.yaw], Disc3DOptions())
    assert skipped == {}
    err = np.linalg.norm(pts - sw.disc_centres_cam[sw.yaw], axis=1)
    assert np.max(err) < 0.03
    with pytest.raises(ValueError, match="depth_frames"):
        measure_yaw_sweep(sw.depth_m[sw.yaw][:3], K, T0, sw.theta_rad[sw.yaw], Disc3DOptions())
