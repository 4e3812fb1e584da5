"""A view measured on its colour, off the sphere, measured again on its luma rim at the other view's radius.

Oracles: supersampled discs whose centre is known exactly (the luma rim
itself), and the parallel stereo rig of ``test_stereo_radius_check``: the
pipeline is given a right view measured 1-2 px off the sphere with about
the right radius (as a colour circle pulled by a background of the sphere's
colour is, seed 5's set-ups 32, 75 and 111 of the sphere family), which no
radius check sees; and two colour views, one of them off.
"""
from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from test_stereo_radius_check import CAL, NEAR, _models, _pair, _proj, _radius
from tudorvision.io.frames import StereoFrame
from tudorvision.stereo import ColorModel, PipelineOptions, SegmentParams, StereoPipeline, TrackerParams
from tudorvision.stereo.detection import SphereDetection
from tudorvision.stereo.remeasure import (RELAXED_MAX_MISMATCH, luma_support, luma_view_at_radius,
                                          refine_circle_on_luma_at_radius)
from tudorvision.stereo.rim_edge import refine_circle_on_luma

SS = 8


def _disc_gray(h, w, cu, cv_, r, inside=170.0, outside=70.0, dead_arc=None, dead_arcs=()):
    """Luma of a supersampled disc; ``dead_arc`` (a0, a1) radians (or several, ``dead_arcs``): there the ground
    takes the disc's level, so that part of the rim has no contrast (a background of the sphere's brightness
    beside it, a link across it)."""
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    ys = -0.5 + (np.arange(h * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, ys)
    disc = ((X - cu) ** 2 + (Y - cv_) ** 2 <= r * r).astype(np.float32)
    ground = np.full_like(disc, outside)
    for arc in ([dead_arc] if dead_arc is not None else []) + list(dead_arcs):
        ang = np.mod(np.arctan2(Y - cv_, X - cu) - arc[0], 2 * math.pi)
        ground[ang < arc[1] - arc[0]] = inside
    hi = disc * inside + (1 - disc) * ground
    return cv2.resize(hi, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)


@pytest.mark.parametrize("seed", range(12))
def test_centre_at_the_known_radius_from_an_off_start(seed):
    """Seeded: a disc of 8-30 px with 90-150 deg of its rim without contrast, started 1.2-2.5 px off with the
    radius 1 % off: the luma circle's centre comes out within 0.1 px, where the ordinary refine from the same
    start finds none."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(8, 30)
    n = int(2 * r + 30)
    cu, cv_ = n / 2 + rng.uniform(-1, 1), n / 2 + rng.uniform(-1, 1)
    a0 = rng.uniform(0, 2 * math.pi)
    gray = _disc_gray(n, n, cu, cv_, r, dead_arc=(a0, a0 + math.radians(rng.uniform(90, 150))))
    gray += rng.normal(0, 1.5, gray.shape).astype(np.float32)
    off = rng.uniform(1.2, 2.5) * np.array([math.cos(a0 + 1.0), math.sin(a0 + 1.0)])
    start = (cu + off[0], cv_ + off[1])
    radius = r * rng.choice([0.99, 1.01])
    assert refine_circle_on_luma(gray, None, start, radius) is None
    fit = refine_circle_on_luma_at_radius(gray, None, start, radius)
    assert fit is not None
    assert math.hypot(fit[0] - cu, fit[1] - cv_) < 0.1
    assert abs(fit[2] - r) < 0.2


def test_luma_support_counts_the_rays_on_the_circle_and_their_widest_gap():
    gray = _disc_gray(60, 60, 30.2, 29.7, 14.0)
    frac, gap = luma_support(gray, None, (30.2, 29.7), 14.0)
    assert frac > 0.95 and gap < math.radians(20)
    frac_off, _ = luma_support(gray, None, (31.7, 29.7), 14.0)          # 1.5 px off: fewer rays within 0.5 px
    assert frac_off < 0.6
    half = _disc_gray(60, 60, 30.2, 29.7, 14.0, dead_arc=(-0.5 * math.pi, 0.5 * math.pi))
    frac, gap = luma_support(half, None, (30.2, 29.7), 14.0)
    assert 0.4 < frac < 0.6 and gap >= math.pi - 1e-9


def _two_arcs(rng, r):
    """A disc whose rim has contrast only on two opposite arcs of 68-80 deg each (a link and the other sphere
    across it: 38-44 % of the rays), started 1-2 px off with the radius 1 % off."""
    n = int(2 * r + 30)
    cu, cv_ = n / 2 + rng.uniform(-1, 1), n / 2 + rng.uniform(-1, 1)
    a0, live = rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(68, 80))
    dead = [(a0 + live, a0 + math.pi), (a0 + math.pi + live, a0 + 2 * math.pi)]
    gray = _disc_gray(n, n, cu, cv_, r, dead_arcs=dead) + rng.normal(0, 1.5, (n, n)).astype(np.float32)
    off = rng.uniform(1.0, 2.0) * np.array([math.cos(a0 + 0.5 * live), math.sin(a0 + 0.5 * live)])
    return gray, (cu, cv_), (cu + off[0], cv_ + off[1]), r * rng.choice([0.99, 1.01])


@pytest.mark.parametrize("seed", range(8))
def test_a_rim_of_which_a_third_has_contrast_needs_the_relaxed_fraction(seed):
    """Seeded: two opposite arcs with contrast, a third of the rim: the half-the-rays refine finds nothing, the
    relaxed one (0.3) the centre within 0.15 px."""
    rng = np.random.default_rng(100 + seed)
    gray, (cu, cv_), start, radius = _two_arcs(rng, rng.uniform(8, 25))
    assert refine_circle_on_luma_at_radius(gray, None, start, radius) is None
    fit = refine_circle_on_luma_at_radius(gray, None, start, radius, min_fraction=0.3)
    assert fit is not None and fit[3] < 0.5
    assert math.hypot(fit[0] - cu, fit[1] - cv_) < 0.15


def test_the_relaxed_fraction_refuses_a_rim_seen_on_one_side_only():
    """A single arc of 140 deg (39 % of the rays) holds enough rays for 0.3 but lies on one side: refused."""
    n, cu, cv_, r = 60, 30.3, 29.6, 14.0
    gray = _disc_gray(n, n, cu, cv_, r, dead_arc=(math.radians(140), 2 * math.pi))
    frac, gap = luma_support(gray, None, (cu, cv_), r)
    assert 0.3 < frac < 0.5 and gap > math.pi
    assert refine_circle_on_luma_at_radius(gray, None, (cu + 0.8, cv_ + 0.6), r, min_fraction=0.3) is None


def _colour_image(gray):
    img = np.repeat(np.clip(gray, 0, 255)[..., None], 3, axis=2).astype(np.uint8)
    model = ColorModel(mean=[200, 170, 170, 0, 40, 200], std=[60] * 6, background=np.ones((6, 256)), prior=0.05)
    return img, model


def test_a_view_on_a_third_of_its_rim_is_measured_again_only_under_the_relaxed_guards():
    """A colour view 1-2 px off with 38-44 % of its luma rim live: re-measured (``agree`` tight); refused when
    the pair's radii differ by more than RELAXED_MAX_MISMATCH; a view already on the centre is left alone
    (its old centre lies as well on the rim as the new one), and so is one whose colour circle is larger than
    the radius predicted for it, or whose radius comes from another colour view (``relax=False``)."""
    rng = np.random.default_rng(7)
    gray, (cu, cv_), start, radius = _two_arcs(rng, 12.0)
    img, model = _colour_image(gray)
    det = SphereDetection(uv=start, area_px=400.0, mean_prob=0.9, circularity=0.9, valid=True, method="chroma",
                          circle_radius_px=radius)
    new = luma_view_at_radius(img, model, det, radius, lambda uv, r: 0.0)
    assert new is not None and new.method == "edge"
    assert math.hypot(new.uv[0] - cu, new.uv[1] - cv_) < 0.15
    assert luma_view_at_radius(img, model, det, radius, lambda uv, r: 1.5 * RELAXED_MAX_MISMATCH) is None
    assert luma_view_at_radius(img, model, det, radius, lambda uv, r: 0.0, relax=False) is None   # no luma partner
    on_centre = replace(det, uv=(cu, cv_), circle_radius_px=12.0)
    assert luma_view_at_radius(img, model, on_centre, 12.0, lambda uv, r: 0.0) is None
    # a colour circle 5 % larger than the radius predicted for it: the prediction is the doubtful one
    larger = replace(det, circle_radius_px=1.05 * radius)
    assert luma_view_at_radius(img, model, larger, radius, lambda uv, r: 0.0) is None
    assert luma_view_at_radius(img, model, replace(det, circle_radius_px=0.9 * radius), radius,
                               lambda uv, r: 0.0) is not None


@pytest.mark.parametrize("seed", range(8))
def test_a_colour_circle_several_pixels_off_is_found_from_the_wider_starts(seed):
    """Seeded: a colour view of 12-15 px, 0.38-0.45 radii (4.6-6.8 px) off the sphere (it took some background
    of its colour), radius right: nothing from its own centre; from the starts half a radius from it the luma
    rim is found, within 0.15 px. The offset points between two of the eight starts (22.5 +- 10 deg off
    one), so that two of them reach the rim, which the search asks for. Without a luma partner
    (``relax=False``) it is not tried."""
    rng = np.random.default_rng(300 + seed)
    r = rng.uniform(12, 15)
    n = int(4 * r + 30)
    cu, cv_ = n / 2 + rng.uniform(-1, 1), n / 2 + rng.uniform(-1, 1)
    gray = _disc_gray(n, n, cu, cv_, r) + rng.normal(0, 1.5, (n, n)).astype(np.float32)
    img, model = _colour_image(gray)
    a = math.radians(45 * rng.integers(8) + 22.5 + rng.uniform(-10, 10))
    off = rng.uniform(0.38, 0.45) * r * np.array([math.cos(a), math.sin(a)])
    det = SphereDetection(uv=(cu + off[0], cv_ + off[1]), area_px=3.0 * r * r, mean_prob=0.9, circularity=0.9,
                          valid=True, method="chroma", circle_radius_px=r)
    assert luma_view_at_radius(img, model, det, r, lambda uv, rr: 0.0, relax=False) is None
    new = luma_view_at_radius(img, model, det, r, lambda uv, rr: math.hypot(uv[0] - det.uv[0], uv[1] - det.uv[1]))
    assert new is not None and new.method == "edge"
    assert math.hypot(new.uv[0] - cu, new.uv[1] - cv_) < 0.15 and abs(new.circle_radius_px - r) < 0.2


def test_a_flat_patch_gives_none():
    gray = np.full((60, 60), 100.0, np.float32)
    assert refine_circle_on_luma_at_radius(gray, None, (30.0, 30.0), 12.0) is None


def test_the_caller_decides_whether_the_new_view_agrees():
    gray = _disc_gray(80, 80, 40.3, 38.6, 15.0)
    img = np.repeat(gray[..., None], 3, axis=2).astype(np.uint8)
    img[..., 2] = np.clip(img[..., 2] * 1.2, 0, 255)
    model = ColorModel(mean=[200, 170, 170, 0, 40, 200], std=[30] * 6, background=np.ones((6, 256)), prior=0.05)
    det = SphereDetection(uv=(41.5, 37.4), area_px=700.0, mean_prob=0.9, circularity=0.9, valid=True,
                          method="chroma", circle_radius_px=15.4)
    seen = []
    assert luma_view_at_radius(img, model, det, 15.0, lambda uv, r: seen.append((uv, r))) is None
    assert len(seen) == 1 and math.hypot(seen[0][0][0] - 40.3, seen[0][0][1] - 38.6) < 0.1
    new = luma_view_at_radius(img, model, det, 15.0, lambda uv, r: 0.0)
    assert new.method == "edge" and new.valid and new.area_px == det.area_px


EDGE = PipelineOptions(tracking=False, tracker=TrackerParams(segment=SegmentParams(edge_refine=True)))


def _forced(monkeypatch, shift, scale, left_too=True):
    """The green sphere's right view handed over as measured on its colour ("chroma"), moved by ``shift`` px
    with its circle radius times ``scale``; ``left_too``: the left view marked "chroma" as well (no luma view)."""
    import tudorvision.stereo.pipeline as pipeline_module
    real = pipeline_module.detect_spheres
    calls = []

    def colour_views(img, models_, params=None):
        out = dict(real(img, models_, params=params))
        calls.append(1)
        d = out["green"]
        if len(calls) % 2 == 0:                           # the right image (left first)
            out["green"] = replace(d, uv=(d.uv[0] + shift[0], d.uv[1] + shift[1]), method="chroma",
                                   circle_radius_px=scale * d.circle_radius_px)
        elif left_too:
            out["green"] = replace(d, method="chroma")
        return out

    monkeypatch.setattr(pipeline_module, "detect_spheres", colour_views)


def test_pipeline_takes_the_luma_rim_of_a_colour_view_beside_a_luma_view(monkeypatch):
    """The right view of the green sphere handed over 1.7 px off with a circle 3 % large and method "chroma"
    (the left on its luma rim): the pipeline measures it again on its luma rim, 3D within 2 mm; the same
    view on the colour rim's pipeline (luma edge off) is left as it is, 10+ mm off."""
    models = _models(NEAR)
    _forced(monkeypatch, (1.5, -0.8), 1.03, left_too=False)
    imgs = _pair(centres=NEAR)
    frame = StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"])
    plain = StereoPipeline(CAL, models, options=PipelineOptions(tracking=False))
    res = plain.process(frame)
    assert plain.n_luma_repaired == 0 and res.detections["right"]["green"].method == "chroma"
    assert np.linalg.norm(res.spheres["green"] - NEAR["green"]) > 0.01
    pipe = StereoPipeline(CAL, models, options=EDGE)
    res = pipe.process(frame)
    assert res.detections["left"]["green"].method == "edge"
    d = res.detections["right"]["green"]
    assert pipe.n_luma_repaired == 1 and d.method == "edge" and d.valid
    u, v = _proj(NEAR["green"], "right")
    assert math.hypot(d.uv[0] - u, d.uv[1] - v) < 0.15
    assert abs(d.circle_radius_px - _radius(NEAR["green"])) < 0.3
    assert np.linalg.norm(res.spheres["green"] - NEAR["green"]) < 0.002
    assert np.linalg.norm(res.spheres["red"] - NEAR["red"]) < 0.01


def test_pipeline_leaves_pairs_alone_unless_exactly_one_view_is_on_its_luma_rim():
    """Clean pair: the green sphere is on its luma rim in both views, the red one (its luma equals the grey
    ground's) on its colour rim in both: nothing is measured again."""
    models = _models(NEAR)
    imgs = _pair(centres=NEAR)
    pipe = StereoPipeline(CAL, models, options=EDGE)
    res = pipe.process(StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"]))
    assert res.valid and pipe.n_luma_repaired == 0
    assert [res.detections[c]["green"].method for c in ("left", "right")] == ["edge", "edge"]
    assert [res.detections[c]["red"].method for c in ("left", "right")] == ["shape", "shape"]


def test_two_colour_views_that_agree_in_radius_are_both_measured_on_their_luma_rims(monkeypatch):
    """Neither view on its luma rim, radii consistent, the right one 1.5 px off: both are measured again on
    their luma rims at the radius the other predicts; the right one comes back within 0.15 px."""
    _forced(monkeypatch, (1.2, 0.9), 1.02)
    imgs = _pair(centres=NEAR)
    pipe = StereoPipeline(CAL, _models(NEAR), options=EDGE)
    res = pipe.process(StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"]))
    assert pipe.n_luma_repaired == 2
    d = res.detections["right"]["green"]
    u, v = _proj(NEAR["green"], "right")
    assert d.method == "edge" and math.hypot(d.uv[0] - u, d.uv[1] - v) < 0.15
    assert np.linalg.norm(res.spheres["green"] - NEAR["green"]) < 0.002


def test_two_colour_views_that_disagree_in_radius_are_left_to_the_radius_check(monkeypatch):
    """The right view's circle 30 % too large: no luma re-measurement (two colour views off together give no
    radius to trust); the radius check measures it again on its chroma edge."""
    _forced(monkeypatch, (1.2, 0.9), 1.3)
    imgs = _pair(centres=NEAR)
    pipe = StereoPipeline(CAL, _models(NEAR), options=EDGE)
    res = pipe.process(StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"]))
    assert pipe.n_luma_repaired == 0
    assert pipe.n_radius_repaired + pipe.n_radius_refused == 1
    assert res.detections["right"]["green"].method == "chroma"


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), u=st.floats(-5, 45), v=st.floats(-5, 45), radius=st.floats(0.5, 40),
       level=st.sampled_from(["noise", "flat", "disc"]))
def test_any_window_and_start_give_a_finite_circle_or_none(seed, u, v, radius, level):
    """Fuzzed: noise, flat and disc windows of 40 x 40 px, starts inside and outside them, radii from half a
    pixel to the window's size: no exception; a circle, when there is one, is finite."""
    rng = np.random.default_rng(seed)
    if level == "noise":
        gray = rng.uniform(0, 255, (40, 40)).astype(np.float32)
    elif level == "flat":
        gray = np.full((40, 40), float(rng.uniform(0, 255)), np.float32)
    else:
        gray = _disc_gray(40, 40, rng.uniform(10, 30), rng.uniform(10, 30), rng.uniform(3, 15))
    log_odds = rng.normal(0, 3, gray.shape).astype(np.float32) if seed % 2 else None
    fit = refine_circle_on_luma_at_radius(gray, log_odds, (u, v), radius)
    assert fit is None or all(math.isfinite(x) for x in fit)
