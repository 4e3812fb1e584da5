"""Kinect-like depth sensor model: range limits, sigma_z(z) noise, invalid edges and dark surfaces.

The noise is a :class:`tudorvision.sensors.DepthNoiseModel` (SI units); by
default the seed's Kinect fit :data:`tudorvision.sensors.KINECT_DEPTH_NOISE`
(sigma read in millimetres: 1.35 mm at 1 m, 35 mm at 5 m). The output is
rounded to ``1 / units_per_m`` (1 mm), which adds ``1 mm / sqrt(12)`` of
quantisation spread where sigma is of that order (below about 1.5 m).

The noise is spatially correlated, as a real Kinect's is (its depth comes
from block matching of a speckle pattern): a white field smoothed by a
Gaussian of standard deviations ``noise_corr_px`` (u, v) and scaled back to
unit variance, so that each pixel keeps ``sigma_z(z)`` while the mean over a
region averages far less noise away than independent pixels would
(:data:`KINECT_NOISE_CORR_PX`, measured on a real frame;
``benchmarks/bench_depth_noise_real.py``).

A real Kinect also has a fixed depth error that does not average away over
frames: block matching of the speckle pattern measures disparity with an
offset that changes slowly over the image and belongs to the unit (Smisek et
al. 2011; Herrera et al. 2012). ``pattern_disparity_px`` models it as a fixed,
smooth disparity offset field (its own seed, the same in every frame), which
moves a depth ``z`` by about ``z^2 * offset / (f b)``: its RMS, correlation and
size were measured on the floor of the real Kinect frames in
``../shared/realdata/rgbd_kinect_room/`` (``benchmarks/bench_depth_pattern_real.py``,
:data:`KINECT_PATTERN_DISPARITY_PX`). Only the part a plane fit cannot absorb
is modelled (the field's best affine fit is removed): an offset or a tilt of
inverse depth maps planes to planes and is what a depth bias calibration sees.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..sensors import KINECT_DEPTH_NOISE, KINECT_RANGE_M, DepthNoiseModel
from .raycast import GBuffer

__all__ = ["DepthSensorModel", "depth_mm_from_gbuffer", "noise_field", "pattern_field", "with_pattern",
           "KINECT_NOISE_CORR_PX", "KINECT_EDGE_JITTER_PX", "KINECT_PATTERN_DISPARITY_PX", "KINECT_PATTERN_CORR_PX",
           "KINECT_FOCAL_BASELINE_PX_M"]

#: Standard deviations (u, v) of the Gaussian that correlates the depth noise, pixels. From the flat desk
#: top of the real TUM frame ``../shared/realdata/rgbd_tum_desk/1_depth.png`` (rows 330-380, columns
#: 90-200, 1.23 m; ``benchmarks/bench_depth_noise_real.py``): the residual of a smooth surface fit is
#: correlated more along rows (0.66 / 0.53 / 0.34 at 1 / 2 / 4 px) than along columns (0.49 / 0.29 / 0.01),
#: and 8 x 8 block means keep 12-27 times the variance independent pixels would leave (the fit's degree
#: decides); this field keeps 11 there, and 11.5-15 over discs of 4-20 px radius (4 pi 1.5 0.9 = 17 at most).
KINECT_NOISE_CORR_PX = (1.5, 0.9)
#: Lateral jitter of depth edges: standard deviation (pixels) of the shift of a pixel's sample and the standard
#: deviation (pixels) of the Gaussian that correlates it between neighbours. From the straight vertical sides
#: of the monitor in the real TUM frame ``../shared/realdata/rgbd_tum_desk/1_depth.png`` (rows 105-204, 1.4-1.6 m):
#: the edge column's residual from a line has 0.77 / 0.92 px sd, correlated 0.80 / 0.75, 0.70 / 0.48 and
#: 0.38 / 0.23 at 1, 2 and 4 rows (``benchmarks/bench_depth_noise_real.py``, edge section); a 0.9 px shift
#: smoothed over 2 px, rounded to whole pixels, gives 0.86 px there (``tests/test_depth_sensor.py``).
KINECT_EDGE_JITTER_PX = (0.9, 2.0)
#: RMS (pixels of a 640 px wide image) of the Kinect's fixed disparity offset pattern, after its best affine fit
#: is removed. From the floor of the real frames ``../shared/realdata/rgbd_kinect_room/depth/2..5.pgm`` (2-4 m):
#: per frame, inverse depth minus its affine (plane) fit, in 16 px blocks, converted to disparity with
#: :data:`KINECT_FOCAL_BASELINE_PX_M`; the frames' residuals agree in image coordinates although the camera moved
#: 1 m between them (correlation 0.59-0.77), which the floor's own shape cannot do; the part they share is
#: 0.051 px RMS (0.31 % of the depth at 2.6 m, 8 mm). The lab's field measured the same way on the same
#: planes and pixels shows 1.03 times that with 0.068 px over eight units (0.86-1.34)
#: (``benchmarks/bench_depth_pattern_real.py``); at 5 m it moves depths by 4 cm RMS.
KINECT_PATTERN_DISPARITY_PX = 0.068
#: Standard deviations (u, v) of the Gaussian that smooths the pattern, pixels of a 640 px wide image: the
#: shared residual's correlation at 32 px lag is 0.42 along u and 0.53 along v; the lab's field, measured the
#: same way over eight units, 1.04 and 0.95 times that (0.51-1.54 and 0.23-1.36).
KINECT_PATTERN_CORR_PX = (24.0, 26.0)
#: Focal length times baseline of a Kinect v1's infrared camera and projector, pixels x metres (580 px, 7.5 cm):
#: a disparity offset ``d`` moves a depth ``z`` to ``1 / (1 / z + d / (f b))``.
KINECT_FOCAL_BASELINE_PX_M = 43.5
NATIVE_WIDTH_PX = 640          # the width ``noise_corr_px`` is given for


def _width_scale(width_px) -> float:
    """Pixel scales given for the sensor's own 640 px wide image, in an image ``width_px`` wide."""
    return float(width_px) / NATIVE_WIDTH_PX


def _two_numbers(name: str, value, labels: str) -> tuple:
    """``value`` as two floats, or a ValueError naming ``name``."""
    try:
        a, b = (float(c) for c in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected two numbers {labels}, got {value!r}") from None
    return a, b


@dataclass(frozen=True, kw_only=True)
class DepthSensorModel:
    """Kinect-like depth sensor model.

    Parameters
    ----------
    min_depth_m, max_depth_m : float
        Usable range, metres; pixels whose true z is outside give 0.
    noise : tudorvision.sensors.DepthNoiseModel
        Depth noise sigma_z(z) in metres (default: the seed's Kinect fit).
    edge_jump_rel : float
        A pixel is invalid when a 4-neighbour's depth differs by more than
        this fraction of its own depth (depth discontinuity).
    edge_width_px : int
        Dilation of the invalid edge band (1: just the pixels at the jump).
    min_albedo : float
        Surfaces darker than this (mean linear RGB albedo) return no depth.
    units_per_m : float
        Scale of the 16-bit output (1000: millimetres).
    noise_corr_px : tuple of float
        Standard deviations (u, v) of the Gaussian that correlates the noise between pixels, in pixels
        of an image 640 px wide (the sensor's own resolution; scaled with the image width, so that a
        320 x 240 render sees half as many pixels of correlation) (:func:`noise_field`); ``(0, 0)``:
        independent pixels (the lab before 2026-11-27).
    edge_jitter_px : tuple of float
        ``(sigma, corr)``, pixels of a 640 px wide image (scaled like ``noise_corr_px``): every pixel
        samples the scene at a point shifted by a Gaussian of standard deviation ``sigma`` along u and v,
        correlated between pixels by a Gaussian of ``corr`` (:func:`noise_field`), rounded to whole
        pixels, where that point lies across a depth edge (a jump of more than ``edge_jump_rel``; a
        smooth surface keeps its own sample), as a real Kinect's block matching places depth edges
        (:data:`KINECT_EDGE_JITTER_PX`);
        ``(0, 0)``: edges where the scene has them (the lab before 2026-11-28).
    pattern_disparity_px : float
        RMS of the fixed disparity offset pattern, pixels of a 640 px wide image (:func:`pattern_field`;
        default :data:`KINECT_PATTERN_DISPARITY_PX`, the measured Kinect); 0: none (the lab before 2026-12-06).
        It is applied with or without noise: it is the unit's, not the frame's.
    pattern_corr_px : tuple of float
        Standard deviations (u, v) of the pattern's smoothing Gaussian, pixels of a 640 px wide image.
    pattern_seed : int
        Which unit: the pattern's own random seed (every frame of a sensor shares its pattern).
    focal_baseline_px_m : float
        ``f * b`` of the depth camera, pixels x metres, converting the disparity offset to depth.

    Raises
    ------
    ValueError
        An empty range, a ``noise`` that is not a ``DepthNoiseModel``, a
        non-positive ``edge_jump_rel``, a bad ``edge_width_px`` or a scale
        that does not fit ``max_depth_m`` in 16 bits.

    Examples
    --------
    >>> m = DepthSensorModel()
    >>> (m.min_depth_m, m.max_depth_m, round(float(m.noise.sigma_m(1.0)), 5))    # 1.35 mm at 1 m
    (0.6, 6.0, 0.00135)
    """

    min_depth_m: float = KINECT_RANGE_M[0]
    max_depth_m: float = KINECT_RANGE_M[1]
    noise: DepthNoiseModel = KINECT_DEPTH_NOISE
    edge_jump_rel: float = 0.03
    edge_width_px: int = 1
    min_albedo: float = 0.03
    units_per_m: float = 1000.0
    noise_corr_px: tuple = KINECT_NOISE_CORR_PX
    edge_jitter_px: tuple = KINECT_EDGE_JITTER_PX
    pattern_disparity_px: float = KINECT_PATTERN_DISPARITY_PX
    pattern_corr_px: tuple = KINECT_PATTERN_CORR_PX
    pattern_seed: int = 0
    focal_baseline_px_m: float = KINECT_FOCAL_BASELINE_PX_M

    def __post_init__(self):
        if not 0 <= self.min_depth_m < self.max_depth_m:
            raise ValueError(f"max_depth_m: expected 0 <= min_depth_m < max_depth_m, got "
                             f"{self.min_depth_m}, {self.max_depth_m}")
        if not isinstance(self.noise, DepthNoiseModel):
            raise ValueError(f"noise: expected a tudorvision.sensors.DepthNoiseModel, got {type(self.noise).__name__}")
        if not self.edge_jump_rel > 0:
            raise ValueError(f"edge_jump_rel: expected > 0, got {self.edge_jump_rel}")
        if int(self.edge_width_px) != self.edge_width_px or self.edge_width_px < 0:
            raise ValueError(f"edge_width_px: expected a non-negative integer, got {self.edge_width_px}")
        if not self.units_per_m > 0 or self.max_depth_m * self.units_per_m > 65535:
            raise ValueError(f"units_per_m: expected > 0 with max_depth_m * units_per_m <= 65535, "
                             f"got {self.units_per_m}")
        su, sv = _two_numbers("noise_corr_px", self.noise_corr_px, "(u, v)")
        if not (0 <= su <= 20 and 0 <= sv <= 20):
            raise ValueError(f"noise_corr_px: expected two standard deviations in [0, 20] px, "
                             f"got {self.noise_corr_px!r}")
        js, jc = _two_numbers("edge_jitter_px", self.edge_jitter_px, "(sigma, corr)")
        if not (0 <= js <= 5 and 0 <= jc <= 20):
            raise ValueError(f"edge_jitter_px: expected sigma in [0, 5] px and corr in [0, 20] px, "
                             f"got {self.edge_jitter_px!r}")
        if not 0 <= float(self.pattern_disparity_px) <= 2:
            raise ValueError(f"pattern_disparity_px: expected an RMS in [0, 2] px, got {self.pattern_disparity_px!r}")
        pu, pv = _two_numbers("pattern_corr_px", self.pattern_corr_px, "(u, v)")
        if not (1 <= pu <= 200 and 1 <= pv <= 200):
            raise ValueError(f"pattern_corr_px: expected two standard deviations in [1, 200] px, "
                             f"got {self.pattern_corr_px!r}")
        if int(self.pattern_seed) != self.pattern_seed or self.pattern_seed < 0:
            raise ValueError(f"pattern_seed: expected a non-negative integer, got {self.pattern_seed!r}")
        if not self.focal_baseline_px_m > 0:
            raise ValueError(f"focal_baseline_px_m: expected > 0, got {self.focal_baseline_px_m!r}")

    def corr_px_for_width(self, width_px: int) -> tuple:
        """``noise_corr_px`` for an image ``width_px`` wide (it is given for 640 px).

        Parameters
        ----------
        width_px : int
            Width of the whole image, pixels.

        Returns
        -------
        tuple of float
            Standard deviations (u, v) of the correlating Gaussian in that image, pixels.

        Examples
        --------
        >>> DepthSensorModel().corr_px_for_width(320)
        (0.75, 0.45)
        """
        k = _width_scale(width_px)
        return (k * float(self.noise_corr_px[0]), k * float(self.noise_corr_px[1]))

    def jitter_reach_px(self, width_px: int) -> int:
        """How far (whole pixels) the edge jitter can move an edge in an image ``width_px`` wide: 4 sigma.

        Parameters
        ----------
        width_px : int
            Width of the whole image, pixels.

        Returns
        -------
        int
            ``ceil(4 sigma)`` with sigma scaled to that width; 0 without jitter.

        Examples
        --------
        >>> DepthSensorModel().jitter_reach_px(640), DepthSensorModel(edge_jitter_px=(0, 0)).jitter_reach_px(640)
        (4, 0)
        """
        return int(math.ceil(4.0 * float(self.edge_jitter_px[0]) * _width_scale(width_px)))

    @property
    def sigma_coeffs_cm(self) -> DepthNoiseModel:
        """Deprecated stand-in for ``sim/roi_render.py`` until it calls ``model.noise.sigma_m``; remove then."""
        return self.noise


#: Old name, kept only while ``sim/render.py`` imports it; use :class:`DepthSensorModel`.
DepthModel = DepthSensorModel


def depth_sigma_m(z_m, noise: DepthNoiseModel = KINECT_DEPTH_NOISE) -> np.ndarray:
    """Deprecated: ``noise.sigma_m(z_m)``; kept only while ``sim/render.py`` and ``sim/roi_render.py`` import it."""
    return noise.sigma_m(z_m)


def _gauss_1d(sigma: float) -> np.ndarray:
    if sigma <= 0:
        return np.ones(1)
    r = int(math.ceil(4.0 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    return k / np.linalg.norm(k)           # unit energy: white noise keeps its variance through it


def noise_field(shape, rng: np.random.Generator, corr_px=(0.0, 0.0), dtype=np.float64) -> np.ndarray:
    """Zero-mean, unit-variance Gaussian noise image, correlated between neighbouring pixels.

    One ``rng.standard_normal(shape, dtype)`` draw (returned as it is for ``corr_px = (0, 0)``; the same
    draw whatever ``corr_px``, so the generator's later draws do not change with it) filtered by a
    separable Gaussian of standard deviations ``corr_px`` (along u, along v) whose kernels have unit
    energy, the image wrapped around at its borders: every pixel has variance 1, and pixels
    ``(du, dv)`` apart (and not near opposite borders) have the correlation
    ``exp(-du^2 / (4 su^2) - dv^2 / (4 sv^2))`` (for scales of about a pixel and more; a sampled Gaussian
    narrower than that correlates neighbours less).

    Parameters
    ----------
    shape : tuple of int
        ``(H, W)``.
    rng : numpy.random.Generator
        Source of the draw.
    corr_px : tuple of float
        Standard deviations ``(su, sv)`` of the smoothing Gaussian, pixels (0: none along that axis).
    dtype : numpy dtype
        float32 or float64.

    Returns
    -------
    ndarray, shape (H, W)
        The field, ``dtype``.

    Examples
    --------
    >>> f = noise_field((400, 400), np.random.default_rng(0), (1.5, 0.9))
    >>> lag1 = np.corrcoef(f[:, 1:].ravel(), f[:, :-1].ravel())[0, 1]     # neighbours along u: exp(-1 / 9)
    >>> round(float(f.std()), 1), round(float(lag1), 1)
    (1.0, 0.9)
    >>> np.array_equal(noise_field((3, 4), np.random.default_rng(1)), np.random.default_rng(1).standard_normal((3, 4)))
    True
    """
    n = rng.standard_normal(shape, dtype=dtype)
    su, sv = (float(c) for c in corr_px)
    if su <= 0 and sv <= 0:
        return n
    kx, ky = _gauss_1d(su).astype(dtype), _gauss_1d(sv).astype(dtype)
    rx, ry = len(kx) // 2, len(ky) // 2
    h, w = n.shape
    # wrapped around (no mirrored border, whose repeated samples would raise the variance there)
    wide = np.pad(n, ((ry, ry), (rx, rx)), mode="wrap")
    return cv2.sepFilter2D(wide, -1, kx, ky)[ry:ry + h, rx:rx + w]


@functools.lru_cache(maxsize=16)
def _pattern_cached(rms_px: float, corr_px: tuple, seed: int, fb: float, height: int, width: int) -> np.ndarray:
    rng = np.random.default_rng([int(seed), 0x9A77E])
    k = _width_scale(width)
    f = noise_field((height, width), rng, (k * corr_px[0], k * corr_px[1]))
    vv, uu = np.mgrid[0:height, 0:width].astype(np.float64)
    A = np.stack([np.ones(f.size), uu.ravel(), vv.ravel()], 1)
    f = f - (A @ np.linalg.lstsq(A, f.ravel(), rcond=None)[0]).reshape(f.shape)
    f *= (rms_px / fb) / float(np.sqrt(np.mean(f * f)))
    f.setflags(write=False)
    return f


def pattern_field(model: DepthSensorModel, height: int, width: int) -> np.ndarray:
    """The sensor unit's fixed inverse-depth offset over a ``height x width`` image, 1/m.

    A smooth Gaussian field (:func:`noise_field` of ``model.pattern_corr_px``, scaled to the width, drawn
    from ``model.pattern_seed`` alone), its best affine fit in (u, v) removed, scaled to an RMS of
    ``model.pattern_disparity_px / model.focal_baseline_px_m``: the sensor reports ``1 / (1 / z + c)``
    for a true depth ``z`` where the field is ``c``. Computed once per model and size (read-only).

    Parameters
    ----------
    model : DepthSensorModel
        ``pattern_disparity_px``, ``pattern_corr_px``, ``pattern_seed``, ``focal_baseline_px_m``.
    height, width : int
        The whole image, pixels.

    Returns
    -------
    ndarray, shape (height, width), float64
        ``c``, 1/m; zeros when ``pattern_disparity_px`` is 0.

    Examples
    --------
    >>> m = DepthSensorModel(pattern_disparity_px=0.05)
    >>> c = pattern_field(m, 480, 640)
    >>> round(float(np.sqrt(np.mean(c ** 2)) * m.focal_baseline_px_m), 3)       # the RMS, disparity pixels
    0.05
    >>> z = 5.0; round(float(np.abs(1 / (1 / z + c) - z).max()) * 1000) > 10       # centimetres at 5 m
    True
    >>> float(np.abs(pattern_field(DepthSensorModel(pattern_disparity_px=0), 4, 6)).max())
    0.0
    """
    if float(model.pattern_disparity_px) == 0.0:
        return np.zeros((int(height), int(width)))
    corr = tuple(float(c) for c in model.pattern_corr_px)
    return _pattern_cached(float(model.pattern_disparity_px), corr, int(model.pattern_seed),
                           float(model.focal_baseline_px_m), int(height), int(width))


def with_pattern(z: np.ndarray, model: DepthSensorModel, shape: tuple, origin=(0, 0)) -> np.ndarray:
    """True depths as the sensor's fixed pattern reports them (:func:`pattern_field`).

    Parameters
    ----------
    z : ndarray, shape (h, w)
        True depths, metres; 0 (invalid) stays 0.
    model : DepthSensorModel
        Its pattern; ``z`` itself is returned when it has none.
    shape : tuple of int
        ``(H, W)`` of the whole image.
    origin : tuple of int
        ``(v0, u0)``: where ``z[0, 0]`` lies in the whole image (a crop).

    Returns
    -------
    ndarray, shape (h, w)
        ``1 / (1 / z + c)`` where ``z > 0``, ``z``'s dtype.

    Examples
    --------
    >>> m = DepthSensorModel(pattern_disparity_px=0.05)
    >>> z = np.full((480, 640), 3.0)
    >>> np.allclose(with_pattern(z, m, (480, 640))[100:110, 200:220],
    ...             with_pattern(z[100:110, 200:220], m, (480, 640), origin=(100, 200)))
    True
    """
    if float(model.pattern_disparity_px) == 0.0:
        return z
    v0, u0 = (int(o) for o in origin)
    c = pattern_field(model, *shape)[v0:v0 + z.shape[0], u0:u0 + z.shape[1]]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(z > 0, 1.0 / (1.0 / z + c), z).astype(z.dtype, copy=False)


def _jittered(z: np.ndarray, albedo: np.ndarray, model: DepthSensorModel, rng, width_px: int):
    """Depth and albedo resampled at positions shifted by the edge jitter (nearest pixel, clipped), where the
    shifted sample lies across a depth edge (a jump of more than ``edge_jump_rel``); elsewhere unchanged.

    The two fields are drawn whole (the generator's later draws do not depend on the scene); only pixels
    within the jitter's reach of a depth edge are resampled.
    """
    k = _width_scale(width_px)
    sigma, corr = k * float(model.edge_jitter_px[0]), k * float(model.edge_jitter_px[1])
    if sigma <= 0:
        return z, albedo
    du = noise_field(z.shape, rng, (corr, corr), np.float32)
    dv = noise_field(z.shape, rng, (corr, corr), np.float32)
    reach = model.jitter_reach_px(width_px)
    near = _edge_mask(z, model.edge_jump_rel, 1)
    if not near.any():
        return z, albedo
    near = cv2.dilate(near.view(np.uint8), np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)).astype(bool)
    v, u = np.nonzero(near)
    h, w = z.shape
    iu = np.clip(np.rint(u + sigma * du[v, u]).astype(np.intp), 0, w - 1)
    iv = np.clip(np.rint(v + sigma * dv[v, u]).astype(np.intp), 0, h - 1)
    z0, zj = z[v, u], z[iv, iu]
    # only across a depth edge: a smooth surface keeps its own sample (block matching is sub-pixel there)
    with np.errstate(invalid="ignore"):
        across = ~(np.abs(zj - z0) <= model.edge_jump_rel * np.minimum(z0, zj))
    z, albedo = z.copy(), albedo.copy()
    z[v[across], u[across]] = zj[across]
    albedo[v[across], u[across]] = albedo[iv[across], iu[across]]
    return z, albedo


def _edge_mask(z: np.ndarray, rel: float, width: int) -> np.ndarray:
    zf = np.where(np.isfinite(z), z, 1e9)
    edge = np.zeros(z.shape, bool)
    for a, b in ((np.s_[:, 1:], np.s_[:, :-1]), (np.s_[1:, :], np.s_[:-1, :])):
        jump = np.abs(zf[a] - zf[b]) > rel * np.minimum(zf[a], zf[b])
        edge[a] |= jump
        edge[b] |= jump
    if width > 1:
        edge = cv2.dilate(edge.view(np.uint8), np.ones((2 * width - 1, 2 * width - 1), np.uint8)).astype(bool)
    return edge if width > 0 else np.zeros_like(edge)


def depth_mm_from_gbuffer(gbuffer: GBuffer, model: DepthSensorModel, rng: np.random.Generator | None, *,
                          image_width_px: int | None = None, image_height_px: int | None = None,
                          image_origin_px=(0, 0)) -> np.ndarray:
    """Registered 16-bit depth image from a ray-cast G-buffer.

    Depth is z along the optical axis plus Gaussian noise of std
    ``model.noise.sigma_m(z)``, correlated between pixels by ``model.noise_corr_px``
    (:func:`noise_field`), rounded to ``1 / model.units_per_m`` metres;
    0 marks invalid pixels (out of range, no hit, depth edges, dark surfaces).
    With noise, a pixel whose position shifted by the edge jitter
    (``model.edge_jitter_px``, whole pixels, clipped to the buffer) lies
    across a depth edge first takes the G-buffer's sample there, so that
    depth edges wander as a real sensor's do; the depth noise is drawn
    first, then the two jitter fields. The sensor's fixed pattern
    (``model.pattern_disparity_px``, :func:`pattern_field`) moves every valid
    depth before the noise, with or without ``rng``.

    Parameters
    ----------
    gbuffer : GBuffer
        Ray-cast buffers; ``depth_m`` (H, W) in metres, ``albedo_rgb`` (H, W, 3).
    model : DepthSensorModel
        Range, noise, edge and albedo rules, output scale.
    rng : numpy.random.Generator or None
        Noise source (``standard_normal((H, W))`` draws: depth noise, then jitter along u and v,
        :func:`noise_field`); None: no noise, no jitter.
    image_width_px : int, optional
        Width of the whole image when ``gbuffer`` is a crop of it (the noise's correlation scales with
        it, :meth:`DepthSensorModel.corr_px_for_width`); default the G-buffer's own width.
    image_height_px : int, optional
        Height of the whole image (the fixed pattern is the whole image's); default the G-buffer's.
    image_origin_px : tuple of int
        ``(v0, u0)``: where the G-buffer's first pixel lies in the whole image (a crop), default (0, 0).

    Returns
    -------
    ndarray, shape (H, W), uint16
        Raw depth in ``1 / model.units_per_m`` metres, 0 = invalid.
    """
    z, albedo = gbuffer.depth_m, gbuffer.albedo_rgb
    width = image_width_px or z.shape[1]
    noise = None
    if rng is not None:
        noise = noise_field(z.shape, rng, model.corr_px_for_width(width))
        z, albedo = _jittered(z, albedo, model, rng, width)
    valid = np.isfinite(z) & (z >= model.min_depth_m) & (z <= model.max_depth_m)
    valid &= ~_edge_mask(z, model.edge_jump_rel, int(model.edge_width_px))
    valid &= albedo.mean(axis=2) >= model.min_albedo
    zv = np.where(valid, z, 0.0)
    zv = with_pattern(zv, model, (image_height_px or z.shape[0], width), image_origin_px)
    if noise is not None:
        zv = zv + model.noise.sigma_m(zv) * noise
    out = np.clip(np.rint(zv * model.units_per_m), 1, 65535)
    return np.where(valid, out, 0).astype(np.uint16)
