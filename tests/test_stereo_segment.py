"""Sphere segmentation on synthetic frames with known sub-pixel centres."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
import scipy.stats

from test_stereo_segment_scenes import GREEN_BGR, RED_BGR, make_frame, sphere_patch, two_spheres
from tudorvision._checks import TudorVisionError
from tudorvision.stereo.colormodel import fit_color_model
from tudorvision.stereo.segment import (
    SegmentParams, SphereDetection, detect_sphere, detect_spheres, hsv_from_bgr, log_odds_image,
    probability_image)

RED_UV, GREEN_UV = (200.3, 150.7), (420.2, 300.4)


@pytest.fixture(scope="module")
def models():
    frame = make_frame(np.random.default_rng(11), two_spheres(RED_UV, GREEN_UV, radius=10.0))
    return {"red": fit_color_model(frame, (200, 151), (210, 151)),
            "green": fit_color_model(frame, (420, 300), (430, 300))}


def random_scene(rng, **extra):
    while True:
        red = np.array([rng.uniform(30, 610), rng.uniform(30, 450)])
        green = np.array([rng.uniform(30, 610), rng.uniform(30, 450)])
        if np.hypot(*(red - green)) > 60:
            break
    radius = rng.uniform(5.0, 14.0)
    return make_frame(rng, two_spheres(red, green, radius=radius, **extra)), {"red": red, "green": green}


@pytest.mark.parametrize("coarse_step", [2, 1])
def test_centroid_accuracy_and_distractors(models, coarse_step):
    """Cluttered frames with red/green distractors: <= 0.25 px RMS, no distractor chosen."""
    rng = np.random.default_rng(2024)
    params = SegmentParams(coarse_step=coarse_step)
    errors = []
    for _ in range(12):
        frame, truth = random_scene(rng)
        dets = detect_spheres(frame, models, params=params)
        for name, uv in truth.items():
            d = dets[name]
            assert d.valid, (name, d.reason)
            errors.append(np.subtract(d.uv, uv))
            assert d.circularity > 0.85 and 0.85 < d.fill < 1.15 and d.mean_prob > 0.8
    errors = np.array(errors)
    rms = np.sqrt(np.mean(np.sum(errors ** 2, axis=1)))
    assert rms <= 0.25, rms
    assert np.abs(errors).max() < 0.6  # no distractor, no neighbouring blob


def test_coarse_and_full_resolution_agree(models):
    rng = np.random.default_rng(7)
    for _ in range(4):
        frame, _ = random_scene(rng)
        a = detect_spheres(frame, models, params=SegmentParams(coarse_step=1))
        b = detect_spheres(frame, models, params=SegmentParams(coarse_step=3))
        for name in a:
            np.testing.assert_allclose(a[name].uv, b[name].uv, atol=1e-9)
            assert a[name].area_px == b[name].area_px


def test_distractors_alone_are_rejected(models):
    """A frame with only the distractors (other shades of red and green) yields no valid sphere."""
    rng = np.random.default_rng(99)
    for _ in range(3):
        frame = make_frame(rng, {})
        for name, d in detect_spheres(frame, models).items():
            assert not d.valid, (name, d)
            assert np.isnan(d.uv[0]) or d.reason


def test_naive_bayes_against_scipy(models):
    """LUT log-odds equal a direct naive Bayes evaluation with scipy.stats.norm."""
    rng = np.random.default_rng(4)
    frame, truth = random_scene(rng)
    hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
    levels = [256, 256, 256, 180, 256, 256]
    pix = [tuple(np.rint(truth["red"]).astype(int)[::-1]), tuple(np.rint(truth["green"]).astype(int)[::-1])]
    pix += [tuple(rng.integers([0, 0], [480, 640])) for _ in range(30)]
    for name, m in models.items():
        post = probability_image(frame, m)
        lo_img = log_odds_image(frame, m)
        for v, u in pix:
            b, g, r = frame[v, u].astype(int)
            h, s, val = hsv[v, u].astype(int)
            lo = np.log(m.prior / (1 - m.prior))
            for c, x in enumerate((r, g, b, h, s, val)):
                grid = np.arange(levels[c])
                if c == 3:  # hue: Gaussian of the circular difference
                    d = (grid - m.mean[3] + 90) % 180 - 90
                    dx = (x - m.mean[3] + 90) % 180 - 90
                else:
                    d, dx = grid - m.mean[c], x - m.mean[c]
                dist = scipy.stats.norm(0.0, m.std[c])
                log_fg = dist.logpdf(dx) - np.log(dist.pdf(d).sum())  # normalised over the levels
                llr = log_fg - np.log(m.background[c, x])
                lo += np.clip(llr, -m.llr_clip, m.llr_clip)
            assert lo_img[v, u] == pytest.approx(lo, abs=2e-4 * max(1.0, abs(lo)))
            assert post[v, u] == pytest.approx(1 / (1 + np.exp(-lo)), abs=1e-5)
        # the sphere centre is confidently the sphere, the other sphere is not
    assert probability_image(frame, models["red"])[pix[0]] > 0.99
    assert probability_image(frame, models["red"])[pix[1]] < 0.01


def test_hue_wrap_detection():
    """A red whose hue sits at 179/0 (noise wraps it) is modelled and found on every frame."""
    rng = np.random.default_rng(8)
    bgr = (30.0, 25.0, 215.0)  # hue -1.6 deg = level 179.2: noise spreads it over 178..1
    img = make_frame(rng, {"red": dict(uv=(100.4, 80.6), radius=10.0, color=bgr)})
    hue = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[76:86, 96:106, 0]
    assert (hue >= 170).sum() > 10 and (hue <= 5).sum() > 10  # the pick straddles the wrap
    m = fit_color_model(img, (100, 81), (110, 81))
    assert min(m.mean[3], 180 - m.mean[3]) < 2 and m.std[3] < 3  # a linear mean would be near 90
    for _ in range(4):
        uv = rng.uniform(40, 440, size=2)
        f = make_frame(rng, {"red": dict(uv=tuple(uv), radius=10.0, color=bgr)})
        d = detect_sphere(f, m)
        assert d.valid and np.hypot(*(np.subtract(d.uv, uv))) < 0.3
        assert d.area_px > 0.7 * np.pi * 10 ** 2  # both sides of the wrap belong to the region


def _plain(shape=(200, 260)):
    return np.full(shape + (3,), 85, np.uint8)


def test_rejections_name_the_reason(models):
    m = models["red"]
    col = tuple(int(c) for c in RED_BGR)
    img = _plain()
    cv2.circle(img, (50, 50), 1, col, -1)
    assert "area" in detect_sphere(img, m, params=SegmentParams(erode_radius_px=0)).reason
    img = _plain()
    cv2.rectangle(img, (40, 90), (80, 98), col, -1)  # a bar 41 x 9 px
    d = detect_sphere(img, m)
    assert not d.valid and "circularity" in d.reason and "motion blur not expected" in d.reason
    d = detect_sphere(img, m, motion_blur=True)  # elongation allowed when blur is expected
    assert d.valid and d.uv == pytest.approx((60.0, 94.0), abs=1e-6)
    img = _plain()
    cv2.ellipse(img, (120, 100), (14, 14), 0, 40, 320, col, 5)  # an open ring: round, not compact
    d = detect_sphere(img, m)
    assert not d.valid and "fill" in d.reason
    img = _plain()
    cv2.circle(img, (120, 100), 14, col, 5)  # a closed ring: the hole is filled, so it is a disc
    d = detect_sphere(img, m)
    assert d.valid and d.area_px == pytest.approx(np.pi * 17.0 ** 2, rel=0.1)
    assert d.uv == pytest.approx((120.0, 100.0), abs=0.05)
    img = _plain()
    cv2.circle(img, (4, 100), 10, col, -1)  # cut by the image border
    d = detect_sphere(img, m)
    assert not d.valid and "image border" in d.reason
    img = _plain()
    cv2.circle(img, (120, 100), 10, col, -1)
    d = detect_sphere(img, m, params=SegmentParams(min_mean_prob=1.0))
    assert not d.valid and "mean probability" in d.reason
    d = detect_sphere(img, m, params=SegmentParams(max_area_px=50))
    assert not d.valid and "max_area_px" in d.reason
    d = detect_sphere(_plain(), m)
    assert not d.valid and np.isnan(d.uv).all() and "p_seed" in d.reason


def test_motion_blur_streak_centroid_is_mean_position(models):
    """A streak 1.5 sphere diameters long: its first moment is the mid-exposure position.

    Searched in a window around the sphere, as the tracker does when it expects
    blur: the blur-tolerant colour tables also accept darker objects of the
    sphere's hue (a blurred red sphere *is* a darker red), so full frames with
    same-hue clutter are not searched with them.
    """
    rng = np.random.default_rng(12)
    errs = []
    while len(errs) < 8:
        red = rng.uniform([60, 60], [580, 420])
        green = rng.uniform([60, 60], [580, 420])
        if np.hypot(*(red - green)) < 80:
            continue
        ang = rng.uniform(0, 2 * np.pi)
        blur = (27.0 * np.cos(ang), 27.0 * np.sin(ang))
        frame = make_frame(rng, two_spheres(red, green, radius=9.0, blur=blur, n_time=32))
        for name, uv in (("red", red), ("green", green)):
            u, v = np.rint(uv).astype(int)
            roi = (u - 35, v - 35, 71, 71)
            strict = detect_sphere(frame, models[name], roi=roi)
            d = detect_sphere(frame, models[name], roi=roi, motion_blur=True)
            assert d.valid, d.reason
            assert d.area_px > strict.area_px  # the tolerant tables keep more of the streak
            errs.append(np.subtract(d.uv, uv))
    errs = np.array(errs)
    assert np.sqrt(np.mean(np.sum(errs ** 2, axis=1))) < 0.4


def test_motion_blur_full_frame_without_clutter(models):
    rng = np.random.default_rng(21)
    red, green = np.array([150.3, 200.8]), np.array([400.6, 260.1])
    frame = make_frame(rng, two_spheres(red, green, radius=9.0, blur=(20.0, -15.0), n_time=32), clutter=False)
    dets = detect_spheres(frame, models, params=SegmentParams(motion_blur=True))
    assert dets["red"].uv == pytest.approx(red, abs=0.3)
    assert dets["green"].uv == pytest.approx(green, abs=0.3)
    assert dets["red"].circularity < 0.8  # elongated, yet accepted


def test_binary_weighting_also_subpixel(models):
    rng = np.random.default_rng(31)
    errs = []
    for _ in range(5):
        frame, truth = random_scene(rng)
        dets = detect_spheres(frame, models, params=SegmentParams(weighting="binary"))
        errs += [np.subtract(dets[n].uv, truth[n]) for n in truth]
    assert np.sqrt(np.mean(np.sum(np.array(errs) ** 2, axis=1))) < 0.3


def test_roi_and_hsv_sharing(models):
    rng = np.random.default_rng(13)
    frame, truth = random_scene(rng)
    hsv = hsv_from_bgr(frame)
    full = detect_sphere(frame, models["green"], params=SegmentParams(coarse_step=1))
    u, v = np.rint(truth["green"]).astype(int)
    win = detect_sphere(frame, models["green"], hsv=hsv, roi=(u - 30, v - 30, 61, 61))
    assert win.uv == pytest.approx(full.uv, abs=1e-9)
    assert not win.touches_window
    tight = detect_sphere(frame, models["green"], roi=(u - 3, v - 3, 7, 7))
    assert tight.touches_window


def test_bad_input(models):
    m = models["red"]
    img = _plain()
    with pytest.raises(TudorVisionError, match="frame_bgr: expected a uint8 BGR image"):
        detect_sphere(img[..., 0], m)
    with pytest.raises(TudorVisionError, match="hsv: expected a uint8 HSV image of shape"):
        detect_sphere(img, m, hsv=np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(TudorVisionError, match="roi: window .* does not overlap"):
        detect_sphere(img, m, roi=(500, 10, 20, 20))
    with pytest.raises(TudorVisionError, match="roi: expected"):
        detect_sphere(img, m, roi=(1, 2, 3))
    with pytest.raises(TudorVisionError, match="p_grow, p_seed"):
        SegmentParams(p_seed=0.4, p_grow=0.5)
    with pytest.raises(TudorVisionError, match="weighting"):
        SegmentParams(weighting="area")
    with pytest.raises(TudorVisionError, match="coarse_step"):
        SegmentParams(coarse_step=0)
    with pytest.raises(TudorVisionError, match="erode_radius_px"):
        SegmentParams(erode_radius_px=-1)
    with pytest.raises(TudorVisionError, match="min_area_px, max_area_px"):
        SegmentParams(min_area_px=10, max_area_px=5)


def test_detection_dataclass():
    d = SphereDetection(uv=(1.0, 2.0), area_px=np.pi * 4, mean_prob=0.9, circularity=1.0, valid=True, reason="")
    assert d.radius_px == pytest.approx(2.0)
    with pytest.raises(AttributeError):
        d.valid = False
    assert GREEN_BGR[1] > GREEN_BGR[2]
    assert callable(sphere_patch)
