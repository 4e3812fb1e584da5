"""Issue 14, files: Ctrl-C, bad frames, paths outside the sequence, huge images, ``sim record --out``.

Sequences are written with :class:`tudorvision.io.SequenceWriter` into
``tmp_path``; Ctrl-C is a ``KeyboardInterrupt`` raised by the frame reader
after N frames.
"""
from __future__ import annotations

import struct
import time
import zlib

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.cli import main
from tudorvision.io import Sequence, SequenceWriter, open_sequence
from tudorvision.io._imageheader import image_size_from_header
from tudorvision.lab import RecordOptions, record

from test_files_atomic import _rgbd_sequence


def _run(capsys, *argv):
    rc = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def _interrupt_after(monkeypatch, n, exc=KeyboardInterrupt):
    """Make Sequence.load_or_report raise ``exc`` when asked for frame ``n``."""
    real = Sequence.load_or_report

    def load(self, i):
        if i == n:
            raise exc() if isinstance(exc, type) else exc
        return real(self, i)

    monkeypatch.setattr(Sequence, "load_or_report", load)


def _mono_sequence(path, n=4, size=(8, 6)):
    w, h = size
    with SequenceWriter(path, kind="mono", rate_hz=10.0, image_ext=".png") as wr:
        for k in range(n):
            wr.add_mono(k / 10.0, np.full((h, w, 3), 10 * k, np.uint8))
    return path


def _png_header_only(path, w, h):
    """A tiny PNG whose IHDR declares w x h pixels (the image data is not there)."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data
                                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
                     + chunk(b"IDAT", zlib.compress(b"\0" * 4096)) + chunk(b"IEND", b""))
    return path


# ----------------------------------------------------------------------------- Ctrl-C keeps the rows
def test_detect_ball_ctrl_c_keeps_the_rows_flagged_exit_130(tmp_path, monkeypatch, capsys):
    seq = _rgbd_sequence(tmp_path / "seq", n=8)
    out = tmp_path / "balls.csv"
    _interrupt_after(monkeypatch, 5)
    rc, _, err = _run(capsys, "detect", "ball", seq, "--out", out, "--background", "2")
    assert rc == 130
    lines = out.read_text().splitlines()
    assert lines[0] == "# interrupted after 5 frames: interrupted (Ctrl-C)"
    assert lines[1] == "frame,t,u,v,x,y,z,valid" and len(lines) == 2 + 5
    assert "interrupted after 5 frames" in err


def test_track_stereo_ctrl_c_keeps_the_rows_flagged_exit_130(tmp_path, monkeypatch, capsys):
    from test_stereo_cli import good_picks
    from tudorvision.stereo import read_trajectory_csv

    seq_dir = tmp_path / "static"
    record("stereo-static", seq_dir, RecordOptions(seed=4, frames=4, show_progress=False, image_ext=".png"))
    models = tmp_path / "models.yaml"
    picks = [a for p in good_picks(open_sequence(seq_dir)) for a in ("--pick", p)]
    assert main(["colormodel", str(seq_dir), *picks, "--out", str(models)]) == 0
    out = tmp_path / "traj.csv"
    _interrupt_after(monkeypatch, 3)
    rc, _, err = _run(capsys, "track", "stereo", seq_dir, "--colormodel", models, "--out", out)
    assert rc == 130, err
    assert "# interrupted after 3 frames: interrupted (Ctrl-C)" in out.read_text().splitlines()[:5]
    assert len(read_trajectory_csv(out).t) == 3


def _ball_image(u=40):
    img = np.full((60, 80, 3), 90, np.uint8)
    cv2.circle(img, (u, 30), 10, (0, 0, 255), -1)
    return img


def test_track_mono_ctrl_c_and_errors_keep_the_rows(tmp_path, monkeypatch, capsys):
    from tudorvision.stereo.colormodel import fit_color_model_set, save_color_models
    from tudorvision.stereo.tracking import read_mono_track_csv, track_mono

    d = tmp_path / "m"
    with SequenceWriter(d, kind="mono", rate_hz=10.0, image_ext=".png") as wr:
        for k in range(6):
            wr.add_mono(k / 10.0, _ball_image(30 + 3 * k))
    models = fit_color_model_set({"mono": _ball_image()}, ["mono:red:40,30:50,30"])
    save_color_models(models, tmp_path / "models.yaml")
    _interrupt_after(monkeypatch, 4)
    out = tmp_path / "track.csv"
    rc, _, err = _run(capsys, "track", "mono", d, "--colormodel", tmp_path / "models.yaml", "--sphere", "red",
                      "--out", out)
    assert rc == 130, err
    assert "# interrupted after 4 frames: interrupted (Ctrl-C)" in out.read_text().splitlines()
    assert read_mono_track_csv(out)["frame"].tolist() == [0, 1, 2, 3]
    # a fatal error: the library keeps the frames done so far only when asked to
    _interrupt_after(monkeypatch, 2, RuntimeError("decoder crashed"))
    res = track_mono(open_sequence(d, strict=False), models.get("mono", "red"), keep_partial=True)
    assert res.stats.interrupted == "stopped by an error (decoder crashed)" and res.frame.tolist() == [0, 1]
    with pytest.raises(RuntimeError, match="decoder crashed"):
        track_mono(open_sequence(d, strict=False), models.get("mono", "red"))


# ----------------------------------------------------------------------------- bad frames
def test_detect_ball_skips_bad_frames_and_says_which(tmp_path, capsys):
    seq = _rgbd_sequence(tmp_path / "seq", n=6)
    bad = seq / "depth" / "000002.png"
    bad.write_bytes(b"not a png")
    rotated = seq / "rgb" / "000004.png"
    cv2.imwrite(str(rotated), np.zeros((16, 12, 3), np.uint8))   # portrait: a rotated phone picture
    out = tmp_path / "balls.csv"
    rc, stdout, err = _run(capsys, "detect", "ball", seq, "--out", out, "--background", "2")
    assert rc == 0, err
    assert "skipped frame 2" in err and "000002.png" in err
    assert "skipped frame 4" in err and "12x16" in err
    text = out.read_text()
    assert text.startswith("# partial: 2 defect(s) skipped\n") and "000002.png" in text
    rows = [ln for ln in text.splitlines() if ln and not ln.startswith("#")][1:]
    assert [int(r.split(",")[0]) for r in rows] == [0, 1, 3, 5]
    assert "partial" in stdout


def test_frames_of_another_size_than_the_first_are_defects(tmp_path):
    d = tmp_path / "folder"   # an image folder declares no size: the first frame read sets it
    d.mkdir()
    for k, shape in enumerate([(6, 8, 3), (8, 6, 3), (6, 8, 3)]):
        cv2.imwrite(str(d / f"{k:06d}.png"), np.zeros(shape, np.uint8))
    seq = open_sequence(d, strict=False)
    assert [f.index for f in seq] == [0, 2]
    assert seq.report[0].frame == 1 and "6x8, expected 8x6 like the first frame" in seq.report[0].reason
    with pytest.raises(TudorVisionError, match="000001.png.*6x8"):
        seq[1]


# ----------------------------------------------------------------------------- index paths
@pytest.mark.parametrize("name", ["../../x.png", "../x.png", "ABS"])
def test_index_paths_outside_the_sequence_are_refused(tmp_path, capsys, name):
    d = _mono_sequence(tmp_path / "a" / "b" / "seq", n=2)
    outside = tmp_path / "a" / "x.png"
    cv2.imwrite(str(outside), np.zeros((6, 8, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "a" / "b" / "x.png"), np.zeros((6, 8, 3), np.uint8))
    entry = str(outside) if name == "ABS" else name
    with open(d / "image.txt", "a") as fh:
        fh.write(f"9.0 {entry}\n")
    line = len((d / "image.txt").read_text().splitlines())
    with pytest.raises(TudorVisionError, match=rf"image\.txt:{line}: file .* is outside the sequence folder"):
        open_sequence(d)
    lenient = open_sequence(d, strict=False)
    assert len(lenient) == 2 and "outside" in lenient.report[0].reason
    rc, _, err = _run(capsys, "seq", "check", d)
    assert rc == 2 and len(err.strip().splitlines()) == 1 and f"image.txt:{line}" in err
    assert len(open_sequence(d, allow_outside=True)) == 3
    rc, stdout, _ = _run(capsys, "seq", "check", d, "--allow-outside")
    assert rc == 0 and "3 frames" in stdout


# ----------------------------------------------------------------------------- huge images
def test_huge_png_is_refused_from_its_header_quickly(tmp_path, capsys):
    d = _mono_sequence(tmp_path / "m", n=2)
    _png_header_only(d / "image" / "000001.png", 30000, 30000)
    assert image_size_from_header((d / "image" / "000001.png").read_bytes()) == (30000, 30000)
    t0 = time.perf_counter()
    rc, _, err = _run(capsys, "seq", "check", d)
    assert time.perf_counter() - t0 < 5.0
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "000001.png" in err and "30000x30000" in err and "--max-pixels" in err


def test_pixel_limit_can_be_raised(tmp_path, capsys):
    d = _mono_sequence(tmp_path / "m", n=2, size=(200, 100))
    rc, _, err = _run(capsys, "seq", "check", d, "--max-pixels", "10000")
    assert rc == 2 and "200x100" in err
    rc, _, _ = _run(capsys, "seq", "check", d, "--max-pixels", "20000")
    assert rc == 0
    assert len(list(open_sequence(d, max_pixels=None))) == 2
    with pytest.raises(ValueError, match="max_pixels"):
        open_sequence(d, max_pixels=-1)


def test_header_sizes_of_jpeg_bmp_pgm(tmp_path):
    img = np.zeros((37, 53, 3), np.uint8)
    for ext in (".jpg", ".png", ".bmp", ".ppm"):
        ok, buf = cv2.imencode(ext, img)
        assert ok and image_size_from_header(buf.tobytes()) == (53, 37), ext
    assert image_size_from_header(b"\xff\xd8\xff") is None and image_size_from_header(b"") is None


# ----------------------------------------------------------------------------- sim record --out
def test_sim_record_refuses_a_non_empty_folder_and_force_keeps_user_files(tmp_path, capsys):
    d = tmp_path / "rec"
    (d / "depth").mkdir(parents=True)
    (d / "depth" / "my_depth_notes.txt").write_text("mine")
    (d / "groundtruth").mkdir()
    (d / "groundtruth" / "my_truth.csv").write_text("a,b\n1,2\n")
    (d / "image").mkdir()
    (d / "image" / "holiday.png").write_bytes(b"png")
    (d / "calibration_mine.yaml").write_text("x: 1\n")
    rc, _, err = _run(capsys, "sim", "record", "servo-views", "--frames", "2", "--out", d)
    assert rc == 2 and "not empty" in err and "--force" in err and len(err.strip().splitlines()) == 1
    rc, _, err = _run(capsys, "sim", "record", "servo-views", "--frames", "2", "--out", d, "--force")
    assert rc == 0, err
    rc, _, err = _run(capsys, "sim", "record", "servo-views", "--frames", "2", "--out", d, "--force")
    assert rc == 0, err   # a second --force replaces the first recording
    assert (d / "depth" / "my_depth_notes.txt").read_text() == "mine"
    assert (d / "groundtruth" / "my_truth.csv").exists() and (d / "image" / "holiday.png").exists()
    assert (d / "calibration_mine.yaml").exists()
    assert len(list((d / "rgb").iterdir())) == 2 and not (d / "INCOMPLETE").exists()
    assert _run(capsys, "seq", "check", d)[0] == 0


def test_interrupted_recording_is_incomplete_for_seq_check(tmp_path, monkeypatch, capsys):
    d = tmp_path / "rec"
    real = SequenceWriter.add_rgbd
    calls = []

    def add(self, *a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(self, *a, **k)

    monkeypatch.setattr(SequenceWriter, "add_rgbd", add)
    rc, _, _ = _run(capsys, "sim", "record", "servo-views", "--frames", "5", "--out", d)
    assert rc == 130
    assert (d / "INCOMPLETE").read_text().startswith("interrupted (Ctrl-C) after 2 frames")
    rc, _, err = _run(capsys, "seq", "check", d)
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "incomplete" in err and "after 2 frames" in err
    assert _run(capsys, "seq", "info", d)[0] == 2
    monkeypatch.undo()
    rc, _, err = _run(capsys, "sim", "record", "servo-views", "--frames", "2", "--out", d, "--force")
    assert rc == 0 and not (d / "INCOMPLETE").exists() and _run(capsys, "seq", "check", d)[0] == 0


def test_killed_recording_without_sequence_yaml_is_incomplete(tmp_path):
    d = tmp_path / "rec"
    w = SequenceWriter(d, kind="mono", rate_hz=10.0)
    w.add_mono(0.0, np.zeros((4, 6), np.uint8))   # never closed: the process was killed
    with pytest.raises(TudorVisionError, match="incomplete"):
        open_sequence(d)
