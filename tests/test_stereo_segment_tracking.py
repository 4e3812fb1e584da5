"""Tracking mode: windows around the prediction, full-frame fallback, image borders."""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from test_stereo_segment_scenes import GREEN_BGR, RED_BGR, clutter_background, make_frame, sphere_patch, two_spheres
from tudorvision._checks import TudorVisionError
from tudorvision.stereo.colormodel import fit_color_model
from tudorvision.stereo.segment import SegmentParams, detect_sphere, detect_spheres
from tudorvision.stereo.tracker2d import FrameTracker, SphereTracker, TrackerParams

COLORS = {"red": RED_BGR, "green": GREEN_BGR}


@pytest.fixture(scope="module")
def models():
    frame = make_frame(np.random.default_rng(11), two_spheres((200.3, 150.7), (420.2, 300.4), radius=10.0))
    return {"red": fit_color_model(frame, (200, 151), (210, 151)),
            "green": fit_color_model(frame, (420, 300), (430, 300))}


def render_sequence(rng, paths, radius=9.0, *, visible=None, blur=None):
    """Frames over a static cluttered background; ``paths[name]`` is (N, 2) centres."""
    n = len(next(iter(paths.values())))
    keep = [(u, v, radius + 25) for p in paths.values() for u, v in p[::2]]
    bg = clutter_background(rng, keep_out=keep)
    frames = []
    for k in range(n):
        img = bg.copy()
        for name, path in paths.items():
            if visible is not None and not visible[name][k]:
                continue
            b = (0.0, 0.0) if blur is None else tuple(blur[name][k])
            sphere_patch(path[k], radius, COLORS[name], img, blur_uv=b, n_time=1 if b == (0.0, 0.0) else 24)
        img += rng.normal(0, 3.0, img.shape).astype(np.float32)
        frames.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return frames


def test_tracking_equals_full_frame(models):
    rng = np.random.default_rng(3)
    t = np.arange(24)
    # up to ~17 px/frame (faster than a radius per frame: blur is expected, yet the sharp
    # sphere passes the strict tables first, so the result equals the full-frame one)
    paths = {"red": np.c_[150 + 6.0 * t + 0.1 * t ** 2, 240 + 80 * np.sin(t / 5.0)],
             "green": np.c_[480 - 5.0 * t, 120 + 3.5 * t + 6 * np.cos(t / 3.0)]}
    frames = render_sequence(rng, paths)
    # moment_speed=inf: the same centroid method as the full frame at every speed
    trk = FrameTracker(models, params=TrackerParams(moment_speed=float("inf")))
    blur_aware = FrameTracker(models)  # default: rim moment for fast, smoothly moving spheres
    n_rim = 0
    for k, frame in enumerate(frames):
        got = trk.update(frame)
        other = blur_aware.update(frame)
        full = detect_spheres(frame, models)
        for name in models:
            assert got[name].valid and full[name].valid, (k, name, got[name].reason)
            np.testing.assert_allclose(got[name].uv, full[name].uv, atol=1e-9)
            assert got[name].area_px == full[name].area_px
            assert np.hypot(*(np.subtract(got[name].uv, paths[name][k]))) < 0.5
            assert other[name].valid and np.hypot(*(np.subtract(other[name].uv, paths[name][k]))) < 0.5
            n_rim += other[name].method == "rim_moment"
    assert n_rim > 0  # the fast red sphere switches to the rim moment
    for t_ in trk.trackers.values():
        # the first frame, and at most once more right after it (velocity still unknown)
        assert t_.n_full <= 2 and t_.n_window >= len(frames) - 2


def test_recovers_after_disappearing(models):
    rng = np.random.default_rng(4)
    n = 16
    path = np.c_[np.linspace(120, 420, n), np.linspace(300, 200, n)]
    path[9:] += [60.0, 90.0]  # it reappears away from where it vanished
    visible = {"red": np.array([k not in (5, 6, 7, 8) for k in range(n)])}
    frames = render_sequence(rng, {"red": path}, visible=visible)
    trk = SphereTracker(models["red"])
    modes = []
    for k, frame in enumerate(frames):
        d = trk.update(frame)
        modes.append(trk.mode)
        if visible["red"][k]:
            assert d.valid, (k, d.reason)
            assert np.hypot(*(np.subtract(d.uv, path[k]))) < 0.5
        else:
            assert not d.valid
            assert trk.predict() is None  # lost: the next frame is searched in full
    assert modes[5:10] == ["window"] * 0 + ["full"] * 5  # absent frames and the recovery: full frames
    assert modes[10:] == ["window"] * (n - 10)


def test_window_at_image_border(models):
    """The sphere runs into the left border: clipped windows, then rejection at the border."""
    rng = np.random.default_rng(5)
    path = np.c_[np.linspace(70.3, 4.3, 13), np.linspace(200.6, 190.1, 13)]  # radius 9
    frames = render_sequence(rng, {"green": path})
    trk = SphereTracker(models["green"])
    clipped_windows = 0
    for k, frame in enumerate(frames):
        pred = trk.predict()
        d = trk.update(frame)
        full = detect_sphere(frame, models["green"])
        if path[k, 0] - 9.0 > 2.0:
            assert d.valid, (k, d.reason)
            np.testing.assert_allclose(d.uv, full.uv, atol=1e-9)
            assert np.hypot(*(np.subtract(d.uv, path[k]))) < 0.5
            if pred is not None and pred[0][0] - pred[1] < 0:
                clipped_windows += 1
                assert trk.mode == "window"
        elif path[k, 0] < 9.0:  # clearly cut by the border
            assert not d.valid and "image border" in d.reason
    assert clipped_windows >= 2


def test_fast_motion_with_blur_uses_window(models):
    """Speeding up to 25 px/frame with a streak as long as the frame-to-frame motion
    (exposure = frame time, the worst case): blur is expected in the window and accepted."""
    rng = np.random.default_rng(6)
    speed = np.minimum(np.arange(14) * 5.0, 25.0)  # px/frame
    direction = np.array([0.97, 0.24])
    travelled = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]))])
    path = np.array([60.2, 120.7]) + travelled[:, None] * direction
    blur = {"red": speed[:, None] * direction}
    frames = render_sequence(rng, {"red": path}, blur=blur)
    trk = SphereTracker(models["red"])
    errs, strict_fails = [], 0
    for k, frame in enumerate(frames):
        pred = trk.predict()
        d = trk.update(frame)
        assert d.valid, (k, d.reason)
        assert trk.mode == ("full" if k == 0 else "window")
        errs.append(np.subtract(d.uv, path[k]))
        if pred is not None:
            h = int(np.ceil(pred[1]))
            u, v = np.rint(pred[0]).astype(int)
            strict_fails += not detect_sphere(frame, models["red"], roi=(u - h, v - h, 2 * h + 1, 2 * h + 1)).valid
    assert strict_fails >= 3  # the longest streaks need the blur-tolerant tables
    assert np.sqrt(np.mean(np.sum(np.array(errs) ** 2, axis=1))) < 0.4


def test_lost_while_fast_reacquires_blurred_sphere(models):
    """A fast, blurred sphere jumps out of the window: found again with the tolerant tables."""
    rng = np.random.default_rng(9)
    speed = np.minimum(np.arange(12) * 6.0, 24.0)
    travelled = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]))])
    path = np.c_[50.2 + travelled, np.full(12, 150.6)]
    path[9:] += [0.0, 110.0]  # a jump the window cannot follow
    frames = render_sequence(rng, {"red": path}, blur={"red": np.c_[speed, np.zeros(12)]})
    trk = SphereTracker(models["red"])
    for k, frame in enumerate(frames):
        d = trk.update(frame)
        assert d.valid, (k, d.reason)
        assert np.hypot(*(np.subtract(d.uv, path[k]))) < 0.5
        if k == 9:
            assert trk.mode == "full"
    # the strict tables alone do not see the streak after the jump
    assert not detect_sphere(frames[9], models["red"]).valid


def test_predict_constant_velocity(models):
    rng = np.random.default_rng(8)
    path = np.array([[200.0, 200.0], [207.0, 196.0], [214.0, 192.0]])
    frames = render_sequence(rng, {"red": path})
    trk = SphereTracker(models["red"])
    assert trk.predict() is None
    trk.update(frames[0])
    uv, half, speed = trk.predict()
    assert uv == pytest.approx(trk.last.uv) and speed == 0.0
    trk.update(frames[1])
    uv, half, speed = trk.predict()
    assert uv == pytest.approx(path[2], abs=0.5)
    assert speed == pytest.approx(np.hypot(7, 4), abs=0.3)
    assert half >= 2.5 * trk.last.radius_px
    trk.reset()
    assert trk.predict() is None and trk.n_full == 0


def test_tracker_errors(models):
    with pytest.raises(TudorVisionError, match="model: expected a ColorModel"):
        SphereTracker({"red": models["red"]})
    with pytest.raises(TudorVisionError, match="params: expected TrackerParams"):
        SphereTracker(models["red"], params=SegmentParams())
    with pytest.raises(TudorVisionError, match="segment: expected SegmentParams"):
        TrackerParams(segment={})
    with pytest.raises(TudorVisionError, match="window_scale"):
        TrackerParams(window_scale=-1.0)
    with pytest.raises(TudorVisionError, match="min_half_window_px, max_half_window_px"):
        TrackerParams(min_half_window_px=50, max_half_window_px=20)
    with pytest.raises(TudorVisionError, match="models: expected a non-empty mapping"):
        FrameTracker({})
    with pytest.raises(TudorVisionError, match="frame_bgr: expected a uint8 BGR image"):
        SphereTracker(models["red"]).update(np.zeros((10, 10), np.uint8))


BALL2 = str(Path(__file__).resolve().parents[1].parent / "shared" / "realdata" / "ball_videos" / "ball2.mp4")


@pytest.mark.skipif(not os.path.exists(BALL2), reason="../shared/realdata/ball_videos/ball2.mp4 not present")
def test_real_video_hand_held_ball():
    """Real camera: a light-green striped ball moved by hand (partly occluded by the hand)."""
    cap = cv2.VideoCapture(BALL2)
    frames = []
    while len(frames) < 220:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    assert len(frames) == 220
    model = fit_color_model(frames[100], (487, 110), (509, 110))  # picked by eye on frame 100
    trk = SphereTracker(model)
    dets = [trk.update(f) for f in frames[60:220]]
    valid = np.array([d.valid for d in dets])
    assert valid.mean() > 0.8
    uv = np.array([d.uv for d in dets])
    k = 100 - 60
    assert valid[k] and np.hypot(*(uv[k] - (487, 110))) < 12
    steps = np.hypot(*np.diff(uv, axis=0).T)
    both = valid[1:] & valid[:-1]
    assert np.median(steps[both]) < 15  # a continuous track, not jumps between blobs
    assert trk.n_window > trk.n_full
