"""Sphere rim on the luma (brightness) edge: a refinement robust to chroma subsampling.

JPEG (and most video codecs) store colour at half resolution (4:2:0): the
decoded chroma is smeared over about a pixel either side of a colour edge, so
a rim taken from the colour probability image is biased wherever the sphere's
colour contrast differs around it (0.3-0.4 px median on the virtual lab's
JPEG frames). The luma ``Y = 0.299 R + 0.587 G + 0.114 B`` is kept at full
resolution, and ``cv2.COLOR_BGR2GRAY`` of the decoded frame recovers it (the
chroma terms of the decoder's YCbCr -> RGB conversion cancel), so the sphere's
silhouette edge is located on the luma instead:

1. From a first circle (centre ``(u, v)``, radius ``r``: the colour rim's
   circle or the region's moment and area radius), cast ``n`` rays, about
   one per pixel of circumference (a multiple of 4 in 16-64), and sample the
   luma bilinearly at radii ``r - span .. r + span`` in ``step`` px steps.
2. Per ray, the polarity is the sign of outer minus inner brightness (a
   sphere may be darker than the background on its shaded side and brighter
   on its lit side); rays whose contrast is below ``min_contrast`` grey levels
   are dropped (no luma edge: the colour rim is all there is).
3. The edge is the centre of gravity of the polarity-signed luma derivative
   in excess of 30 % of its peak, over the run of samples around the peak
   where it exceeds that level.
4. Colour gate: the colour log-odds must be negative 2 px outside the edge,
   so an edge inside the sphere's own shading (the terminator) is not taken
   for the rim. The inside is not gated by default: the shaded limb's dark
   pixels have negative log-odds, and requiring positive ones 1.5 px inside
   (``inside_gate=True``, the rule before 2026-11-26) dropped the shaded
   side's rays, so the circle leaned towards the lit side (on the sphere
   family's JPEG views by a median 0.12-0.18 px). An occluder's edge is left
   to the trimmed fit of step 5.
5. A circle is fitted to the edge points by trimmed least squares: points
   more than 1.5 px off the first circle are left out (the edge of an
   occluder in front of the sphere lies inside its rim), then those more
   than ``tol_px`` off the fitted circle. It is used only when it
   explains at least half of the rays and stays within 1.5 px of the first
   circle in centre and radius.

It costs about as much again as the rest of a detection (Python), so the
segmentation uses it only when asked (``SegmentParams(edge_refine=True)``);
the CLI's ``--luma-edge auto`` asks for it when
:func:`chroma_subsampled_source` says the recording is JPEG frames or a video.

On the virtual lab's static frames (5 seeds, both cameras, both spheres) the
centroid RMS error of single full-frame detections is 0.12 px with PNG and
0.13 px with JPEG frames (colour rim: 0.13 px PNG, 0.43 px JPEG).
"""
from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from ._circle import circle_lsq, fit_rim_circle_multi

__all__ = ["luma_rim_points", "refine_circle_on_luma", "refine_circle_on_luma_wide", "chroma_rim_points",
           "refine_circle_on_chroma", "chroma_circle", "sphere_chroma", "MIN_INSIDE", "LOSSY_SUFFIXES",
           "chroma_subsampled_source", "WIDE_LUMA_MIN_PX", "refine_luma_from_first_fit"]

#: File suffixes whose colour is usually stored at reduced resolution (JPEG; video codecs).
LOSSY_SUFFIXES = frozenset({".jpg", ".jpeg", ".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg"})


_GATE = np.array([-1.5, 2.0])

#: Smallest chroma 2 px inside a chroma rim point, as a fraction of the sphere's own (see chroma_rim_points).
MIN_INSIDE = 0.4
_RAYS: dict = {}


def _rays(k: int, span: float, step: float):
    """Cached ray geometry: cos, sin (k, 1), radial offsets (ns,), sample index row (1, ns - 1)."""
    key = (k, span, step)
    if key not in _RAYS:
        ang = (2.0 * math.pi / k) * np.arange(k)
        offsets = np.arange(-span, span + 0.5 * step, step)
        _RAYS[key] = (np.cos(ang)[:, None], np.sin(ang)[:, None], offsets, np.arange(len(offsets) - 1)[None, :])
    return _RAYS[key]


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``img`` at float positions (edge pixels repeated beyond the border).

    In float64 (``cv2.remap`` rounds positions to 1/32 px, enough to make a
    symmetric disc's centre come out 0.01 px off).
    """
    h, w = img.shape
    x = np.clip(x, 0.0, w - 1.0)
    y = np.clip(y, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.intp), w - 2) if w > 1 else np.zeros(x.shape, np.intp)
    y0 = np.minimum(np.floor(y).astype(np.intp), h - 2) if h > 1 else np.zeros(y.shape, np.intp)
    fx, fy = x - x0, y - y0
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    top = img[y0, x0] * (1.0 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1.0 - fx) + img[y1, x1] * fx
    return top * (1.0 - fy) + bot * fy


def luma_rim_points(gray, log_odds, centre, radius: float, *, span: float = 3.0, step: float = 0.25,
                    min_contrast: float = 8.0, n_rays: int | None = None, inside_gate: bool = False):
    """Sub-pixel luma edge points of a sphere's rim along rays from a first circle.

    Parameters
    ----------
    gray : ndarray, shape (H, W)
        Luma (``cv2.COLOR_BGR2GRAY``) of an image window, 0..255, float.
    log_odds : ndarray, shape (H, W), float32, or None
        The sphere's colour log-odds on the same window (the colour gate of
        step 4 in the module docstring); None disables the gate.
    centre : tuple of float
        First estimate ``(u, v)`` of the circle centre, window pixels (u
        right, v down, pixel centres at integers).
    radius : float
        First estimate of the radius, pixels.
    span, step : float
        Radii ``radius - span .. radius + span`` are sampled every ``step`` px.
    min_contrast : float
        Smallest outer-minus-inner luma difference (grey levels) of a ray.
    n_rays : int, optional
        Rays (default: about one per pixel of circumference, a multiple of 4
        in 16..64).
    inside_gate : bool
        Also require positive log-odds 1.5 px inside the edge (drops the
        shaded limb's rays; see step 4 of the module notes).

    Returns
    -------
    points : ndarray, shape (K, 2)
        Edge points ``(u, v)`` in window pixels of the rays that passed the
        contrast and colour gates.
    n_rays : int
        Rays cast.

    Examples
    --------
    >>> yy, xx = np.mgrid[0:40, 0:40]
    >>> disc = np.clip(8.5 - np.hypot(xx - 20.3, yy - 19.6), 0, 1)   # antialiased disc, r = 8
    >>> gray = (160 - 100 * disc).astype(np.float32)                  # dark sphere, bright ground
    >>> pts, n = luma_rim_points(gray, None, (20.0, 20.0), 7.0)
    >>> n, len(pts), bool(np.abs(np.hypot(pts[:, 0] - 20.3, pts[:, 1] - 19.6) - 8.0).max() < 0.3)
    (44, 44, True)
    """
    cu, cv_ = float(centre[0]), float(centre[1])
    r = float(radius)
    # a multiple of 4: the rays are symmetric about both image axes, so a symmetric disc comes out centred
    k = 4 * int(np.clip(round(0.5 * math.pi * r), 4, 16)) if n_rays is None else int(n_rays)
    ca, sa, offsets, j = _rays(k, float(span), float(step))
    s = r + offsets
    ns = len(s)
    prof = cv2.remap(gray, (cu + ca * s).astype(np.float32), (cv_ + sa * s).astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)                # (k, ns)
    diff = (prof[:, -3:].sum(axis=1) - prof[:, :3].sum(axis=1)) * (1.0 / 3.0)    # outer - inner level
    g = np.diff(prof, axis=1) * np.sign(diff)[:, None]                           # (k, ns - 1), at s + step/2
    peak = np.argmax(g, axis=1)
    gmax = g[np.arange(k), peak]
    pos, wsum, lo_end, hi_end = _peak_centroid(g, peak, j, s[0], step)
    ok = (np.abs(diff) >= min_contrast) & (gmax > 0) & (wsum > 0)
    ok &= (lo_end >= 0) & (hi_end < ns - 1)       # an edge at the end of the span is no edge
    if log_odds is not None:
        rad = pos[:, None] + _GATE                                                   # (k, 2): inside, outside
        lo = _bilinear(log_odds, cu + ca * rad, cv_ + sa * rad)
        ok &= (lo[:, 1] < 0) & ((lo[:, 0] > 0) | (not inside_gate))
    pts = np.column_stack([cu + ca[ok, 0] * pos[ok], cv_ + sa[ok, 0] * pos[ok]])
    return pts, k


def _trimmed_circle(pts: np.ndarray, centre, radius: float, bands) -> tuple | None:
    """Least-squares circle ``(u, v, r)`` of the points within each band of the circle so far, in turn; None
    when fewer than 5 points remain in a band or the fit degenerates. Starts from ``centre``, ``radius``."""
    fu, fv, fr = float(centre[0]), float(centre[1]), float(radius)
    for band in bands:
        inl = np.abs(np.hypot(pts[:, 0] - fu, pts[:, 1] - fv) - fr) < band
        if np.count_nonzero(inl) < 5:
            return None
        fu, fv, fr = circle_lsq(pts[inl])
        if not math.isfinite(fr):
            return None
    return fu, fv, fr


def refine_circle_on_luma(gray, log_odds, centre, radius: float, *, tol_px: float = 0.5,
                          min_fraction: float = 0.5, max_shift_px: float = 1.5, min_contrast: float = 8.0):
    """Circle fitted robustly to the luma rim points, or None when it is not trustworthy.

    Parameters
    ----------
    gray, log_odds, centre, radius, min_contrast
        As for :func:`luma_rim_points`.
    tol_px : float
        Edge points within this distance of the circle are inliers.
    min_fraction : float
        Smallest fraction of the rays cast whose edge points must be inliers.
    max_shift_px : float
        Largest change of centre and of radius from the first circle.

    Returns
    -------
    tuple or None
        ``(u, v, r, inlier_fraction, rms_px)`` in window pixels, or None.

    Examples
    --------
    >>> yy, xx = np.mgrid[0:40, 0:40]
    >>> disc = np.clip(8.5 - np.hypot(xx - 20.3, yy - 19.6), 0, 1)
    >>> gray = (60 + 100 * disc).astype(np.float32)                   # bright sphere, dark ground
    >>> u, v, r, frac, rms = refine_circle_on_luma(gray, None, (20.0, 20.0), 7.0)
    >>> round(u, 1), round(v, 1), round(r, 1), frac
    (20.3, 19.6, 8.0, 1.0)
    """
    pts, n = luma_rim_points(gray, log_odds, centre, radius, min_contrast=min_contrast)
    if len(pts) < max(8, min_fraction * n):
        return None
    # trimmed least squares started from the first circle: points more than max_shift_px off it
    # (an occluder's edge, a highlight) are left out, then those off the fitted circle by tol_px
    fit = _trimmed_circle(pts, centre, radius, (max_shift_px, 2.0 * tol_px, tol_px))
    if fit is None:
        return None
    fu, fv, fr = fit
    inl = np.abs(np.hypot(pts[:, 0] - fu, pts[:, 1] - fv) - fr) < tol_px
    n_in = int(np.count_nonzero(inl))
    if (n_in < min_fraction * n or abs(fr - radius) > max_shift_px
            or math.hypot(fu - centre[0], fv - centre[1]) > max_shift_px):
        return None
    res = np.hypot(pts[inl, 0] - fu, pts[inl, 1] - fv) - fr
    return fu, fv, fr, n_in / n, float(np.sqrt(np.mean(res * res)))


#: Spheres whose colour region's area radius is at least this (px) and that are still on their colour circle
#: after the chroma edge get the wider luma search (:func:`refine_circle_on_luma_wide`).
WIDE_LUMA_MIN_PX = 12.0


def refine_circle_on_luma_wide(gray, log_odds, centre, radius: float, *, span_frac: float = 0.35,
                               min_contrast: float = 8.0):
    """The luma rim circle of a sphere whose first circle may be several pixels off, or None.

    For a large sphere whose colour region stops short of its silhouette on one side (a shaded limb on a
    background of the sphere's hue): :func:`refine_circle_on_luma` searches 3 px either side of the first
    circle and allows 1.5 px of change, which cannot reach a rim 5-10 px away. Here the rays span
    ``span_frac`` radii (at least 3 px), the circle is fitted to the edge points with a trimming band
    narrowing from that span to 1 px, and the result is accepted only as a start from which
    :func:`refine_circle_on_luma` itself converges (half of its rays within 0.5 px).

    Parameters
    ----------
    gray, log_odds, centre, radius, min_contrast
        As for :func:`luma_rim_points`.
    span_frac : float
        Half width of the search along each ray, in radii.

    Returns
    -------
    tuple or None
        ``(u, v, r, inlier_fraction, rms_px)`` in window pixels, as :func:`refine_circle_on_luma`.

    Examples
    --------
    >>> yy, xx = np.mgrid[0:80, 0:80]
    >>> disc = np.clip(25.5 - np.hypot(xx - 41.3, yy - 38.6), 0, 1)
    >>> gray = (60 + 100 * disc).astype(np.float32)
    >>> refine_circle_on_luma(gray, None, (36.0, 35.0), 20.0) is None     # 6 px off: out of its reach
    True
    >>> u, v, r, frac, rms = refine_circle_on_luma_wide(gray, None, (36.0, 35.0), 20.0)
    >>> round(u, 1), round(v, 1), round(r, 1)
    (41.3, 38.6, 25.0)
    """
    span = max(3.0, float(span_frac) * float(radius))
    return refine_luma_from_first_fit(gray, log_odds, centre, radius,
                                      lambda pts: _trimmed_circle(pts, centre, radius, (span, 3.0, 1.5, 1.0)),
                                      span=span, min_contrast=min_contrast)


def refine_luma_from_first_fit(gray, log_odds, centre, radius: float, first_fit, *, span: float = 3.0,
                               min_fraction: float = 0.5, min_contrast: float = 8.0, fit_min_fraction: float = 0.5):
    """A rough circle fitted to the luma rim points, kept only as a start from which the ordinary refine converges.

    The mechanism of :func:`refine_circle_on_luma_wide` and
    :func:`~tudorvision.stereo.remeasure.refine_circle_on_luma_at_radius`: edge points along rays from the
    first circle, a rough fit of them, then :func:`refine_circle_on_luma` from the rough circle.

    Parameters
    ----------
    gray, log_odds, centre, radius, min_contrast
        As for :func:`luma_rim_points` (the first circle).
    first_fit : callable
        ``first_fit(points)`` -> ``(u, v, r)`` or None; ``points`` shape (K, 2), window pixels.
    span : float
        The rays reach this many pixels either side of the first circle.
    min_fraction : float
        Smallest fraction of the rays (and at least 8) that must find an edge point.
    fit_min_fraction : float
        ``min_fraction`` of the final :func:`refine_circle_on_luma`: the fraction of its rays within 0.5 px
        of its circle.

    Returns
    -------
    tuple or None
        ``(u, v, r, inlier_fraction, rms_px)`` in window pixels, as :func:`refine_circle_on_luma`.
    """
    pts, n = luma_rim_points(gray, log_odds, centre, radius, span=span, min_contrast=min_contrast)
    if len(pts) < max(8, min_fraction * n):
        return None
    fit = first_fit(pts)
    if fit is None:
        return None
    return refine_circle_on_luma(gray, log_odds, fit[:2], fit[2], min_contrast=min_contrast,
                                 min_fraction=fit_min_fraction)


@functools.lru_cache(maxsize=64)
def _chroma_of(r: float, g: float, b: float) -> tuple:
    px = np.array([[[b, g, r]]], np.float32) / np.float32(255.0)
    return tuple(float(x) for x in cv2.cvtColor(px, cv2.COLOR_BGR2Lab)[0, 0, 1:])


def sphere_chroma(rgb) -> np.ndarray:
    """CIE a*, b* of an RGB colour (the sphere's mean colour), shape (2,).

    Parameters
    ----------
    rgb : sequence of float, shape (3,)
        R, G, B in 8-bit levels.

    Returns
    -------
    ndarray, shape (2,), float64
        ``(a*, b*)`` of OpenCV's float Lab (D65; roughly -100..100).

    Examples
    --------
    >>> [round(float(x)) for x in sphere_chroma((128, 128, 128))]
    [0, 0]
    """
    return np.array(_chroma_of(float(rgb[0]), float(rgb[1]), float(rgb[2])))


def chroma_rim_points(bgr, chroma, centre, radius: float, *, lo: float = 0.6, hi: float = 1.35,
                      step: float = 0.5, sigma: float | None = None, rel: float = 0.3, min_inside: float = MIN_INSIDE):
    """Sub-pixel silhouette points of a coloured sphere on its chroma edge, along rays from a first circle.

    The sphere's rim is taken where its colour ends, not where the colour
    model's thresholds end: a washed-out highlight, the dark shaded limb or a
    light ring keep the sphere's hue direction at a lower strength, so the
    colour model leaves them out while the chroma still drops only at the
    silhouette. Per pixel the feature is the CIE chroma ``(a*, b*)`` (float
    Lab of the window, lightly smoothed) projected on the
    sphere's chroma direction; along each ray (radii ``lo * r .. hi * r``,
    every ``step`` px) the edge is the **outermost** local maximum of the
    outward drop of that feature that is at least ``rel`` of the ray's largest
    drop, with sphere-like chroma 2 px inside it (> ``min_inside``, 40 %, of the sphere's),
    background-like chroma 2 px outside it (< 50 %) and a step between the two
    of at least 25 %. Its position is the centre of gravity of the drop above
    30 % of its peak. An occluding finger in front of the sphere gives an
    edge inside the rim; the circle fit (:func:`refine_circle_on_chroma`)
    leaves such points out.

    Parameters
    ----------
    bgr : ndarray, shape (H, W, 3), uint8
        Image window (BGR).
    chroma : array_like, shape (2,)
        The sphere's ``(a*, b*)`` (:func:`sphere_chroma` of the colour
        model's mean R, G, B).
    centre : tuple of float
        First estimate ``(u, v)`` of the centre, window pixels.
    radius : float
        First estimate of the radius, pixels.
    lo, hi, step, rel : float
        Ray span (fractions of ``radius``), sample step (px) and the
        relative strength of an accepted drop.
    min_inside : float
        Smallest chroma 2 px inside an accepted edge, as a fraction of the
        sphere's (0.25 until 2026-11-26: the edge of a weakly tinted band
        outside the ball, e.g. a hand under a blurred ball, was taken).
    sigma : float, optional
        Gaussian smoothing of the feature, px (default ``min(1, radius / 20)``:
        more would merge a small sphere's rim with an occluder's edge).

    Returns
    -------
    points : ndarray, shape (K, 2)
        Edge points ``(u, v)`` in window pixels.
    n_rays : int
        Rays cast (about one per 2 px of circumference, a multiple of 4 in 32..128).

    Examples
    --------
    >>> import cv2
    >>> img = np.full((80, 80, 3), 200, np.uint8)
    >>> _ = cv2.circle(img, (40, 40), 20, (60, 160, 60), -1, cv2.LINE_AA)
    >>> pts, n = chroma_rim_points(img, sphere_chroma((60, 160, 60)), (41.0, 39.0), 18.0)
    >>> # cv2.circle's disc of radius 20 reaches to about 20.5 px
    >>> len(pts) == n, bool(np.abs(np.hypot(pts[:, 0] - 40, pts[:, 1] - 40) - 20.5).max() < 0.35)
    (True, True)
    """
    r = float(radius)
    fs = float(np.hypot(*np.asarray(chroma, np.float64)))          # the sphere's own level
    if not fs > 0 or not r > 0:
        return np.zeros((0, 2)), 0
    feat = _chroma_feature(bgr, chroma, min(1.0, r / 20.0) if sigma is None else float(sigma))
    return _rim_on_feature(feat, fs, centre, r, lo, hi, step, rel, min_inside)


def _chroma_feature(bgr, chroma, sigma: float) -> np.ndarray:
    """Float Lab chroma of ``bgr`` projected on the unit direction of ``chroma``, smoothed by ``sigma`` px."""
    ab = np.asarray(chroma, np.float64)
    norm = float(np.hypot(ab[0], ab[1]))
    lab = cv2.cvtColor(np.asarray(bgr, np.float32) * np.float32(1.0 / 255.0), cv2.COLOR_BGR2Lab)
    feat = cv2.addWeighted(lab[..., 1], ab[0] / norm, lab[..., 2], ab[1] / norm, 0.0)
    return cv2.GaussianBlur(feat, (0, 0), sigma) if sigma > 0 else feat


def _peak_centroid(g, peak, j, s0: float, step: float):
    """Sub-sample edge positions along rays from the profile derivative ``g`` (k, n) around ``peak`` (k,).

    The centre of gravity of the derivative's excess over 30 % of its value at the peak, over the run
    of samples around the peak where it is positive: the weights vanish at the run's ends, so the
    position changes continuously with the image (ties at the peak, common on bilinear profiles, do
    not matter). ``j`` (1, n) are the sample indices, ``s0`` the first sample's distance and ``step``
    the sample spacing, px. Returns the positions (k,) px, the weight sums (k,; 0: no edge) and the
    run's ends (k,; -1 / n: the run reaches the span's end).
    """
    ns = g.shape[1] + 1
    w = np.clip(g - 0.3 * g[np.arange(len(peak)), peak][:, None], 0.0, None)
    off = w <= 0.0
    lo_end = np.where(off & (j < peak[:, None]), j, -1).max(axis=1)
    hi_end = np.where(off & (j > peak[:, None]), j, ns - 1).min(axis=1)
    w = np.where((j > lo_end[:, None]) & (j < hi_end[:, None]), w, 0.0)
    wsum = w.sum(axis=1)
    return s0 + step * (0.5 + (w * j).sum(axis=1) / np.where(wsum > 0, wsum, 1.0)), wsum, lo_end, hi_end


def _rim_on_feature(feat, fs, centre, r, lo, hi, step, rel, min_inside=MIN_INSIDE):
    """:func:`chroma_rim_points` on a feature image from :func:`_chroma_feature` (sphere level ``fs``)."""
    k = 4 * int(np.clip(round(0.25 * math.pi * r), 8, 32))
    ca, sa, offsets, j = _rays(k, 0.5 * (hi - lo) * r, step)
    s = 0.5 * (hi + lo) * r + offsets
    ns = len(s)
    cu, cv_ = float(centre[0]), float(centre[1])
    prof = cv2.remap(feat, (cu + ca * s).astype(np.float32), (cv_ + sa * s).astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)              # (k, ns)
    g = prof[:, :-1] - prof[:, 1:]                                                   # drop outward, (k, ns - 1)
    gmax = g.max(axis=1)
    m = max(int(round(2.0 / step)), 1)
    inner = prof[:, np.clip(j[0] - m, 0, ns - 1)]                                    # 2 px inside each gap
    outer = prof[:, np.clip(j[0] + 1 + m, 0, ns - 1)]                                # 2 px outside
    left = np.concatenate([np.full((k, 1), np.inf), g[:, :-1]], axis=1)             # no peak at either end
    right = np.concatenate([g[:, 1:], np.full((k, 1), np.inf)], axis=1)
    cand = ((g >= left) & (g >= right) & (g >= rel * gmax[:, None]) & (g > 0)
            & (inner - outer >= 0.25 * fs) & (outer < 0.5 * fs)
            & (inner > min_inside * fs))
    has = cand.any(axis=1)
    peak = (ns - 2) - np.argmax(cand[:, ::-1], axis=1)                               # outermost candidate
    pos, wsum, _, _ = _peak_centroid(g, peak, j, s[0], step)
    ok = has & (wsum > 0)
    return np.column_stack([cu + ca[ok, 0] * pos[ok], cv_ + sa[ok, 0] * pos[ok]]), k


def refine_circle_on_chroma(bgr, chroma, centre, radius: float, *, tol_frac: float = 0.08,
                            min_fraction: float = 0.3, max_shift_frac: float = 0.3, passes: int = 2,
                            max_grow: float = 1.4, confirm: float | None = None):
    """Circle fitted robustly to the chroma rim points, or None when it is not trustworthy.

    Rays from the first circle give edge points (:func:`chroma_rim_points`);
    a circle is fitted to them by :func:`~tudorvision.stereo._circle.fit_rim_circle_multi`
    (points inside the circle, i.e. an occluder's edge, are not held against
    it; points outside it are), with the inlier band ``max(0.75, tol_frac * r)``
    px. The fit is repeated from its own circle (``passes``).

    Parameters
    ----------
    bgr : ndarray, shape (H, W, 3), uint8
        Image window (BGR).
    chroma : array_like, shape (2,)
        The sphere's ``(a*, b*)``.
    centre : tuple of float
        First estimate ``(u, v)`` of the centre, window pixels.
    radius : float
        First estimate of the radius, pixels.
    tol_frac : float
        Inlier band as a fraction of the radius.
    min_fraction : float
        Smallest fraction of the rays cast whose points must be inliers.
    max_shift_frac : float
        Largest move of the centre, as a fraction of the first radius; the
        radius must stay within 0.7 and ``max_grow`` times the first.
    passes : int
        Ray casts (each from the previous pass's circle).
    max_grow : float
        Largest radius as a multiple of the first; the rays reach to
        ``max_grow - 0.05`` of it (1.7 was tried on the sphere family: mixed).
    confirm : float, optional
        Fixed-point mode, for a first circle that may be far off (see
        :func:`chroma_circle`): only the first pass reaches ``max_grow``,
        later ones ``min(max_grow, 1.4) - 0.05`` of their circle, and a circle
        is returned only once a pass moves it (centre plus radius) by less
        than ``confirm`` times its radius, i.e. the rays cast from the circle
        found give that circle again; None when no pass does.

    Returns
    -------
    tuple or None
        ``(u, v, r, inlier_fraction)`` in window pixels, or None.

    Examples
    --------
    >>> import cv2
    >>> img = np.full((90, 90, 3), 200, np.uint8)
    >>> _ = cv2.circle(img, (45, 44), 24, (60, 160, 60), -1, cv2.LINE_AA)
    >>> _ = cv2.rectangle(img, (50, 30), (80, 80), (120, 140, 200), -1)      # a finger over the right
    >>> u, v, r, frac = refine_circle_on_chroma(img, sphere_chroma((60, 160, 60)), (40.0, 44.0), 20.0)
    >>> bool(np.hypot(u - 45, v - 44) < 0.2), bool(abs(r - 24.5) < 0.3)
    (True, True)
    """
    cu, cv_, cr = float(centre[0]), float(centre[1]), float(radius)
    fs = float(np.hypot(*np.asarray(chroma, np.float64)))
    if not fs > 0 or not cr > 0:
        return None
    feat = _chroma_feature(bgr, chroma, min(1.0, cr / 20.0))      # once for all passes
    out = None
    for i in range(passes):
        reach = max_grow if confirm is None or i == 0 else min(max_grow, 1.4)
        pts, n = _rim_on_feature(feat, fs, (cu, cv_), cr, 0.6, reach - 0.05, 0.5, 0.3)
        if n == 0 or len(pts) < max(8, min_fraction * n):
            break
        fit = fit_rim_circle_multi(pts, max(0.75, tol_frac * cr))
        if fit is None:
            break
        fu, fv, fr, inl = fit
        frac = int(np.count_nonzero(inl)) / n
        if (frac < min_fraction or math.hypot(fu - centre[0], fv - centre[1]) > max_shift_frac * radius
                or not 0.7 * radius <= fr <= max_grow * radius):
            break
        moved = math.hypot(fu - cu, fv - cv_) + abs(fr - cr)
        cu, cv_, cr = fu, fv, fr
        if confirm is None:
            out = (fu, fv, fr, frac)
        elif i >= 1 and moved < confirm * fr:
            return fu, fv, fr, frac
    return out


def chroma_circle(bgr, chroma, centre, radius: float):
    """The sphere's circle on its chroma edge in a full frame, from a first circle that may be poor.

    :func:`refine_circle_on_chroma` in a window of ``1.4 radius + 6`` px
    around ``centre``, up to 3 passes, in the fixed-point mode
    (``confirm=0.15``: a circle that the next ray cast still moves by more
    than 0.15 of its radius is not taken). When that finds no trustworthy
    circle (the first circle was far off: the colour model's region was a
    third of the ball, or fingers split it), the search is made once more in a window of
    ``2.4 radius + 6`` px with looser limits (centre move up to 0.6 r,
    radius up to 1.8 r, first rays to 1.75 r) but in the fixed-point mode
    (``confirm=0.1``, up to 3 passes): the rays cast from the circle found
    must find it again. The second search runs only where the first fails,
    so fully visible spheres and most partly hidden ones cost nothing more.

    Parameters
    ----------
    bgr : ndarray, shape (H, W, 3), uint8
        The full frame (BGR).
    chroma : array_like, shape (2,)
        The sphere's ``(a*, b*)`` (:func:`sphere_chroma`).
    centre : tuple of float
        First estimate ``(u, v)`` of the centre, frame pixels.
    radius : float
        First estimate of the radius, pixels.

    Returns
    -------
    tuple or None
        ``(u, v, r)`` in frame pixels, or None (also for grey spheres,
        chroma below 5, and windows under 8 px).

    Examples
    --------
    >>> import cv2
    >>> img = np.full((120, 160, 3), 200, np.uint8)
    >>> _ = cv2.circle(img, (80, 60), 30, (60, 160, 60), -1, cv2.LINE_AA)
    >>> green = sphere_chroma((60, 160, 60))
    >>> refine_circle_on_chroma(img, green, (74.0, 68.0), 20.0) is None      # a poor first circle
    True
    >>> u, v, r = chroma_circle(img, green, (74.0, 68.0), 20.0)
    >>> bool(np.hypot(u - 80, v - 60) < 0.2), bool(abs(r - 30.5) < 0.3)
    (True, True)
    """
    h, w = bgr.shape[:2]
    if not math.hypot(*chroma) >= 5.0:          # a grey sphere has no chroma edge
        return None
    for span, kw in ((1.4, dict(passes=3, confirm=0.15)),
                     (2.4, dict(max_shift_frac=0.6, max_grow=1.8, passes=3, confirm=0.1))):
        m = int(math.ceil(span * radius)) + 6
        x0, y0 = max(int(centre[0]) - m, 0), max(int(centre[1]) - m, 0)
        x1, y1 = min(int(centre[0]) + m + 1, w), min(int(centre[1]) + m + 1, h)
        if x1 - x0 < 8 or y1 - y0 < 8:
            return None
        fit = refine_circle_on_chroma(bgr[y0:y1, x0:x1], chroma, (centre[0] - x0, centre[1] - y0), radius, **kw)
        if fit is not None:
            return fit[0] + x0, fit[1] + y0, fit[2]
    return None


def chroma_subsampled_source(path) -> bool:
    """Whether a recording is stored in a format that subsamples colour (JPEG frames or a video file).

    Parameters
    ----------
    path : str or Path
        A video file, or a sequence directory (its image files are looked at
        down to two levels, e.g. ``left/000000.jpg``).

    Returns
    -------
    bool
        True for a video file or a directory whose first image file found is
        JPEG; False otherwise (PNG and other lossless frames, nothing found).

    Examples
    --------
    >>> chroma_subsampled_source("ball.mp4"), chroma_subsampled_source("/nonexistent")
    (True, False)
    """
    from pathlib import Path

    p = Path(path)
    if p.suffix.lower() in LOSSY_SUFFIXES and not p.is_dir():
        return True
    if not p.is_dir():
        return False
    image_suffixes = LOSSY_SUFFIXES | {".png", ".bmp", ".tif", ".tiff", ".ppm", ".pgm"}
    for pattern in ("*", "*/*"):
        for f in sorted(p.glob(pattern)):
            if f.is_file() and f.suffix.lower() in image_suffixes:
                return f.suffix.lower() in LOSSY_SUFFIXES
    return False
