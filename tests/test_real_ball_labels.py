"""Hand-checked labels of real ball videos (issue 15) and the tracker's centre error against them.

The labels (tests/data/ball_labels/labels.csv, see the README there) come with
the repository; the videos live beside it in ../shared/realdata/ball_videos
and the tracker tests skip when they are absent.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.io import open_sequence
from tudorvision.io.labels import BallLabel, read_ball_labels, write_ball_labels

HERE = Path(__file__).resolve().parent
LABELS = HERE / "data" / "ball_labels" / "labels.csv"
VIDEOS = Path(__file__).resolve().parents[1].parent / "shared" / "realdata" / "ball_videos"
PICK_FRAME = {"ball2.mp4": 660, "ball3.mp4": 179, "ball4.mp4": 208}   # as in benchmarks/bench_real_balls.py
# Regression bounds = figures measured with the chroma-edge rim of 2026-11-26 (full-frame detection on every
# clean labelled frame: 97.6 % found, median 1.12 px, p90 3.80 px; 2026-11-25: 1.24 / 4.53 px; before the
# chroma edge 2.60 / 6.06 px; see docs/benchmarks.md "Issue 15: chroma rim, real-ball p90 and the sphere
# family"). Issue 15's TARGET is >= 95 % found, median <= 2 px, p90 <= 4 px: met since 2026-11-26.
MIN_FOUND, MAX_MEDIAN_PX, MAX_P90_PX = 0.95, 1.4, 4.0
TARGET_FOUND, TARGET_MEDIAN_PX, TARGET_P90_PX = 0.95, 2.0, 4.0

needs_videos = pytest.mark.skipif(not VIDEOS.is_dir(), reason=f"real ball videos not found at {VIDEOS} "
                                  "(../shared/realdata beside the repository; see its SOURCES.md)")


@pytest.fixture(scope="module")
def labels():
    return read_ball_labels(LABELS)


def test_label_file_is_consistent(labels):
    videos = {lab.video for lab in labels}
    assert videos == {"ball2.mp4", "ball3.mp4", "ball4.mp4"}
    with_circle = [lab for lab in labels if lab.has_circle]
    assert len(with_circle) >= 150
    assert sum(lab.clean for lab in labels) >= 150
    for lab in labels:
        assert lab.clean <= lab.has_circle
        if lab.has_circle:
            w, h = (640, 480) if lab.video == "ball2.mp4" else (1280, 720)
            assert 10 < lab.r_px < 80
            # a clean ball lies wholly inside the frame
            if lab.clean:
                assert lab.r_px - 1 <= lab.u_px <= w - lab.r_px + 1
                assert lab.r_px - 1 <= lab.v_px <= h - lab.r_px + 1
        else:
            assert lab.method == "none"
        if lab.method == "hand-corrected":
            assert lab.note, f"{lab.video} {lab.frame}: a hand correction says why"
    for name, frame in PICK_FRAME.items():
        assert any(lab.video == name and lab.frame == frame and lab.clean for lab in labels)
    # labels move smoothly: neighbouring labelled frames (<= 12 frames apart) of one video differ by less
    # than the ball can move by hand, and radii change slowly
    for name in videos:
        rows = sorted((lab for lab in with_circle if lab.video == name), key=lambda lab: lab.frame)
        for a, b in zip(rows, rows[1:]):
            if b.frame - a.frame <= 12:
                assert abs(b.r_px - a.r_px) < 0.35 * a.r_px + 3, (name, a.frame, b.frame)


def test_label_round_trip(tmp_path, labels):
    out = write_ball_labels(tmp_path / "l.csv", labels[::-1], comment="copy")
    back = read_ball_labels(out)
    assert back == sorted(labels, key=lambda lab: (lab.video, lab.frame))


@pytest.mark.parametrize("row, match", [
    ("b.mp4,1,1,2,,1,auto-checked,", "all of u_px"),
    ("b.mp4,1,,,,1,none,", "clean frame needs a circle"),
    ("b.mp4,1,1,2,3,2,auto-checked,", "clean: expected 0 or 1"),
    ("b.mp4,1,1,2,3,1,guessed,", "method must be one of"),
    ("b.mp4,1,1,2,-3,1,auto-checked,", "r_px must be positive"),
    ("b.mp4,x,1,2,3,1,auto-checked,", "frame: expected an integer"),
])
def test_bad_rows_are_refused(tmp_path, row, match):
    p = tmp_path / "bad.csv"
    p.write_text("video,frame,u_px,v_px,r_px,clean,method,note\n" + row + "\n")
    with pytest.raises(TudorVisionError, match=match):
        read_ball_labels(p)


def test_duplicate_frame_is_refused(tmp_path):
    p = tmp_path / "dup.csv"
    p.write_text("video,frame,u_px,v_px,r_px,clean,method,note\n"
                 "b.mp4,1,1,2,3,1,auto-checked,\nb.mp4,1,1,2,3,1,auto-checked,\n")
    with pytest.raises(TudorVisionError, match="already labelled on line 2"):
        read_ball_labels(p)


def test_label_rejects_circle_with_method_none():
    with pytest.raises(TudorVisionError, match="method 'none'"):
        BallLabel(video="b.mp4", frame=0, u_px=1.0, v_px=1.0, r_px=1.0, clean=False, method="none")


def _disc_image(u, v, r, size=(140, 120), supersample=8):
    """Grey image with a green disc, each pixel's colour mixed by its exact (supersampled) disc coverage."""
    w, h = size
    yy, xx = np.mgrid[0:h * supersample, 0:w * supersample]
    inside = ((xx + 0.5) / supersample - 0.5 - u) ** 2 + ((yy + 0.5) / supersample - 0.5 - v) ** 2 <= r * r
    cov = inside.reshape(h, supersample, w, supersample).mean(axis=(1, 3))[..., None]
    return (205 * (1 - cov) + np.array([90, 175, 95]) * cov).round().astype(np.uint8)


def test_proposal_finds_an_occluded_disc():
    """The labelling helper's proposal against an exactly rendered disc with a 'finger' over a quarter of it."""
    import cv2
    from tudorvision.cli.label import propose_ball_circle
    rng = np.random.default_rng(3)
    for _ in range(5):
        u, v, r = rng.uniform(50, 90), rng.uniform(50, 70), rng.uniform(12, 30)
        img = _disc_image(u, v, r)
        cv2.rectangle(img, (int(u), int(v + r / 3)), (int(u + r + 5), int(v + r + 5)), (140, 160, 215), -1)
        res = propose_ball_circle(img, (-30.0, 20.0))
        assert res is not None
        assert math.hypot(res[0] - u, res[1] - v) < 0.2
        assert abs(res[2] - r) < 0.2
        # without the sub-pixel rim the boundary pixels (+0.5 px) overestimate the radius by about 1 px
        coarse = propose_ball_circle(img, (-30.0, 20.0), refine=False)
        assert 0.5 < coarse[2] - r < 1.5


def _measure(labels, step=1):
    """Full-frame detection on every ``step``-th clean labelled frame: found rate, median, p90 (px)."""
    from tudorvision.io import open_sequence
    from tudorvision.stereo import detect_sphere, fit_color_model
    errs, found, n = [], 0, 0
    for name, pick_frame in PICK_FRAME.items():
        rows = [lab for lab in labels if lab.video == name and lab.clean]
        pick = next(lab for lab in rows if lab.frame == pick_frame)
        with open_sequence(VIDEOS / name) as seq:
            c = np.array([pick.u_px, pick.v_px])
            model = fit_color_model(np.asarray(seq[pick.frame].image), np.round(c),
                                    np.round(c - [0.8 * pick.r_px, 0.0]))
            for lab in rows[::step]:
                d = detect_sphere(np.asarray(seq[lab.frame].image), model)
                n += 1
                if d.valid:
                    found += 1
                    errs.append(math.hypot(d.uv[0] - lab.u_px, d.uv[1] - lab.v_px))
    errs = np.array(errs)
    return found / n, float(np.median(errs)), float(np.percentile(errs, 90))


@needs_videos
def test_tracker_centre_error_on_labelled_real_frames(labels):
    rate, med, p90 = _measure(labels)
    print(f"found {100 * rate:.1f} %, centre error median {med:.2f} px, p90 {p90:.2f} px "
          f"(issue 15 target: >= {100 * TARGET_FOUND:.0f} %, <= {TARGET_MEDIAN_PX} px, <= {TARGET_P90_PX} px)")
    assert rate >= MIN_FOUND
    assert med <= min(MAX_MEDIAN_PX, TARGET_MEDIAN_PX)
    assert p90 <= MAX_P90_PX


def test_label_command_on_an_image_folder(tmp_path):
    """``tudorvision label balls`` end to end on rendered frames: labels, review options, sheets, one-line errors."""
    import cv2
    from tudorvision.cli import main
    truth = [(60.0 + 7 * i, 50.0 + 3 * i, 18.0 + i) for i in range(4)]
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, (u, v, r) in enumerate(truth):
        cv2.imwrite(str(folder / f"{i:03d}.png"), _disc_image(u, v, r))
    out = tmp_path / "labels.csv"
    args = ["label", "balls", str(folder), "--frames", "0:4", "--pick", "0=60,50", "--out", str(out),
            "--sheet", str(tmp_path / "sheet.png"), "--set", "2=1,2,3", "--note", "2=by hand",
            "--unclean", "3=blurred"]
    assert main(args) == 0
    rows = read_ball_labels(out)
    assert [lab.frame for lab in rows] == [0, 1, 2, 3]
    for lab, (u, v, r) in zip(rows, truth):
        if lab.frame != 2:
            assert math.hypot(lab.u_px - u, lab.v_px - v) < 0.2 and abs(lab.r_px - r) < 0.2
    assert (rows[2].u_px, rows[2].method, rows[2].note) == (1.0, "hand-corrected", "by hand")
    assert [lab.clean for lab in rows] == [True, True, True, False] and rows[3].note == "blurred"
    assert (tmp_path / "sheet_01.png").is_file()
    # a second run on other frames keeps the first run's rows
    assert main(["label", "balls", str(folder), "--frames", "1", "--pick", "0=60,50", "--out", str(out),
                 "--none", "1"]) == 0
    rows = read_ball_labels(out)
    assert len(rows) == 4 and rows[1].method == "none" and not rows[1].has_circle


@pytest.mark.parametrize("extra, match", [
    (["--pick", "9=60,50"], "--pick: frame 9 outside"),
    (["--pick", "0=60"], "--pick: expected FRAME=X,X"),
    (["--pick", "0=5,5"], "nearly the wall's"),
    (["--pick", "0=60,50", "--set", "3=1,2,3"], "frame 3 is not in --frames"),
])
def test_label_command_errors_are_one_line(tmp_path, capsys, extra, match):
    import cv2
    from tudorvision.cli import main
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(2):
        cv2.imwrite(str(folder / f"{i:03d}.png"), _disc_image(60, 50, 18))
    code = main(["label", "balls", str(folder), "--frames", "0:2", "--out", str(tmp_path / "l.csv")] + extra)
    err = capsys.readouterr().err
    assert code == 2
    assert match in err and len(err.strip().splitlines()) == 1


@needs_videos
def test_video_random_access_is_frame_exact():
    """``seq[i]`` is the i-th decoded frame, also where OpenCV's frame seek lands one frame early
    (ball3.mp4 from frame 108): the oracle is a plain sequential decode."""
    import cv2

    path = VIDEOS / "ball3.mp4"
    cap = cv2.VideoCapture(str(path))
    decoded = []
    while len(decoded) < 125:
        ok, img = cap.read()
        assert ok
        decoded.append(img)
    cap.release()
    seq = open_sequence(path)
    for i in (120, 108, 3, 124, 110):          # forward, backward and repeated jumps
        assert np.array_equal(np.asarray(seq[i].image), decoded[i]), i
