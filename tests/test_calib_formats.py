"""Calibration in, calibration out (issue 16): one loader for every ``--calib``, ``calib convert``, and the
swapped-stereo / 0 %-valid warnings on a real calibration pipeline.

Oracle of the round trips: 3D points projected with the original and with the round-tripped calibration
(``cv2.projectPoints``, left and right camera) agree to 1e-9 px, and ``R``, ``T`` agree to 1e-9.
"""
from __future__ import annotations

import shlex
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.cli import main
from tudorvision.io import Calibration, CameraModel, StereoExtrinsics, load_calibration, save_calibration
from tudorvision.io.calib_formats import (CALIBRATION_FORMATS, load_any_calibration, save_calibration_as,
                                          swapped_stereo_reason)
from tudorvision.io.kalibr import drop_k3, equidistant_to_plumb_bob, load_kalibr_camchain

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
DATA = Path(__file__).resolve().parent / "data"
README_CALIB = ("tudorvision calib stereo --dir sample_data/stereo-checkerboard --board 8x6 --square 0.08 "
                "--out calib.yaml --export-opencv DIR --export-ros DIR")
SWEEP_PICKS = ["left:red:448.9,376.5:456.1,376.5", "left:green:422.0,394.8:429.5,394.8",
               "right:red:217.0,394.8:224.4,394.8", "right:green:190.1,376.5:197.4,376.5"]   # docs/stereo.md


def _run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def _rig(rng, *, k3=True, rectify=True, size=(640, 480)):
    cams = {}
    for name in ("left", "right"):
        K = np.array([[rng.uniform(600, 900), 0, rng.uniform(300, 340)],
                      [0, rng.uniform(600, 900), rng.uniform(220, 260)], [0, 0, 1]])
        d = rng.normal(size=5) * [0.08, 0.05, 0.001, 0.001, 0.02]
        if not k3:
            d[4] = 0.0
        cams[name] = CameraModel(K=K, dist=d, width=size[0], height=size[1])
    R = cv2.Rodrigues(rng.normal(size=3) * 0.2)[0]
    T = np.array([-rng.uniform(0.1, 3.0), 0.0, 0.0]) + rng.normal(size=3) * 0.02
    rect = {}
    if rectify:
        R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(cams["left"].K, cams["left"].dist, cams["right"].K,
                                                    cams["right"].dist, size, R, T.reshape(3, 1))
        rect = dict(R1=R1, R2=R2, P1=P1, P2=P2, Q=Q)
    return Calibration(cameras=cams, stereo=StereoExtrinsics(R=R, T=T, **rect))


def _points(rng, n=200):
    """Points in front of both cameras, left frame, metres."""
    return np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-1.5, 1.5, n), rng.uniform(2, 8, n)])


def _project(cal, X):
    st = cal.stereo
    cl, cr = cal.camera(st.left), cal.camera(st.right)
    ul = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cl.K, cl.dist)[0].reshape(-1, 2)
    ur = cv2.projectPoints(X, cv2.Rodrigues(st.R)[0], st.T, cr.K, cr.dist)[0].reshape(-1, 2)
    return ul, ur


def _assert_same_geometry(a, b, X):
    for pa, pb in zip(_project(a, X), _project(b, X)):
        assert np.max(np.abs(pa - pb)) < 1e-9
    assert np.allclose(a.stereo.R, b.stereo.R, atol=1e-9, rtol=0)
    assert np.allclose(a.stereo.T, b.stereo.T, atol=1e-9, rtol=0)
    for name in (a.stereo.left, a.stereo.right):
        assert a.camera(name).size == b.camera(name).size


def _out_for(fmt, d: Path, tag: str) -> Path:
    return d / f"{tag}.yaml" if fmt in ("tudorvision", "kalibr") else d / tag


# ----------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("fmt", CALIBRATION_FORMATS)
def test_round_trip_through_each_format_projects_identically(tmp_path, fmt):
    rng = np.random.default_rng(16)
    X = _points(rng)
    for k in range(4):
        cal = _rig(rng, k3=fmt != "kalibr", rectify=k % 2 == 0)
        paths, notes = save_calibration_as(cal, fmt, _out_for(fmt, tmp_path, f"c{k}"))
        assert all(p.is_file() for p in paths)
        back = load_any_calibration(paths[0].parent if len(paths) == 2 else paths[0])
        assert back.format == fmt
        _assert_same_geometry(cal, back.calibration, X)
        # the intrinsics themselves, not only their projections
        for name in ("left", "right"):
            assert back.calibration.camera(name).allclose(cal.camera(name), atol=1e-12)


def test_cli_convert_matrix_every_format_to_every_format(tmp_path, capsys):
    """IN -> A -> B -> tudorvision for all 16 (A, B): projections and extrinsics unchanged."""
    rng = np.random.default_rng(7)
    cal = _rig(rng, k3=False)
    X = _points(rng)
    src = save_calibration(cal, tmp_path / "src.yaml")
    labels = {"tudorvision": "tudorvision YAML", "ros": "ROS camera_info", "opencv": "OpenCV FileStorage",
              "kalibr": "Kalibr camchain"}
    for a in CALIBRATION_FORMATS:
        pa = _out_for(a, tmp_path, f"a_{a}")
        rc, out, err = _run(capsys, "calib", "convert", src, "--to", a, "--out", pa)
        assert rc == 0, err
        for b in CALIBRATION_FORMATS:
            pb = _out_for(b, tmp_path, f"b_{a}_{b}")
            rc, out, err = _run(capsys, "calib", "convert", pa, "--to", b, "--out", pb)
            assert rc == 0, err
            assert err.startswith(f"calibration: read {labels[a]} ") and len(err.splitlines()) == 1, err
            assert "wrote" in out
            final = tmp_path / f"final_{a}_{b}.yaml"
            assert _run(capsys, "calib", "convert", pb, "--to", "tudorvision", "--out", final)[0] == 0
            _assert_same_geometry(cal, load_calibration(final), X)


def test_convert_lists_what_the_format_cannot_hold(tmp_path, capsys):
    rng = np.random.default_rng(3)
    cal = _rig(rng).with_updates(transforms={"T_base_left": np.eye(4)},
                                 cameras={"left": _rig(rng).camera("left").replace(line_time_s=3e-5)})
    src = save_calibration(cal, tmp_path / "src.yaml")
    rc, out, err = _run(capsys, "calib", "convert", src, "--to", "ros", "--out", tmp_path / "ros")
    assert rc == 0, err
    assert "note: ROS camera_info has no place for line_time_s (left)" in out
    assert "transforms T_base_left" in out
    # Kalibr: k3 != 0 is refused (one line naming the camera and the pixel cost), written with --allow-lossy
    rc, out, err = _run(capsys, "calib", "convert", src, "--to", "kalibr", "--out", tmp_path / "k.yaml")
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 2 and "k3" in lines[1] and "--allow-lossy" in lines[1]
    assert not (tmp_path / "k.yaml").exists()
    rc, out, err = _run(capsys, "calib", "convert", src, "--to", "kalibr", "--out", tmp_path / "k.yaml",
                        "--allow-lossy")
    assert rc == 0 and "refit is off by" in out


def test_drop_k3_error_is_the_true_pixel_difference():
    rng = np.random.default_rng(5)
    cam = _rig(rng).camera("left")
    fitted, err = drop_k3(cam)
    assert fitted.dist[4] == 0 and err > 0
    # sample the image densely: projected pixels of both models differ by at most the reported error
    u, v = np.meshgrid(np.linspace(0, cam.width - 1, 40), np.linspace(0, cam.height - 1, 30))
    uv = np.column_stack([u.ravel(), v.ravel()]).reshape(-1, 1, 2).astype(np.float64)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    xy = cv2.undistortPoints(uv, cam.K, cam.dist, criteria=crit).reshape(-1, 2)
    X = np.column_stack([xy, np.ones(len(xy))])
    a = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2)
    b = cv2.projectPoints(X, np.zeros(3), np.zeros(3), fitted.K, fitted.dist)[0].reshape(-1, 2)
    diff = np.max(np.linalg.norm(a - b, axis=1))
    assert diff <= err * 1.02 and diff >= 0.5 * err


# ----------------------------------------------------------------------------- Kalibr
KALIBR = """\
cam0:
  cam_overlaps: [1]
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
cam1:
  T_cn_cnm1:
  - [0.9999972564778, 0.0022598375167, 0.0003055440366, -0.1101081303]
  - [-0.0022590764913, 0.9999882899952, -0.0039867316487, 0.0003991619]
  - [-0.0003145600327, 0.0039860304427, 0.9999920064545, -0.0008534657]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [0]
  camera_model: pinhole
  distortion_coeffs: [-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05]
  distortion_model: radtan
  intrinsics: [457.587, 456.134, 379.999, 255.238]
  resolution: [752, 480]
  rostopic: /cam1/image_raw
"""


def test_kalibr_camchain_read_as_written(tmp_path):
    path = tmp_path / "camchain.yaml"
    path.write_text(KALIBR)
    loaded = load_any_calibration(tmp_path)                   # the folder holding one camchain*.yaml
    assert loaded.format == "kalibr"
    assert loaded.summary.startswith("Kalibr camchain camchain.yaml (2 cameras: left, right; baseline 0.11")
    cal = loaded.calibration
    left = cal.camera("left")
    assert (left.fx, left.fy, left.cx, left.cy, left.size) == (458.654, 457.296, 367.215, 248.375, (752, 480))
    assert np.array_equal(left.dist, [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0])
    assert cal.stereo.T.tolist() == [-0.1101081303, 0.0003991619, -0.0008534657]
    assert cal.stereo.R[0, 1] == 0.0022598375167
    assert swapped_stereo_reason(cal) is None


def test_kalibr_equidistant_is_fitted_and_checked_against_cv2_fisheye(tmp_path):
    k = np.array([-0.0137, -0.0030, 0.0015, -0.0004])
    # a 752x480 camera with f = 800 px sees 33 degrees off axis at the corners: representable
    text = KALIBR.replace("distortion_model: radtan", "distortion_model: equidistant", 1).replace(
        "[-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]", str(k.tolist())).replace(
        "458.654, 457.296", "800.0, 800.0")
    path = tmp_path / "camchain.yaml"
    path.write_text(text)
    loaded = load_any_calibration(path)
    note = loaded.notes[0]
    assert note.startswith("cam0 equidistant converted to plumb_bob (max ") and note in loaded.summary
    err = float(note.split("max ")[1].split(" px")[0])
    cam = loaded.calibration.camera("left")
    # oracle: cv2.fisheye projects the same rays; inside the image they agree within the reported error
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(-0.6, 0.6, 4000), rng.uniform(-0.4, 0.4, 4000), np.ones(4000)])
    a = cv2.fisheye.projectPoints(X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, k)[0].reshape(-1, 2)
    b = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2)
    inside = (a[:, 0] >= 0) & (a[:, 0] <= 751) & (a[:, 1] >= 0) & (a[:, 1] <= 479)
    assert inside.sum() > 1000
    assert np.max(np.linalg.norm(a[inside] - b[inside], axis=1)) <= err + 5e-4 and err < 0.02   # note rounds to 0.001 px
    assert cal_meta(loaded) == [note]
    # lenses too wide for plumb_bob (58 degrees at f = 458 px: 1.06 px; beyond 80 degrees at 150 px): refused, naming
    # file, line and key
    for f, what in (("458.654, 457.296", "the best plumb_bob fit is off by 1.06 px"), ("150.0, 150.0", "no plumb_bob fit")):
        path.write_text(text.replace("800.0, 800.0", f))
        with pytest.raises(TudorVisionError, match=r"camchain\.yaml:5: cam0\.distortion_model: equidistant "
                                                   rf"\(fisheye\) lens: {what}"):
            load_kalibr_camchain(path)


def cal_meta(loaded):
    return list(loaded.calibration.metadata["converted"])


def test_equidistant_fit_reports_its_true_error():
    K = np.array([[800.0, 0, 320], [0, 800.0, 240], [0, 0, 1]])
    dist, err = equidistant_to_plumb_bob(K, [0, 0, 0, 0], 640, 480)
    # theta = atan(r) is not r: the fit reproduces the equidistant projection (barrel: k1 < 0)
    assert dist[0] < 0 and err < 0.01
    # the reported error is the true worst radial difference: check it on a dense set of radii
    r = np.linspace(1e-4, 0.5, 5000)
    brown = r * (1 + dist[0] * r ** 2 + dist[1] * r ** 4 + dist[4] * r ** 6)
    true = np.arctan(r)
    inside = true <= np.hypot(320, 240) / 800.0
    assert abs(np.max(np.abs(brown - true)[inside]) * 800.0 - err) < 0.05 * err


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("name, text, match", [
    ("camchain.yaml", KALIBR.replace("  intrinsics: [458.654, 457.296, 367.215, 248.375]\n", ""),
     r"camchain\.yaml:2: cam0: missing 'intrinsics'"),
    ("camchain.yaml", KALIBR.replace("[458.654, 457.296, 367.215, 248.375]", "[458.654, 457.296]"),
     r"camchain\.yaml:6: cam0\.intrinsics: expected shape \(4\)"),
    ("camchain.yaml", KALIBR.replace("camera_model: pinhole", "camera_model: omni", 1),
     r"camchain\.yaml:3: cam0\.camera_model: unsupported camera model 'omni'"),
    ("camchain.yaml", KALIBR.replace("  T_cn_cnm1:\n", "  T_xx:\n"), r"cam1: missing 'T_cn_cnm1'"),
    ("cal.yaml", "image: left.png\nexposure: 3\n", r"cal\.yaml:1: not a calibration .* top-level keys: image"),
    ("cal.yaml", "- 1\n- 2\n", r"cal\.yaml:1: not a calibration file: expected a mapping, got list"),
    ("cal.yaml", "cameras: {left: {width: 640\n", r"cal\.yaml:\d+: malformed YAML"),
    ("cal.yaml", "", r"cal\.yaml: empty file"),
    ("intrinsics.yml", "%YAML:1.0\nM1: !!opencv-matrix\n   rows: 3\n   cols: [\n", r"intrinsics\.yml:4: malformed"),
])
def test_garbled_files_are_one_line_errors_naming_file_and_line(tmp_path, capsys, name, text, match):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(TudorVisionError, match=match):
        load_any_calibration(path)
    rc, out, err = _run(capsys, "calib", "convert", path, "--to", "ros", "--out", tmp_path / "o")
    assert rc == 2 and len(err.strip().splitlines()) == 1 and str(path) in err
    assert not (tmp_path / "o").exists()


def test_pairs_folders_and_missing_pieces(tmp_path, capsys):
    rng = np.random.default_rng(9)
    cal = _rig(rng)
    ros = save_calibration_as(cal, "ros", tmp_path / "ros")[0]
    cv = save_calibration_as(cal, "opencv", tmp_path / "cv")[0]
    with pytest.raises(TudorVisionError, match="two files must be ROS camera_info left,right or OpenCV"):
        load_any_calibration(f"{ros[0]},{cv[0]}")
    with pytest.raises(TudorVisionError, match="extrinsics alone hold no cameras"):
        load_any_calibration(cv[1])
    (tmp_path / "empty").mkdir()
    with pytest.raises(TudorVisionError, match=r"empty: no calibration in the folder"):
        load_any_calibration(tmp_path / "empty")
    with pytest.raises(TudorVisionError, match=r"absent\.yaml: calibration file not found"):
        load_any_calibration(tmp_path / "absent.yaml")
    # one ROS file is one camera, named by camera_name
    one = load_any_calibration(ros[0])
    assert list(one.calibration.cameras) == ["left"] and one.calibration.stereo is None
    # the OpenCV sample stores no image size: a hint on the command line, --size fixes it
    rc, _, err = _run(capsys, "calib", "convert", f"{DATA / 'io_opencv_intrinsics.yml'},"
                      f"{DATA / 'io_opencv_extrinsics.yml'}", "--to", "tudorvision", "--out", tmp_path / "x.yaml")
    assert rc == 2 and "--size WxH" in err
    rc, _, err = _run(capsys, "calib", "convert", f"{DATA / 'io_opencv_extrinsics.yml'},"
                      f"{DATA / 'io_opencv_intrinsics.yml'}", "--to", "tudorvision", "--out", tmp_path / "x.yaml",
                      "--size", "640x480", "--m-per-unit", "0.025")
    assert rc == 0, err
    assert np.allclose(load_calibration(tmp_path / "x.yaml").stereo.T, [-3.0, 0.0, 1.0])


# ----------------------------------------------------------------------------- the real pipeline
def _sample_link(tmp_path: Path) -> None:
    (tmp_path / "sample_data").symlink_to(SAMPLE, target_is_directory=True)


def test_readme_calib_stereo_command_runs_as_written(tmp_path, capsys, monkeypatch):
    _sample_link(tmp_path)
    monkeypatch.chdir(tmp_path)
    argv = shlex.split(README_CALIB)
    assert argv[0] == "tudorvision"
    rc, out, err = _run(capsys, *argv[1:])
    assert rc == 0, err
    assert "views used: 10, skipped: 0" in out and "warning" not in err
    cal = load_calibration(tmp_path / "calib.yaml")
    assert abs(cal.stereo.baseline_m - 3.0) < 0.01 and swapped_stereo_reason(cal) is None
    X = _points(np.random.default_rng(0))
    for spec in ("DIR/left.yaml,DIR/right.yaml", "DIR/intrinsics.yml,DIR/extrinsics.yml"):
        loaded = load_any_calibration(tmp_path / spec.split(",")[0]).calibration  # one file: one/two cameras
        assert loaded.cameras
        pair = load_any_calibration(",".join(str(tmp_path / s) for s in spec.split(","))).calibration
        _assert_same_geometry(cal, pair, X)


def test_calib_stereo_dir_layouts(tmp_path, capsys):
    src = SAMPLE / "stereo-checkerboard"
    # left_cam/ + right_cam/ folders
    for side in ("left", "right"):
        shutil.copytree(src / side, tmp_path / "a" / f"{side}_cam")
    rc, out, err = _run(capsys, "calib", "stereo", "--dir", tmp_path / "a", "--board", "8x6", "--square", "0.08")
    assert rc == 0 and "views used: 10" in out, err
    # left*/right* files side by side
    (tmp_path / "b").mkdir()
    for side in ("left", "right"):
        for f in sorted((src / side).iterdir())[:6]:
            shutil.copy(f, tmp_path / "b" / f"{side}_{f.name}")
    rc, out, err = _run(capsys, "calib", "stereo", "--dir", tmp_path / "b", "--board", "8x6", "--square", "0.08")
    assert rc == 0 and "views used: 6" in out, err
    # one side short: one line naming the folders
    (tmp_path / "a" / "right_cam" / "000009.jpg").unlink()
    rc, out, err = _run(capsys, "calib", "stereo", "--dir", tmp_path / "a", "--board", "8x6", "--square", "0.08")
    assert rc == 2 and "found 10 left and 9 right images (left_cam/ and right_cam/)" in err


@pytest.fixture(scope="module")
def sweep_models(tmp_path_factory):
    path = tmp_path_factory.mktemp("models") / "models.yaml"
    argv = ["colormodel", str(SAMPLE / "stereo-sweep"), "--frame", "0"]
    for p in SWEEP_PICKS:
        argv += ["--pick", p]
    assert main(argv + ["--out", str(path)]) == 0
    return path


def test_swapped_cameras_warn_and_exit_nonzero_then_track_0_valid(tmp_path, capsys, sweep_models):
    src = SAMPLE / "stereo-checkerboard"
    left = ",".join(str(p) for p in sorted((src / "left").iterdir()))
    right = ",".join(str(p) for p in sorted((src / "right").iterdir()))
    base = ["calib", "stereo", "--board", "8x6", "--square", "0.08"]
    # the cables crossed: the right camera's images given as left
    rc, out, err = _run(capsys, *base, "--left", right, "--right", left, "--out", tmp_path / "swapped.yaml")
    assert rc == 3
    assert "warning: left and right look swapped: T_x = +2.4" in err and "exchange --left/--right" in err
    swapped = load_calibration(tmp_path / "swapped.yaml")          # still written, and flagged in the file
    assert "WARNING: left and right look swapped" in (tmp_path / "swapped.yaml").read_text()
    assert swapped.stereo.T[0] > 2.0
    rc, out, err = _run(capsys, *base, "--left", right, "--right", left, "--allow-swapped")
    assert rc == 0 and "accepted: --allow-swapped" in err
    # tracking with it: the trajectory is written, 0 % valid is a warning naming the cause and exit 3
    out_csv = tmp_path / "traj.csv"
    rc, out, err = _run(capsys, "track", "stereo", SAMPLE / "stereo-sweep", "--calib", tmp_path / "swapped.yaml",
                        "--colormodel", sweep_models, "--out", out_csv)
    assert rc == 3 and out_csv.is_file()
    assert "0.0% valid" in out
    assert "warning: 0 % valid" in err and "left and right look swapped" in err
    # the base-frame calibration tracking the same sweep stops with the same cause (one error line, exit 2)
    rc, out, err = _run(capsys, "calib", "base-stereo", SAMPLE / "stereo-sweep", "--calib",
                        tmp_path / "swapped.yaml", "--colormodel", sweep_models, "--out", tmp_path / "base.yaml")
    errors = [ln for ln in err.splitlines() if "error" in ln]
    assert rc == 2 and len(errors) == 1 and "likely cause" in errors[0] and "look swapped" in errors[0]
    assert not (tmp_path / "base.yaml").exists()


def test_exchanged_images_with_a_good_calibration_name_the_epipolar_geometry(tmp_path, capsys, sweep_models):
    seq = tmp_path / "sweep"
    shutil.copytree(SAMPLE / "stereo-sweep", seq)
    (seq / "left.txt").rename(seq / "tmp.txt")
    (seq / "right.txt").rename(seq / "left.txt")
    (seq / "tmp.txt").rename(seq / "right.txt")
    rc, out, err = _run(capsys, "track", "stereo", seq, "--calib", SAMPLE / "stereo-sweep" / "calibration.yaml",
                        "--colormodel", sweep_models, "--out", tmp_path / "t.csv")
    assert rc == 3
    assert "do not fit the calibration's epipolar geometry" in err and "left and right images are exchanged" in err


# ----------------------------------------------------------------------------- the guide runs as written
def test_calibration_formats_guide_runs_as_written(tmp_path, capsys, monkeypatch):
    """Every command of docs/calibration_formats.md, expanded by bash as a user's shell would, exits as stated."""
    import re
    import subprocess

    text = (ROOT / "docs" / "calibration_formats.md").read_text()
    for name in ("sample_data", "calib", "tests"):
        (tmp_path / name).symlink_to(ROOT / name, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    prefix, ran = [], 0
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.strip().splitlines():
            cmd, _, comment = line.partition("  #")
            if not cmd.startswith("tudorvision "):
                prefix.append(cmd)
                continue
            m = re.search(r"exits (\d+)", comment)
            expected = int(m.group(1)) if m else 0
            script = "\n".join(prefix + ["printf '%s\\0' " + cmd])
            argv = subprocess.run(["bash", "-c", script], cwd=tmp_path, capture_output=True, text=True,
                                  check=True).stdout.split("\0")[:-1]
            rc, out, err = _run(capsys, *argv[1:])
            assert rc == expected, f"{line}\n{out}\n{err}"
            ran += 1
    assert ran >= 12
    # what the guide wrote is what it says: the same rig through ROS, OpenCV and Kalibr (lossy k3 refit aside)
    lab = load_calibration(ROOT / "calib" / "stereo_lab.yaml")
    X = _points(np.random.default_rng(2))
    _assert_same_geometry(lab, load_calibration(tmp_path / "out" / "calib" / "from_opencv.yaml"), X)
    kal = load_calibration(tmp_path / "out" / "calib" / "from_kalibr.yaml")
    assert np.allclose(kal.stereo.T, lab.stereo.T, atol=1e-12) and np.allclose(kal.stereo.R, lab.stereo.R, atol=1e-12)
    assert swapped_stereo_reason(load_calibration(tmp_path / "out" / "calib" / "swapped.yaml")) is not None
    # tracked through the ROS pair and the Kalibr file: every frame valid, the same trajectory
    from tudorvision.stereo import read_trajectory_csv
    a, b = (read_trajectory_csv(tmp_path / "out" / "calib" / n) for n in ("traj.csv", "traj_kalibr.csv"))
    assert a.valid.all() and b.valid.all() and len(a.t) == 40
    assert np.max(np.abs(a.p - b.p)) < 0.02          # Kalibr's k3-free refit moves pixels by < 0.7 px


def test_mutated_files_never_crash_the_loader(tmp_path):
    """Seeded fuzz: byte and line mutations of valid files of every format load or give TudorVisionError."""
    rng = np.random.default_rng(1616)
    cal = _rig(rng, k3=False)
    good = {}
    for fmt in CALIBRATION_FORMATS:
        good[fmt] = save_calibration_as(cal, fmt, _out_for(fmt, tmp_path / "good", fmt))[0]
    single = save_calibration_as(Calibration(cameras={"cam": cal.camera("left")}), "opencv",
                                 tmp_path / "good" / "camera.yml")[0]
    sources = [p for paths in good.values() for p in paths] + single
    alphabet = list(b"0123456789.-e:[]{},\n #!%abcxyzMDRTP")
    n_ok = n_err = 0
    for k in range(300):
        src = sources[k % len(sources)]
        data = bytearray(src.read_bytes())
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(0, len(data)))
            op = rng.integers(0, 3)
            if op == 0:
                data[i] = alphabet[int(rng.integers(0, len(alphabet)))]
            elif op == 1:
                del data[i:i + int(rng.integers(1, 40))]
            else:
                data[i:i] = bytes(alphabet[int(j)] for j in rng.integers(0, len(alphabet), 5))
        d = tmp_path / f"m{k}"
        d.mkdir()
        target = d / src.name
        target.write_bytes(bytes(data))
        spec = str(target)
        if src.parent.name in ("ros", "opencv"):        # a pair: the mutated file with its intact partner
            partner = next(p for p in good[src.parent.name] if p != src)
            shutil.copy(partner, d / partner.name)
            spec = str(d)
        try:
            load_any_calibration(spec)
            n_ok += 1
        except TudorVisionError as exc:
            assert "\n" not in str(exc).strip() and str(d) in str(exc), str(exc)
            n_err += 1
    assert n_ok > 10 and n_err > 50


@pytest.mark.parametrize("T", [[-0.3, 0.01, 0.02], [0.01, -0.25, 0.0]])       # horizontal and vertical rigs
def test_ros_pair_q_matches_cv2_stereo_rectify(tmp_path, T):
    from tudorvision.io.formats import load_ros_stereo, rectified_q, save_ros_stereo

    rng = np.random.default_rng(11)
    base = _rig(rng, rectify=False)
    cl, cr = base.camera("left"), base.camera("right")
    R = cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0]
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(cl.K, cl.dist, cr.K, cr.dist, cl.size, R, np.reshape(T, (3, 1)))
    assert np.allclose(rectified_q(P1, P2), Q, rtol=1e-12, atol=1e-9)
    cal = Calibration(cameras=base.cameras, stereo=StereoExtrinsics(R=R, T=T))
    back = load_ros_stereo(*save_ros_stereo(cal, tmp_path / "l.yaml", tmp_path / "r.yaml"))
    assert np.allclose(back.stereo.R, R, atol=1e-12) and np.allclose(back.stereo.T, T, atol=1e-12)
    assert np.allclose(back.stereo.Q, Q, rtol=1e-12, atol=1e-9)       # same rectification (alpha -1) as above
