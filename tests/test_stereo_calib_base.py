"""Robot base frame from synthetic theta1 sweeps (rigid FK + gravity sag + noise)."""
import numpy as np
import pytest

from tudorvision.cli import main
from tudorvision.geometry import invert_transform, make_frame, transform_difference, transform_points
from tudorvision.io.calibration import load_calibration
from tudorvision.robot import fk_ee, load_robot_params
from tudorvision.stereo.base_frame import base_frame_from_theta1_sweep
from tudorvision.stereo.trajectory import trajectory_from_points, write_trajectory_csv

P = load_robot_params()
REACH = P.link2_length_m + P.link3_length_m


def _camera_pose():
    pos = np.array([-1.5, -2.4, 2.7])
    z = np.array([0.0, 0.0, 0.6]) - pos
    return make_frame(pos, z, np.cross(z, [0.0, 0.0, 1.0]))   # T_base_left


T_BASE_LEFT = _camera_pose()


def _errors(T_base_left):
    """Origin error (m) and rotation error (deg) of the base frame.

    The translation of T_base_left itself (the camera centre in the base
    frame) mixes in rotation error times the 4 m lever arm; the origin error,
    i.e. the translation of T_left_base, is what a point at the robot sees.
    """
    dt, da = transform_difference(invert_transform(T_base_left), invert_transform(T_BASE_LEFT))
    return dt, np.rad2deg(da)


def _sweep(rng, *, sag=0.03, noise=3e-4, deg=(-160, 160), n=60, outliers=0):
    """theta1 sweep in the base frame: the stretched arm droops by `sag` at the tip."""
    th = np.column_stack([np.deg2rad(np.linspace(*deg, n)), np.zeros(n), np.zeros(n)])
    rigid = fk_ee(th)
    r = np.sqrt(REACH ** 2 - sag ** 2)
    pts = np.column_stack([r * np.cos(th[:, 0]), r * np.sin(th[:, 0]), rigid[:, 2] - sag])
    pts += rng.normal(scale=noise, size=pts.shape)
    if outliers:
        idx = rng.choice(n, outliers, replace=False)
        pts[idx] += rng.normal(scale=0.04, size=(outliers, 3))
    vert = fk_ee([0.0, np.pi / 2, 0.0]) + rng.normal(scale=noise, size=3)
    to_left = invert_transform(T_BASE_LEFT)
    return th, transform_points(to_left, pts), transform_points(to_left, vert)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recovers_base_frame_with_sag_noise_and_outliers(seed):
    rng = np.random.default_rng(seed)
    th, pts, vert = _sweep(rng, outliers=3)
    T, rep = base_frame_from_theta1_sweep(pts, th, vert, P)
    dt, da = _errors(T)
    assert dt < 1e-3 and da < 0.2
    ws = fk_ee(np.random.default_rng(seed).uniform([-3, 0, -1.5], [3, 2, 1.5], (200, 3)))
    ws_left = transform_points(invert_transform(T_BASE_LEFT), ws)
    assert np.abs(transform_points(T, ws_left) - ws).max() < 1.5e-3
    assert abs(rep.sag_m - 0.03) < 1e-3
    assert 1.5e-4 < rep.circle_rmse_m < 6e-4 < rep.circle.rmse_all
    assert rep.n_inliers >= 55 and rep.vertical_axis_offset_m < 2e-3
    assert rep.azimuth_rms_rad < np.deg2rad(0.1) and not rep.warnings
    assert "circle RMSE" in rep.summary()
    # the measured vertical point lands on the rigid model's vertical posture
    assert np.allclose(transform_points(T, vert), fk_ee([0, np.pi / 2, 0]), atol=1.5e-3)


def test_without_joint_angles_x_points_at_first_sample():
    rng = np.random.default_rng(3)
    th, pts, vert = _sweep(rng, deg=(0, 300), noise=1e-4)
    T, rep = base_frame_from_theta1_sweep(pts, None, vert, P)
    dt, da = _errors(T)
    assert dt < 1e-3 and da < 0.2
    assert np.isnan(rep.azimuth_rms_rad)


def test_without_vertical_point_sag_is_not_removed():
    rng = np.random.default_rng(4)
    th, pts, _ = _sweep(rng, noise=1e-4)
    T, rep = base_frame_from_theta1_sweep(pts, th, None, P)
    dt, da = _errors(T)
    assert da < 0.2                        # z from the normal (oriented by theta1), x from theta1
    assert abs(dt - 0.03) < 1e-3           # origin off by the sag along z
    assert np.isnan(rep.sag_m)


def test_partial_arc_and_reversed_sweep_direction():
    rng = np.random.default_rng(5)
    th, pts, vert = _sweep(rng, deg=(60, -60), noise=1e-4)   # theta1 decreasing, 120 deg arc
    T, rep = base_frame_from_theta1_sweep(pts, th, vert, P)
    dt, da = _errors(T)
    assert dt < 2e-3 and da < 0.3


def test_inconsistent_joint_sign_is_reported():
    rng = np.random.default_rng(6)
    th, pts, vert = _sweep(rng, noise=1e-4)
    th_bad = th.copy()
    th_bad[:, 0] *= -1
    _, rep = base_frame_from_theta1_sweep(pts, th_bad, vert, P)
    assert any("clockwise" in w for w in rep.warnings)


def test_bad_input_names_argument():
    rng = np.random.default_rng(7)
    th, pts, vert = _sweep(rng)
    th2 = th.copy()
    th2[5, 1] = 0.2
    with pytest.raises(ValueError, match="theta: a theta1 sweep needs"):
        base_frame_from_theta1_sweep(pts, th2, vert, P)
    with pytest.raises(ValueError, match="theta: expected shape"):
        base_frame_from_theta1_sweep(pts, th[:-1], vert, P)
    with pytest.raises(ValueError, match="points: need at least 3"):
        base_frame_from_theta1_sweep(pts[:2], None, vert, P)
    with pytest.raises(ValueError, match="vertical_point_left"):
        base_frame_from_theta1_sweep(pts, th, [1.0, 2.0], P)


def _write_sequence_files(tmp_path, rng, *, with_vertical=True):
    """A camera-rate trajectory (left frame) and a 500 Hz joints.txt for sweep + vertical posture."""
    th_sweep, pts, vert = _sweep(rng, n=150, noise=2e-4)
    t_cam = np.arange(150 + 40) * 0.02
    p = np.full((len(t_cam), 3), np.nan)
    p[:150] = pts
    p[7] = np.nan                                     # a lost frame
    if with_vertical:
        p[160:190] = vert + rng.normal(scale=2e-4, size=(30, 3))
    traj = trajectory_from_points(t_cam, p, frame="left")
    write_trajectory_csv(tmp_path / "traj.csv", traj)
    t_j = np.arange(0, t_cam[-1] + 0.02, 0.002)
    theta = np.zeros((len(t_j), 3))
    theta[:, 0] = np.interp(t_j, t_cam[:150], th_sweep[:, 0])
    theta[t_j > t_cam[149], 0] = 0.0
    mid = (t_j > t_cam[149]) & (t_j < t_cam[158])     # moving up to the vertical posture
    theta[mid, 1] = np.linspace(0, np.pi / 2, mid.sum())
    theta[t_j >= t_cam[158], 1] = np.pi / 2
    lines = ["# timestamp theta1 theta2 theta3 (rad)"] + [" ".join(f"{x:.9f}" for x in (t, *row))
                                                         for t, row in zip(t_j, theta)]
    (tmp_path / "joints.txt").write_text("\n".join(lines) + "\n")


def test_cli_base_stereo_from_trajectory_and_joints(tmp_path, capsys):
    rng = np.random.default_rng(8)
    _write_sequence_files(tmp_path, rng)
    out = tmp_path / "cal.yaml"
    rc = main(["calib", "base-stereo", "--traj", str(tmp_path / "traj.csv"), "--joints",
               str(tmp_path / "joints.txt"), "--out", str(out)])
    text = capsys.readouterr()
    assert rc == 0, text.err
    assert "circle RMSE" in text.out and "sag" in text.out
    cal = load_calibration(out)
    dt, da = _errors(cal.transform("T_base_left"))
    assert dt < 1e-3 and da < 0.2
    assert cal.circle_rmse_m is not None and cal.circle_rmse_m < 5e-4
    # --vertical-frame picks the vertical posture explicitly; existing content is kept
    rc = main(["calib", "base-stereo", "--traj", str(tmp_path / "traj.csv"), "--joints",
               str(tmp_path / "joints.txt"), "--vertical-frame", "170", "--out", str(out)])
    assert rc == 0


def test_cli_base_stereo_errors(tmp_path, capsys):
    rng = np.random.default_rng(9)
    _write_sequence_files(tmp_path, rng, with_vertical=False)
    rc = main(["calib", "base-stereo", "--traj", str(tmp_path / "traj.csv"), "--joints",
               str(tmp_path / "joints.txt"), "--out", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and "vertical" in err and len(err.strip().splitlines()) == 1
    rc = main(["calib", "base-stereo", "--traj", str(tmp_path / "nope.csv"), "--joints",
               str(tmp_path / "joints.txt"), "--out", str(tmp_path / "c.yaml")])
    assert rc == 2 and "nope.csv" in capsys.readouterr().err
    rc = main(["calib", "base-stereo", "--traj", str(tmp_path / "traj.csv"), "--out", str(tmp_path / "c.yaml")])
    assert rc == 2 and "joints" in capsys.readouterr().err
