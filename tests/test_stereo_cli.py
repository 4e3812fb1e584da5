"""``tudorvision colormodel``, ``track stereo``, ``track mono`` and ``calib base-stereo SEQ``."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from test_stereo_pipeline import gt_ee, good_picks, gt_transform
from tudorvision.cli import main
from tudorvision.io import load_calibration, open_sequence, save_calibration
from tudorvision.lab import RecordOptions, record
from tudorvision.stereo import load_color_models, read_mono_track_csv, read_trajectory_csv

BALL_VIDEO = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "ball_videos" / "ball2.mp4"


def _pick_args(picks):
    return [a for p in picks for a in ("--pick", p)]


def _run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def _one_line_error(rc, err):
    assert rc == 2
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("calibration: read ")]
    assert len(lines) == 1, err
    return lines[0]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    root = tmp_path_factory.mktemp("stereo_cli")
    static = root / "static"
    record("stereo-static", static, RecordOptions(seed=4, frames=4, show_progress=False))
    sweep = root / "sweep"
    record("stereo-sweep", sweep, RecordOptions(seed=5, frames=11, show_progress=False))
    return {"static": static, "sweep": sweep, "root": root}


@pytest.fixture(scope="module")
def static_models(lab):
    path = lab["root"] / "static_models.yaml"
    seq = open_sequence(lab["static"])
    assert main(["colormodel", str(lab["static"]), "--frame", "0", *_pick_args(good_picks(seq)),
                 "--out", str(path)]) == 0
    return path


def test_colormodel_writes_all_models(lab, static_models, capsys):
    models = load_color_models(static_models)
    assert models.cameras == ("left", "right")
    assert models.spheres("left") == ("red", "green")
    rc, out, _ = _run(capsys, "colormodel", lab["static"], "--frame", 1, "--save-frame", lab["root"] / "f1.png")
    assert rc == 0 and (lab["root"] / "f1.png").stat().st_size > 0


def test_track_stereo_round_trip(lab, static_models, tmp_path, capsys):
    seq = open_sequence(lab["static"])
    base = tmp_path / "base.yaml"
    save_calibration(seq.calibration.with_updates(transforms={"T_base_left": gt_transform(seq)}), base)
    out = tmp_path / "traj.csv"
    rc, stdout, err = _run(capsys, "track", "stereo", lab["static"], "--calib", lab["static"] / "calibration.yaml",
                           "--colormodel", static_models, "--base-calib", base, "--out", out,
                           "--plot", tmp_path / "traj.png", "--rerun", tmp_path / "traj.rrd")
    assert rc == 0, err
    traj = read_trajectory_csv(out)
    assert traj.frame == "base" and traj.valid.all() and len(traj.t) == len(seq)
    np.testing.assert_allclose(traj.t, seq.timestamps)
    err3 = np.linalg.norm(traj.p - gt_ee(seq), axis=1)
    assert np.sqrt(np.mean(err3 ** 2)) < 3e-3, err3
    text = out.read_text()
    assert "# frame: base" in text and "t,x,y,z,vx,vy,vz,ax,ay,az,valid" in text
    assert (tmp_path / "traj.png").read_bytes()[:4] == b"\x89PNG"
    rrd = tmp_path / "traj.rrd"
    assert rrd.stat().st_size > 10_000
    assert "4/4 frames tracked, 100.0% valid" in stdout and "fps" in stdout
    assert "luma edge: on (static is JPEG frames or a video)" in stdout      # the lab writes JPEG frames
    # forced off: the colour-rim circle alone, still within the static target of the issue (1 mm)
    rc, stdout, err = _run(capsys, "track", "stereo", lab["static"], "--colormodel", static_models,
                           "--base-calib", base, "--out", tmp_path / "rim.csv", "--luma-edge", "off")
    assert rc == 0, err
    assert "luma edge: off (--luma-edge)" in stdout
    rim = read_trajectory_csv(tmp_path / "rim.csv")
    assert rim.valid.all() and not np.allclose(rim.p, traj.p, atol=1e-7)


def test_track_stereo_left_frame_without_base(lab, static_models, tmp_path, capsys):
    out = tmp_path / "left.csv"
    rc, stdout, err = _run(capsys, "track", "stereo", lab["static"], "--colormodel", static_models,
                           "--out", out, "--full-frame")
    assert rc == 0, err
    traj = read_trajectory_csv(out)
    assert traj.frame == "left"
    assert "# frame: left (left camera optical frame, x right, y down, z forward)" in out.read_text()


def test_track_stereo_live(lab, static_models, tmp_path, capsys):
    rc, stdout, err = _run(capsys, "track", "stereo", lab["static"], "--colormodel", static_models,
                           "--out", tmp_path / "live.csv", "--live", "--speed", "4")
    assert rc == 0, err
    assert "latency mean" in stdout and "dropped" in stdout


def test_track_stereo_corrupt_frame_partial(lab, static_models, tmp_path, capsys):
    d = tmp_path / "seq"
    shutil.copytree(lab["static"], d)
    bad = sorted((d / "right").iterdir())[2]
    bad.write_bytes(b"garbage")
    out = tmp_path / "partial.csv"
    rc, stdout, err = _run(capsys, "track", "stereo", d, "--colormodel", static_models, "--out", out)
    assert rc == 0, err
    assert "1 corrupt frame(s) skipped" in stdout and bad.name in err   # which frame: on stderr (issue 14)
    assert f"skipped frame 2: " in err and bad.name in out.read_text()   # ... and flagged in the CSV
    traj = read_trajectory_csv(out)
    assert len(traj.t) == 3 and traj.valid.all()


# ----------------------------------------------------------------------------- bad input
def test_bad_inputs_exit_2_with_one_line(lab, static_models, tmp_path, capsys):
    seq = open_sequence(lab["static"])
    picks = good_picks(seq)
    # missing sequence, missing model file
    line = _one_line_error(*_run(capsys, "track", "stereo", tmp_path / "nope", "--colormodel", static_models,
                                 "--out", tmp_path / "x.csv")[::2])
    assert "nope" in line
    line = _one_line_error(*_run(capsys, "track", "stereo", lab["static"], "--colormodel", tmp_path / "none.yaml",
                                 "--out", tmp_path / "x.csv")[::2])
    assert "none.yaml" in line
    # a pick outside the image names the pick
    bad = "left:red:700,100:705,100"
    line = _one_line_error(*_run(capsys, "colormodel", lab["static"], "--pick", bad, "--out",
                                 tmp_path / "m.yaml")[::2])
    assert bad in line and "outside" in line
    # a pick on the background, not on a sphere
    bad = "left:red:5,5:12,5"
    line = _one_line_error(*_run(capsys, "colormodel", lab["static"], "--pick", picks[0], "--pick", bad,
                                 "--out", tmp_path / "m.yaml")[::2])
    assert "left:red" in line
    # a malformed pick
    line = _one_line_error(*_run(capsys, "colormodel", lab["static"], "--pick", "left:red:1,2", "--out",
                                 tmp_path / "m.yaml")[::2])
    assert "CAMERA:SPHERE" in line
    # a frame outside the sequence
    line = _one_line_error(*_run(capsys, "colormodel", lab["static"], "--frame", 99, "--pick", picks[0],
                                 "--out", tmp_path / "m.yaml")[::2])
    assert "--frame" in line
    assert not (tmp_path / "m.yaml").exists()


def test_calibration_size_mismatch_exit_2(lab, static_models, tmp_path, capsys):
    cal = load_calibration(lab["static"] / "calibration.yaml")
    small = cal.with_updates(cameras={n: cal.camera(n).replace(width=320, height=240) for n in ("left", "right")})
    save_calibration(small, tmp_path / "small.yaml")
    line = _one_line_error(*_run(capsys, "track", "stereo", lab["static"], "--calib", tmp_path / "small.yaml",
                                 "--colormodel", static_models, "--out", tmp_path / "x.csv")[::2])
    assert "320x240" in line and "640x480" in line


def test_model_that_finds_nothing_gives_invalid_rows(lab, tmp_path, capsys):
    import cv2
    from tudorvision.stereo import ColorModelSet, fit_color_model, save_color_models
    img = np.full((480, 640, 3), 90, np.uint8)
    cv2.circle(img, (320, 240), 10, (230, 40, 200), -1)
    m = fit_color_model(img, (320, 240), (330, 240))
    save_color_models(ColorModelSet({c: {"red": m, "green": m} for c in ("left", "right")}), tmp_path / "m.yaml")
    out = tmp_path / "none.csv"
    rc, stdout, err = _run(capsys, "track", "stereo", lab["static"], "--colormodel", tmp_path / "m.yaml",
                           "--out", out, "--plot", tmp_path / "none.png")
    assert rc == 3, err       # written, but nothing valid: a warning with the likely cause and a non-zero exit
    assert "0.0% valid" in stdout and "warning: 0 % valid" in err and "colour models" in err
    traj = read_trajectory_csv(out)
    assert len(traj.t) == 4 and not traj.valid.any()


# ----------------------------------------------------------------------------- base frame
def test_calib_base_stereo_tracks_the_sweep(lab, tmp_path, capsys):
    sweep = lab["sweep"]
    seq = open_sequence(sweep)
    models = tmp_path / "sweep_models.yaml"
    assert main(["colormodel", str(sweep), "--frame", "0", *_pick_args(good_picks(seq)), "--out", str(models)]) == 0
    out = tmp_path / "base.yaml"
    rc, stdout, err = _run(capsys, "calib", "base-stereo", sweep, "--calib", sweep / "calibration.yaml",
                           "--colormodel", models, "--out", out)
    assert rc == 0, err
    assert "circle RMSE" in stdout
    cal = load_calibration(out)
    assert cal.stereo is not None                  # the tracking calibration is kept
    T_left_base = np.linalg.inv(cal.transforms["T_base_left"])
    G_left_base = np.linalg.inv(gt_transform(seq))
    origin_err_base = gt_transform(seq)[:3, :3] @ (T_left_base[:3, 3] - G_left_base[:3, 3])
    axis_err = np.rad2deg(np.arccos(np.clip(np.sum(T_left_base[:3, :3] * G_left_base[:3, :3], axis=0), -1, 1)))
    # measured over seeds 5-8: origin 0.3-6.7 mm, almost all of it along z (the height comes from the
    # vertical posture, whose sphere images lose their top highlight to the colour model: ~1 px low);
    # horizontal < 3 mm; axes 0.01-0.12 deg
    assert np.hypot(*origin_err_base[:2]) < 5e-3, origin_err_base
    assert abs(origin_err_base[2]) < 10e-3, origin_err_base
    assert np.all(axis_err < 0.5), axis_err
    # the base frame is then used by track stereo (T_base_left from --calib)
    traj_csv = tmp_path / "sweep.csv"
    rc, stdout, err = _run(capsys, "track", "stereo", sweep, "--calib", out, "--colormodel", models,
                           "--out", traj_csv)
    assert rc == 0, err
    traj = read_trajectory_csv(traj_csv)
    assert traj.frame == "base"
    assert np.nanmax(np.linalg.norm(traj.p - gt_ee(seq), axis=1)) < 8e-3


def test_calib_base_stereo_needs_colormodel(lab, tmp_path, capsys):
    line = _one_line_error(*_run(capsys, "calib", "base-stereo", lab["sweep"], "--out", tmp_path / "b.yaml")[::2])
    assert "--colormodel" in line


# ----------------------------------------------------------------------------- mono on a real video
@pytest.mark.skipif(not BALL_VIDEO.is_file(), reason="real ball videos not available")
def test_track_mono_real_video(tmp_path, capsys):
    models = tmp_path / "ball.yaml"
    # frame 153 of ball2.mp4: the green ball in a hand, centre about (524, 205), radius about 25 px
    rc, _, err = _run(capsys, "colormodel", BALL_VIDEO, "--frame", 153, "--pick", "mono:green:524,205:546,205",
                      "--out", models)
    assert rc == 0, err
    out = tmp_path / "ball.csv"
    rc, stdout, err = _run(capsys, "track", "mono", BALL_VIDEO, "--colormodel", models, "--sphere", "green",
                           "--out", out)
    assert rc == 0, err
    d = read_mono_track_csv(out)
    assert len(d["frame"]) == 1004 and list(d["frame"][:3]) == [0, 1, 2]
    assert not d["valid"][:28].any()                # the ball enters the view at frame 28
    assert d["valid"].mean() > 0.7
    assert abs(d["u"][153] - 524) < 8 and abs(d["v"][153] - 207) < 8
    steps = np.hypot(np.diff(d["u"]), np.diff(d["v"]))
    assert np.nanmedian(steps) < 15                 # a smooth track, not jumping between blobs
    line = _one_line_error(*_run(capsys, "track", "mono", BALL_VIDEO, "--colormodel", models, "--sphere", "red",
                                 "--out", out)[::2])
    assert "red" in line


def test_track_stereo_known_sphere_radius(lab, static_models, tmp_path, capsys):
    """The lab's 35 mm spheres: the true radius keeps every frame; a wrong one flags every frame; bad input exits 2."""
    for mm, want_valid in ((35.0, True), (60.0, False)):
        out = tmp_path / f"r{mm:.0f}.csv"
        rc, stdout, err = _run(capsys, "track", "stereo", lab["static"], "--colormodel", static_models,
                               "--out", out, "--sphere-radius-mm", mm)
        assert rc == (0 if want_valid else 3), err          # 3: written, but no valid frame (a warning says why)
        valid = read_trajectory_csv(out).valid
        assert valid.all() == want_valid and valid.any() == want_valid
    rc, _, err = _run(capsys, "track", "stereo", lab["static"], "--colormodel", static_models,
                      "--out", tmp_path / "x.csv", "--sphere-radius-mm", "-3")
    assert "--sphere-radius-mm" in _one_line_error(rc, err)
