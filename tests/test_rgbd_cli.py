"""The RGB-D commands end to end: rgbd cloud, detect ball, calib rgbd-depth, calib rgbd-base."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from tudorvision.cli import main

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"


def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"real data not available: {path} (see ../shared/realdata/SOURCES.md)")
    return path


def _ros_camera_info(path, fx, fy, cx, cy, w=640, h=480):
    path.write_text(
        f"image_width: {w}\nimage_height: {h}\ncamera_name: rgbd\n"
        f"camera_matrix: {{rows: 3, cols: 3, data: [{fx}, 0, {cx}, 0, {fy}, {cy}, 0, 0, 1]}}\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
    return path


def test_cloud_from_tum_frame_with_ros_intrinsics(tmp_path, capsys):
    pytest.importorskip("open3d")
    seq = _need(REALDATA / "rgbd_tum_desk")
    from tudorvision.rgbd.cloud import read_ply

    # the folder has no intrinsics: a clear one-line error naming the fix
    assert main(["rgbd", "cloud", str(seq), "--frame", "0", "--out", str(tmp_path / "x.ply")]) == 2
    assert "--calib" in capsys.readouterr().err
    info = _ros_camera_info(tmp_path / "tum.yaml", 520.9, 521.0, 325.1, 249.7)
    out = tmp_path / "desk.ply"
    assert main(["rgbd", "cloud", str(seq), "--frame", "0", "--out", str(out), "--calib", str(info)]) == 0
    pts, cols = read_ply(out)
    assert len(pts) > 100000 and cols is not None
    assert 0.5 < np.median(pts[:, 2]) < 3.0 and pts[:, 2].max() <= 6.0 + 1e-6
    assert main(["rgbd", "cloud", str(seq), "--frame", "99", "--out", str(out), "--calib", str(info)]) == 2


def test_detect_ball_on_real_video(tmp_path):
    video = _need(REALDATA / "ball_videos" / "ball.mp4")
    out = tmp_path / "balls.csv"
    assert main(["detect", "ball", str(video), "--out", str(out), "--background", "5"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["frame", "t", "u", "v", "x", "y", "z", "valid"]
    hits = [r for r in rows if r["valid"] == "1"]
    assert len(rows) == 60 and len(hits) >= 14
    assert all(r["x"] == "" for r in hits)           # colour-only: pixels, no 3D


@pytest.fixture(scope="module")
def lab_recordings(tmp_path_factory):
    from tudorvision.lab.record import RecordOptions, record

    root = tmp_path_factory.mktemp("lab")
    opts = RecordOptions(small=True, show_progress=False, seed=3)
    return {kind: record(kind, root / kind, opts)
            for kind in ("rgbd-plane", "rgbd-disc", "rgbd-throws", "rgbd-wall")}


def test_calib_rgbd_depth_on_virtual_lab(lab_recordings, tmp_path):
    from tudorvision.io import load_calibration

    seqs = sorted(str(p) for p in Path(lab_recordings["rgbd-plane"]).iterdir() if p.is_dir())
    out, rep, plot = tmp_path / "cal.yaml", tmp_path / "depth.csv", tmp_path / "depth.png"
    assert main(["calib", "rgbd-depth", *seqs, "--out", str(out), "--report", str(rep), "--plot", str(plot)]) == 0
    rows = list(csv.DictReader(rep.open()))
    assert len(rows) == len(seqs) and list(rows[0]) == ["distance_m", "sigma_m", "bias_m", "n_pixels"]
    dm = load_calibration(out).depth_model
    z = np.linspace(1.0, 6.0, 50)
    seed = (0.51 * z ** 3 - 2.1 * z ** 2 + 5.12 * z - 2.18) / 1000          # the seed's fit in mm (issue 18)
    # 5 frames per distance in the small recording (their std is biased low by c4(5) = 0.94): a looser bound
    # than the 10 % of the full one; below 1 m the 1 mm output step dominates the 0.25-1.3 mm noise
    assert np.max(np.abs(dm.sigma_m(z) / seed - 1)) < 0.15
    zn = np.linspace(0.6, 1.0, 10)
    assert np.max(np.abs(dm.sigma_m(zn) - (0.51 * zn ** 3 - 2.1 * zn ** 2 + 5.12 * zn - 2.18) / 1000)) < 1e-3
    assert plot.stat().st_size > 1000


def test_calib_rgbd_base_on_virtual_lab(lab_recordings, tmp_path, capsys):
    from tudorvision.geometry import invert_transform, rotation_angle
    from tudorvision.io import load_calibration, open_sequence

    path = lab_recordings["rgbd-disc"]
    seq = open_sequence(path)
    gt = seq.groundtruth("disc")
    c = np.array([gt["disc_x_cam_m"][0], gt["disc_y_cam_m"][0], gt["disc_z_cam_m"][0]])
    K = seq.calibration.camera("rgbd").K
    seed_uv = f"{K[0, 0] * c[0] / c[2] + K[0, 2]:.0f},{K[1, 1] * c[1] / c[2] + K[1, 2]:.0f}"
    out, rep = tmp_path / "cal.yaml", tmp_path / "base.json"
    assert main(["calib", "rgbd-base", str(path), "--seed", seed_uv, "--out", str(out), "--report", str(rep)]) == 0
    report = json.loads(rep.read_text())
    T = np.array(report["T_base_cam"])
    np.testing.assert_allclose(load_calibration(out).transform("T_base_cam"), T)
    T_gt = seq.groundtruth("T_base_cam")
    T_true = np.array([[T_gt[f"m{i}{j}"][0] for j in range(4)] for i in range(4)])
    # 32 frames at 5 m with 35 mm per-pixel depth noise: a smoke test of the chain, not the accuracy
    # acceptance (see tests/test_rgbd_base_calib.py for that)
    d_origin = np.linalg.norm(invert_transform(T)[:3, 3] - invert_transform(T_true)[:3, 3])
    d_angle = np.degrees(rotation_angle(T[:3, :3].T @ T_true[:3, :3]))
    assert d_origin < 0.15 and d_angle < 8.0
    # theta = [0, 90, 0] deg in joints.txt: frames 5 and 11-14; at 5 m the disc (9 px) with the sensor's ragged
    # edges can lose a frame or two there (area ratio just under 0.45)
    assert set(report["vertical_frames"]) <= {5, 11, 12, 13, 14} and len(report["vertical_frames"]) >= 3
    yaw = seq.joints().theta_rad[:, 0] != 0.0                  # the theta1 sweep at the end (8 frames)
    assert yaw.sum() == 8 and np.all(yaw[-8:])
    assert len(report["points_used"]) + len(report["rejected"]) == len(seq) - 8 >= 10
    assert {"circle_rmse_m", "rejected", "points_used", "mirror", "yaw"} <= set(report)
    # the theta1 sweep turned the frame's tilt (--yaw auto: joints.txt has one), measured in every frame
    assert report["yaw"]["yaw_points_used"] >= 7 and report["yaw"]["lost"] == {}
    # the sweep's mirror symmetry refined the frame (joints.txt has mirrored poses); --mirror off does not
    assert report["mirror"]["pairs"] >= 3
    # the bootstrap spread of the sweep part: 32 frames at 5 m leave it centimetres wide (and say so)
    spread = report["spread"]
    assert spread["n_boot"] >= 80 and 0.002 < spread["translation_p95_m"] < 0.5
    assert ("warning" in spread) == (spread["translation_p95_m"] > 0.005 or spread["rotation_p95_deg"] > 0.5)
    # without --depth-pattern the warning names the Kinect's fixed pattern as a cause to remove first
    assert "warning" in spread and "calib rgbd-pattern" in spread["warning"]
    runs = {}
    for name, extra in (("mirror", ["--yaw", "off", "--spread-refits", "0"]),
                        ("none", ["--mirror", "off", "--yaw", "off", "--spread-refits", "0"])):
        rp = tmp_path / f"base_{name}.json"
        assert main(["calib", "rgbd-base", str(path), "--seed", seed_uv, *extra, "--report", str(rp)]) == 0
        runs[name] = json.loads(rp.read_text())
    assert runs["none"]["mirror"] is None and runs["none"]["yaw"] is None and runs["mirror"]["yaw"] is None
    assert runs["none"]["spread"] is None
    T_m, T_none = np.array(runs["mirror"]["T_base_cam"]), np.array(runs["none"]["T_base_cam"])
    turn = np.degrees(rotation_angle(T_none[:3, :3].T @ T_m[:3, :3]))
    assert abs(turn - abs(report["mirror"]["mirror_rotation_deg"])) < 1e-6
    turn = np.degrees(rotation_angle(T_m[:3, :3].T @ T[:3, :3]))          # the yaw step: a turn about base x
    assert abs(turn - abs(report["yaw"]["yaw_tilt_correction_deg"])) < 1e-6
    assert abs(np.degrees(rotation_angle(T[:3, :3].T @ T_true[:3, :3]))) < 8.0
    # a seed off the disc (on the far, invalid background) is a clear error
    assert main(["calib", "rgbd-base", str(path), "--seed", "5,5", "--out", str(out)]) == 2
    assert "error" in capsys.readouterr().err


def test_detect_ball_on_virtual_lab_throws(lab_recordings, tmp_path, capsys):
    """The lab's Kinect has a fixed depth pattern: a user calibrates it from a flat wall (``calib rgbd-pattern``)
    and hands it to ``detect ball --depth-pattern``; without it the balls are centimetres off."""
    from tudorvision.io import open_sequence
    from tudorvision.rgbd.depth_pattern import read_depth_pattern

    walls = sorted(str(p) for p in Path(lab_recordings["rgbd-wall"]).iterdir() if p.is_dir())
    pattern, plot = tmp_path / "pattern.yaml", tmp_path / "pattern.png"
    assert len(walls) == 3
    assert main(["calib", "rgbd-pattern", *walls, "--out", str(pattern), "--plot", str(plot)]) == 0
    assert read_depth_pattern(pattern).n_frames == 12 and plot.stat().st_size > 1000
    path = lab_recordings["rgbd-throws"]
    gt = open_sequence(path).groundtruth("ball")
    truth = np.column_stack([gt["x_cam_m"], gt["y_cam_m"], gt["z_cam_m"]])
    med = {}
    for name, extra in (("raw", []), ("corrected", ["--depth-pattern", str(pattern)])):
        out = tmp_path / f"balls_{name}.csv"
        assert main(["detect", "ball", str(path), "--out", str(out), *extra]) == 0
        rows = list(csv.DictReader(out.open()))
        errs = [np.linalg.norm(np.array([float(r["x"]), float(r["y"]), float(r["z"])]) - truth[int(r["frame"])])
                for r in rows if r["valid"] == "1"]
        assert len(errs) >= 5
        med[name] = float(np.median(errs))
    # mm depth noise correlated between pixels as a real Kinect's: 3.4 mm median (0.6 mm with independent pixels)
    assert med["corrected"] < 0.008 and med["raw"] > med["corrected"] + 0.002
    # a pattern made for another image size is refused in one line
    from tudorvision.rgbd.depth_pattern import DepthPatternCorrection, write_depth_pattern
    small = write_depth_pattern(tmp_path / "small.yaml", DepthPatternCorrection(np.zeros((2, 2)), 8, (16, 16)))
    assert main(["detect", "ball", str(path), "--out", str(tmp_path / "x.csv"), "--depth-pattern", str(small)]) == 2
    assert "made for 16x16 px images" in capsys.readouterr().err


def test_calib_rgbd_pattern_refuses_bad_input_in_one_line(lab_recordings, tmp_path, capsys):
    from tudorvision.cli import main

    walls = sorted(str(p) for p in Path(lab_recordings["rgbd-wall"]).iterdir() if p.is_dir())
    capsys.readouterr()
    for extra, what in ((["--step-px", "0"], "--step-px"), (["--min-plane-fraction", "1.5"], "--min-plane-fraction")):
        assert main(["calib", "rgbd-pattern", *walls, "--out", str(tmp_path / "p.yaml"), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and what in err[0]
    # frames of the throws (no wall filling the view): refused, nothing written
    assert main(["calib", "rgbd-pattern", str(lab_recordings["rgbd-throws"]), "--out", str(tmp_path / "q.yaml"),
                 "--min-plane-fraction", "0.9"]) == 2
    assert "flat wall" in capsys.readouterr().err and not (tmp_path / "q.yaml").exists()
    # a stereo recording is not an RGB-D one
    stereo = Path(__file__).resolve().parents[1] / "sample_data" / "stereo-static"
    assert main(["calib", "rgbd-pattern", str(stereo), "--out", str(tmp_path / "r.yaml")]) == 2
    assert "expected an RGB-D sequence" in capsys.readouterr().err


def test_point_cloud_of_a_wall_is_flatter_with_the_depth_pattern_removed(lab_recordings, tmp_path):
    """``rgbd cloud --depth-pattern``: the lab's Kinect sees a flat wall wavy; with its calibrated pattern removed
    the exported points lie closer to a plane (oracle: a plane fit to the PLY's points)."""
    from tudorvision.rgbd.cloud import read_ply

    walls = sorted(str(p) for p in Path(lab_recordings["rgbd-wall"]).iterdir() if p.is_dir())
    pattern = tmp_path / "pattern.yaml"
    assert main(["calib", "rgbd-pattern", *walls, "--out", str(pattern)]) == 0
    rms = {}
    for name, extra in (("raw", []), ("corrected", ["--depth-pattern", str(pattern)])):
        out = tmp_path / f"{name}.ply"
        assert main(["rgbd", "cloud", walls[-1], "--frame", "1", "--out", str(out), "--no-color", *extra]) == 0
        pts = read_ply(out)[0]
        c = pts.mean(axis=0)
        normal = np.linalg.svd(pts - c, full_matrices=False)[2][2]
        rms[name] = float(np.sqrt(np.mean(((pts - c) @ normal) ** 2)))
    # 4.5 m: the pattern is about 3.2 cm RMS there, the per-pixel noise about 2.5 cm
    assert rms["corrected"] < 0.8 * rms["raw"]
