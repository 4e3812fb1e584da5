"""Disc segmentation by uniform-depth region growing, and tracking (section 9.3).

For the wall-camera calibration a solid disc sits in the catching net. The
camera sees it as a region of uniform depth. From a seed pixel, the region is
the connected set of pixels (4- or 8-connected) whose depth lies within a
tolerance of the seed neighbourhood's median depth (a fixed-range flood fill);
the tolerance scales with the depth noise ``sigma_z(z)``. The region's 3D
centroid is the end-effector sample. Between sweep steps the seed follows the
disc: the next seed is the previous centroid's pixel.

Depth noise at 5 m is tens of centimetres per pixel (seed model), so growing
runs on a median-filtered depth image (``smooth_px``). The centroid is the
region's mean pixel back-projected at the robust mean raw depth of a pixel set
taken geometrically, not from the noisy mask.

Selection bias of the depth mean: whether a rim pixel joins the grown region
depends on its own noise (the median filter mixes it with the invalid band
and the background), so the region, its centroid and its moment ellipse all
lean toward rim pixels that read too far. Any depth window whose boundary is
set by the region and cuts through valid disc pixels then averages a biased
sample: the region's moment ellipse read +0.5 to +0.7 cm too far at 5 m on
the virtual lab (+0.2 cm for a circle one pixel inside the rim). With the
disc radius known (``disc_radius_m``) the window is therefore the disc's whole
image circle, radius ``f R / z``, around the region centroid: its boundary
lies on the disc rim, where a depth sensor returns no depth (the jump to the
background), so which pixels it holds no longer depends on their noise. It is
cut by the moment ellipse scaled by 1.5 only to follow a strongly tilted disc.
``depth_annulus`` (fractions of that window) can leave out the centre, where
end-effector hardware may stand in front of the disc.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks import TudorVisionError, check_array
from ..sensors import KINECT_DEPTH_NOISE, DepthNoiseModel
from .frames import Intrinsics, check_depth

__all__ = ["DiscOptions", "DiscObservation", "segment_uniform_depth", "observe_disc",
           "DiscTracker", "track_disc"]


@dataclass(frozen=True, kw_only=True)
class DiscOptions:
    """Options of the disc segmentation.

    Parameters
    ----------
    neighbourhood_px : int
        Side of the square seed neighbourhood whose median depth is the
        reference depth (odd).
    n_sigma : float
        Tolerance in units of the (smoothed) depth noise at the seed depth.
    min_tol_m, max_tol_m : float
        Bounds of the depth tolerance, metres.
    smooth_px : int
        Median filter size (1, 3 or 5) applied before growing; 1 = none.
    connectivity : int
        4 or 8.
    min_pixels, max_pixels : int
        Plausible region size; outside it the disc counts as lost.
    disc_radius_m : float, optional
        Disc radius; when given, the region must also cover between
        ``area_ratio[0]`` and ``area_ratio[1]`` times the disc's
        fronto-parallel image area at its depth.
    area_ratio : tuple of float
        ``(low, high)`` bounds of (region pixels) / (expected disc image area
        ``pi (f R / z)^2``); used only with ``disc_radius_m``.
    depth_annulus : tuple of float
        The centroid depth is the robust mean raw depth of the pixels between
        these fractions of the depth window (see ``depth_window``). Default
        ``(0, 1)``: the whole window. ``(0.7, 1.0)`` leaves out an occluded
        centre at the price of fewer pixels and a bias of its own: the inner
        boundary cuts through valid disc pixels (see the module notes).
    depth_window : {"disc", "ellipse", "segment"}
        ``"disc"`` (default; needs ``disc_radius_m``, else ``"ellipse"`` is
        used): the disc's image circle of radius ``f R / z_ref -
        rim_margin_px`` around the region centroid, cut by 1.5 times the
        region's moment ellipse. ``"ellipse"``: the region's moment ellipse
        (the earlier estimator; biased away from the camera under strong
        depth noise, see the module notes). ``"segment"``: the grown region
        itself, the seed's plain centroid (``depth_annulus`` ignored; for
        comparison).
    rim_margin_px : float
        Pixels taken off the disc's image radius (``"disc"`` window); keep it
        below one pixel so that the window's edge stays on the disc rim.
    depth_model : tudorvision.sensors.DepthNoiseModel
        ``sigma_z(z)`` in metres, used for the tolerance.
    """

    neighbourhood_px: int = 5
    n_sigma: float = 3.0
    min_tol_m: float = 0.03
    max_tol_m: float = 0.5
    smooth_px: int = 5
    connectivity: int = 8
    min_pixels: int = 15
    max_pixels: int = 40000
    disc_radius_m: float | None = None
    area_ratio: tuple = (0.25, 2.5)
    depth_annulus: tuple = (0.0, 1.0)
    depth_window: str = "disc"
    rim_margin_px: float = 0.0
    depth_model: DepthNoiseModel = field(default=KINECT_DEPTH_NOISE)

    def __post_init__(self):
        if self.neighbourhood_px < 1 or self.neighbourhood_px % 2 == 0:
            raise ValueError(f"neighbourhood_px: expected an odd positive size, got {self.neighbourhood_px}")
        if self.smooth_px not in (1, 3, 5):
            raise ValueError(f"smooth_px: expected 1, 3 or 5, got {self.smooth_px}")
        if self.connectivity not in (4, 8):
            raise ValueError(f"connectivity: expected 4 or 8, got {self.connectivity}")
        if not 0 < self.min_tol_m <= self.max_tol_m:
            raise ValueError("min_tol_m, max_tol_m: expected 0 < min_tol_m <= max_tol_m")
        if self.depth_window not in ("disc", "ellipse", "segment"):
            raise ValueError(f"depth_window: expected 'disc', 'ellipse' or 'segment', got {self.depth_window!r}")
        if not 0 <= self.depth_annulus[0] < self.depth_annulus[1]:
            raise ValueError(f"depth_annulus: expected 0 <= lo < hi, got {self.depth_annulus}")
        if not 0 < self.min_pixels <= self.max_pixels:
            raise ValueError("min_pixels, max_pixels: expected 0 < min_pixels <= max_pixels")


@dataclass(frozen=True)
class DiscObservation:
    """One disc sample.

    Parameters
    ----------
    valid : bool
        False when the disc was lost (``reason`` says why).
    centroid_cam : ndarray, shape (3,)
        Disc centroid, metres, camera optical frame (x right, y down, z
        forward); NaN when lost.
    centroid_uv : ndarray, shape (2,)
        Pixel centroid of the region (u right, v down); NaN when lost.
    seed_uv : tuple of int
        The seed pixel ``(u, v)`` used.
    depth_m : float
        Reference depth at the seed (median of the smoothed seed
        neighbourhood), metres; NaN when the seed had no valid depth.
    n_pixels : int
        Region size, pixels.
    reason : str
        Why the disc was lost; empty when ``valid``.
    """

    valid: bool
    centroid_cam: np.ndarray
    centroid_uv: np.ndarray
    seed_uv: tuple
    depth_m: float
    n_pixels: int
    reason: str = ""


def _smooth(d: np.ndarray, k: int) -> np.ndarray:
    if k == 1:
        return d
    import cv2

    f = np.where(np.isfinite(d), d, 0.0).astype(np.float32)
    m = cv2.medianBlur(f, k).astype(np.float64)
    m[m <= 0] = np.nan
    return m


def _seed_pixel(seed_uv, shape) -> tuple[int, int]:
    s = check_array(seed_uv, "seed_uv", (2,))
    u, v = int(round(s[0])), int(round(s[1]))
    if not (0 <= u < shape[1] and 0 <= v < shape[0]):
        raise TudorVisionError(f"seed_uv: ({u}, {v}) lies outside the {shape[1]}x{shape[0]} image")
    return u, v


def segment_uniform_depth(depth_m, seed_uv, options: DiscOptions = DiscOptions()):
    """Region of uniform depth grown from a seed pixel.

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        Depth in metres, NaN or 0 = invalid.
    seed_uv : array_like, shape (2,)
        Seed pixel (u right, v down).
    options : DiscOptions

    Returns
    -------
    mask : ndarray of bool, shape (H, W)
        The connected region containing the seed (or the nearest region pixel
        in the seed neighbourhood).
    z_ref : float
        Reference depth (median of the smoothed seed neighbourhood), metres.
    tol : float
        Depth tolerance used, metres.

    Raises
    ------
    TudorVisionError
        If the seed is outside the image or its neighbourhood has no valid depth.

    Examples
    --------
    >>> d = np.full((20, 20), 3.0); d[5:12, 5:12] = 2.0
    >>> mask, z, tol = segment_uniform_depth(d, (8, 8), DiscOptions(smooth_px=1))
    >>> int(mask.sum()), z
    (49, 2.0)
    """
    import cv2

    d = check_depth(depth_m, require_valid=False)
    u, v = _seed_pixel(seed_uv, d.shape)
    ds = _smooth(d, options.smooth_px)
    h = options.neighbourhood_px // 2
    v0, v1, u0, u1 = max(0, v - h), min(d.shape[0], v + h + 1), max(0, u - h), min(d.shape[1], u + h + 1)
    patch = ds[v0:v1, u0:u1]
    if not np.any(np.isfinite(patch)):
        raise TudorVisionError(f"seed pixel ({u}, {v}) has no valid depth in its "
                               f"{options.neighbourhood_px}x{options.neighbourhood_px} neighbourhood")
    z_ref = float(np.nanmedian(patch))
    # median of k*k samples has about 1.25 sigma / k noise
    noise = float(options.depth_model.sigma_m(z_ref)) * (1.0 if options.smooth_px == 1 else 1.25 / options.smooth_px)
    tol = float(np.clip(options.n_sigma * noise, options.min_tol_m, options.max_tol_m))
    with np.errstate(invalid="ignore"):
        # pixels without a raw depth stay barriers (sensors drop depth at object edges)
        cand = (np.abs(ds - z_ref) <= tol) & np.isfinite(d)
    _, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=options.connectivity)
    lab = labels[v, u]
    if lab == 0:
        sub = labels[v0:v1, u0:u1]
        vv, uu = np.nonzero(sub)
        if len(vv) == 0:
            return np.zeros(d.shape, bool), z_ref, tol
        k = int(np.argmin((vv + v0 - v) ** 2 + (uu + u0 - u) ** 2))
        lab = sub[vv[k], uu[k]]
    return labels == lab, z_ref, tol


def observe_disc(depth_m, intrinsics: Intrinsics, seed_uv, options: DiscOptions = DiscOptions(), *,
                 strict: bool = True) -> DiscObservation:
    """Segment the disc and compute its 3D centroid.

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        Depth in metres.
    intrinsics : Intrinsics
    seed_uv : array_like, shape (2,)
        Seed pixel on the disc.
    options : DiscOptions
    strict : bool
        Raise when the disc is lost; otherwise return an invalid observation
        with the reason.

    Returns
    -------
    DiscObservation

    Raises
    ------
    TudorVisionError
        Seed without valid depth, or (``strict``) a region of implausible size.
    """
    d = check_depth(depth_m, intrinsics=intrinsics)
    u, v = _seed_pixel(seed_uv, d.shape)
    try:
        mask, z_ref, tol = segment_uniform_depth(d, (u, v), options)
    except TudorVisionError as exc:
        if strict:
            raise
        return _lost((u, v), float("nan"), 0, str(exc))
    n = int(mask.sum())
    if n >= options.min_pixels and n <= options.max_pixels:
        # re-grow once from the region's centre: a seed near the rim (the disc moved
        # since the last step) biases the reference depth toward the background
        vv, uu = np.nonzero(mask)
        uc, vc = int(round(uu.mean())), int(round(vv.mean()))
        if (uc, vc) != (u, v) and mask[vc, uc]:
            try:
                mask, z_ref, tol = segment_uniform_depth(d, (uc, vc), options)
            except TudorVisionError:
                pass
            n = int(mask.sum())
    lo, hi = options.min_pixels, options.max_pixels
    if options.disc_radius_m is not None:
        r_px = np.sqrt(intrinsics.fx * intrinsics.fy) * options.disc_radius_m / z_ref
        expected = np.pi * r_px ** 2
        lo = max(lo, int(np.floor(options.area_ratio[0] * expected)))
        hi = min(hi, int(np.ceil(options.area_ratio[1] * expected)))
    reason = ""
    if n < lo:
        reason = f"disc region too small at seed ({u}, {v}): {n} pixels < {lo}"
    elif n > hi:
        reason = f"disc region too large at seed ({u}, {v}): {n} pixels > {hi} (leaked into the background?)"
    if reason:
        if strict:
            raise TudorVisionError(reason)
        return _lost((u, v), z_ref, n, reason)
    import cv2

    # pixel centroid and shape (second moments) from the region; the depth from a
    # window taken geometrically, whose boundary does not cut through valid disc
    # pixels (see the module notes: a boundary set by the noisy region inside the
    # disc selects rim pixels by their noise)
    vv, uu = np.nonzero(mask)
    uv = np.array([uu.mean(), vv.mean()])
    C = np.cov(np.stack([uu, vv]).astype(np.float64)) + 0.25 * np.eye(2)
    Ci = np.linalg.inv(C)
    lo, hi = options.depth_annulus
    r_disc = None
    scale = 1.0
    if options.depth_window == "disc" and options.disc_radius_m is not None:
        r_disc = np.sqrt(intrinsics.fx * intrinsics.fy) * options.disc_radius_m / z_ref - options.rim_margin_px
        r_disc = max(r_disc, 1.0)
        scale = 1.5
    half = int(np.ceil(2.0 * scale * hi * np.sqrt(np.max(np.linalg.eigvalsh(C))))) + 1
    if r_disc is not None:
        half = min(half, int(np.ceil(hi * r_disc)) + 1)
    u0, u1 = max(0, int(uv[0]) - half), min(d.shape[1], int(uv[0]) + half + 2)
    v0, v1 = max(0, int(uv[1]) - half), min(d.shape[0], int(uv[1]) + half + 2)
    gv, gu = np.mgrid[v0:v1, u0:u1]
    du, dv = gu - uv[0], gv - uv[1]
    # normalised radius: 1 on the window's edge
    rho = np.sqrt((Ci[0, 0] * du * du + 2 * Ci[0, 1] * du * dv + Ci[1, 1] * dv * dv) / 4.0) / scale
    if r_disc is not None:
        rho = np.maximum(rho, np.hypot(du, dv) / r_disc)
    win = d[v0:v1, u0:u1]
    z = win[(rho >= lo) & (rho <= hi)]
    if options.depth_window == "segment":
        z = d[mask]
    if np.isfinite(z).sum() < 10:                      # tiny region: use all of it
        z = win[rho <= hi]
    z = z[np.isfinite(z)]
    if len(z) < 3:
        reason = f"disc region at seed ({u}, {v}) has only {len(z)} valid raw depths"
        if strict:
            raise TudorVisionError(reason)
        return _lost((u, v), z_ref, n, reason)
    med = float(np.median(z))
    clip = 3.0 * float(options.depth_model.sigma_m(med))
    zk = z[np.abs(z - med) <= clip]
    z_mean = float(zk.mean()) if len(zk) >= 3 else med
    c = np.array([(uv[0] - intrinsics.cx) * z_mean / intrinsics.fx,
                  (uv[1] - intrinsics.cy) * z_mean / intrinsics.fy, z_mean])
    return DiscObservation(True, c, uv, (u, v), z_ref, n)


def _lost(seed, z, n, reason) -> DiscObservation:
    return DiscObservation(False, np.full(3, np.nan), np.full(2, np.nan), tuple(seed), z, n, reason)


class DiscTracker:
    """Follow the disc through a sweep: each seed is the previous centroid's pixel.

    The seed is first the constant-velocity prediction (previous centroid plus
    the last displacement), then the previous centroid; when neither grows a
    plausible disc at about the previous depth, seeds on rings around the
    prediction (1, 2, 3.5 and 5 disc radii) are tried. A frame where all fail is a
    lost sample.

    Parameters
    ----------
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels); depth frames must
        have its ``(height, width)``.
    seed_uv : array_like, shape (2,)
        Seed pixel on the disc in the first frame (u right, v down).
    options : DiscOptions
        Segmentation options (tolerances, region size, disc radius, depth
        window).
    max_consecutive_lost : int
        Raise once the disc has been lost this many frames in a row.

    Raises
    ------
    TudorVisionError
        If ``seed_uv`` lies outside the image.

    Examples
    --------
    >>> K = Intrinsics(500.0, 500.0, 20.0, 20.0, 40, 40)
    >>> d = np.full((40, 40), 4.0); d[10:21, 10:21] = 3.0
    >>> tr = DiscTracker(K, (12, 12), DiscOptions(smooth_px=1))
    >>> obs = tr.update(d)
    >>> obs.valid, np.round(obs.centroid_uv, 1).tolist(), tr.seed_uv
    (True, [15.0, 15.0], (15, 15))
    """

    def __init__(self, intrinsics: Intrinsics, seed_uv, options: DiscOptions = DiscOptions(), *,
                 max_consecutive_lost: int = 3):
        self.intrinsics = intrinsics
        self.options = options
        self.max_consecutive_lost = int(max_consecutive_lost)
        u, v = _seed_pixel(seed_uv, intrinsics.shape)
        self.seed_uv = (u, v)
        self.n_lost = 0
        self.frame = 0
        self._velocity = np.zeros(2)
        self._last_uv: np.ndarray | None = None
        self._last_z: float | None = None

    def reseed(self, seed_uv, depth_m: float | None = None) -> None:
        """Restart the search at ``seed_uv`` (e.g. after the arm jumped), optionally near depth ``depth_m``.

        Parameters
        ----------
        seed_uv : array_like, shape (2,)
            New seed pixel on the disc (u right, v down); the velocity
            prediction is reset.
        depth_m : float, optional
            Expected disc depth (z), metres: observations far from it are
            skipped until the disc is found again. ``None`` accepts any
            depth.

        Raises
        ------
        TudorVisionError
            If ``seed_uv`` lies outside the image.
        """
        u, v = _seed_pixel(seed_uv, self.intrinsics.shape)
        self.seed_uv = (u, v)
        self._velocity = np.zeros(2)
        self._last_uv = None
        self._last_z = None if depth_m is None else float(depth_m)

    def _candidates(self):
        K = self.intrinsics
        base = np.array(self.seed_uv, float)
        pred = base + self._velocity
        out = [pred, base]
        if self.options.disc_radius_m is not None and self._last_z:
            r = float(np.sqrt(K.fx * K.fy) * self.options.disc_radius_m / self._last_z)
        else:
            r = 5.0
        for rad, n_dir in ((r, 8), (2 * r, 8), (3.5 * r, 12), (5 * r, 16)):
            ang = np.linspace(0, 2 * np.pi, n_dir, endpoint=False)
            out += [pred + rad * np.array([np.cos(a), np.sin(a)]) for a in ang]
        seen, uniq = set(), []
        for c in out:
            q = (int(round(c[0])), int(round(c[1])))
            if q not in seen and 0 <= q[0] < K.width and 0 <= q[1] < K.height:
                seen.add(q)
                uniq.append(q)
        return uniq

    def update(self, depth_m) -> DiscObservation:
        """Observe the disc in the next frame; returns the (possibly invalid) observation.

        Parameters
        ----------
        depth_m : array_like, shape (H, W)
            Depth (z) in metres, NaN or 0 = invalid; the intrinsics' image
            shape.

        Returns
        -------
        DiscObservation
            The disc's centroid (metres, camera optical frame); when lost in
            this frame, an observation with ``valid=False`` and the reason.

        Raises
        ------
        ValueError
            If ``depth_m`` does not have the intrinsics' image shape.
        TudorVisionError
            When the disc has been lost ``max_consecutive_lost`` frames in a row,
            or the depth frame has no valid pixel.
        """
        d = check_depth(depth_m, intrinsics=self.intrinsics)
        first = None
        obs = None
        for seed in self._candidates():
            o = observe_disc(d, self.intrinsics, seed, self.options, strict=False)
            first = first or o
            if not o.valid:
                continue
            if self._last_z is not None:
                gate = max(0.3, 3.0 * float(self.options.depth_model.sigma_m(self._last_z)) / 4.0)
                if abs(o.centroid_cam[2] - self._last_z) > gate:
                    continue
            obs = o
            break
        self.frame += 1
        if obs is None:
            self.n_lost += 1
            self._velocity = np.zeros(2)
            if self.n_lost >= self.max_consecutive_lost:
                raise TudorVisionError(f"disc lost in {self.n_lost} consecutive frames up to frame "
                                       f"{self.frame - 1}: {first.reason}")
            return first
        self.n_lost = 0
        uv = obs.centroid_uv
        if self._last_uv is not None:
            self._velocity = uv - self._last_uv
        self._last_uv = uv.copy()
        self._last_z = float(obs.centroid_cam[2])
        u, v = (int(round(x)) for x in uv)
        if 0 <= u < self.intrinsics.width and 0 <= v < self.intrinsics.height:
            self.seed_uv = (u, v)
        return obs


def track_disc(depth_frames, intrinsics: Intrinsics, seed_uv, options: DiscOptions = DiscOptions(), *,
               max_consecutive_lost: int = 3) -> list[DiscObservation]:
    """Track the disc over a sequence of depth frames (see :class:`DiscTracker`).

    Parameters
    ----------
    depth_frames : iterable of array_like, each shape (H, W)
        Depth in metres, one frame per sweep step.
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels).
    seed_uv : array_like, shape (2,)
        Seed pixel on the disc in the first frame (u right, v down).
    options : DiscOptions
        Segmentation options.
    max_consecutive_lost : int
        Raise once the disc has been lost this many frames in a row.

    Returns
    -------
    list of DiscObservation
        One per frame, centroids in metres, camera optical frame; lost
        samples have ``valid=False``.

    Raises
    ------
    ValueError
        If a frame does not have the intrinsics' image shape.
    TudorVisionError
        If ``seed_uv`` lies outside the image, a frame has no valid depth, or
        the disc is lost ``max_consecutive_lost`` frames in a row.
    """
    tr = DiscTracker(intrinsics, seed_uv, options, max_consecutive_lost=max_consecutive_lost)
    return [tr.update(d) for d in depth_frames]
