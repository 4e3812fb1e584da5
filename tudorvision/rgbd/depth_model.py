"""Depth uncertainty model sigma_z(z) and its calibration (sections 2.3, 9.3).

A planar target perpendicular to the optical axis is recorded at stepped
distances, about 100 frames per distance. Per distance, sigma is the mean over
the planar region of the per-pixel temporal standard deviation; the bias is the
depth of a plane fitted to the per-pixel mean depths minus the nominal target
distance. ``sigma_z(z)`` is fitted as the seed's cubic polynomial and
returned as a :class:`tudorvision.sensors.DepthNoiseModel` (SI units); the
seed's own fit is :data:`tudorvision.sensors.KINECT_DEPTH_NOISE`.
"""
from __future__ import annotations

import csv
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError, check_array
from ..sensors import KINECT_DEPTH_NOISE, KINECT_SIGMA_UNIT, KINECT_SIGMA_Z_COEFFS, DepthNoiseModel
from .frames import Intrinsics, check_depth

__all__ = [
    "DepthStepStats", "planar_region_mask",
    "depth_step_stats", "fit_depth_model", "calibrate_depth_model",
    "write_depth_table_csv", "read_depth_table_csv", "plot_depth_model",
]

TABLE_COLUMNS = ("distance_m", "sigma_m", "bias_m", "n_pixels")


@dataclass(frozen=True)
class DepthStepStats:
    """Depth statistics of one target distance (one row of the calibration table).

    ``distance_m``: nominal distance if given, else the fitted plane's depth;
    ``sigma_m``: mean per-pixel temporal std; ``bias_m``: plane depth minus
    nominal distance (NaN without a nominal distance); ``n_pixels``: pixels in
    the planar region; ``plane_rms_m``: RMS of the mean depths about the plane.
    """

    distance_m: float
    sigma_m: float
    bias_m: float
    n_pixels: int
    plane_rms_m: float = float("nan")


def _check_stack(stack, intrinsics: Intrinsics | None) -> np.ndarray:
    s = np.array(stack, dtype=np.float64)
    if s.ndim != 3:
        raise ValueError(f"depth_stack: expected shape (F, H, W), got {s.shape}")
    if s.shape[0] < 2:
        raise TudorVisionError(f"depth_stack: need at least 2 frames for a temporal std, got {s.shape[0]}")
    if intrinsics is not None and s.shape[1:] != intrinsics.shape:
        raise ValueError(f"depth_stack: frame shape {s.shape[1:]} does not match intrinsics {intrinsics.shape}")
    with np.errstate(invalid="ignore"):
        s[~(s > 0) | ~np.isfinite(s)] = np.nan
    if not np.any(np.isfinite(s)):
        raise TudorVisionError("depth_stack: no valid depth in any frame (all zero or invalid)")
    return s


def planar_region_mask(mean_depth_m, *, roi=None, rel_tol: float = 0.05,
                       min_pixels: int = 100) -> np.ndarray:
    """Planar evaluation region in a (temporal mean) depth image.

    Parameters
    ----------
    mean_depth_m : array_like, shape (H, W)
        Per-pixel mean depth, metres, NaN = invalid.
    roi : tuple (u0, v0, u1, v1), optional
        Pixel box (u right, v down; end exclusive). When given, the region is
        the valid pixels of the box. Otherwise automatic (the target sits on
        the optical axis): the connected region of valid pixels within
        ``rel_tol`` of the median depth of the central image window that
        contains (or lies nearest to) the image centre.
    rel_tol : float
        Relative depth tolerance of the automatic region.
    min_pixels : int
        Minimum region size.

    Returns
    -------
    mask : ndarray of bool, shape (H, W)

    Raises
    ------
    TudorVisionError
        If the region has fewer than ``min_pixels`` pixels.
    """
    import cv2

    d = check_depth(mean_depth_m, "mean_depth_m")
    valid = np.isfinite(d)
    if roi is not None:
        u0, v0, u1, v1 = (int(x) for x in roi)
        if not (0 <= u0 < u1 <= d.shape[1] and 0 <= v0 < v1 <= d.shape[0]):
            raise ValueError(f"roi: expected (u0, v0, u1, v1) inside the {d.shape[1]}x{d.shape[0]} image, got {roi}")
        mask = np.zeros_like(valid)
        mask[v0:v1, u0:u1] = valid[v0:v1, u0:u1]
    else:
        h, w = d.shape
        vc, uc = h // 2, w // 2
        centre = d[vc - max(1, h // 10): vc + max(1, h // 10) + 1, uc - max(1, w // 10): uc + max(1, w // 10) + 1]
        if not np.any(np.isfinite(centre)):
            raise TudorVisionError("planar region: no valid depth near the image centre (give an roi)")
        med = float(np.nanmedian(centre))
        with np.errstate(invalid="ignore"):
            cand = valid & (np.abs(d - med) <= rel_tol * med)
        _, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=4)
        vv, uu = np.nonzero(labels)
        if len(vv) == 0:
            mask = cand
        else:
            k = int(np.argmin((vv - vc) ** 2 + (uu - uc) ** 2))
            mask = labels == labels[vv[k], uu[k]]
    if int(mask.sum()) < min_pixels:
        raise TudorVisionError(f"planar region has {int(mask.sum())} valid pixels, need at least {min_pixels}")
    return mask


def _fit_plane_depth(u, v, z):
    """Least-squares plane in (x, y, z) expressed as depth; returns predicted z at the pixels."""
    # a plane not through the camera centre: 1/z is affine in the normalised coordinates
    A = np.stack([u, v, np.ones_like(u)], axis=1)
    coef, *_ = np.linalg.lstsq(A, 1.0 / z, rcond=None)
    return 1.0 / (A @ coef)


def depth_step_stats(depth_stack_m, intrinsics: Intrinsics, *, nominal_distance_m: float | None = None,
                     roi=None, min_valid_fraction: float = 0.9, rel_tol: float = 0.05,
                     min_pixels: int = 100) -> DepthStepStats:
    """Noise and bias of one target distance from a stack of depth frames.

    Parameters
    ----------
    depth_stack_m : array_like, shape (F, H, W)
        Depth frames in metres (NaN or 0 = invalid) of a static planar target.
    intrinsics : Intrinsics
    nominal_distance_m : float, optional
        True target distance along the optical axis; gives the bias.
    roi : tuple (u0, v0, u1, v1), optional
        Planar region; automatic when omitted (see :func:`planar_region_mask`).
    min_valid_fraction : float
        Pixels valid in fewer frames than this fraction are left out.

    Returns
    -------
    DepthStepStats

    Raises
    ------
    TudorVisionError
        Fewer than 2 frames, no valid depth, or a too small planar region.
    """
    s = _check_stack(depth_stack_m, intrinsics)
    n_valid = np.sum(np.isfinite(s), axis=0)
    steady = n_valid >= max(2, int(np.ceil(min_valid_fraction * s.shape[0])))
    if not np.any(steady):
        raise TudorVisionError("depth_stack: no pixel is valid in enough frames "
                               f"(min_valid_fraction={min_valid_fraction:g})")
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.where(steady, np.nanmean(s, axis=0), np.nan)
        std = np.nanstd(s, axis=0, ddof=1)
    mask = planar_region_mask(mean, roi=roi, rel_tol=rel_tol, min_pixels=min_pixels) & steady
    if int(mask.sum()) < min_pixels:
        raise TudorVisionError(f"planar region has {int(mask.sum())} steady pixels, need at least {min_pixels}")
    v, u = np.nonzero(mask)
    xn = (u - intrinsics.cx) / intrinsics.fx
    yn = (v - intrinsics.cy) / intrinsics.fy
    z = mean[v, u]
    z_plane = _fit_plane_depth(xn, yn, z)
    plane_rms = float(np.sqrt(np.mean((z - z_plane) ** 2)))
    z_fit = float(np.mean(z_plane))
    sigma = float(np.mean(std[v, u]))
    if nominal_distance_m is None:
        return DepthStepStats(z_fit, sigma, float("nan"), int(mask.sum()), plane_rms)
    nominal = float(nominal_distance_m)
    return DepthStepStats(nominal, sigma, z_fit - nominal, int(mask.sum()), plane_rms)


def fit_depth_model(distances_m, sigmas_m, *, degree: int = 3) -> DepthNoiseModel:
    """Fit ``sigma_z(z)`` as a polynomial (the seed's cubic by default).

    Weighted least squares with weights ``1 / sigma`` so that the relative
    error is balanced over the range (sigma grows by two orders of magnitude
    from 0.6 to 6 m).

    Parameters
    ----------
    distances_m, sigmas_m : array_like, shape (N,)
        N >= degree + 1 distinct distances, positive sigmas; metres.
    degree : int
        Polynomial degree.

    Returns
    -------
    DepthNoiseModel
        Coefficients in metres, ``z_range_m`` the span of the distances,
        the default ``floor_m``.

    Raises
    ------
    TudorVisionError
        Too few distances for the degree.
    ValueError
        Non-positive sigmas, mismatched lengths.

    Examples
    --------
    >>> z = np.linspace(0.6, 6.0, 10)
    >>> from tudorvision.sensors import KINECT_DEPTH_NOISE
    >>> m = fit_depth_model(z, KINECT_DEPTH_NOISE.sigma_m(z))
    >>> np.allclose(m.coeffs, KINECT_DEPTH_NOISE.coeffs)
    True
    """
    z = check_array(distances_m, "distances_m", (None,))
    s = check_array(sigmas_m, "sigmas_m", (len(z),))
    if len(np.unique(z)) < degree + 1:
        raise TudorVisionError(f"need at least {degree + 1} distinct distances for a degree-{degree} fit, "
                               f"got {len(np.unique(z))}")
    if np.any(s <= 0):
        raise ValueError("sigmas_m: expected positive values")
    coeffs = np.polyfit(z, s, degree, w=1.0 / s)
    return DepthNoiseModel(coeffs=tuple(coeffs), z_range_m=(float(z.min()), float(z.max())))


def calibrate_depth_model(stacks, intrinsics: Intrinsics, *, nominal_distances_m=None, rois=None,
                          degree: int = 3, **step_options) -> tuple[DepthNoiseModel, list[DepthStepStats]]:
    """Full depth calibration: statistics per distance, then the polynomial fit.

    Parameters
    ----------
    stacks : sequence of array_like, each shape (F, H, W)
        One depth stack (metres) per target distance.
    intrinsics : Intrinsics
        Depth camera intrinsics (the planar fit works on back-projected points).
    nominal_distances_m : sequence of float, optional
        True distances (for the bias column).
    rois : sequence of (u0, v0, u1, v1) or None, optional
        Planar region per stack.
    degree : int
        Polynomial degree of ``sigma_z(z)`` (3 as in the seed).
    **step_options
        Passed to :func:`depth_step_stats`.

    Returns
    -------
    model : DepthNoiseModel
    table : list of DepthStepStats
        Sorted by distance.
    """
    n = len(stacks)
    nominal = [None] * n if nominal_distances_m is None else list(nominal_distances_m)
    rr = [None] * n if rois is None else list(rois)
    if len(nominal) != n or len(rr) != n:
        raise ValueError(f"nominal_distances_m / rois: expected {n} entries, one per stack")
    table = [depth_step_stats(s, intrinsics, nominal_distance_m=d, roi=r, **step_options)
             for s, d, r in zip(stacks, nominal, rr)]
    table.sort(key=lambda row: row.distance_m)
    model = fit_depth_model([r.distance_m for r in table], [r.sigma_m for r in table], degree=degree)
    return model, table


def write_depth_table_csv(path, table) -> Path:
    """Write the calibration table (columns distance_m, sigma_m, bias_m, n_pixels).

    Parameters
    ----------
    path : str or Path
        Output CSV.
    table : sequence of DepthStepStats
        Rows, SI units.

    Returns
    -------
    Path
        ``path``.
    """
    from ..io.atomic import atomic_write
    path = Path(path)
    with atomic_write(path, "w", newline="", mkdir=False) as fh:
        w = csv.writer(fh)
        w.writerow(TABLE_COLUMNS)
        for r in table:
            w.writerow([f"{r.distance_m:.6f}", f"{r.sigma_m:.6g}", f"{r.bias_m:.6g}", int(r.n_pixels)])
    return path


def read_depth_table_csv(path) -> list[DepthStepStats]:
    """Read a table written by :func:`write_depth_table_csv`.

    Parameters
    ----------
    path : str or Path
        CSV file.

    Returns
    -------
    list of DepthStepStats

    Raises
    ------
    TudorVisionError
        Missing columns (the message names the file).
    """
    path = Path(path)
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    try:
        return [DepthStepStats(float(r["distance_m"]), float(r["sigma_m"]), float(r["bias_m"]),
                               int(r["n_pixels"])) for r in rows]
    except (KeyError, ValueError) as exc:
        raise TudorVisionError(f"{path}: invalid depth table ({exc})") from None


def plot_depth_model(path, table, model: DepthNoiseModel, *,
                     reference: DepthNoiseModel | None = KINECT_DEPTH_NOISE) -> Path:
    """PNG plot of measured sigma per distance and the fitted ``sigma_z(z)`` (millimetres).

    Draws on its own :class:`matplotlib.figure.Figure` (the global backend is not touched).

    Parameters
    ----------
    path : str or Path
        Output PNG.
    table : sequence of DepthStepStats
        Measured per-distance statistics (distance and sigma in metres).
    model : DepthNoiseModel
        Fitted model (SI units).
    reference : DepthNoiseModel, optional
        Drawn dashed for comparison (default: the seed's Kinect fit); ``None`` to omit.

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.figure import Figure

    path = Path(path)
    d = np.array([r.distance_m for r in table])
    s = np.array([r.sigma_m for r in table])
    lo, hi = min(model.z_range_m[0], d.min(initial=np.inf)), max(model.z_range_m[1], d.max(initial=-np.inf))
    z = np.linspace(lo, hi, 200)
    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    ax.plot(d, s * 1000, "o", label="measured (mean per-pixel std)")
    c = model.coeffs
    ax.plot(z, model.sigma_m(z) * 1000, "-", label="fit: " + " ".join(f"{1000 * a:+.3g}" for a in c) + " (mm, z in m)")
    if reference is not None:
        seed = "".join(f"{c:+g}{'z' if k else ''}{'²³'[k - 2] if k > 1 else ''}"
                       for c, k in zip(KINECT_SIGMA_Z_COEFFS, range(len(KINECT_SIGMA_Z_COEFFS) - 1, -1, -1)))
        ax.plot(z, reference.sigma_m(z) * 1000, "--", label=f"seed: {seed.lstrip('+')} ({KINECT_SIGMA_UNIT})")
    ax.set_xlabel("distance z [m]")
    ax.set_ylabel("σz [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path
