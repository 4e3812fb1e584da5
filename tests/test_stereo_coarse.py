"""The full-frame search's coarse pass (``stereo._coarse``): 16-bit log-odds and contour boxes.

Oracles: the float32 naive-Bayes log-odds of ``segment.log_odds_image`` and a
connected-component labelling with statistics of the same masks.
"""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from tudorvision.stereo._coarse import coarse_boxes, coarse_log_odds_q
from tudorvision.stereo._colortables import LOG_ODDS_Q
from tudorvision.stereo._frame import FramePlanes
from tudorvision.stereo.colormodel import fit_color_model
from tudorvision.stereo.segment import SegmentParams, detect_sphere, log_odds_image


def _scene(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = rng.integers(40, 200, (120, 160, 3), dtype=np.uint8)
    img = cv2.GaussianBlur(img, (5, 5), 0)
    cv2.circle(img, (60, 50), 12, (40, 40, 210), -1)
    return img


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_quantised_log_odds_match_float(seed):
    img = _scene(seed)
    model = fit_color_model(img, (60, 50), (71, 50))
    lo = log_odds_image(img, model)
    q = coarse_log_odds_q(FramePlanes(img).full_planes(), model)
    assert q.dtype == np.int16
    approx = q.astype(np.float64) / LOG_ODDS_Q + model.log_prior_odds
    # six planes rounded to 1/16 each: at most 6 / 32 off
    assert np.max(np.abs(approx - lo)) <= 6 / (2 * LOG_ODDS_Q) + 1e-6


def _logit(p):
    return math.log(p / (1 - p))


@pytest.mark.parametrize("seed", range(6))
def test_boxes_agree_with_labelling(seed):
    """Random blobs: every seeded component's box and mass, as a labelling with statistics gives them."""
    rng = np.random.default_rng(seed)
    lo = np.full((60, 80), -100, np.int16)
    for _ in range(6):   # separated blobs: no box holds another's pixels
        cx, cy = rng.integers(0, 4) * 20 + 10, rng.integers(0, 3) * 20 + 10
        r = int(rng.integers(2, 8))
        val = int(rng.choice([80, 120]))   # 5 (grown only) or 7.5 (seeded) in log-odds units of 1/16
        cv2.circle(lo, (int(cx), int(cy)), r, val, -1)
    p_seed, p_grow, step = 0.999, 0.99, 2
    got = coarse_boxes(lo, 0.0, p_seed, p_grow, step)
    grow = (lo / LOG_ODDS_Q >= _logit(p_grow)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(grow, connectivity=8)
    want = []
    for k in range(1, n):
        lab = labels == k
        if not np.any(lo[lab] / LOG_ODDS_Q >= _logit(p_seed)):
            continue
        x, y, w, h = (int(v) for v in stats[k, :4])
        p = 1 / (1 + np.exp(-(lo[lab] / LOG_ODDS_Q)))
        want.append(((x * step, y * step, w * step, h * step), float(p.sum()) * step * step))
    masses = [m for _, m in got]
    assert masses == sorted(masses, reverse=True)        # heaviest first (ties in any order)
    got, want = sorted(got), sorted(want)
    assert [b for b, _ in got] == [b for b, _ in want]
    np.testing.assert_allclose([m for _, m in got], [m for _, m in want], rtol=1e-9)


def test_nothing_seeded_gives_no_box():
    lo = np.full((30, 40), 90, np.int16)   # 5.6: above p_grow, below p_seed
    assert coarse_boxes(lo, 0.0, 0.999, 0.99, 2) == []


def test_sphere_found_beside_a_long_red_stripe():
    """An elongated distractor cut by its window is not widened forever, and the sphere is still found."""
    img = np.full((240, 320, 3), 120, np.uint8)
    cv2.circle(img, (220, 150), 14, (40, 40, 210), -1)
    model = fit_color_model(img, (220, 150), (233, 150))
    img[0:200, 60:66] = (40, 40, 210)          # a thin red stripe from the top edge
    det = detect_sphere(img, model, params=SegmentParams(coarse_step=2))
    assert det.valid
    assert abs(det.uv[0] - 220) < 0.3 and abs(det.uv[1] - 150) < 0.3
