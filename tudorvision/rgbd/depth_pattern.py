"""A depth camera's fixed pattern: calibrated from frames of a flat wall, removed from every frame.

A structured-light depth camera (a Kinect) measures disparity with an offset
that changes slowly over the image and stays from frame to frame; it moves a
depth ``z`` by about ``z^2 d / (f b)`` and does not average away (on the real
Kinect frames of ``../shared/realdata/rgbd_kinect_room/`` about 0.05 px of
disparity, 8 mm at 2.6 m; ``benchmarks/bench_depth_pattern_real.py``). In
inverse depth it is an additive field ``c(u, v)``: the camera reports
``1 / (1 / z + c)``.

Calibration needs frames of a flat wall (or any plane filling most of the
view) at one or more distances and angles; the distances need not be known.
A plane is exactly affine in inverse depth, ``1/z = a + b u + c v``, so every
frame's robust affine fit leaves ``c`` minus its affine part plus noise; the
mean over frames, on a grid of ``step_px`` blocks, is the correction. The
affine part of ``c`` (an offset or a tilt of inverse depth) maps planes to
planes and cannot be seen this way; a bias calibration against known
distances (:mod:`tudorvision.rgbd.depth_model`) sees its offset.

The correction is stored in OpenCV's YAML (``cv2.FileStorage``) as the grid,
its step and the image size.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError
from ..io.atomic import atomic_path

__all__ = ["DepthPatternCorrection", "plane_residual_inv_depth", "calibrate_depth_pattern",
           "write_depth_pattern", "read_depth_pattern", "plot_depth_pattern"]

_TAG = "tudorvision_depth_pattern"


@dataclass(frozen=True)
class DepthPatternCorrection:
    """A depth camera's fixed inverse-depth offset, on a grid of blocks.

    Attributes
    ----------
    grid_inv_m : ndarray, shape (h, w)
        Mean inverse-depth offset ``c`` of each ``step_px x step_px`` block, 1/m (block ``(i, j)`` covers rows
        ``i * step_px ...`` and columns ``j * step_px ...``).
    step_px : int
        Block size, pixels.
    image_size : tuple of int
        ``(width, height)`` of the camera's image, pixels.
    n_frames : int
        Frames the calibration used.
    """

    grid_inv_m: np.ndarray
    step_px: int
    image_size: tuple
    n_frames: int = 0

    def __post_init__(self):
        g = np.asarray(self.grid_inv_m, dtype=np.float64)
        w, h = (int(v) for v in self.image_size)
        s = int(self.step_px)
        if s < 1 or w < 1 or h < 1:
            raise ValueError(f"step_px / image_size: expected positive, got {self.step_px}, {self.image_size}")
        if g.shape != (-(-h // s), -(-w // s)) or not np.all(np.isfinite(g)):
            raise ValueError(f"grid_inv_m: expected a finite ({-(-h // s)}, {-(-w // s)}) grid for "
                             f"{w} x {h} px in {s} px blocks, got shape {g.shape}")
        object.__setattr__(self, "grid_inv_m", g)

    @functools.cached_property
    def _field(self) -> np.ndarray:
        w, h = (int(v) for v in self.image_size)
        s = float(self.step_px)
        # block centres sit at (j + 0.5) s - 0.5; pixel u maps to grid coordinate (u + 0.5) / s - 0.5
        gu = np.clip((np.arange(w) + 0.5) / s - 0.5, 0, self.grid_inv_m.shape[1] - 1).astype(np.float32)
        gv = np.clip((np.arange(h) + 0.5) / s - 0.5, 0, self.grid_inv_m.shape[0] - 1).astype(np.float32)
        mu, mv = np.meshgrid(gu, gv)
        f = cv2.remap(self.grid_inv_m.astype(np.float32), mu, mv, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
        f.setflags(write=False)
        return f

    def field(self) -> np.ndarray:
        """The offset at every pixel, 1/m (bilinear between block centres), shape (height, width).

        Returns
        -------
        ndarray, shape (height, width), float64
            Read-only; computed once per correction.
        """
        return self._field

    def apply(self, depth_m, *, origin_px=(0, 0)) -> np.ndarray:
        """Depths with the pattern removed: ``1 / (1 / z - c)``; invalid pixels (0, NaN) stay as they are.

        Parameters
        ----------
        depth_m : array_like, shape (h, w)
            Depth in metres, the whole image or a crop of it.
        origin_px : tuple of int
            ``(v0, u0)`` of the crop's first pixel in the whole image.

        Returns
        -------
        ndarray, shape (h, w), float64

        Raises
        ------
        ValueError
            A crop that does not fit the calibrated image.

        Examples
        --------
        >>> corr = DepthPatternCorrection(np.full((2, 2), 0.01), 4, (8, 8))
        >>> z = 1 / (1 / np.full((8, 8), 2.0) + 0.01)             # what the camera reports for 2 m
        >>> np.allclose(corr.apply(z), 2.0)
        True
        """
        z = np.asarray(depth_m, dtype=np.float64)
        v0, u0 = (int(o) for o in origin_px)
        w, h = (int(v) for v in self.image_size)
        if z.ndim != 2 or v0 < 0 or u0 < 0 or v0 + z.shape[0] > h or u0 + z.shape[1] > w:
            raise ValueError(f"depth_m: a {z.shape} crop at {origin_px} does not fit the pattern's {w} x {h} image")
        c = self.field()[v0:v0 + z.shape[0], u0:u0 + z.shape[1]]
        with np.errstate(divide="ignore", invalid="ignore"):
            out = 1.0 / (1.0 / z - c)
        return np.where(np.isfinite(z) & (z > 0) & (out > 0), out, z)

    def correct_points(self, p_cam, intrinsics) -> np.ndarray:
        """3D points measured by the camera, with the pattern at their pixels removed (moved along their rays).

        For a detection that averages the depth over a few pixels (a ball, a disc) the pattern, smooth over
        tens of pixels, is the one at its centre: the point's depth ``z`` becomes ``1 / (1 / z - c(u, v))``
        at its pixel ``(u, v)`` (nearest pixel, clipped to the image), its pixel stays.

        Parameters
        ----------
        p_cam : array_like, shape (3,) or (N, 3)
            Points, metres, camera optical frame (z forward).
        intrinsics : Intrinsics
            ``fx, fy, cx, cy`` of the camera the correction belongs to (pixels).

        Returns
        -------
        ndarray, same shape as ``p_cam``

        Examples
        --------
        >>> from tudorvision.rgbd.frames import Intrinsics
        >>> corr = DepthPatternCorrection(np.full((2, 2), 0.01), 4, (8, 8))
        >>> K = Intrinsics(10.0, 10.0, 3.5, 3.5, 8, 8)
        >>> z = 1 / (1 / 2.0 + 0.01)                              # reported for a point 2 m away
        >>> corr.correct_points([0.1 * z, 0.0, z], K).round(6).tolist()
        [0.2, 0.0, 2.0]
        """
        p = np.asarray(p_cam, dtype=np.float64)
        q = np.atleast_2d(p)
        w, h = (int(v) for v in self.image_size)
        z = q[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.clip(np.rint(intrinsics.fx * q[:, 0] / z + intrinsics.cx), 0, w - 1)
            v = np.clip(np.rint(intrinsics.fy * q[:, 1] / z + intrinsics.cy), 0, h - 1)
        ok = np.isfinite(u) & np.isfinite(v) & (z > 0)
        c = np.zeros(len(q))
        c[ok] = self.field()[v[ok].astype(np.intp), u[ok].astype(np.intp)]
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(ok, 1.0 / (1.0 - z * c), 1.0)
        scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
        out = q * scale[:, None]
        return out.reshape(p.shape)


def plane_residual_inv_depth(depth_m, *, max_dev_m: float = 0.15, iterations: int = 4):
    """Inverse depth minus its robust affine (plane) fit in the pixel coordinates.

    The largest plane first (three-point draws: the plane most valid pixels
    lie within ``max_dev_m`` of), then least squares of ``1/z = a + b u + c v``
    over those pixels, again over the pixels within ``max_dev_m`` of the fit
    (and of 4 robust standard deviations), ``iterations`` times; pixels off the
    plane (things in front of the wall, its edges) drop out.

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        One frame, metres; 0 or NaN invalid.
    max_dev_m : float
        Largest depth deviation from the fit kept, metres.
    iterations : int
        Refits.

    Returns
    -------
    residual : ndarray, shape (H, W)
        ``1/z - fit``, 1/m; NaN off the plane and at invalid pixels.
    fraction : float
        Share of the image on the plane.

    Examples
    --------
    >>> vv, uu = np.mgrid[0:60, 0:80]
    >>> z = 1.0 / (0.3 + 1e-3 * uu - 2e-3 * vv)              # a tilted plane
    >>> r, f = plane_residual_inv_depth(z)
    >>> float(np.nanmax(np.abs(r))) < 1e-9, f
    (True, 1.0)
    """
    z = np.asarray(depth_m, dtype=np.float64)
    if z.ndim != 2:
        raise ValueError(f"depth_m: expected one (H, W) frame, got shape {z.shape}")
    vv, uu = np.mgrid[0:z.shape[0], 0:z.shape[1]].astype(np.float64)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(z) & (z > 0)
    if ok.sum() < 3:
        return np.full(z.shape, np.nan), 0.0
    inv = np.where(ok, 1.0 / np.where(ok, z, 1.0), np.nan)
    A = np.stack([np.ones(z.shape), uu, vv], -1)
    keep = _consensus(A[ok], inv[ok], z[ok], max_dev_m)
    keep = ok & (np.abs(1.0 / np.where(ok, A @ keep, 1.0) - np.where(ok, z, 0.0)) <= max_dev_m) \
        if keep is not None else ok.copy()
    fit = None
    for _ in range(max(1, int(iterations))):
        if keep.sum() < 3:
            return np.full(z.shape, np.nan), 0.0
        coef = np.linalg.lstsq(A[keep], inv[keep], rcond=None)[0]
        fit = A @ coef
        res = inv - fit
        mad = float(np.median(np.abs(res[keep])))
        with np.errstate(divide="ignore", invalid="ignore"):
            dev = np.abs(1.0 / fit - np.where(ok, z, np.nan))
            keep = ok & (fit > 0) & (dev <= max_dev_m) & (np.abs(res) <= max(4.0 * 1.4826 * mad, 1e-12))
    out = np.where(keep, inv - fit, np.nan)
    return out, float(keep.mean())


def _consensus(A, inv, z, max_dev_m: float, trials: int = 200, sample: int = 5000):
    """The plane (inverse-depth coefficients) that most valid pixels lie within ``max_dev_m`` of: three-point
    draws on a subsample (seeded: the same frame gives the same plane); None when no draw is well posed."""
    rng = np.random.default_rng(0)
    idx = rng.choice(len(z), size=min(sample, len(z)), replace=False)
    As, invs, zs = A[idx], inv[idx], z[idx]
    best, best_n = None, -1
    for _ in range(trials):
        pick = rng.choice(len(zs), size=3, replace=False)
        try:
            coef = np.linalg.solve(As[pick], invs[pick])
        except np.linalg.LinAlgError:
            continue
        fit = As @ coef
        with np.errstate(divide="ignore", invalid="ignore"):
            n = int(np.count_nonzero((fit > 0) & (np.abs(1.0 / fit - zs) <= max_dev_m)))
        if n > best_n:
            best, best_n = coef, n
    return best


def calibrate_depth_pattern(frames, *, step_px: int = 8, min_plane_fraction: float = 0.5,
                            max_dev_m: float = 0.15, min_samples: int = 16) -> DepthPatternCorrection:
    """The fixed inverse-depth pattern from frames of a flat wall.

    Parameters
    ----------
    frames : iterable of array_like, each (H, W)
        Depth frames in metres (0 or NaN invalid), each showing a plane over at least ``min_plane_fraction``
        of the image; several distances and angles help, ten or more frames per distance average the noise.
    step_px : int
        Block size of the correction grid, pixels (the pattern is smooth over tens of pixels).
    min_plane_fraction : float
        Frames whose plane covers less of the image are left out (counted in the error if none is left).
    max_dev_m : float
        Pixels farther from their frame's plane are left out (:func:`plane_residual_inv_depth`).
    min_samples : int
        Blocks with fewer residual samples over all frames take their value from their neighbours.

    Returns
    -------
    DepthPatternCorrection

    Raises
    ------
    TudorVisionError
        No frame, frames of different sizes, or no frame with a plane large enough.

    Examples
    --------
    >>> vv, uu = np.mgrid[0:48, 0:64]
    >>> c = 2e-3 * np.sin(uu / 9.0) * np.cos(vv / 11.0)           # a smooth pattern, 1/m
    >>> frames = [1 / (0.4 + 0.01 * k + 1e-4 * uu + c) for k in range(3)]
    >>> corr = calibrate_depth_pattern(frames, step_px=4)
    >>> bool(np.abs(corr.apply(frames[0]) - 1 / (0.4 + 1e-4 * uu)).max() < 0.01)
    True
    """
    step = int(step_px)
    if step < 1:
        raise ValueError(f"step_px: expected a positive integer, got {step_px!r}")
    total = count = None
    shape = None
    used = seen = 0
    for k, f in enumerate(frames):
        z = np.asarray(f, dtype=np.float64)
        if shape is None:
            shape = z.shape
        elif z.shape != shape:
            raise TudorVisionError(f"frame {k}: shape {z.shape} differs from the first frame's {shape}")
        seen += 1
        res, frac = plane_residual_inv_depth(z, max_dev_m=max_dev_m)
        if frac < min_plane_fraction:
            continue
        ok = np.isfinite(res)
        if total is None:
            total, count = np.zeros(shape), np.zeros(shape)
        total += np.where(ok, res, 0.0)
        count += ok
        used += 1
    if seen == 0:
        raise TudorVisionError("depth pattern: no frames")
    if used == 0:
        raise TudorVisionError(f"depth pattern: none of the {seen} frames shows a plane over "
                               f"{min_plane_fraction:.0%} of the image (point the camera at a flat wall)")
    h, w = shape
    gh, gw = -(-h // step), -(-w // step)
    pad = ((0, gh * step - h), (0, gw * step - w))
    t = np.pad(total, pad).reshape(gh, step, gw, step).sum(axis=(1, 3))
    n = np.pad(count, pad).reshape(gh, step, gw, step).sum(axis=(1, 3))
    grid = np.where(n >= min_samples, t / np.maximum(n, 1), np.nan)
    grid = _fill(grid)
    # the affine part cannot be seen from planes (every frame's fit took it): the grid keeps none either
    gv, gu = np.mgrid[0:gh, 0:gw].astype(np.float64)
    A = np.stack([np.ones(grid.size), gu.ravel(), gv.ravel()], 1)
    wts = np.sqrt(n.ravel().astype(np.float64))
    coef = np.linalg.lstsq(A * wts[:, None], grid.ravel() * wts, rcond=None)[0]
    grid = grid - (A @ coef).reshape(grid.shape)
    return DepthPatternCorrection(grid, step, (w, h), used)


def _fill(grid: np.ndarray) -> np.ndarray:
    """NaN blocks from their neighbours: normalised Gaussian smoothing, widened until every block has a value."""
    ok = np.isfinite(grid)
    if ok.all():
        return grid
    if not ok.any():
        return np.zeros_like(grid)
    out = grid.copy()
    sigma = 1.0
    while not np.all(np.isfinite(out)):
        num = cv2.GaussianBlur(np.where(ok, grid, 0.0), (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        den = cv2.GaussianBlur(ok.astype(np.float64), (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        with np.errstate(invalid="ignore", divide="ignore"):
            est = num / den
        out = np.where(ok, grid, np.where(den > 1e-6, est, np.nan))
        sigma *= 2.0
    return out


def write_depth_pattern(path, corr: DepthPatternCorrection) -> Path:
    """Write the correction as OpenCV YAML (``cv2.FileStorage``), whole or not at all.

    Written to a temporary file beside ``path`` and moved onto it (:func:`~tudorvision.io.atomic.atomic_path`), so
    a reader (another worker process of an experiment) never sees half a file.

    Parameters
    ----------
    path : str or Path
        ``.yaml`` / ``.yml`` file.
    corr : DepthPatternCorrection

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    TudorVisionError
        The folder cannot be created or written (the message names ``path``); an earlier file stays as it was.
    """
    path = Path(path)
    with atomic_path(path) as tmp:          # whole or not at all: a reader never sees half a file
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        try:
            fs.write("kind", _TAG)
            fs.write("image_width", int(corr.image_size[0]))
            fs.write("image_height", int(corr.image_size[1]))
            fs.write("step_px", int(corr.step_px))
            fs.write("n_frames", int(corr.n_frames))
            fs.writeComment("inverse-depth offset c per block, 1/m: the camera reports 1 / (1 / z + c)")
            fs.write("grid_inv_m", corr.grid_inv_m.astype(np.float64))
        finally:
            fs.release()
    return path


def read_depth_pattern(path) -> DepthPatternCorrection:
    """Read a correction written by :func:`write_depth_pattern`.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    DepthPatternCorrection

    Raises
    ------
    TudorVisionError
        A missing file, or one that is not a depth pattern (the message names the file and the field).
    """
    from ..io.formats import cv_matrix_node_ok

    path = Path(path)
    if not path.is_file():
        raise TudorVisionError(f"{path}: no such depth pattern file")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read as a depth pattern file ({exc})") from None
    fs = None
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        if not fs.isOpened() or not fs.root().isMap() or fs.getNode("kind").string() != _TAG:
            raise TudorVisionError(f"{path}: not a depth pattern file (kind is not {_TAG!r})")
        vals = {}
        for key in ("image_width", "image_height", "step_px", "n_frames"):
            node = fs.getNode(key)
            if node.empty() or not node.isInt():
                raise TudorVisionError(f"{path}: {key}: missing or not an integer")
            vals[key] = int(node.real())
        node = fs.getNode("grid_inv_m")
        grid = node.mat() if node.isMap() and cv_matrix_node_ok(node) else None
    except (cv2.error, SystemError) as exc:       # text OpenCV cannot parse: one line, not a traceback
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise TudorVisionError(f"{path}: not a depth pattern file ({msg})") from None
    finally:
        if fs is not None:
            fs.release()
    if grid is None:
        raise TudorVisionError(f"{path}: grid_inv_m: missing or not a matrix")
    try:
        return DepthPatternCorrection(np.asarray(grid, np.float64), vals["step_px"],
                                      (vals["image_width"], vals["image_height"]), vals["n_frames"])
    except ValueError as exc:
        raise TudorVisionError(f"{path}: {exc}") from None


def plot_depth_pattern(path, corr: DepthPatternCorrection, *, at_depth_m: float = 3.0) -> Path:
    """PNG image of the pattern as the depth error it makes at ``at_depth_m`` (millimetres).

    Draws on its own :class:`matplotlib.figure.Figure` (the global backend is not touched).

    Parameters
    ----------
    path : str or Path
        Output PNG.
    corr : DepthPatternCorrection
        The pattern.
    at_depth_m : float
        The depth the error is shown for, metres (the error grows with its square).

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.figure import Figure

    path = Path(path)
    z = float(at_depth_m)
    err_mm = (1.0 / (1.0 / z + corr.field()) - z) * 1e3
    lim = float(np.abs(err_mm).max()) or 1.0
    fig = Figure(figsize=(6.4, 4.4))
    ax = fig.add_subplot()
    im = ax.imshow(err_mm, cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(im, ax=ax, label=f"depth error at {z:g} m, mm (the camera reports z + this)")
    ax.set_xlabel("u, px")
    ax.set_ylabel("v, px")
    ax.set_title(f"fixed depth pattern, {corr.n_frames} frames, RMS {np.sqrt(np.mean(err_mm ** 2)):.1f} mm at {z:g} m")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    return path
