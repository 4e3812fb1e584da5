"""Statistics of a picked circle for :func:`~tudorvision.stereo.colormodel.fit_color_model` (internal).

Rows are the picked pixels as ``(n, 6)`` arrays of R, G, B, H, S, V levels
(OpenCV hue, 0..179).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from tudorvision.stereo._colortables import CHANNELS, HUE_INDEX, HUE_LEVELS, ColorModel
from tudorvision.stereo.segment import log_odds_image

__all__ = ["circular_hue_stats", "pick_stats", "reject_outlier_rows", "trim_highlights_rows", "calibrated_prior",
           "pick_contrast", "fits_pick", "part_of_pick", "PICK_CHECK_MIN_RADIUS_PX",
           "PICK_CHECK_MAX_OFFSET_PX"]

#: Picks of at least this radius (pixels) must find the picked circle on their frame (:func:`part_of_pick`);
#: below it a click's rounding and the rim's blur make a picked circle too coarse to judge a region by.
PICK_CHECK_MIN_RADIUS_PX = 6.0
#: ... and centre their circle within this many pixels of the click (or a fifth of the picked radius): on the
#: sphere family a click is 1-3 px off the centre of a well found sphere, the lit cap of one of the
#: background's colour 4-15 px.
PICK_CHECK_MAX_OFFSET_PX = 4.0


def circular_hue_stats(hue) -> tuple[float, float]:
    """Circular mean and standard deviation of OpenCV hue values (0..179).

    Parameters
    ----------
    hue : array_like, shape (N,)
        Hue levels, two degrees per level; 179 and 0 are neighbours.

    Returns
    -------
    mean : float
        Circular mean in levels, in [0, 180).
    std : float
        Circular standard deviation ``sqrt(-2 ln R)`` in levels, where ``R``
        is the mean resultant length.

    Examples
    --------
    >>> m, s = circular_hue_stats([178, 179, 0, 1])
    >>> round(m, 3), round(s, 2)     # not the linear mean 89.5
    (179.5, 1.12)
    """
    ang = np.asarray(hue, dtype=np.float64).ravel() * (2.0 * np.pi / HUE_LEVELS)
    if ang.size == 0:
        raise ValueError("hue: needs at least one value")
    c, s = np.cos(ang).mean(), np.sin(ang).mean()
    r = min(math.hypot(c, s), 1.0)
    mean = (math.atan2(s, c) % (2.0 * np.pi)) * HUE_LEVELS / (2.0 * np.pi)
    std = math.sqrt(-2.0 * math.log(max(r, 1e-300))) * HUE_LEVELS / (2.0 * np.pi)
    return float(mean % HUE_LEVELS), float(std)



def trim_highlights_rows(fg: np.ndarray, core: np.ndarray, min_pixels: int) -> np.ndarray:
    """Which of the pick's pixels (R G B H S V rows) to keep: all but the washed-out highlight; bool (n,).

    A highlight pixel is at least as bright (V) as the core's median and less
    saturated than its median by more than 3.5 robust sigmas (1.4826 MAD of
    the core, at least 6 levels); ``core`` marks the inner half of the circle.
    Shading (darker, same saturation) is kept. The trim is skipped when it
    would keep fewer than half the pixels or fewer than ``min_pixels``.
    """
    s_core, v_core = fg[core][:, 4], fg[core][:, 5]
    s_med, v_med = float(np.median(s_core)), float(np.median(v_core))
    sigma = max(1.4826 * float(np.median(np.abs(s_core - s_med))), 6.0)
    keep = ~((fg[:, 4] < s_med - 3.5 * sigma) & (fg[:, 5] >= v_med))
    n_keep = int(keep.sum())
    if n_keep < max(min_pixels, fg.shape[0] // 2):
        return np.ones(fg.shape[0], dtype=bool)
    return keep


def pick_stats(fg: np.ndarray, min_saturation: float, max_std: float, max_hue_std: float):
    """Mean, std (n, 6 rows R G B H S V; circular hue), whether hue is used, and the channels too spread."""
    mean = fg.mean(axis=0)
    std = fg.std(axis=0)
    mean[HUE_INDEX], std[HUE_INDEX] = circular_hue_stats(fg[:, HUE_INDEX])
    use_hue = bool(mean[4] >= min_saturation)
    bad = [f"{ch}={std[i]:.1f}" for i, ch in enumerate(CHANNELS)
           if (i != HUE_INDEX and std[i] > max_std) or (i == HUE_INDEX and use_hue and std[i] > max_hue_std)]
    return mean, std, use_hue, bad


def reject_outlier_rows(fg: np.ndarray, core: np.ndarray, min_std: np.ndarray, min_pixels: int) -> np.ndarray:
    """Rows of ``fg`` (n, 6: R G B H S V) within 3 robust sigmas of the median in every channel.

    ``fg`` unchanged when that keeps fewer than 60 % of the rows or fewer than
    half of the ``core`` rows (bool, n; the pixels near the picked centre):
    then the majority is not the sphere (a pick reaching far beyond it).
    """
    med = np.median(fg, axis=0)
    dev = np.abs(fg - med)
    hue = dev[:, HUE_INDEX]
    dev[:, HUE_INDEX] = np.minimum(hue, HUE_LEVELS - hue)          # circular hue distance
    sig = np.maximum(1.4826 * np.median(dev, axis=0), min_std)
    keep = (dev <= 3.0 * sig).all(axis=1)
    if keep.sum() < max(min_pixels, 0.6 * len(fg)) or keep[core].sum() < 0.5 * core.sum():
        return fg
    return fg[keep]


def pick_contrast(model: ColorModel, img: np.ndarray, c: np.ndarray, r_core: float, r_bg: float):
    """The picked core's median log-odds and the background's 99.9th percentile, or None.

    Core: pixels within ``r_core`` of ``c``; background: every second pixel farther than ``r_bg``. None when
    either is empty or the background has fewer than 100 pixels. A core median at or below the background's
    percentile means that no threshold singles the sphere out by its colour in ``img``.
    """
    h, w = img.shape[:2]
    lo = log_odds_image(img, model)
    yy, xx = np.mgrid[0:h, 0:w]
    d2 = (xx - c[0]) ** 2 + (yy - c[1]) ** 2
    core = lo[d2 <= r_core ** 2]
    background = lo[::2, ::2][d2[::2, ::2] > r_bg ** 2]
    if core.size == 0 or background.size < 100:
        return None
    return float(np.median(core)), float(np.percentile(background, 99.9))


def calibrated_prior(model: ColorModel, img: np.ndarray, c: np.ndarray, r_core: float, r_bg: float,
                     params, *, background_room: bool = True) -> ColorModel:
    """``model`` with its prior raised so the picked core passes ``params.p_seed`` (see ``calibrate_prior``).

    ``background_room=False`` drops the limit set by the background's 99.9th percentile (the core then
    passes ``p_seed`` by one logit, the prior at most 0.5): for a local model, whose acceptance judges the
    regions the background's sphere-like pixels form instead of counting them one by one.
    """
    contrast = pick_contrast(model, img, c, r_core, r_bg)
    if contrast is None:
        return model
    need = math.log(params.p_seed / (1.0 - params.p_seed)) + 1.0 - contrast[0]
    room = math.log(params.p_grow / (1.0 - params.p_grow)) - 1.0 - contrast[1]
    delta = min(need, room) if background_room else need
    if not delta > 0:
        return model
    prior = 1.0 / (1.0 + math.exp(-(model.log_prior_odds + delta)))
    return replace(model, prior=min(prior, 0.5))


def _det_radius(det) -> float:
    """A detection's circle radius, or its region's area radius when it has no circle (pixels)."""
    return det.circle_radius_px if math.isfinite(det.circle_radius_px) else math.sqrt(det.area_px / math.pi)


def fits_pick(det, center_uv, radius: float) -> bool:
    """Whether a detection on the pick frame is the picked circle: centre within 0.3 picked radii, radius 0.85-1.6.

    The stricter check for a pick whose circle was not one colour (its model's spread capped): the
    picked edge lies at about 80 % of the sphere's radius, so the sphere's circle is 1.0-1.5 times the
    picked one; a region much smaller or off-centre is part of the sphere or something else.
    """
    if not det.valid:
        return False
    off = math.hypot(det.uv[0] - center_uv[0], det.uv[1] - center_uv[1])
    return off <= 0.3 * radius and 0.85 * radius <= _det_radius(det) <= 1.6 * radius


def part_of_pick(det, center_uv, radius: float) -> str:
    """Why a valid detection on the pick frame is only part of the picked sphere, or "" when it is not.

    The check on every pick of ``radius >= PICK_CHECK_MIN_RADIUS_PX``: the detection's circle (its area
    radius without one) is shorter than 0.8 picked radii, or its centre lies more than
    ``PICK_CHECK_MAX_OFFSET_PX`` (or a fifth of the picked radius) from the picked centre. A sphere of the background's colour (a red sphere on red
    wood) is then found as its lit cap, whose centre lies towards the light in both cameras alike, so
    the stereo checks cannot tell: on the randomised sphere family such picks gave the 15-30 px bins'
    gross 3D errors (docs/benchmarks.md). An invalid detection or a smaller pick gives "".

    Examples
    --------
    >>> from types import SimpleNamespace as D
    >>> part_of_pick(D(valid=True, uv=(50.0, 40.0), circle_radius_px=12.0, area_px=0.0), (50, 40), 10.0)
    ''
    >>> part_of_pick(D(valid=True, uv=(50.0, 34.0), circle_radius_px=7.0, area_px=0.0), (50, 40), 10.0)
    'a circle of 7.0 px radius (0.70 of the picked 10.0 px), its centre 6.0 px from the picked one'
    """
    if not det.valid or radius < PICK_CHECK_MIN_RADIUS_PX:
        return ""
    r_det = _det_radius(det)
    off = math.hypot(det.uv[0] - center_uv[0], det.uv[1] - center_uv[1])
    if r_det >= 0.8 * radius and off <= max(PICK_CHECK_MAX_OFFSET_PX, 0.2 * radius):
        return ""
    return (f"a {'circle' if math.isfinite(det.circle_radius_px) else 'region'} of {r_det:.1f} px radius "
            f"({r_det / radius:.2f} of the picked {radius:.1f} px), its centre {off:.1f} px from the picked one")
