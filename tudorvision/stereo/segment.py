"""Sphere segmentation: naive Bayes probability image, erosion, region growing, centroid.

The pipeline of section 2.4, per camera and sphere:

1. **Probability image.** Naive Bayes over the six channels R, G, B, H, S, V:
   ``log_odds = log_prior_odds + sum_c llr_c(x_c)`` with the per-channel
   log-likelihood-ratio tables of :class:`~tudorvision.stereo.colormodel.ColorModel`
   applied by ``cv2.LUT`` to the six 8-bit planes B, G, R, H, S, V and
   summed in float32 (no per-pixel Gaussian is evaluated; the HSV image and
   the planes are computed once per frame and shared between spheres). The
   posterior probability is ``sigmoid(log_odds)``; thresholds are applied to
   the log-odds, so the sigmoid is evaluated only inside candidate regions.
2. **Seeds.** Pixels with probability >= ``p_seed``, eroded by a disc of
   radius ``erode_radius_px`` (removes isolated clutter pixels).
3. **Region growing.** Every 8-connected region of pixels with probability
   >= ``p_grow`` that contains a seed (hysteresis thresholding, computed
   with ``cv2.connectedComponentsWithStats``).
4. **Centroid.** Holes enclosed by the region (a specular highlight, a
   marking) are filled: the region is the sphere's silhouette. Its first
   moment, each pixel weighted by its probability (``weighting="probability"``,
   default: rim pixels that mix sphere and background count partially, which
   gives sub-pixel accuracy; filled hole pixels count fully) or equally
   (``"binary"``). Image coordinates: ``u`` right, ``v`` down, pixel
   centres at integer coordinates (OpenCV). Under motion blur the region is
   the part of the streak that passes the thresholds; the streak is
   symmetric about the mid-exposure position, so its first moment is the
   mean position over the exposure.
4b. **Shape refinement** (``centroid="shape"``, default). The moment measures
   only what passes the thresholds: a bar or link in front of the sphere, a
   dark shaded rim below ``p_grow`` or a bright, desaturated cap the colour
   model rejects move it toward the visible part (0.5-1.5 px on the virtual
   lab). The region is grown by the pixels within 2 px of it at probability
   >= ``rim_prob`` (0.5: the shaded rim), the outer contour of the result
   (pixel centres) is the rim, and a circle is fitted to it robustly:
   candidate circles through triples of rim points spread along the contour
   are scored by the points within ``max(rim_tol_px, rim_tol_frac * r)`` minus twice those clearly
   outside (hidden or missed parts only remove silhouette, so true rim points
   hardly lie outside), and the best is refined by least squares on its
   inliers. Its centre is the position (the silhouette of a sphere is close
   to a circle at these sizes; an ellipse's centroid is its centre). When the
   circle explains fewer than ``min_rim_fraction`` of the rim points or its
   radius does not fit the area, the moment is kept. ``rim_fraction`` and
   ``rim_rms_px`` of the detection give the fit's quality, ``method`` which
   was used, ``uv_moment`` the moment. Below ``chroma_edge_below`` (0.8) of the rim
   (a highlight, a shaded limb, fingers) the rim is searched again on the chroma
   edge along rays (:func:`~tudorvision.stereo.rim_edge.refine_circle_on_chroma`, ``"chroma"``).
4c. **Luma edge** (``edge_refine=True``, with ``centroid="shape"``; off by
   default, since it about doubles the cost of a detection; the CLI turns it
   on for JPEG and video recordings, ``--luma-edge``).
   JPEG's 4:2:0 chroma subsampling smears the colour rim by about a pixel;
   from the circle so far the rim is located again on the full-resolution
   luma along rays (:mod:`~tudorvision.stereo.rim_edge`), used when it explains half of the rays
   within 1.5 px of that circle (``method="edge"``); spheres of 12 px or more that the chroma edge
   missed are searched 0.35 radii either side (``refine_circle_on_luma_wide``).
   Blurred streaks (``motion_blur``) keep the moment; the tracker switches
   fast, smoothly moving spheres to the moment of the grown region
   (``"rim_moment"``): a streak's core is a lens of two arcs.
5. **Quality and plausibility.** Area, mean probability, circularity and a
   fill ratio from the region's second moments; regions outside the limits
   of :class:`SegmentParams` are rejected with a reason. The best region is
   the valid one with the largest probability mass (the tracker instead takes
   the valid one nearest its prediction).

Full frames are searched coarse to fine (``SegmentParams.coarse_step``):
candidates on a decimated frame, then the steps above at full resolution in a
window around each; windows (``roi``) are searched at full resolution.

Shape measures (area and the central second moments of the filled region,
eigenvalues ``lam1 >= lam2`` of its pixel covariance):

- ``circularity = sqrt(lam2 / lam1)``: 1 for a disc, ``1/elongation`` for
  an ellipse or a blur streak. It does not suffer from the pixel-staircase
  perimeter of ``4 pi A / P^2`` on small blobs.
- ``fill = area / (4 pi sqrt(lam1 lam2))``: 1 for a filled ellipse (any
  elongation), about 0.95 for a rectangle, less for rings, crescents and
  ragged clutter.

Motion blur: a streak mixes the sphere's colour with the background's (a
pixel in the middle of a streak of length ``L`` sees the sphere for at most
``d / L`` of the exposure), which mostly moves R, G, B, S and V, much less the
hue. With ``motion_blur=True`` (per call, or by the tracker when the strict
tables find nothing in the window of a fast sphere) the log-odds come from the
model's blur-tolerant tables
(``ColorModel.plane_tables_blur``: spreads of at least ``blur_min_std``
levels, hue kept tight) and the circularity limit drops to
``min_circularity_blur`` (a streak of length ``L`` behind a sphere of diameter
``d`` has circularity of roughly ``d / (d + L)``) while the fill check still
requires a compact, convex-looking blob. On synthetic frames this keeps
streaks of up to about 1.5 diameters valid with the centroid at the
mid-exposure position (0.1-0.2 px). The tolerant tables also accept darker
objects of the sphere's hue (a blurred red sphere *is* a darker red), so use
them in a window around the predicted position (tracking mode) rather than on
full frames with such clutter.
"""
from __future__ import annotations

import math
from typing import Mapping

import cv2
import numpy as np

from tudorvision._checks import TudorVisionError
from tudorvision.stereo._circle import circle_lsq, fit_rim_circle
from tudorvision.stereo._coarse import coarse_boxes, coarse_log_odds_q, lut_sum
from tudorvision.stereo._colortables import ColorModel
from tudorvision.stereo._frame import FramePlanes, check_frame
from tudorvision.stereo.detection import SegmentParams, SphereDetection
from tudorvision.stereo.rim_edge import (WIDE_LUMA_MIN_PX, chroma_circle, refine_circle_on_luma,
                                        refine_circle_on_luma_wide, sphere_chroma)

__all__ = ["SegmentParams", "SphereDetection", "hsv_from_bgr", "log_odds_image", "probability_image", "detect_sphere",
           "detect_spheres"]

_CCL = getattr(cv2, "CCL_GRANA", 1)  # block-based 8-connectivity: fastest on sparse masks

_NOTHING = "no pixel above p_seed survives erosion"
#: In a full-frame search, coarse candidates lighter (area x mean probability) than a valid region already
#: found divided by this factor are not examined at full resolution: they could not be picked over it.
_LIGHTER_CANDIDATE = 4.0


def _none(reason: str = _NOTHING) -> SphereDetection:
    return SphereDetection(uv=(math.nan, math.nan), area_px=0.0, mean_prob=0.0, circularity=0.0, valid=False,
                           reason=reason)


def _logit(p: float) -> float:
    return math.log(p / (1.0 - p))


def _log_odds_planes(planes, model: ColorModel, blur: bool = False) -> np.ndarray:
    acc = lut_sum(planes, model.plane_tables_blur if blur else model.plane_tables, model.use_hue)
    acc += np.float32(model.log_prior_odds)
    return acc


def hsv_from_bgr(frame_bgr) -> np.ndarray:
    """OpenCV 8-bit HSV of a BGR frame (H in 0..179, S and V in 0..255).

    Compute it once per frame and pass it as ``hsv=`` to the functions of this
    module to share it between spheres.
    """
    return cv2.cvtColor(check_frame(frame_bgr), cv2.COLOR_BGR2HSV)


def log_odds_image(frame_bgr, model: ColorModel, *, hsv=None) -> np.ndarray:
    """Naive Bayes log posterior odds ``log P(sphere|x) / P(background|x)`` per pixel.

    ``log_prior_odds + sum over R, G, B, H, S, V of the model's clipped
    per-channel log-likelihood ratio`` (six ``cv2.LUT`` look-ups and adds).

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        BGR frame.
    model : ColorModel
        The sphere's colour model.
    hsv : ndarray, shape (H, W, 3), uint8, optional
        ``hsv_from_bgr(frame_bgr)`` if already computed.

    Returns
    -------
    ndarray, shape (H, W), float32
    """
    frame = FramePlanes.checked(frame_bgr, hsv)
    return _log_odds_planes(frame.full_planes(), model)


def probability_image(frame_bgr, model: ColorModel, *, hsv=None) -> np.ndarray:
    """Posterior probability that each pixel shows the sphere.

    Returns
    -------
    ndarray, shape (H, W), float32
        Values in [0, 1]: ``1 / (1 + exp(-log_odds_image(...)))``.

    Examples
    --------
    >>> import cv2
    >>> from tudorvision.stereo.colormodel import fit_color_model
    >>> img = np.full((60, 80, 3), 90, np.uint8)
    >>> _ = cv2.circle(img, (40, 30), 10, (40, 40, 200), -1)
    >>> p = probability_image(img, fit_color_model(img, (40, 30), (50, 30)))
    >>> bool(p[30, 40] > 0.99), bool(p[5, 5] < 0.01)
    (True, True)
    """
    lo = log_odds_image(frame_bgr, model, hsv=hsv)
    with np.errstate(over="ignore"):
        return (1.0 / (1.0 + np.exp(-lo))).astype(np.float32)


_KERNELS = {}


def _erode_kernel(r: int):
    if r not in _KERNELS:   # built once per radius, not per frame
        _KERNELS[r] = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return _KERNELS[r]


def _fill_holes(mask: np.ndarray) -> np.ndarray:
    """``mask`` (bool, h x w) with every hole it encloses filled (4-connected background)."""
    h, w = mask.shape
    pad = np.zeros((h + 2, w + 2), np.uint8)
    pad[1:-1, 1:-1] = mask
    cv2.floodFill(pad, None, (0, 0), 1)  # everything outside the region becomes 1
    return mask | (pad[1:-1, 1:-1] == 0)


def _candidates(log_odds: np.ndarray, params: SegmentParams, offset: tuple, image_size: tuple,
                blur: bool, *, erode: int, edge_src=None) -> list:
    """Seeds, region growing, centroid and checks on a log-odds window.

    ``offset`` = (x0, y0) of the window in frame pixels, ``image_size`` = (W, H)
    of the frame, ``edge_src`` the frame's :class:`_EdgeSource` for the luma
    edge (None skips it). Returns every seeded region as a SphereDetection, best first
    (valid before invalid, then by probability mass).
    """
    seeds = cv2.compare(log_odds, _logit(params.p_seed), cv2.CMP_GE)
    if erode > 0:
        seeds = cv2.erode(seeds, _erode_kernel(erode))
    if cv2.countNonZero(seeds) == 0:
        return []
    grow = cv2.compare(log_odds, _logit(params.p_grow), cv2.CMP_GE)
    n, labels, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(grow, 8, cv2.CV_32S, _CCL)
    hh, ww = log_odds.shape
    x0, y0 = offset
    img_w, img_h = image_size
    min_circ = params.min_circularity_blur if blur else params.min_circularity
    out = []
    for k in range(1, n):
        x, y, w, h, area = (int(s) for s in stats[k])
        lab = labels[y:y + h, x:x + w] == k
        if not seeds[y:y + h, x:x + w][lab].any():
            continue  # no seed inside: not grown
        p_box = 1.0 / (1.0 + np.exp(-log_odds[y:y + h, x:x + w].astype(np.float64)))
        mean_prob = float(p_box[lab].mean())
        # the silhouette: holes enclosed by the region (a specular highlight, markings) belong to it
        filled = _fill_holes(lab)
        area = int(np.count_nonzero(filled))
        mb = cv2.moments(filled.view(np.uint8), True)         # one C pass instead of pixel lists
        if params.weighting == "probability":
            mw = cv2.moments(np.where(lab, p_box, filled.astype(np.float64)))     # holes weigh 1
        else:
            mw = mb
        mass, mu, mv = mw["m00"], mw["m10"], mw["m01"]
        cu = mu / mass + (x + x0)
        cv_ = mv / mass + (y + y0)
        uv_moment = (cu, cv_)
        # shape from the binary central second moments; +1/12: pixels are unit squares
        suu = mb["mu20"] / area + 1.0 / 12.0
        svv = mb["mu02"] / area + 1.0 / 12.0
        suv = mb["mu11"] / area
        tr, det = suu + svv, suu * svv - suv * suv
        disc = math.sqrt(max(tr * tr / 4.0 - det, 0.0))
        lam1, lam2 = tr / 2.0 + disc, max(tr / 2.0 - disc, 1e-12)
        circ = math.sqrt(lam2 / lam1)
        fill = area / (4.0 * math.pi * math.sqrt(lam1 * lam2))
        on_left, on_top, on_right, on_bottom = x == 0, y == 0, x + w == ww, y + h == hh
        at_image = ((on_left and x0 == 0) or (on_top and y0 == 0)
                    or (on_right and x0 + ww == img_w) or (on_bottom and y0 + hh == img_h))
        at_window = ((on_left and x0 > 0) or (on_top and y0 > 0)
                     or (on_right and x0 + ww < img_w) or (on_bottom and y0 + hh < img_h))
        reason = ""
        if area < params.min_area_px:
            reason = f"area {area} px < min_area_px {params.min_area_px:g}"
        elif area > params.max_area_px:
            reason = f"area {area} px > max_area_px {params.max_area_px:g}"
        elif mean_prob < params.min_mean_prob:
            reason = f"mean probability {mean_prob:.2f} < min_mean_prob {params.min_mean_prob:g}"
        elif circ < min_circ:
            reason = (f"circularity {circ:.2f} < {min_circ:g} (not round"
                      f"{'' if blur else '; motion blur not expected'})")
        elif not (params.min_fill <= fill <= params.max_fill):
            reason = f"fill {fill:.2f} outside [{params.min_fill:g}, {params.max_fill:g}] (not a compact blob)"
        elif params.reject_border and at_image:
            reason = "region touches the image border (sphere partly out of view)"
        rim_frac = rim_rms = r_fit = float("nan")
        method = "moment"
        if params.centroid == "rim_moment" and not reason:
            rm = _rim_mask(filled, params, (x, y), log_odds)
            (ru, rv), (sx, sy) = rm[1], rm[2]
            cu, cv_, method = ru + sx + x0, rv + sy + y0, "rim_moment"
        if params.centroid == "shape" and not blur and not reason and area >= 20:
            # only for valid regions: the fit costs about as much as the rest of the segmentation
            ref = _refine_shape(filled, math.sqrt(area / math.pi), params, (x, y), log_odds,
                                (mu / mass, mv / mass))
            start = ((mu / mass + x, mv / mass + y), math.sqrt(area / math.pi))
            used = False
            if ref is not None:
                ru, rv, rr, rim_frac, rim_rms, used = ref
                if used:
                    cu, cv_, method, r_fit = ru + x0, rv + y0, "shape", rr
                    start = ((ru, rv), rr)
            below = params.chroma_edge_below
            if below > 0 and area >= math.pi * params.chroma_edge_large_px ** 2:
                below = max(below, params.chroma_edge_below_large)
            if edge_src is not None and below > 0 and not (used and rim_frac >= below and below < 1.0):
                ch = edge_src.refine_chroma((start[0][0] + x0, start[0][1] + y0), start[1])
                if ch is not None:
                    cu, cv_, method, r_fit = ch[0], ch[1], "chroma", ch[2]
                    start = ((ch[0] - x0, ch[1] - y0), ch[2])
            if params.edge_refine and edge_src is not None:     # wide: a large sphere the chroma edge missed
                wide = method in ("shape", "moment") and area >= math.pi * WIDE_LUMA_MIN_PX ** 2
                edge = edge_src.refine((start[0][0] + x0, start[0][1] + y0), start[1], params, wide=wide)
                if edge is not None:
                    cu, cv_, method, r_fit = edge[0], edge[1], "edge", edge[2]
        out.append(SphereDetection(uv=(cu, cv_), area_px=float(area), mean_prob=mean_prob, circularity=circ,
                                   valid=not reason, reason=reason, fill=fill,
                                   bbox=(x + x0, y + y0, w, h), touches_window=at_window,
                                   uv_moment=uv_moment, rim_fraction=rim_frac, rim_rms_px=rim_rms,
                                   method=method, circle_radius_px=r_fit, blur=bool(blur)))
    out.sort(key=lambda d: (d.valid, d.area_px * d.mean_prob), reverse=True)
    return out


def _rim_mask(filled, params, box_xy, log_odds, moment=True):
    """The silhouette grown by the pixels within 2 px of it at probability >= ``rim_prob``.

    Returns ``(mask uint8, (u, v) moment in mask coordinates or None, (x0, y0) of the mask in the window)``.
    """
    bx, by = box_xy
    mg = 2
    hh, ww = log_odds.shape
    sx0, sy0 = max(bx - mg, 0), max(by - mg, 0)
    sx1, sy1 = min(bx + filled.shape[1] + mg, ww), min(by + filled.shape[0] + mg, hh)
    reg = cv2.copyMakeBorder(filled.view(np.uint8), by - sy0, sy1 - by - filled.shape[0], bx - sx0,
                             sx1 - bx - filled.shape[1], cv2.BORDER_CONSTANT, value=0)
    low = cv2.compare(log_odds[sy0:sy1, sx0:sx1], _logit(params.rim_prob), cv2.CMP_GE)   # 0 / 255
    grown = cv2.bitwise_or(reg, cv2.bitwise_and(cv2.dilate(reg, _erode_kernel(mg)), low))  # 0 / 1
    # fill the holes: whatever the outside (flooded from the padded corner) does not reach
    pad = cv2.copyMakeBorder(grown, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    cv2.floodFill(pad, None, (0, 0), 2)
    mask = cv2.compare(pad[1:-1, 1:-1], 2, cv2.CMP_NE)                                    # 0 / 255
    uv = None
    if moment:
        m = cv2.moments(mask, True)
        uv = (m["m10"] / m["m00"], m["m01"] / m["m00"])
    return mask, uv, (sx0, sy0)


def _refine_shape(filled: np.ndarray, r_area: float, params: SegmentParams, box_xy: tuple,
                  log_odds: np.ndarray, moment_uv: tuple):
    """The sphere's image centre from a circle fitted robustly to the region's rim.

    ``filled``: the silhouette (bool, its bounding box at ``box_xy`` in the
    log-odds window ``log_odds``); ``r_area``: the radius of its area.
    The rim is the outer contour (pixel centres) of the silhouette extended
    by the pixels within 2 px of it whose probability is at least
    ``params.rim_prob`` (the dark, shaded rim that misses ``p_grow``).
    Returns ``(u, v, r, rim fraction, rim RMS, used)`` in window coordinates,
    ``used`` False when the circle explains too few rim points or its radius
    does not fit the area, or None when no circle could be fitted.
    """
    bx, by = box_xy
    rim_mask, _, (sx0, sy0) = _rim_mask(filled, params, box_xy, log_odds, moment=False)
    sx0, sy0 = sx0 - bx, sy0 - by
    cs, _ = cv2.findContours(rim_mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not cs:
        return None
    c = max(cs, key=len)
    if len(c) < 12:
        return None
    pts = c.reshape(-1, 2).astype(np.float64) + (sx0, sy0)
    tol = max(params.rim_tol_px, params.rim_tol_frac * r_area)
    fit = fit_rim_circle(pts, tol)
    if fit is None:
        return None
    fu, fv, fr, inl = fit
    n_in = int(np.count_nonzero(inl))
    frac = n_in / len(inl)
    res = np.hypot(pts[:, 0] - fu, pts[:, 1] - fv) - fr
    rms = math.sqrt(float(res @ (res * inl)) / n_in)
    used = frac >= params.min_rim_fraction and r_area - 1.5 <= fr <= 2.0 * r_area + 1.0
    if used and params.lens_check and len(inl) - int(inl.sum()) >= 6:
        # a blur streak's core (where the sphere covers the pixel all the exposure) is a lens: the
        # intersection of the discs at the start and the end of the exposure, two arcs of the same
        # radius. The circle then fits one of them; the lens is symmetric about the mid-exposure
        # position, so its moment is the right measure.
        ou, ov, orr = circle_lsq(pts[~inl])
        if (math.isfinite(orr) and 0.6 * fr <= orr <= 1.6 * fr and math.hypot(ou - fu, ov - fv) < fr
                and float(np.sqrt(np.mean((np.hypot(pts[~inl, 0] - ou, pts[~inl, 1] - ov) - orr) ** 2)))
                < tol):
            # and the region's moment sits halfway between the two centres
            mu_, mv_ = moment_uv
            sep = math.hypot(ou - fu, ov - fv)
            used = math.hypot(mu_ - 0.5 * (ou + fu), mv_ - 0.5 * (ov + fv)) > 0.25 * sep + 0.3
    return fu + bx, fv + by, fr, frac, rms, used


def _edge_source(frame, model, params, blur):
    """The frame's :class:`_EdgeSource` when the luma or the chroma edge may be asked for, else None."""
    return _EdgeSource(frame, model, blur) if params.edge_refine or params.chroma_edge_below > 0 else None


class _EdgeSource:
    """Luma and log-odds patches of the full frame for the luma edge (step 4c), private.

    Taken from the full frame (not the searched window) so that tracking
    windows and full-frame search give the same result.
    """

    def __init__(self, frame: FramePlanes, model: ColorModel, blur: bool):
        self.frame, self.model, self.blur = frame, model, blur

    def refine(self, centre: tuple, radius: float, params: SegmentParams, wide: bool = False):
        """Circle ``(u, v, r)`` on the luma edge in frame pixels, or None (``wide``: then searched wider)."""
        f = self.frame
        m = int(math.ceil(radius * (1.35 if wide else 1.0))) + 7
        px0, py0 = max(int(centre[0]) - m, 0), max(int(centre[1]) - m, 0)
        px1, py1 = min(int(centre[0]) + m + 1, f.width), min(int(centre[1]) + m + 1, f.height)
        if px1 - px0 < 4 or py1 - py0 < 4:
            return None
        gray = cv2.cvtColor(f.bgr[py0:py1, px0:px1], cv2.COLOR_BGR2GRAY).astype(np.float32)
        lo = _log_odds_planes(f.window_planes(px0, py0, px1 - px0, py1 - py0), self.model, self.blur)
        fit = refine_circle_on_luma(gray, lo, (centre[0] - px0, centre[1] - py0), radius,
                                    min_contrast=params.edge_min_contrast)
        if fit is None and wide:
            fit = refine_circle_on_luma_wide(gray, lo, (centre[0] - px0, centre[1] - py0), radius,
                                             min_contrast=params.edge_min_contrast)
        if fit is None:
            return None
        return fit[0] + px0, fit[1] + py0, fit[2]

    def refine_chroma(self, centre: tuple, radius: float):
        """Circle ``(u, v, r)`` on the sphere's chroma edge in frame pixels (step 4b), or None."""
        cache = self.frame.results      # the windows of a full-frame search find the same region again
        key = ("chroma", id(self.model), round(centre[0], 6), round(centre[1], 6), round(radius, 6))
        if key not in cache:
            cache[key] = self._refine_chroma(centre, radius)
        return cache[key]

    def _refine_chroma(self, centre: tuple, radius: float):
        return chroma_circle(self.frame.bgr, sphere_chroma(tuple(self.model.mean[:3])), centre, radius)


def _check_roi(roi, width: int, height: int) -> tuple:
    try:
        x, y, w, h = (int(v) for v in roi)
    except (TypeError, ValueError):
        raise TudorVisionError(f"roi: expected (x, y, w, h) integers, got {roi!r}") from None
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + w, width), min(y + h, height)
    if x1 - x0 < 1 or y1 - y0 < 1:
        raise TudorVisionError(f"roi: window {roi!r} does not overlap the {width}x{height} image")
    return x0, y0, x1 - x0, y1 - y0


def regions_in_window(frame: FramePlanes, model: ColorModel, params: SegmentParams, roi: tuple,
                      blur: bool) -> list:
    """Every seeded region of one sphere in a window of a frame, at full resolution, best first.

    For the trackers and the stereo pipeline, which share one
    :class:`~tudorvision.stereo._frame.FramePlanes` between spheres; not in
    ``__all__``.

    Parameters
    ----------
    frame : FramePlanes
        The frame and its cached planes.
    model : ColorModel
        The sphere's colour model for this camera.
    params : SegmentParams
        Thresholds and limits.
    roi : tuple of int
        Window ``(x, y, w, h)`` in frame pixels, already inside the frame.
    blur : bool
        Use the model's blur-tolerant tables and ``min_circularity_blur``.

    Returns
    -------
    list of SphereDetection
        Valid regions before invalid ones, then by probability mass; ``uv``
        in full-frame pixels.
    """
    x0, y0, w, h = roi
    lo = _log_odds_planes(frame.window_planes(x0, y0, w, h), model, blur)
    return _candidates(lo, params, (x0, y0), (frame.width, frame.height), blur,
                       erode=int(params.erode_radius_px), edge_src=_edge_source(frame, model, params, blur))


def _grow_roi(bbox, margin: int, width: int, height: int) -> tuple:
    x, y, w, h = bbox
    x0, y0 = max(x - margin, 0), max(y - margin, 0)
    x1, y1 = min(x + w + margin, width), min(y + h + margin, height)
    return x0, y0, x1 - x0, y1 - y0


def _cut_along_length(det: SphereDetection, roi: tuple, params: SegmentParams, blur: bool) -> bool:
    """An elongated invalid region that the window cuts only across its length: widening keeps it elongated."""
    min_circ = params.min_circularity_blur if blur else params.min_circularity
    if det.valid or not det.circularity < 0.5 * min_circ:
        return False
    (x, y, w, h), (rx, ry, rw, rh) = det.bbox, roi
    cut_x, cut_y = x == rx or x + w == rx + rw, y == ry or y + h == ry + rh
    return (h > 2 * w and cut_y and not cut_x) or (w > 2 * h and cut_x and not cut_y)


def _detect_full(frame: FramePlanes, model: ColorModel, params: SegmentParams, blur: bool) -> SphereDetection:
    step = int(params.coarse_step)
    if step == 1:
        lo = _log_odds_planes(frame.full_planes(), model, blur)
        found = _candidates(lo, params, (0, 0), (frame.width, frame.height), blur,
                            erode=int(params.erode_radius_px), edge_src=_edge_source(frame, model, params, blur))
        return found[0] if found else _none()
    # coarse pass on the decimated frame, no erosion (it would erase small spheres there)
    lo_q = coarse_log_odds_q(frame.coarse_planes(step), model, blur)
    coarse = coarse_boxes(lo_q, model.log_prior_odds, params.p_seed, params.p_grow, step)
    best = []   # the heaviest max_candidates, then further ones (up to 4x) while none is valid
    heaviest_valid = 0.0
    margin = 2 * step + int(params.erode_radius_px) + 2
    for k, (bbox, mass) in enumerate(coarse[:4 * params.max_candidates]):
        if heaviest_valid > 0.0 and (k >= params.max_candidates or mass * _LIGHTER_CANDIDATE < heaviest_valid):
            break   # the rest are lighter still: none of them would be picked over the valid one found
        for _ in range(4):  # widen the window until the full-resolution region fits
            roi = _grow_roi(bbox, margin, frame.width, frame.height)
            found = regions_in_window(frame, model, params, roi, blur)
            if not found or not found[0].touches_window or _cut_along_length(found[0], roi, params, blur):
                break
            bbox = found[0].bbox
        best.extend(found[:1])
        if found and found[0].valid and not found[0].touches_window:
            heaviest_valid = max(heaviest_valid, found[0].area_px * found[0].mean_prob)
    best.sort(key=lambda d: (d.valid and not d.touches_window, d.valid, d.area_px * d.mean_prob), reverse=True)
    return best[0] if best else _none()


def detect_on_planes(frame: FramePlanes, model: ColorModel, params: SegmentParams, roi,
                     blur: bool) -> SphereDetection:
    """One sphere in a frame whose planes are cached: :func:`detect_sphere` after its input checks.

    For the trackers, which share one
    :class:`~tudorvision.stereo._frame.FramePlanes` between spheres; not in
    ``__all__``.

    Parameters
    ----------
    frame : FramePlanes
        The frame and its cached planes.
    model : ColorModel
        The sphere's colour model for this camera.
    params : SegmentParams
        Thresholds and limits.
    roi : tuple of int or None
        Checked window ``(x, y, w, h)`` in frame pixels, or None for the full
        frame (coarse to fine when ``params.coarse_step > 1``; a local model's
        ``local_roi`` around its pick instead).
    blur : bool
        Use the model's blur-tolerant tables and ``min_circularity_blur``.

    Returns
    -------
    SphereDetection
        The best region (invalid, with a reason, when there is none).
    """
    roi = model.local_roi(None, frame.width, frame.height) if roi is None else roi   # a local model: its window
    if roi is None:
        return _detect_full(frame, model, params, blur)
    found = regions_in_window(frame, model, params, roi, blur)
    return found[0] if found else _none()


def detect_sphere(frame_bgr, model: ColorModel, *, params: SegmentParams | None = None, hsv=None,
                  roi=None, motion_blur: bool | None = None) -> SphereDetection:
    """Find one sphere in a BGR frame (full frame or a window).

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        The full frame, OpenCV BGR order.
    model : ColorModel
        The sphere's colour model for this camera.
    params : SegmentParams, optional
        Thresholds and limits (default ``SegmentParams()``).
    hsv : ndarray, shape (H, W, 3), uint8, optional
        ``hsv_from_bgr(frame_bgr)`` of the full frame, to share between
        spheres (:func:`detect_spheres` does this for you).
    roi : tuple of int, optional
        Search window ``(x, y, w, h)`` in frame pixels; it is clipped to the
        image. Without it the full frame is searched (coarse to fine when
        ``params.coarse_step > 1``), or a local model's ``local_roi``.
    motion_blur : bool, optional
        Overrides ``params.motion_blur`` for this call: use the model's
        blur-tolerant tables and ``min_circularity_blur``.

    Returns
    -------
    SphereDetection
        ``uv`` in full-frame coordinates even when ``roi`` is given.

    Raises
    ------
    TudorVisionError
        Bad ``frame_bgr``, ``hsv`` or ``roi``.

    Examples
    --------
    >>> import cv2
    >>> from tudorvision.stereo.colormodel import fit_color_model
    >>> img = np.full((60, 80, 3), 90, np.uint8)
    >>> _ = cv2.circle(img, (40, 30), 10, (40, 40, 200), -1)
    >>> model = fit_color_model(img, (40, 30), (50, 30))
    >>> moved = np.roll(img, 5, axis=1)            # the sphere now sits at u = 45
    >>> det = detect_sphere(moved, model)
    >>> det.valid, round(det.uv[0], 2), round(det.uv[1], 2)
    (True, 45.0, 30.0)
    """
    params = SegmentParams() if params is None else params
    frame = FramePlanes.checked(frame_bgr, hsv)
    blur = params.motion_blur if motion_blur is None else bool(motion_blur)
    if roi is not None:
        roi = _check_roi(roi, frame.width, frame.height)
    return detect_on_planes(frame, model, params, roi, blur)


def detect_spheres(frame_bgr, models: Mapping[str, ColorModel], *, params: SegmentParams | None = None,
                   hsv=None) -> dict:
    """Find every modelled sphere in one full BGR frame, sharing the colour conversion.

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        BGR frame of one camera.
    models : mapping of str to ColorModel
        ``{sphere: model}`` for this camera, e.g.
        ``ColorModelSet.for_camera("left")``.
    params : SegmentParams, optional
        Segmentation thresholds and limits (pixels); default
        ``SegmentParams()``.
    hsv : ndarray, shape (H, W, 3), uint8, optional
        Precomputed HSV of the frame.

    Returns
    -------
    dict of str to SphereDetection
        One detection per model name, centre ``uv`` and radius in pixels
        (u right, v down); invalid ones say why in ``reason``.

    Raises
    ------
    TudorVisionError
        If ``frame_bgr`` is not a uint8 (H, W, 3) image, or ``hsv`` is not a
        uint8 image of the same shape.
    """
    params = SegmentParams() if params is None else params
    frame = FramePlanes.checked(frame_bgr, hsv)
    return {name: detect_on_planes(frame, m, params, None, params.motion_blur) for name, m in models.items()}
