"""Background histograms and the local colour model of a pick (internal).

:func:`~tudorvision.stereo.colormodel.fit_color_model` samples the
background over the whole frame. When the frame holds the sphere's colour
elsewhere (a photograph, a poster, a red sphere in front of red), that
*global* model cannot single the sphere out: the picked core stays below
``p_seed`` and the pick is refused. Its fallback, :func:`fit_local_model`,
samples the background only in a square window around the pick (outside
``background_margin`` radii), where the sphere usually does stand out, and
marks the model as local (``ColorModel.local_radius_px``): every search with
it that would cover the full frame covers that window around the sphere's
last position instead (:meth:`ColorModel.local_roi`), so look-alikes
elsewhere in the frame are never examined.

Rows are pixels as ``(n, 6)`` arrays of R, G, B, H, S, V levels (OpenCV hue,
0..179).
"""
from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np

from tudorvision.stereo._colortables import CHANNEL_LEVELS, HUE_INDEX, ColorModel
from tudorvision.stereo._frame import FramePlanes
from tudorvision.stereo._pick import calibrated_prior, pick_contrast
from tudorvision.stereo.segment import regions_in_window

__all__ = ["smooth_pmf", "background_pmf", "rgbhsv_rows", "fit_local_model", "LOCAL_SCALE", "LOCAL_MIN_PX",
           "LOCAL_MARGIN"]

#: Half size of a local model's window in picked radii, and at least this many pixels more than the radius.
LOCAL_SCALE, LOCAL_MIN_PX = 4.0, 12.0
#: A local model's background starts this many picked radii from the pick: the window is small, so the sphere's
#: own limb (a pick short of the rim puts it up to 1.2-1.9 picked radii out) would weigh in its histogram.
LOCAL_MARGIN = 2.5
#: A local model whose prior was raised past the background's most sphere-like pixels (see fit_local_model) is
#: accepted only when its region is centred within this many picked radii of the pick, with an area radius in
#: this range of picked radii.
RESCUE_FIT = (0.3, (0.7, 1.6))


def smooth_pmf(counts: np.ndarray, sigma: float, circular: bool, floor: float) -> np.ndarray:
    """Histogram ``counts`` smoothed by a Gaussian of ``sigma`` levels, normalised, with a uniform ``floor``."""
    levels = counts.size
    half = int(math.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    k /= k.sum()
    c = counts.astype(np.float64)
    if circular:
        c = np.concatenate([c[-half:], c, c[:half]])
        sm = np.convolve(c, k, mode="valid")
    else:
        sm = np.convolve(c, k, mode="same")
    total = sm.sum()
    pmf = sm / total if total > 0 else np.full(levels, 1.0 / levels)
    return (1.0 - floor) * pmf + floor / levels


def background_pmf(rows: np.ndarray) -> np.ndarray:
    """Per-channel background pmf, shape (6, 256), of pixel rows (n, 6: R G B H S V, integer levels)."""
    background = np.zeros((6, 256))
    for ch in range(6):
        counts = np.bincount(rows[:, ch], minlength=CHANNEL_LEVELS[ch])[:CHANNEL_LEVELS[ch]]
        background[ch, :CHANNEL_LEVELS[ch]] = smooth_pmf(counts, sigma=2.0, circular=(ch == HUE_INDEX), floor=0.01)
    return background


def rgbhsv_rows(bgr: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Rows (n, 6: R G B H S V) of the pixels of a BGR uint8 image where ``mask`` is true."""
    hsv = cv2.cvtColor(np.ascontiguousarray(bgr), cv2.COLOR_BGR2HSV)
    return np.concatenate([bgr[mask][:, ::-1], hsv[mask]], axis=1)


def fit_local_model(model: ColorModel, img: np.ndarray, c: np.ndarray, radius: float, r_core: float, r_bg: float,
                    params, *, scale: float = LOCAL_SCALE):
    """The local model of a pick whose global ``model`` was refused, or the reason it is refused too.

    ``model``: the pick's sphere statistics with the frame's background;
    ``c``, ``radius``: the picked centre and radius (pixels); ``r_core``: the
    radius of the core that must pass ``params.p_seed``; ``r_bg``: background
    pixels lie farther than this from ``c`` (and than ``LOCAL_MARGIN * radius``); ``params``: the verification's
    :class:`SegmentParams`. The window's half size is ``max(scale * radius,
    radius + LOCAL_MIN_PX)``. The background is sampled in the window (every
    pixel), the prior is the circle's share of the window, raised as
    ``calibrate_prior`` does against the window's background. Accepted only
    when, in that window, the heaviest valid region lies within ``radius``
    of the pick, does not touch the window's edge (the sphere's colour does
    not run on into the surroundings), its area radius is 0.5 to 2.5
    picked radii and no other valid region in the window has a quarter of
    its mass (a look-alike that a search could take).

    When that model fails, one more is tried: its prior raised until the
    core passes ``p_seed`` by one logit even where that lifts the window's
    most sphere-like 0.1 % of pixels past ``p_grow`` (a warm photograph's
    scattered pixels of the sphere's red: erosion removes them, and the
    checks above see the regions they form). It is accepted only under the
    same checks with a tighter fit: the region centred within
    ``RESCUE_FIT[0]`` picked radii of the pick, its area radius within
    ``RESCUE_FIT[1]`` picked radii. Otherwise the first model's reason is
    returned.

    Returns ``(ColorModel, "")`` or ``(None, reason)``.
    """
    r_bg = max(r_bg, LOCAL_MARGIN * radius)
    h, w = img.shape[:2]
    half = max(scale * radius, radius + LOCAL_MIN_PX)
    roi = replace(model, local_radius_px=half).local_roi(c, w, h)
    if roi is None:
        return None, "the pick's neighbourhood leaves the frame"
    x0, y0, ww, hh = roi
    win = img[y0:y0 + hh, x0:x0 + ww]
    yy, xx = np.mgrid[y0:y0 + hh, x0:x0 + ww]
    outside = (xx - c[0]) ** 2 + (yy - c[1]) ** 2 > r_bg ** 2
    if outside.sum() < 100:
        return None, "too little background around the pick"
    prior = float(np.clip(math.pi * radius ** 2 / (ww * hh), 1e-3, 0.2))
    local = replace(model, background=background_pmf(rgbhsv_rows(win, outside)), prior=prior, local_radius_px=half)
    win, cw = np.ascontiguousarray(win), c - (x0, y0)
    first = calibrated_prior(local, win, cw, r_core, r_bg, params)
    why = _local_verdict(first, img, win, c, cw, radius, r_core, r_bg, params, roi, None)
    if not why:
        return first, ""
    rescue = calibrated_prior(local, win, cw, r_core, r_bg, params, background_room=False)
    if rescue.prior > first.prior and not _local_verdict(rescue, img, win, c, cw, radius, r_core, r_bg, params, roi,
                                                         RESCUE_FIT):
        return rescue, ""
    return None, why


def _local_verdict(local: ColorModel, img, win, c, cw, radius, r_core, r_bg, params, roi, fit) -> str:
    """Why ``local`` does not single out the pick in its window ("" when it does); ``fit``: stricter (off, size)."""
    found = regions_in_window(FramePlanes(img), local, params, roi, False)
    if not found or not found[0].valid:
        contrast = pick_contrast(local, win, cw, r_core, r_bg)
        if contrast is not None and contrast[0] <= contrast[1]:
            return (f"its colour is as likely around the sphere as on it (the picked core's median "
                    f"log-odds {contrast[0]:.1f}, the surroundings' most sphere-like 0.1 % {contrast[1]:.1f})")
        return found[0].reason if found else "no pixel above p_seed near the pick"
    det = found[0]
    off = math.hypot(det.uv[0] - c[0], det.uv[1] - c[1])
    if off > radius:
        return f"the best region near the pick lies at ({det.uv[0]:.1f}, {det.uv[1]:.1f})"
    if det.touches_window:
        return "the sphere's colour runs on into its surroundings"
    lo, hi = (0.5, 2.5) if fit is None else fit[1]
    if not lo * radius <= det.radius_px <= hi * radius:
        return f"the region near the pick has radius {det.radius_px:.1f} px, not that of the pick"
    if fit is not None and off > fit[0] * radius:
        return f"the region near the pick is centred {off:.1f} px from it"
    mass = det.area_px * det.mean_prob
    if any(d.valid and d.area_px * d.mean_prob >= 0.25 * mass for d in found[1:]):
        return "another region of the sphere's colour lies near the pick"
    return ""
