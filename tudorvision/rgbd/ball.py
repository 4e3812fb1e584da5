"""Ball detection by background subtraction (section 9.3).

RGB-D mode
----------
The ball (9 cm diameter) is the only moving object within 4.5 m of the wall
camera. A background model (per-pixel temporal median depth of the first
frames) is compared with each frame in two stages:

1. coarse search on block-averaged depth (``downsample`` x ``downsample``
   blocks; averaging divides the depth noise by ``downsample``): foreground
   blocks are nearer than the background by more than ``n_sigma`` block noise
   sigmas (from ``sigma_z`` at the background depth) and nearer than
   ``max_range_m``;
2. per coarse blob, local refinement at full resolution: pixels within a
   depth band around the blob depth and inside the expected silhouette
   (radius ``f R / z``) give the pixel centroid and the pixel count, which must
   fit the ball's image area at that depth.

The 3D centre lies on the viewing ray through the silhouette centroid. Its
distance along that ray is, per pixel, where the ray point lies at the radius
from the pixel's back-projected surface point (exact perspective; for the
central pixel this is "surface depth plus radius along the viewing ray"),
averaged over the pixels: using every pixel averages the noise and stays
unbiased when the limb pixels are invalid.

Measurement covariance: along the ray ``sigma_z(z)^2 / n_eff`` with
``n_eff = n_pixels / noise_correlation_px``; across the ray
``(pixel_sigma_px z / f)^2``.

Colour mode
-----------
For colour-only input (videos): :mod:`tudorvision.rgbd.ball_color` (re-exported here).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks import TudorVisionError
from ..sensors import KINECT_DEPTH_NOISE, DepthNoiseModel
from .ball_color import ColorBallDetector, ColorBallOptions, PixelDetection
from .frames import Intrinsics

__all__ = ["BallDetectorOptions", "BallDetection", "DepthBackground", "detect_balls", "BallDetector",
           "ball_center_cam_from_pixels", "detection_covariance", "cut_by_border", "ColorBallOptions",
           "ColorBallDetector", "PixelDetection"]


@dataclass(frozen=True, kw_only=True)
class BallDetectorOptions:
    """Options of the RGB-D ball detector (SI units).

    Parameters
    ----------
    ball_radius_m : float
        Ball radius (the seed's ball: 9 cm diameter).
    max_range_m, min_range_m : float
        Depth interval searched (the seed: ball within 4.5 m of the sensor).
    downsample : int
        Block size of the coarse search.
    n_sigma : float
        Coarse foreground threshold in block-noise sigmas.
    min_depth_diff_m : float
        Minimum depth difference to the background.
    area_ratio : tuple of float
        Accepted range of (valid silhouette pixels) / (expected area pi r^2).
    pixel_sigma_px : float
        Standard deviation of the silhouette centroid across the viewing ray, pixels. Default 0.5: the
        detector on the virtual lab's rendered throws, whose depth edges wander as a real Kinect's do
        (:data:`tudorvision.sim.depth_sensor.KINECT_EDGE_JITTER_PX`, measured on a real frame), scatters
        0.30-0.50 px (robust sd per axis; balls of 5-25 px radius, 0.8-4.5 m; 2026-11-28), a little
        more on small, far balls (the edge scatter averages over a shorter rim).
    border_margin_px : float
        A ball whose expected silhouette (its projected radius about the centroid) comes nearer than
        this to the image border gives no detection: the border cuts its silhouette and pulls the
        centroid inwards (by up to 10 px on the lab's throws); negative: keep them.
    noise_correlation_px : float
        Pixels per independent depth sample (1: independent pixel noise). Default 14: a real
        Kinect's depth noise is correlated over a few pixels (block matching), so the mean of a
        region averages far less of it away; 8 x 8 block means of a flat desk top in a real TUM
        frame keep 12-27 times the variance of independent pixels
        (``benchmarks/bench_depth_noise_real.py``), and the virtual lab's sensor, set to match,
        keeps 11.5-15 times over discs of 4-20 px radius (the ball at 4.5-1 m).
    max_candidates : int
        Coarse blobs refined per frame (largest first).
    depth_model : tudorvision.sensors.DepthNoiseModel
        ``sigma_z(z)`` in metres.
    """

    ball_radius_m: float = 0.045
    max_range_m: float = 4.5
    min_range_m: float = 0.4
    downsample: int = 4
    n_sigma: float = 4.0
    min_depth_diff_m: float = 0.1
    area_ratio: tuple = (0.3, 2.0)
    pixel_sigma_px: float = 0.5
    border_margin_px: float = 1.0
    noise_correlation_px: float = 14.0
    max_candidates: int = 5
    depth_model: DepthNoiseModel = field(default=KINECT_DEPTH_NOISE)

    def __post_init__(self):
        if not self.ball_radius_m > 0:
            raise ValueError(f"ball_radius_m: expected > 0, got {self.ball_radius_m}")
        if not 0 <= self.min_range_m < self.max_range_m:
            raise ValueError("min_range_m, max_range_m: expected 0 <= min_range_m < max_range_m")
        if int(self.downsample) != self.downsample or self.downsample < 1:
            raise ValueError(f"downsample: expected a positive integer, got {self.downsample}")
        if not 0 < self.area_ratio[0] < self.area_ratio[1]:
            raise ValueError(f"area_ratio: expected 0 < low < high, got {self.area_ratio}")
        if not self.noise_correlation_px >= 1:
            raise ValueError(f"noise_correlation_px: expected >= 1 pixel per independent sample, "
                             f"got {self.noise_correlation_px}")
        if not self.pixel_sigma_px > 0:
            raise ValueError(f"pixel_sigma_px: expected > 0, got {self.pixel_sigma_px}")
        if np.isnan(self.border_margin_px) or self.border_margin_px == np.inf:
            raise ValueError(f"border_margin_px: expected a number of pixels (-inf: keep all), "
                             f"got {self.border_margin_px}")


@dataclass(frozen=True)
class BallDetection:
    """One detected ball.

    Parameters
    ----------
    uv : ndarray, shape (2,)
        Silhouette centroid, pixels (u right, v down).
    p_cam : ndarray, shape (3,)
        Ball centre, metres, camera optical frame (x right, y down, z
        forward).
    cov_cam : ndarray, shape (3, 3)
        Covariance of ``p_cam``, m^2, camera optical frame: depth noise
        along the viewing ray, centroid noise across it.
    n_pixels : int
        Valid silhouette pixels used.
    area_ratio : float
        ``n_pixels`` / expected silhouette area ``pi radius_px^2``.
    radius_px : float
        Expected image radius of the ball at the detected depth, pixels.
    """

    uv: np.ndarray
    p_cam: np.ndarray
    cov_cam: np.ndarray
    n_pixels: int
    area_ratio: float
    radius_px: float


def _as_depth32(depth, shape) -> np.ndarray:
    d = np.asarray(depth)
    if d.shape != shape:
        raise ValueError(f"depth_m: expected shape {shape}, got {d.shape}")
    if d.dtype != np.float32:
        d = d.astype(np.float32)
    return d


def _block_mean(d: np.ndarray, n: int, min_valid: float = 0.25) -> np.ndarray:
    """Block mean over valid (> 0, finite) pixels; NaN where too few are valid. float32 in and out."""
    import cv2

    h, w = d.shape
    hc, wc = h // n, w // n
    z = np.ascontiguousarray(d[: hc * n, : wc * n], dtype=np.float32).copy()
    cv2.patchNaNs(z, 0.0)
    _, valid = cv2.threshold(z, 0.0, 1.0, cv2.THRESH_BINARY)
    z = cv2.max(z, 0.0)
    s = cv2.resize(z, (wc, hc), interpolation=cv2.INTER_AREA)
    c = cv2.resize(valid, (wc, hc), interpolation=cv2.INTER_AREA)
    out = cv2.divide(s, c)
    out[c < min_valid] = np.nan
    return out


class DepthBackground:
    """Per-pixel background depth from static frames, with precomputed thresholds.

    Parameters
    ----------
    frames : sequence of array_like, each shape (H, W)
        Depth in metres (NaN or 0 invalid) without the ball.
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels); every frame must
        have its ``(height, width)``.
    options : BallDetectorOptions
        Detector options; the range limits, thresholds and depth noise model
        set the foreground limits precomputed here.

    Raises
    ------
    ValueError
        A frame whose shape does not match the intrinsics.
    TudorVisionError
        No frames, or no valid depth in any of them.
    """

    def __init__(self, frames, intrinsics: Intrinsics, options: BallDetectorOptions = BallDetectorOptions()):
        stack = [_as_depth32(f, intrinsics.shape) for f in frames]
        if not stack:
            raise TudorVisionError("background: need at least one depth frame")
        s = np.stack(stack).astype(np.float32)
        s[~(s > 0)] = np.nan
        if not np.any(np.isfinite(s)):
            raise TudorVisionError("background: no valid depth in the background frames")
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            bg = np.nanmedian(s, axis=0).astype(np.float32)
        self.intrinsics = intrinsics
        self.options = options
        self.n_frames = len(stack)
        self.depth_m = bg
        o = options
        # noise of a frame minus the background median (median of N: ~1.25 sigma / sqrt(N))
        k = float(np.sqrt(1.0 + 1.57 / self.n_frames))
        with np.errstate(invalid="ignore"):
            sig = o.depth_model.sigma_m(np.nan_to_num(bg, nan=o.max_range_m)).astype(np.float32) * k
            thr = np.maximum(o.min_depth_diff_m, o.n_sigma * sig)
            # full-resolution limit: a foreground pixel is nearer than this
            lim = np.where(np.isfinite(bg), bg - np.maximum(o.min_depth_diff_m, sig), np.inf)
            self.limit_full = np.minimum(lim, o.max_range_m).astype(np.float32)
            n = int(o.downsample)
            bg_c = _block_mean(bg, n)
            sig_c = o.depth_model.sigma_m(np.nan_to_num(bg_c, nan=o.max_range_m)) * k / n
            thr_c = np.maximum(o.min_depth_diff_m, o.n_sigma * sig_c)
            lim_c = np.where(np.isfinite(bg_c), bg_c - thr_c, np.inf)
            self.limit_coarse = np.minimum(lim_c, o.max_range_m).astype(np.float32)
        self._thr = thr


def ball_center_cam_from_pixels(u, v, z, intrinsics: Intrinsics, radius_m: float, *, iterations: int = 2):
    """Ball centre from the depths of its visible pixels (exact perspective sphere geometry).

    The centre lies on the viewing ray ``d`` through the pixel centroid, ``R`` from
    each pixel's back-projected surface point ``P``: at ``P.d + sqrt(R^2 - |P|^2 + (P.d)^2)``
    along ``d``, averaged over the pixels (unbiased whichever are visible; the earlier
    orthographic version was 0.2-1.3 mm far at 1-4 m, several millimetre-noise sigmas).

    Parameters
    ----------
    u, v : ndarray, shape (N,)
        Pixel coordinates of valid silhouette pixels.
    z : ndarray, shape (N,)
        Their depths, metres.
    intrinsics : Intrinsics
        The depth camera's intrinsics (pixels).
    radius_m : float
        Ball radius.
    iterations : int, optional
        Unused (closed form); kept for callers of the earlier iterative version.

    Returns
    -------
    p_cam : ndarray, shape (3,)
        Centre, metres, camera optical frame.
    uv : ndarray, shape (2,)
        Pixel centroid.

    Examples
    --------
    >>> K, c = Intrinsics(500.0, 500.0, 50.0, 50.0, 100, 100), np.array([0.0, 0.0, 2.0])    # 10 cm sphere at 2 m
    >>> vv, uu = np.mgrid[0:100, 0:100].reshape(2, -1)
    >>> r = np.stack([(uu - 50.0) / 500.0, (vv - 50.0) / 500.0, np.ones(uu.shape)], axis=1)
    >>> b, a = r @ c, np.sum(r * r, axis=1)
    >>> hit = b * b - a * (c @ c - 0.1 ** 2) > 0
    >>> zz = (b[hit] - np.sqrt(b[hit] ** 2 - a[hit] * (c @ c - 0.1 ** 2))) / a[hit]
    >>> p, uv = ball_center_cam_from_pixels(uu[hit], vv[hit], zz, K, 0.1)
    >>> np.round(p, 6).tolist(), uv.tolist()
    ([0.0, 0.0, 2.0], [50.0, 50.0])
    """
    u = np.asarray(u, np.float64)
    v = np.asarray(v, np.float64)
    z = np.asarray(z, np.float64)
    uc, vc = float(u.mean()), float(v.mean())
    K = intrinsics
    d = np.array([(uc - K.cx) / K.fx, (vc - K.cy) / K.fy, 1.0])
    d /= np.linalg.norm(d)
    P = np.stack([(u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z], axis=1)
    a = P @ d
    perp2 = np.einsum("ij,ij->i", P, P) - a * a
    dist = float(np.mean(a + np.sqrt(np.maximum(radius_m ** 2 - perp2, 0.0))))
    return dist * d, np.array([uc, vc])


def cut_by_border(u: float, v: float, r_px: float, intrinsics: Intrinsics, o: BallDetectorOptions) -> bool:
    """Whether a ball's expected silhouette comes nearer than ``o.border_margin_px`` to the image border.

    Such a ball gives no detection: the border cuts its silhouette and pulls the centroid inwards.

    Parameters
    ----------
    u, v : float
        The silhouette's centre, pixels.
    r_px : float
        Its expected radius, pixels.
    intrinsics : Intrinsics
        The image size (pixels).
    o : BallDetectorOptions
        ``border_margin_px``.

    Returns
    -------
    bool

    Examples
    --------
    >>> K = Intrinsics(525.0, 525.0, 320, 240, 640, 480)
    >>> cut_by_border(10.0, 240.0, 9.5, K, BallDetectorOptions()), cut_by_border(320.0, 240.0, 9.5, K,
    ...                                                                           BallDetectorOptions())
    (True, False)
    """
    K = intrinsics
    return min(u, v, K.width - 1 - u, K.height - 1 - v) - r_px < o.border_margin_px


def detection_covariance(p: np.ndarray, n: float, intrinsics: Intrinsics, o: BallDetectorOptions) -> np.ndarray:
    """Covariance of a detected centre: ``sigma_z(z)^2 / n_eff`` along the ray, ``(pixel_sigma_px z / f)^2`` across.

    Parameters
    ----------
    p : ndarray, shape (3,)
        The centre, metres, camera optical frame.
    n : float
        Valid silhouette pixels (``n_eff = max(1, n / noise_correlation_px)``).
    intrinsics : Intrinsics
        The depth camera's intrinsics (pixels).
    o : BallDetectorOptions
        ``depth_model``, ``noise_correlation_px`` and ``pixel_sigma_px``.

    Returns
    -------
    ndarray, shape (3, 3)
        Covariance, m^2, camera frame.

    Examples
    --------
    >>> C = detection_covariance(np.array([0.0, 0.0, 2.0]), 140, Intrinsics(525.0, 525.0, 320, 240, 640, 480),
    ...                          BallDetectorOptions())
    >>> round(float(np.sqrt(C[0, 0])) * 525 / 2.0, 3)             # across the ray: pixel_sigma_px
    0.5
    """
    r = p / np.linalg.norm(p)
    z = p[2]
    n_eff = max(1.0, n / o.noise_correlation_px)
    s_along = float(o.depth_model.sigma_m(z)) / np.sqrt(n_eff) / max(r[2], 1e-6)
    s_lat = o.pixel_sigma_px * z / np.sqrt(intrinsics.fx * intrinsics.fy)
    P = np.outer(r, r)
    return s_along ** 2 * P + s_lat ** 2 * (np.eye(3) - P)


def detect_balls(depth_m, background: DepthBackground) -> list[BallDetection]:
    """Detect balls in one depth frame against a background model.

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        Depth in metres (float32 fastest), NaN or 0 = invalid.
    background : DepthBackground
        Background model of the same camera; supplies the intrinsics, the
        options and the per-pixel foreground limits.

    Returns
    -------
    list of BallDetection
        Plausible detections, best (area ratio nearest 1) first; empty if none.

    Raises
    ------
    ValueError
        If ``depth_m`` does not have the background's image shape.
    """
    import cv2

    bg = background
    o, K = bg.options, bg.intrinsics
    d = _as_depth32(depth_m, K.shape)
    n = int(o.downsample)
    d_c = _block_mean(d, n)
    with np.errstate(invalid="ignore"):
        fg = (d_c < bg.limit_coarse) & (d_c > o.min_range_m)
    if not fg.any():
        return []
    nl, labels, stats, cents = cv2.connectedComponentsWithStats(fg.view(np.uint8), connectivity=8)
    f = float(np.sqrt(K.fx * K.fy))
    R = o.ball_radius_m
    order = 1 + np.argsort(-stats[1:, cv2.CC_STAT_AREA])
    out = []
    for lab in order[: o.max_candidates]:
        x0, y0, w, h, area = stats[lab]
        blk = labels[y0:y0 + h, x0:x0 + w] == lab
        z0 = float(np.nanmedian(d_c[y0:y0 + h, x0:x0 + w][blk]))
        r_px = f * R / z0
        expected_c = np.pi * (r_px / n) ** 2
        if area > 4.0 * expected_c + 4 or area < 0.1 * expected_c:
            continue
        uc = (cents[lab, 0] + 0.5) * n - 0.5
        vc = (cents[lab, 1] + 0.5) * n - 0.5
        det = _refine(d, bg, uc, vc, z0, f)
        if det is not None:
            out.append(det)
    out.sort(key=lambda b: abs(np.log(b.area_ratio)))
    return out


def _refine(d: np.ndarray, bg: DepthBackground, uc: float, vc: float, z0: float, f: float):
    o, K = bg.options, bg.intrinsics
    R = o.ball_radius_m
    n_px = 0
    p = None
    for it in range(3):
        r_px = f * R / z0
        half = int(np.ceil(1.6 * r_px + 2))
        u0, u1 = max(0, int(uc) - half), min(K.width, int(uc) + half + 2)
        v0, v1 = max(0, int(vc) - half), min(K.height, int(vc) + half + 2)
        if u1 <= u0 or v1 <= v0:
            return None
        win = d[v0:v1, u0:u1]
        vv, uu = np.mgrid[v0:v1, u0:u1]
        rad = 1.3 * r_px + 1.0 if it else 1.6 * r_px + 2.0
        band = max(3.0 * float(o.depth_model.sigma_m(z0)), 2.0 * R)
        with np.errstate(invalid="ignore"):
            if it == 0:
                # the coarse blob's edge blocks mix ball and background (up to 10 cm off before a near wall):
                # start from the median full-resolution foreground depth within twice the band
                fg0 = ((np.abs(win - z0) < 2.0 * band) & (win < bg.limit_full[v0:v1, u0:u1])
                       & ((uu - uc) ** 2 + (vv - vc) ** 2 <= rad * rad))
                if fg0.any():
                    z0 = float(np.median(win[fg0]))
                    band = max(3.0 * float(o.depth_model.sigma_m(z0)), 2.0 * R)
        with np.errstate(invalid="ignore"):
            sel = ((np.abs(win - z0) < band) & (win < bg.limit_full[v0:v1, u0:u1])
                   & ((uu - uc) ** 2 + (vv - vc) ** 2 <= rad * rad))
        n_px = int(sel.sum())
        if n_px < 3:
            return None
        p, uv = ball_center_cam_from_pixels(uu[sel], vv[sel], win[sel], K, R)
        uc, vc = float(uv[0]), float(uv[1])
        z_new = p[2] - 2.0 * R / 3.0      # mean visible surface depth
        if abs(z_new - z0) < 1e-3 and it:
            z0 = z_new
            break
        z0 = z_new
    if not (o.min_range_m < p[2] < o.max_range_m + R):
        return None
    r_px = f * R / p[2]
    if cut_by_border(uc, vc, r_px, K, o):
        return None                      # cut by the border: the centroid is pulled inwards
    ratio = n_px / (np.pi * r_px ** 2)
    if not o.area_ratio[0] <= ratio <= o.area_ratio[1]:
        return None
    # silhouette test free of selection: every valid pixel inside the expected
    # silhouette must be nearer than the background on average (noise blobs made of
    # the pixels that happen to pass the per-pixel test average out here)
    rr = max(0.8 * r_px, 1.0)
    u0, u1 = max(0, int(uc - rr)), min(K.width, int(uc + rr) + 2)
    v0, v1 = max(0, int(vc - rr)), min(K.height, int(vc + rr) + 2)
    vv, uu = np.mgrid[v0:v1, u0:u1]
    inside = (uu - uc) ** 2 + (vv - vc) ** 2 <= rr * rr
    dd = d[v0:v1, u0:u1][inside]
    bb = bg.depth_m[v0:v1, u0:u1][inside]
    ok = dd > 0
    if ok.sum() < 3:
        return None
    diff = np.where(np.isfinite(bb[ok]), bb[ok], o.max_range_m + 2.0) - dd[ok]
    sig = float(o.depth_model.sigma_m(min(float(np.nanmedian(np.where(np.isfinite(bb[ok]), bb[ok], np.nan)))
                                        if np.isfinite(bb[ok]).any() else p[2], o.max_range_m + 2.0)))
    if float(diff.mean()) < max(o.min_depth_diff_m, 1.5 * o.n_sigma * sig / np.sqrt(ok.sum())):
        return None
    return BallDetection(np.array([uc, vc]), p, detection_covariance(p, n_px, K, o), n_px, float(ratio), float(r_px))


class BallDetector:
    """Stateful RGB-D ball detector: learns the background from the first frames.

    Parameters
    ----------
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels); frames must have its
        ``(height, width)``.
    options : BallDetectorOptions
        Detector options (ball radius, range, thresholds, depth noise model).
    n_background : int
        Number of initial frames used for the background (no detections then).

    Raises
    ------
    ValueError
        If ``n_background`` is below 1.

    Examples
    --------
    >>> K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    >>> det = BallDetector(K, n_background=2)
    >>> wall = np.full((480, 640), 5.0, np.float32)
    >>> det.update(wall) is None and det.update(wall) is None
    True
    >>> frame = wall.copy(); vv, uu = np.mgrid[:480, :640]
    >>> rho2 = ((uu - 400) ** 2 + (vv - 200) ** 2) * (3.0 / 525.0) ** 2
    >>> frame[rho2 < 0.045 ** 2] = 3.0 - np.sqrt(0.045 ** 2 - rho2[rho2 < 0.045 ** 2])
    >>> np.round(det.update(frame).p_cam, 2).tolist()
    [0.46, -0.23, 3.0]
    """

    def __init__(self, intrinsics: Intrinsics, options: BallDetectorOptions = BallDetectorOptions(), *,
                 n_background: int = 10):
        if n_background < 1:
            raise ValueError(f"n_background: expected >= 1, got {n_background}")
        self.intrinsics = intrinsics
        self.options = options
        self.n_background = int(n_background)
        self._frames: list[np.ndarray] = []
        self.background: DepthBackground | None = None

    def update(self, depth_m) -> BallDetection | None:
        """Feed the next frame; returns the best detection (None while learning or if none).

        Parameters
        ----------
        depth_m : array_like, shape (H, W)
            Depth in metres, NaN or 0 = invalid; the first ``n_background``
            frames (without the ball) build the background.

        Returns
        -------
        BallDetection or None
            The best detection (centre in metres, camera optical frame);
            ``None`` while the background is being learnt or when no ball is
            found.

        Raises
        ------
        ValueError
            If ``depth_m`` does not have the intrinsics' image shape.
        """
        if self.background is None:
            self._frames.append(_as_depth32(depth_m, self.intrinsics.shape).copy())
            if len(self._frames) >= self.n_background:
                self.background = DepthBackground(self._frames, self.intrinsics, self.options)
                self._frames = []
            return None
        dets = detect_balls(depth_m, self.background)
        return dets[0] if dets else None
