"""One view of a sphere measured again, from the radius the other camera predicts (issue 15).

:class:`~tudorvision.stereo.pipeline.StereoPipeline` compares the two views of
each sphere once they are triangulated (:mod:`tudorvision.stereo.stereo_radius`).
Where one view is doubtful, it is measured again with the other view's
radius carried over (``r Z / f`` is the same metric radius in both cameras):

- :func:`chroma_view_at_radius`: a view whose radius disagrees with the
  other's, on the sphere's chroma edge (started at the detection and half a
  radius either side of it, for a sphere split by a link);
- :func:`luma_view_at_radius`: a view measured on its colour (chroma edge,
  colour rim or region moment) beside one measured on its luma rim, when the
  luma edge is used (``SegmentParams(edge_refine=True)``): a background of
  the sphere's colour on one side can hold a colour circle 1-3 px off the
  sphere with about the right radius, where no radius check sees it. It is
  measured on its luma rim with the radius fixed first
  (:func:`refine_circle_on_luma_at_radius`). Two views both measured on their
  colour are each measured so from the other's radius, but only when those
  radii agree (two colour views off together give no radius to trust; such a
  pair is left to the radius check).

Both return a new :class:`~tudorvision.stereo.detection.SphereDetection` only
when the caller's ``agree`` (the pair's radius and epipolar consistency with
the new measurement) accepts it. Neither reads ground truth.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

import cv2
import numpy as np

from .colormodel import ColorModel
from .detection import SphereDetection
from .rim_edge import chroma_circle, luma_rim_points, refine_luma_from_first_fit, sphere_chroma
from .segment import log_odds_image

__all__ = ["chroma_view_at_radius", "luma_support", "luma_view_at_radius", "refine_circle_on_luma_at_radius"]

#: A view of at least this apparent radius (px) may be re-measured on a luma rim that holds fewer than half of
#: its rays (a link or the other sphere across it), down to ``RELAXED_FRACTION`` of them, under three guards:
#: those rays spread around the circle (no gap of half a turn), at least ``RELAXED_SUPPORT_MARGIN`` more of them
#: than the old centre has on a circle of the same radius, and a pair whose radii agree within
#: ``RELAXED_MAX_MISMATCH`` (log ratio). Smaller views keep the half (on the sphere family the relaxed rule made
#: 4-5 px views worse), and so does a view whose colour circle is more than ``RELAXED_MAX_EXCESS`` larger than the
#: radius predicted for it: a colour circle stops short of a shaded limb rather than beyond the silhouette, so
#: there the predicting view's own radius is the doubtful one (on the family such views were pulled off).
RELAXED_MIN_PX = 5.0
RELAXED_FRACTION = 0.3
RELAXED_SUPPORT_MARGIN = 0.1
RELAXED_MAX_MISMATCH = 0.03
RELAXED_MAX_EXCESS = 0.02

#: ``agree(uv, radius_px)``: the pair's log radius mismatch with this view at ``uv`` and ``radius_px`` when the
#: pair is consistent (radius and epipolar line), else None.
Agree = Callable[[tuple, float], "float | None"]


def _centre_at_radius(pts: np.ndarray, centre, radius: float, bands) -> tuple | None:
    """Centre ``(u, v)`` of the circle of the given ``radius`` through the points within each band of the circle
    so far, in turn (Gauss-Newton, a few steps per band); None when fewer than 5 points remain in a band."""
    c = np.array([float(centre[0]), float(centre[1])])
    for band in bands:
        for _ in range(5):
            d = pts - c
            dist = np.hypot(d[:, 0], d[:, 1])
            inl = np.abs(dist - radius) < band
            if np.count_nonzero(inl) < 5:
                return None
            unit = d[inl] / np.maximum(dist[inl], 1e-9)[:, None]      # d dist / d c = -unit
            step, *_ = np.linalg.lstsq(unit, dist[inl] - radius, rcond=None)
            c = c + step
            if float(np.hypot(*step)) < 1e-3:
                break
    return float(c[0]), float(c[1])


def luma_support(gray, log_odds, centre, radius: float, *, min_contrast: float = 8.0, tol_px: float = 0.5):
    """How well a circle lies on the luma rim: the fraction of its rays with an edge point within ``tol_px`` of it,
    and the widest angular gap between those points (radians; 2 pi when there are none).

    Parameters
    ----------
    gray, log_odds, centre, radius, min_contrast
        As for :func:`~tudorvision.stereo.rim_edge.luma_rim_points` (rays 3 px either side of the circle).
    tol_px : float
        Largest distance of an edge point from the circle, pixels.

    Returns
    -------
    fraction : float
    max_gap_rad : float

    Examples
    --------
    >>> yy, xx = np.mgrid[0:40, 0:40]
    >>> disc = np.clip(10.5 - np.hypot(xx - 20.0, yy - 20.0), 0, 1)
    >>> gray = (60 + 100 * disc).astype(np.float32)
    >>> gray[:, 20:] = 60 + 100 * disc[:, 20:] * 0.05        # only the left half of the rim has contrast
    >>> frac, gap = luma_support(gray, None, (20.0, 20.0), 10.0)
    >>> round(frac, 2), round(float(np.degrees(gap)))
    (0.48, 191)
    """
    pts, n = luma_rim_points(gray, log_odds, centre, radius, min_contrast=min_contrast)
    on = np.abs(np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1]) - radius) < tol_px
    if not np.any(on):
        return 0.0, 2.0 * math.pi
    ang = np.sort(np.arctan2(pts[on, 1] - centre[1], pts[on, 0] - centre[0]))
    gaps = np.diff(np.concatenate([ang, ang[:1] + 2.0 * math.pi]))
    return float(np.count_nonzero(on)) / n, float(gaps.max())


def refine_circle_on_luma_at_radius(gray, log_odds, centre, radius: float, *, min_contrast: float = 8.0,
                                    min_fraction: float = 0.5):
    """The luma rim circle of a sphere whose radius is known (the other camera's), from an off centre, or None.

    A view measured on its colour (chroma edge or colour rim) can sit 1-3 px off the sphere while its radius
    is about right (a background of the sphere's colour on one side);
    :func:`~tudorvision.stereo.rim_edge.refine_circle_on_luma` from that circle then fails (fewer than half of
    its rays on one circle). With the radius given, the centre alone is fitted to the luma edge points
    (trimming bands 3, 1.5, 1 and 0.5 px), which moves it onto the rim; the result is accepted only as a start
    from which the ordinary refine converges, radius free
    (:func:`~tudorvision.stereo.rim_edge.refine_luma_from_first_fit`).

    Parameters
    ----------
    gray, log_odds, centre, min_contrast
        As for :func:`~tudorvision.stereo.rim_edge.luma_rim_points`.
    radius : float
        The sphere's apparent radius in this view (pixels), e.g. predicted from the other camera's.
    min_fraction : float
        Smallest fraction of the rays within 0.5 px of the final circle. Below one half, those rays must
        also spread around the circle (no gap of half a turn or more between them).

    Returns
    -------
    tuple or None
        ``(u, v, r, inlier_fraction, rms_px)`` in window pixels, as
        :func:`~tudorvision.stereo.rim_edge.refine_circle_on_luma`.

    Examples
    --------
    >>> yy, xx = np.mgrid[0:80, 0:80]
    >>> disc = np.clip(20.5 - np.hypot(xx - 41.3, yy - 38.6), 0, 1)
    >>> gray = (60 + 100 * disc).astype(np.float32)
    >>> gray[:, 55:] = 60 + 100 * disc[:, 55:] * 0.05        # the right side of the rim has no contrast
    >>> from tudorvision.stereo.rim_edge import refine_circle_on_luma
    >>> refine_circle_on_luma(gray, None, (39.0, 39.5), 21.0) is None
    True
    >>> u, v, r, frac, rms = refine_circle_on_luma_at_radius(gray, None, (39.0, 39.5), 20.0)
    >>> round(u, 1), round(v, 1), round(r, 1)
    (41.3, 38.6, 20.0)
    """
    def first_fit(pts):
        c = _centre_at_radius(pts, centre, float(radius), (3.0, 1.5, 1.0, 0.5))
        return None if c is None else (c[0], c[1], radius)

    # from an off start fewer rays find the rim (0.35 of them suffice); the final refine asks min_fraction
    fit = refine_luma_from_first_fit(gray, log_odds, centre, radius, first_fit, min_fraction=0.35,
                                     min_contrast=min_contrast, fit_min_fraction=min_fraction)
    if fit is None or min_fraction >= 0.5:
        return fit
    _, gap = luma_support(gray, log_odds, fit[:2], fit[2], min_contrast=min_contrast)
    return fit if gap < math.pi else None


def chroma_view_at_radius(frame_bgr, model: ColorModel, det: SphereDetection, want_px: float,
                          agree: Agree) -> SphereDetection | None:
    """The view ``det`` measured again on its chroma edge at the predicted radius, or None.

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        The view's image.
    model : ColorModel
        The sphere's colour model in this camera (its mean colour gives the chroma).
    det : SphereDetection
        The view's detection.
    want_px : float
        The radius the other view predicts here, pixels.
    agree : callable
        ``agree(uv, radius_px)`` -> the log radius mismatch when the pair is consistent, else None.

    Returns
    -------
    SphereDetection or None
        ``det`` with the new centre, ``method="chroma"`` and the circle's radius: of the circles started at
        the detection and at four points ``want_px / 2`` from it, the one that agrees best.
    """
    chroma = sphere_chroma(tuple(model.mean[:3]))
    u0, v0 = det.uv
    best, seen = None, []
    for du, dv in ((0.0, 0.0), (0.5, 0.0), (-0.5, 0.0), (0.0, 0.5), (0.0, -0.5)):
        circle = chroma_circle(np.asarray(frame_bgr), chroma, (u0 + du * want_px, v0 + dv * want_px), want_px)
        if circle is None or any(math.hypot(circle[0] - a, circle[1] - b) < 0.05 for a, b in seen):
            continue
        seen.append(circle[:2])
        mis = agree((circle[0], circle[1]), circle[2])
        if mis is not None and (best is None or mis < best[0]):
            best = (mis, replace(det, uv=(circle[0], circle[1]), method="chroma", circle_radius_px=circle[2]))
    return None if best is None else best[1]


def luma_view_at_radius(frame_bgr, model: ColorModel, det: SphereDetection, want_px: float, agree: Agree, *,
                        min_contrast: float = 8.0, relax: bool = True) -> SphereDetection | None:
    """The view ``det`` measured again on its luma rim, started at the predicted radius, or None.

    Half of the rays must lie on the new circle; for a view of ``RELAXED_MIN_PX`` or more, ``RELAXED_FRACTION``
    of them under the guards described there. When nothing is found from the view's own centre (and ``relax``),
    the search starts again half a predicted radius from it in eight directions (half of the rays on the
    circle), for a colour circle that took some background of its colour and sits several pixels off; a circle
    is kept only when two starts reach it (within ``WIDER_SAME_PX``), of those the one the pair agrees with
    best. Sphere family: docs/benchmarks.md, "Issue 15: a luma rim partly hidden,
    and a colour circle several pixels off".

    Parameters
    ----------
    frame_bgr, model, det, want_px, agree
        As for :func:`chroma_view_at_radius`; ``model`` gives the colour gate of the luma edge points.
    min_contrast : float
        Smallest luma contrast of a ray (``SegmentParams.edge_min_contrast``).
    relax : bool
        Whether the relaxed fraction and the wider starts may be used at all: only when ``want_px`` comes from
        a view on its luma rim (two colour views give no radius to trust that far; on the sphere family such a
        pair went wrong).

    Returns
    -------
    SphereDetection or None
        ``det`` with the luma circle's centre and radius and ``method="edge"``.

    Examples
    --------
    >>> yy, xx = np.mgrid[0:80, 0:80]
    >>> disc = np.clip(15.5 - np.hypot(xx - 40.3, yy - 38.6), 0, 1)[..., None]
    >>> img = (disc * [40, 40, 200] + (1 - disc) * [90, 110, 120]).astype(np.uint8)
    >>> img[:, 50:] = (disc[:, 50:] * [60, 70, 150] + (1 - disc[:, 50:]) * [60, 70, 150]).astype(np.uint8)
    >>> model = ColorModel(mean=[200, 40, 40, 0, 200, 200], std=[12] * 6, background=np.ones((6, 256)),
    ...                    prior=0.05)
    >>> off = SphereDetection(uv=(38.5, 39.4), area_px=700.0, mean_prob=0.9, circularity=0.9, valid=True,
    ...                       method="chroma", circle_radius_px=15.6)
    >>> new = luma_view_at_radius(img, model, off, 15.0, lambda uv, r: 0.0)
    >>> new.method, round(new.uv[0], 1), round(new.uv[1], 1)
    ('edge', 40.3, 38.6)
    """
    wider = relax and want_px >= RELAXED_MIN_PX
    may_relax = wider and not det.circle_radius_px > (1.0 + RELAXED_MAX_EXCESS) * want_px
    # one window (luma and log-odds) for every start: the own centre's and, if needed, the wider ones
    h, w = frame_bgr.shape[:2]
    u0, v0 = det.uv
    m = int(math.ceil((1.5 if wider else 1.0) * want_px)) + 7
    x0, y0 = max(int(u0) - m, 0), max(int(v0) - m, 0)
    x1, y1 = min(int(u0) + m + 1, w), min(int(v0) + m + 1, h)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return None
    win = np.ascontiguousarray(frame_bgr[y0:y1, x0:x1])
    gray = cv2.cvtColor(win, cv2.COLOR_BGR2GRAY).astype(np.float32)
    log_odds = log_odds_image(win, model)

    def near(u, v, min_fraction):
        return _luma_circle_near(gray, log_odds, (x0, y0), (u, v), want_px, agree, min_contrast, min_fraction)

    got = near(u0, v0, RELAXED_FRACTION if may_relax else 0.5)
    if got is None and wider:
        # a colour circle several pixels off (it took some background of its colour): started half a radius
        # from it in eight directions, half of the rays on the circle, the start that agrees best
        found = [t for du, dv in _WIDER_STARTS if (t := near(u0 + du * want_px, v0 + dv * want_px, 0.5)) is not None]
        # a rim found from one start only may be a shading or blur edge: two starts must reach the same circle
        agreed = [t for t in found if sum(math.hypot(t[1][0] - o[1][0], t[1][1] - o[1][1]) < WIDER_SAME_PX
                                          for o in found) >= 2]
        got = min(agreed, key=lambda t: t[0], default=None)
    if got is None:
        return None
    return replace(det, uv=got[1], method="edge", circle_radius_px=got[2])


#: Circles found from two of the wider starts whose centres lie within this (px) are the same circle.
WIDER_SAME_PX = 0.3
#: Starts of the wider search of :func:`luma_view_at_radius`, in predicted radii from the colour circle.
_WIDER_STARTS = tuple((0.5 * math.cos(a), 0.5 * math.sin(a)) for a in np.arange(8) * (math.pi / 4))


def _luma_circle_near(gray, log_odds, offset, centre_uv, want_px: float, agree: Agree, min_contrast: float,
                      min_fraction: float):
    """``(mismatch, (u, v), r)`` of the luma circle found from ``centre_uv`` (image pixels) at ``want_px`` that the
    pair agrees with, or None (the relaxed guards of :data:`RELAXED_MIN_PX` apply when fewer than half its rays
    fit). ``gray``, ``log_odds``: the window whose top-left pixel is ``offset`` in the image."""
    x0, y0 = offset
    start = (centre_uv[0] - x0, centre_uv[1] - y0)
    fit = refine_circle_on_luma_at_radius(gray, log_odds, start, want_px, min_contrast=min_contrast,
                                          min_fraction=min_fraction)
    if fit is None:
        return None
    relaxed = fit[3] < 0.5
    if relaxed and fit[3] < luma_support(gray, log_odds, start, fit[2], min_contrast=min_contrast)[0] + \
            RELAXED_SUPPORT_MARGIN:
        return None                      # the old centre lies about as well on the luma rim
    uv = (fit[0] + x0, fit[1] + y0)
    mis = agree(uv, fit[2])
    if mis is None or (relaxed and mis > RELAXED_MAX_MISMATCH):
        return None
    return mis, uv, fit[2]
