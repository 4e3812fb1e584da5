"""The chroma-edge rim (:mod:`tudorvision.stereo.rim_edge`, issue 15): a tinted band outside the ball, a poor start.

Oracles: supersampled (8 x 8) discs with exactly known centres; the failure
modes found on the labelled real ball frames (docs/benchmarks.md, "Issue 15:
chroma rim, real-ball p90"): a weakly ball-tinted band next to the rim (a hand
under a blurred ball) whose outer edge was taken for the rim, and a first
circle (the colour model's region) so far off that the rays from it never
reach the far rim.
"""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from tudorvision.stereo.rim_edge import chroma_circle, chroma_rim_points, refine_circle_on_chroma, sphere_chroma

SS = 8
BALL = np.array([60.0, 150.0, 70.0])        # R, G, B
GROUND = np.array([190.0, 190.0, 190.0])


def _coverage(h, w, cu, cv_, r):
    """Pixel coverage of a disc, (h, w, 1) float64 (supersampled SS x SS)."""
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    ys = -0.5 + (np.arange(h * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, ys)
    return cv2.resize(((X - cu) ** 2 + (Y - cv_) ** 2 <= r * r).astype(np.float32), (w, h),
                      interpolation=cv2.INTER_AREA).astype(np.float64)[..., None]


def _paint(img, cov, rgb):
    return img * (1.0 - cov) + cov * np.asarray(rgb)[::-1]


def _ball_over_tinted_band(tint):
    """140 x 140 BGR frame: a ball (r = 32 px) over a larger disc tinted ``tint`` of the way to its colour."""
    h = w = 140
    cu, cv_, r = 70.3, 62.6, 32.0
    img = np.empty((h, w, 3))
    img[:] = GROUND[::-1]
    img = _paint(img, _coverage(h, w, cu, cv_ + 7.0, r + 5.0), GROUND + tint * (BALL - GROUND))
    img = _paint(img, _coverage(h, w, cu, cv_, r), BALL)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), (cu, cv_, r)


@pytest.mark.parametrize("tint", [0.2, 0.3])
def test_a_weakly_tinted_band_outside_the_ball_is_not_its_rim(tint):
    img, (cu, cv_, r) = _ball_over_tinted_band(tint)
    chroma = sphere_chroma(tuple(BALL))
    pts, n = chroma_rim_points(img, chroma, (cu + 2.0, cv_ + 3.0), r - 3.0)
    d = np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r
    assert len(pts) >= 0.9 * n and np.all(np.abs(d) < 1.0)   # the band shifts its side by up to 0.8 px
    u, v, rr, frac = refine_circle_on_chroma(img, chroma, (cu + 2.0, cv_ + 3.0), r - 3.0)
    assert math.hypot(u - cu, v - cv_) < 0.15 and abs(rr - r) < 0.3
    # the old threshold (sphere-like = 25 % of the ball's chroma) takes the band's outer edge below the ball
    pts, _ = chroma_rim_points(img, chroma, (cu + 2.0, cv_ + 3.0), r - 3.0, min_inside=0.25)
    if tint == 0.3:
        assert np.count_nonzero(np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r > 1.0) >= 8


def test_a_poor_first_circle_is_recovered_and_confirmed():
    h, w = 140, 180
    cu, cv_, r = 88.4, 71.7, 34.0
    img = np.empty((h, w, 3))
    img[:] = GROUND[::-1]
    img = _paint(img, _coverage(h, w, cu, cv_, r), BALL)
    img[:, 112:] = (110, 140, 205)                     # a finger over the right third of the ball
    img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    chroma = sphere_chroma(tuple(BALL))
    start = (cu - 8.0, cv_ + 8.0), 22.0                  # a colour region of part of the ball, low and left
    assert refine_circle_on_chroma(img, chroma, *start) is None
    u, v, rr = chroma_circle(img, chroma, *start)
    assert math.hypot(u - cu, v - cv_) < 0.3 and abs(rr - r) < 0.4


def test_no_circle_on_a_ground_of_the_ball_colour():
    """Without a chroma edge near the first circle the wide search finds nothing rather than something."""
    img = np.empty((140, 140, 3))
    img[:] = BALL[::-1]
    img = np.clip(np.rint(img + np.random.default_rng(3).normal(0, 2, img.shape)), 0, 255).astype(np.uint8)
    assert chroma_circle(img, sphere_chroma(tuple(BALL)), (70.0, 70.0), 20.0) is None
