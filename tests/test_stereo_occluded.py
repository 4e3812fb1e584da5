"""Large spheres partly hidden by a foreground object: the centre comes from the visible rim only (issue 15).

Analytic oracle: a supersampled, shaded sphere of radius 33 px (the size of
the sphere family's set-up 141) whose true image position is its disc
centre, partly covered by a light link (a bar of another colour) or by
another sphere in front of it. Along the occluder the region's boundary is a
chord (or a concave arc) inside the sphere's rim; those points must not pull
the circle. Each scene is checked to be one where they would: the region's
moment and a plain least-squares circle through all its boundary points are
more than a pixel off, the detection is not.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from test_stereo_segment_scenes import GREEN_BGR, RED_BGR, SS, sphere_patch
from tudorvision.stereo._circle import circle_lsq
from tudorvision.stereo.colormodel import fit_color_model
from tudorvision.stereo.segment import SegmentParams, detect_sphere, probability_image

CENTER = (80.37, 78.71)
RADIUS = 33.0
LINK_BGR = (215.0, 215.0, 222.0)
# the default detection (the chroma edge on a sphere this large) and the colour-rim circle alone
PATHS = pytest.mark.parametrize("params", [SegmentParams(), SegmentParams(chroma_edge_below=0.0)],
                                ids=["default", "colour-rim"])


def _background(h=160, w=170):
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    base = 90 + 35 * u / w + 25 * v / h
    return np.repeat(base[..., None], 3, axis=2) * np.float32([1.0, 0.97, 0.92])


def _finish(img, seed):
    img = img + np.random.default_rng(seed).normal(0, 2.0, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _coverage(h, w, inside):
    """Pixel coverage (h x w float32) of the region ``inside(X, Y)`` on an SS x SS grid per pixel."""
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    ys = -0.5 + (np.arange(h * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, ys)
    return cv2.resize(inside(X, Y).astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)


def _sphere():
    img = _background()
    sphere_patch(CENTER, RADIUS, RED_BGR, img)
    return img


def _with_link(offset, width, angle_deg, seed=1):
    """The sphere behind a light bar whose axis passes ``offset`` px from the centre."""
    img = _sphere()
    a = np.deg2rad(angle_deg)
    nx, ny = -np.sin(a), np.cos(a)

    def bar(X, Y):
        return np.abs((X - CENTER[0]) * nx + (Y - CENTER[1]) * ny - offset) <= width / 2

    cover = _coverage(*img.shape[:2], bar)[..., None]
    img[:] = cover * np.float32(LINK_BGR) + (1 - cover) * img
    return _finish(img, seed)


def _behind_sphere(du, dv, radius=28.0, seed=2):
    """The sphere with a green sphere of ``radius`` px in front of it, its centre at ``(du, dv)`` from ours."""
    img = _sphere()
    sphere_patch((CENTER[0] + du, CENTER[1] + dv), radius, GREEN_BGR, img)
    return _finish(img, seed)


@pytest.fixture(scope="module")
def model():
    return fit_color_model(_finish(_sphere(), 0), (80, 79), (105, 79))


def _err(uv):
    return float(np.hypot(uv[0] - CENTER[0], uv[1] - CENTER[1]))


def _plain_circle_error(img, model):
    """Centre error of a least-squares circle through every outer boundary point of the p >= 0.5 region."""
    mask = (probability_image(img, model) >= 0.5).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, 8)
    big = (labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))).astype(np.uint8)
    cs, _ = cv2.findContours(big, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cu, cv_, _ = circle_lsq(max(cs, key=len).reshape(-1, 2).astype(np.float64))
    return _err((cu, cv_))


@PATHS
def test_clear_sphere(model, params):
    det = detect_sphere(_finish(_sphere(), 3), model, params=params)
    # by default a sphere this large is measured on its chroma edge whatever its colour rim
    assert det.valid and det.method == ("chroma" if params.chroma_edge_below > 0 else "shape")
    assert _err(det.uv) < 0.15, det.uv
    assert det.rim_fraction > 0.9
    assert abs(det.circle_radius_px - RADIUS) < 1.0


def _occluded_centre_ok(img, model, params):
    """The scene bites (the visible part's moment and a circle through all its boundary points are off by
    more than 1 px) and the detection does not (centre within 0.3 px, radius within 1 px); returns it."""
    moment = detect_sphere(img, model, params=SegmentParams(centroid="moment"))
    det = detect_sphere(img, model, params=params)
    assert moment.valid and det.valid
    assert _err(moment.uv) > 1.0, moment.uv
    assert _plain_circle_error(img, model) > 1.0
    assert _err(det.uv) < 0.3, (det.uv, det.method, det.rim_fraction)
    assert abs(det.circle_radius_px - RADIUS) < 1.0
    return det


# (axis offset px, bar width px, angle deg): from a thin link over the edge to a third of the sphere hidden
LINKS = [(20.0, 8.0, 10.0), (12.0, 10.0, -35.0), (5.0, 10.0, 60.0), (-15.0, 16.0, 100.0), (22.0, 24.0, 150.0)]


@PATHS
@pytest.mark.parametrize("offset, width, angle", LINKS, ids=[f"link{a:g}" for _, _, a in LINKS])
def test_link_in_front(model, params, offset, width, angle):
    det = _occluded_centre_ok(_with_link(offset, width, angle), model, params)
    assert det.rim_fraction < 0.95          # the boundary along the link is left out


# (du, dv) of the front sphere's centre: a quarter to a third of ours hidden behind a concave arc
FRONT = [(50.0, 10.0), (-20.0, 45.0), (35.0, -35.0)]


@PATHS
@pytest.mark.parametrize("du, dv", FRONT, ids=[f"front{i}" for i in range(len(FRONT))])
def test_other_sphere_in_front(model, params, du, dv):
    _occluded_centre_ok(_behind_sphere(du, dv), model, params)


def test_more_than_half_hidden_is_refused_not_misplaced(model):
    """Beyond half hidden the region is not round enough: no detection rather than a wrong one."""
    det = detect_sphere(_with_link(-12.0, 40.0, 30.0), model)
    assert not det.valid
    assert "circularity" in det.reason
