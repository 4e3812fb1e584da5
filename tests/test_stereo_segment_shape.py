"""Shape-model centroid (``SegmentParams(centroid="shape")``): partial occlusion, missed bright caps.

Synthetic supersampled spheres (see ``test_stereo_segment_scenes.py``) whose
true image position is the disc centre, partly hidden by a dark bar or with
a saturated, near-white cap the colour model rejects. The region's first
moment measures the visible part; the circle fitted to the rim recovers the
whole silhouette's centre.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from test_stereo_segment_scenes import RED_BGR, SS, sphere_patch
from tudorvision._checks import TudorVisionError
from tudorvision.stereo._circle import circle_lsq, fit_rim_circle, fit_rim_circle_multi
from tudorvision.stereo.colormodel import fit_color_model
from tudorvision.stereo.segment import SegmentParams, detect_sphere

CENTER = (60.37, 58.71)
RADIUS = 9.0
MOMENT = SegmentParams(centroid="moment")
# the colour-rim circle alone (no chroma edge), and with the luma-edge refinement
RIM = pytest.mark.parametrize("params, method", [(SegmentParams(edge_refine=False, chroma_edge_below=0.0), "shape"),
                                                 (SegmentParams(edge_refine=True), "edge")],
                         ids=["colour-rim", "luma-edge"])


def _background(seed=0, h=120, w=120):
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    base = 95 + 30 * u / w + 20 * v / h
    return np.repeat(base[..., None], 3, axis=2) * np.float32([1.0, 0.97, 0.93])


def _finish(img, seed=0):
    img = img + np.random.default_rng(seed).normal(0, 2.0, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _supersampled_mask(h, w, inside):
    """Pixel coverage (h x w float32) of the region ``inside(X, Y)`` on an SS x SS grid per pixel."""
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    ys = -0.5 + (np.arange(h * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, ys)
    return cv2.resize(inside(X, Y).astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)


@pytest.fixture(scope="module")
def model():
    img = _background()
    sphere_patch(CENTER, RADIUS, RED_BGR, img)
    return fit_color_model(_finish(img), (60, 59), (67, 59))


def _with_bar(offset=5.0, width=3.0, angle_deg=12.0):
    """The sphere with a dark bar (a chord ``offset`` px below the centre) in front of it."""
    img = _background()
    sphere_patch(CENTER, RADIUS, RED_BGR, img)
    a = np.deg2rad(angle_deg)
    nx, ny = -np.sin(a), np.cos(a)  # bar normal (pointing down)

    def bar(X, Y):
        d = (X - CENTER[0]) * nx + (Y - CENTER[1]) * ny - offset
        return np.abs(d) <= width / 2

    cover = _supersampled_mask(*img.shape[:2], bar)[..., None]
    img[:] = cover * np.float32((55, 55, 60)) + (1 - cover) * img
    return _finish(img, 1)


def _with_white_cap(cap_radius=4.5, dist=7.5):
    """The sphere with a near-white, saturated cap at its top rim (a disc intersecting the sphere)."""
    img = _background()
    sphere_patch(CENTER, RADIUS, RED_BGR, img)
    cu, cv_ = CENTER

    def cap(X, Y):
        return (((X - cu) ** 2 + (Y - cv_ + dist) ** 2 <= cap_radius ** 2)
                & ((X - cu) ** 2 + (Y - cv_) ** 2 <= RADIUS ** 2))

    cover = _supersampled_mask(*img.shape[:2], cap)[..., None]
    img[:] = cover * np.float32((245, 245, 255)) + (1 - cover) * img
    return _finish(img, 2)


def _err(uv):
    return float(np.hypot(uv[0] - CENTER[0], uv[1] - CENTER[1]))


@RIM
def test_unoccluded_sphere_shape_and_moment_agree(model, params, method):
    img = _background()
    sphere_patch(CENTER, RADIUS, RED_BGR, img)
    img = _finish(img, 3)
    det = detect_sphere(img, model, params=params)
    assert det.valid and det.method == method
    assert _err(det.uv) < 0.15 and _err(det.uv_moment) < 0.2
    assert det.rim_fraction > 0.9 and det.rim_rms_px < 0.5


@RIM
@pytest.mark.parametrize("angle", [0.0, 12.0, -25.0])
def test_bar_occlusion_recovers_the_full_silhouette_centre(model, angle, params, method):
    img = _with_bar(angle_deg=angle)
    plain = detect_sphere(img, model, params=MOMENT)
    det = detect_sphere(img, model, params=params)
    assert plain.valid and det.valid
    assert plain.method == "moment" and det.method == method
    assert _err(plain.uv) > 0.5, plain.uv          # the moment measures the visible part only
    assert _err(det.uv) < 0.2, (det.uv, det.rim_fraction)
    assert det.uv_moment == pytest.approx(plain.uv)
    assert 0.5 <= det.rim_fraction < 0.95           # the rim along the bar is not used


@RIM
def test_saturated_bright_cap_is_completed(model, params, method):
    img = _with_white_cap()
    plain = detect_sphere(img, model, params=MOMENT)
    det = detect_sphere(img, model, params=params)
    assert plain.valid and det.valid and det.method == method
    assert plain.uv[1] - CENTER[1] > 0.3               # the moment sinks below the missing top
    assert _err(det.uv) < 0.2, det.uv


@pytest.mark.parametrize("scene", ["bar0", "bar12", "bar-25", "cap"])
def test_chroma_edge_takes_over_a_partial_colour_rim(model, scene):
    """The colour rim explains < 90 % of its points, so the chroma edge along rays is used when asked at 0.9."""
    img = _with_white_cap() if scene == "cap" else _with_bar(angle_deg=float(scene[3:]))
    det = detect_sphere(img, model, params=SegmentParams(chroma_edge_below=0.9))
    off = detect_sphere(img, model, params=SegmentParams(chroma_edge_below=0.0))
    assert det.valid and det.method == "chroma" and off.method == "shape"
    assert det.rim_fraction < 0.9
    if scene != "cap":                              # rim fractions 0.68-0.71: the default (0.8) takes it too
        assert detect_sphere(img, model).method == "chroma"
    assert _err(det.uv) < 0.1, det.uv              # measured 0.00-0.05 px (colour rim alone: 0.11-0.15)


def test_blur_streak_keeps_the_moment(model):
    img = _background()
    sphere_patch(CENTER, RADIUS, RED_BGR, img, blur_uv=(14.0, 3.0), n_time=24)
    det = detect_sphere(_finish(img, 4), model, motion_blur=True)
    assert det.valid and det.method == "moment"
    assert _err(det.uv) < 0.3


def test_circle_fits():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    pts = np.c_[10 + 6 * np.cos(t), 20 + 6 * np.sin(t)]
    assert circle_lsq(pts) == pytest.approx((10, 20, 6))
    # a third of the rim pulled 2 px inwards (an occluder): the robust fit ignores it
    bad = pts.copy()
    bad[:13] = np.c_[10 + 4 * np.cos(t[:13]), 20 + 4 * np.sin(t[:13])]
    cu, cv_, r, inl = fit_rim_circle(bad, 0.5)
    assert (cu, cv_, r) == pytest.approx((10, 20, 6), abs=1e-9)
    assert not inl[:13].any() and inl[13:].all()
    assert np.hypot(*(np.subtract(circle_lsq(bad)[:2], (10, 20)))) > 0.5  # plain least squares is pulled
    # the many-hypothesis fit of the chroma edge: the same with noise and a third of the rim 2.5 px inside
    rng = np.random.default_rng(0)
    noisy = pts + rng.normal(0, 0.05, pts.shape)
    noisy[:13] = np.c_[10 + 3.5 * np.cos(t[:13]), 20 + 3.5 * np.sin(t[:13])]
    cu, cv_, r, inl = fit_rim_circle_multi(noisy, 0.3)
    assert np.hypot(cu - 10, cv_ - 20) < 0.1 and abs(r - 6) < 0.1
    assert not inl[:13].any() and inl[13:].all()
    assert fit_rim_circle_multi(noisy[:4], 0.3) is None        # too few points for five inliers


def test_params_checked():
    with pytest.raises(TudorVisionError, match="centroid"):
        SegmentParams(centroid="ellipse")
    with pytest.raises(TudorVisionError, match="rim_prob"):
        SegmentParams(rim_prob=0.999)
    with pytest.raises(TudorVisionError, match="rim_tol_px"):
        SegmentParams(rim_tol_px=0.0)
    with pytest.raises(TudorVisionError, match="chroma_edge_below"):
        SegmentParams(chroma_edge_below=1.5)
    with pytest.raises(TudorVisionError, match="edge_min_contrast"):
        SegmentParams(edge_min_contrast=-1.0)


def _shaded_large_sphere(r=30.0, centre=(80.4, 79.3), seed=3):
    """A 30 px green sphere lit from the upper left: beyond 0.85 r its lower-right half darkens to 30 %
    (colour kept, only the level falls), so the colour region stops 1-4 px short of the silhouette there."""
    h = w = 160
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.repeat((100 + 20 * u / w)[..., None], 3, axis=2) * np.float32([1.0, 0.9, 1.1])   # greyish purple
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, xs)
    dx, dy = X - centre[0], Y - centre[1]
    rho = np.hypot(dx, dy) / r
    lit = np.clip((dx + dy) / (np.sqrt(2.0) * r), 0.0, 1.0)          # 0 on the lit half, 1 at the far limb
    level = 1.0 - 0.7 * lit * np.clip((rho - 0.85) / 0.15, 0.0, 1.0)
    inside = rho <= 1.0
    cov = cv2.resize(inside.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    lev = cv2.resize((level * inside).astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    lev = np.where(cov > 0, lev / np.maximum(cov, 1e-6), 1.0)
    green = np.float32([60, 200, 70])
    img = img * (1.0 - cov[..., None]) + cov[..., None] * green * lev[..., None]
    return _finish(img, seed)


def test_a_large_sphere_whose_colour_region_stops_short_of_a_shaded_limb_is_measured_on_its_chroma_edge():
    """The colour rim is round (the circle explains it all) but inside the silhouette and off its centre;
    large spheres search the chroma edge whatever the rim fraction (``chroma_edge_below_large=1``)."""
    centre, r = (80.4, 79.3), 30.0
    img = _shaded_large_sphere(r, centre)
    model = fit_color_model(img, (80, 79), (80 + 24, 79))
    old = detect_sphere(img, model, params=SegmentParams(chroma_edge_below_large=0.9, chroma_edge_large_px=25.0))
    new = detect_sphere(img, model)
    assert old.method == "shape" and old.rim_fraction >= 0.9
    assert np.hypot(old.uv[0] - centre[0], old.uv[1] - centre[1]) > 0.5 and old.circle_radius_px < r - 0.8
    err_old = np.hypot(old.uv[0] - centre[0], old.uv[1] - centre[1])
    assert new.method == "chroma" and abs(new.circle_radius_px - r) < 0.6
    # Lab chroma falls with the level too, so the chroma edge of the dark limb still lies a little inside
    assert np.hypot(new.uv[0] - centre[0], new.uv[1] - centre[1]) < 0.5 * err_old
    # ... which the luma edge, started from the chroma circle, takes back
    edge = detect_sphere(img, model, params=SegmentParams(edge_refine=True))
    assert edge.method == "edge" and np.hypot(edge.uv[0] - centre[0], edge.uv[1] - centre[1]) < 0.15


def _limb_in_the_dark(r=30.0, centre=(80.4, 79.3), seed=3):
    """A 30 px red sphere (CIE L 70) whose lower-right limb falls to L 30 between 0.72 and 0.8 radii, on a
    ground of the same chroma at L 14 (a shaded limb on a background of the sphere's own hue): the colour
    region stops 4-5 px short there, no chroma edge exists, only the luma step at the silhouette."""
    h = w = 160
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, xs)
    dx, dy = X - centre[0], Y - centre[1]
    rho = np.hypot(dx, dy) / r
    lit = np.clip((dx + dy) / (np.sqrt(2.0) * r), 0.0, 1.0) ** 0.5
    L = 70.0 - 40.0 * lit * np.clip((rho - 0.72) / 0.08, 0.0, 1.0)
    L = np.where(rho <= 1.0, L, 14.0).astype(np.float32)
    lab = np.dstack([L, np.full_like(L, 45.0), np.full_like(L, 30.0)]).astype(np.float32)
    bgr = cv2.cvtColor(lab, cv2.COLOR_Lab2BGR) * 255.0
    return _finish(cv2.resize(bgr, (w, h), interpolation=cv2.INTER_AREA), seed)


def test_a_large_sphere_far_inside_its_silhouette_is_found_on_a_wider_luma_search(monkeypatch):
    """The colour region's circle is 4.5 px off and 4.4 px small; the chroma edge finds nothing (one hue
    everywhere) and the luma edge, searched 3 px either side, cannot reach the rim. Large spheres still on
    their colour region are searched 0.35 radii either side (``refine_circle_on_luma_wide``): 0.1 px."""
    import tudorvision.stereo.segment as segment_module
    centre, r = (80.4, 79.3), 30.0
    img = _limb_in_the_dark(r, centre)
    model = fit_color_model(img, (80, 79), (80 - 17, 79 - 17))
    wide = detect_sphere(img, model, params=SegmentParams(edge_refine=True))
    assert wide.method == "edge" and np.hypot(wide.uv[0] - centre[0], wide.uv[1] - centre[1]) < 0.1
    assert abs(wide.circle_radius_px - r) < 0.2
    monkeypatch.setattr(segment_module, "refine_circle_on_luma_wide", lambda *a, **k: None)
    narrow = detect_sphere(img, model, params=SegmentParams(edge_refine=True))
    assert narrow.method == "shape" and np.hypot(narrow.uv[0] - centre[0], narrow.uv[1] - centre[1]) > 3.0


def test_wide_luma_search_finds_nothing_where_there_is_no_rim():
    """No sphere under the first circle (a smooth ramp, a uniform patch): None, not a circle of noise."""
    from tudorvision.stereo.rim_edge import refine_circle_on_luma_wide
    v, u = np.mgrid[0:80, 0:80].astype(np.float32)
    assert refine_circle_on_luma_wide(100.0 + 0.5 * u, None, (40.0, 40.0), 20.0) is None
    noise = np.random.default_rng(0).normal(120.0, 3.0, (80, 80)).astype(np.float32)
    assert refine_circle_on_luma_wide(noise, None, (40.0, 40.0), 20.0) is None

