"""Bad input of the stereo CLIs that is skipped and counted rather than fatal (issue 3, "Bad input").

Fatal user mistakes (missing files, malformed picks, a calibration of another
image size) are covered in ``test_stereo_cli.py``, ``test_stereo_calib.py``
and ``test_colormodel.py``; here the views and frames that are skipped while
the rest is still calibrated or tracked and written:

- ``calib stereo`` with an unreadable image, an image of another size and a
  view without the checkerboard among OpenCV's sample pairs;
- ``track mono`` on a sequence with a corrupt frame and frames without the
  sphere, and with a colour model that finds nothing.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision.cli import main
from tudorvision.io import SequenceWriter, load_calibration
from tudorvision.stereo import ColorModelSet, fit_color_model, read_mono_track_csv, save_color_models

DATA = Path(__file__).resolve().parent / "data" / "opencv_stereo"
IDS = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]


def _run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


@pytest.mark.skipif(not (DATA / "left01.jpg").is_file(), reason=f"{DATA}: OpenCV sample images not present")
def test_calib_stereo_skips_and_counts_bad_views(tmp_path, capsys):
    d = tmp_path / "pairs"
    d.mkdir()
    for i in IDS:
        for side in ("left", "right"):
            shutil.copy(DATA / f"{side}{i}.jpg", d / f"{side}{i}.jpg")
    (d / "right03.jpg").write_bytes(b"\xff\xd8 not really a jpeg")                     # unreadable
    small = cv2.imread(str(DATA / "left05.jpg"))
    cv2.imwrite(str(d / "left05.jpg"), cv2.resize(small, (320, 240)))                  # another size
    cv2.imwrite(str(d / "left08.jpg"), np.full((480, 640, 3), 128, np.uint8))          # no board
    rc, out, err = _run(capsys, "calib", "stereo", "--dir", d, "--board", "9x6", "--square", "1",
                        "--out", tmp_path / "cal.yaml")
    assert rc == 0, err
    skipped = [line for line in out.splitlines() if line.startswith("skipped ")]
    assert len(skipped) == 3, out
    assert any("right03.jpg" in s and "cannot read image" in s for s in skipped)
    assert any("left05.jpg" in s and "320x240" in s and "640x480" in s for s in skipped)
    assert any("left08.jpg" in s and "checkerboard 9x6 not found" in s for s in skipped)
    assert "views used: 10, skipped: 3" in out
    # the remaining ten pairs still calibrate the rig: baseline within 1 % of the 13-pair result
    cal = load_calibration(tmp_path / "cal.yaml")
    rc, out13, err = _run(capsys, "calib", "stereo", "--dir", DATA, "--board", "9x6", "--square", "1")
    assert rc == 0, err
    baseline13 = float(out13.split("baseline:")[1].split("m")[0])
    assert cal.stereo.baseline_m == pytest.approx(baseline13, rel=0.01)
    assert cal.metadata["skipped"] == 3 and cal.metadata["views"] == 10


def _mono_sequence(root, *, n=6, absent=(2,)):
    """A 50 Hz mono PNG sequence of a red disc moving right; it is missing in the frames ``absent``."""
    frames, centres = [], []
    with SequenceWriter(root, kind="mono", rate_hz=50.0, image_ext=".png") as w:
        for k in range(n):
            img = np.full((120, 160, 3), 100, np.uint8)
            c = (40 + 12 * k, 60)
            if k not in absent:
                cv2.circle(img, c, 9, (40, 40, 210), -1, lineType=cv2.LINE_AA)
            w.add_mono(k / 50.0, img)
            frames.append(img)
            centres.append(c)
    return frames, centres


def test_track_mono_skips_corrupt_frames_and_writes_the_partial_track(tmp_path, capsys):
    seq = tmp_path / "mono"
    frames, centres = _mono_sequence(seq)
    images = sorted(p for p in seq.rglob("*.png"))
    assert len(images) == 6
    images[4].write_bytes(b"garbage")                   # frame 4 cannot be decoded
    m = fit_color_model(frames[0], centres[0], (centres[0][0] + 7, centres[0][1]))
    save_color_models(ColorModelSet({"mono": {"red": m}}), tmp_path / "m.yaml")
    out = tmp_path / "track.csv"
    rc, stdout, err = _run(capsys, "track", "mono", seq, "--colormodel", tmp_path / "m.yaml", "--sphere", "red",
                           "--out", out)
    assert rc == 0, err
    assert "skipped" in err and images[4].name in err          # named on stderr (and in the CSV)
    tr = read_mono_track_csv(out)
    assert list(tr["frame"]) == [0, 1, 2, 3, 5]                 # the corrupt frame is left out, the rest kept
    assert list(tr["valid"]) == [1, 1, 0, 1, 1]                 # frame 2 has no sphere: a nan row
    uv = np.c_[tr["u"], tr["v"]]
    assert np.isnan(uv[2]).all()
    np.testing.assert_allclose(uv[tr["valid"] == 1], np.array(centres, float)[[0, 1, 3, 5]], atol=0.2)

    # a colour model that finds nothing: every row invalid, still written, with a warning
    blue = np.full((120, 160, 3), 100, np.uint8)
    cv2.circle(blue, (80, 60), 9, (210, 60, 30), -1)
    save_color_models(ColorModelSet({"mono": {"red": fit_color_model(blue, (80, 60), (87, 60))}}),
                      tmp_path / "blue.yaml")
    rc, stdout, err = _run(capsys, "track", "mono", seq, "--colormodel", tmp_path / "blue.yaml",
                           "--sphere", "red", "--out", tmp_path / "none.csv")
    assert rc == 3, err       # the track is written, but nothing valid: a warning with the cause, non-zero exit
    assert "warning: 0 % valid: sphere 'red' found in no frame" in err and "colour model" in err
    tr = read_mono_track_csv(tmp_path / "none.csv")
    assert len(tr["frame"]) == 5 and not tr["valid"].any()
