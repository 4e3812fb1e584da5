"""RGB-D frames: pinhole intrinsics, depth checks and back-projection.

Conventions
-----------
Camera optical frame ``cam``: x right, y down, z forward (metres). Image
coordinates: ``u`` to the right (column), ``v`` down (row), pixel centres at
integer coordinates. Depth images hold the z coordinate (not the range along
the ray), as Kinect-type sensors and the TUM benchmark do. Invalid depth is
``NaN`` in metric depth images and ``0`` in raw 16-bit images; the
conversions between the two are :func:`tudorvision.sensors.depth_m_from_raw`
and :func:`tudorvision.sensors.raw_from_depth_m`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import TudorVisionError, check_points

__all__ = [
    "Intrinsics", "check_depth",
    "points_cam_from_depth", "organized_points_cam_from_depth",
    "uv_from_points_cam", "rays_cam_from_uv",
]

@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of a registered RGB-D camera (no distortion).

    Parameters
    ----------
    fx, fy : float
        Focal lengths, pixels.
    cx, cy : float
        Principal point, pixels (u right, v down).
    width, height : int
        Image size, pixels.

    Examples
    --------
    >>> K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    >>> K.matrix[0].tolist()
    [525.0, 0.0, 319.5]
    >>> K.scaled(0.5).width
    320
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self):
        for name in ("fx", "fy"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"Intrinsics.{name}: expected a positive focal length, got {v}")
        for name in ("cx", "cy"):
            if not np.isfinite(float(getattr(self, name))):
                raise ValueError(f"Intrinsics.{name}: must be finite")
        for name in ("width", "height"):
            v = getattr(self, name)
            if int(v) != v or int(v) <= 0:
                raise ValueError(f"Intrinsics.{name}: expected a positive integer, got {v}")

    @property
    def matrix(self) -> np.ndarray:
        """Camera matrix K, shape (3, 3)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(height, width)``."""
        return int(self.height), int(self.width)

    @classmethod
    def from_matrix(cls, K, width: int, height: int) -> "Intrinsics":
        """Build from a 3x3 camera matrix.

        Parameters
        ----------
        K : array_like, shape (3, 3)
            Camera matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, pixels;
            the skew ``K[0, 1]`` is ignored.
        width, height : int
            Image size, pixels.

        Returns
        -------
        Intrinsics
            Focal lengths and principal point read from ``K``.

        Raises
        ------
        ValueError
            If ``K`` is not 3x3, a focal length is not positive or the image
            size is not a positive integer.

        Examples
        --------
        >>> Intrinsics.from_matrix([[500, 0, 320], [0, 501, 240], [0, 0, 1]], 640, 480).fy
        501.0
        """
        K = np.asarray(K, dtype=np.float64)
        if K.shape != (3, 3):
            raise ValueError(f"K: expected shape (3, 3), got {K.shape}")
        return cls(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]),
                   int(width), int(height))

    def scaled(self, factor: float) -> "Intrinsics":
        """Intrinsics of the image resized by ``factor`` (pixel-centre convention).

        Block-averaging by an integer ``n`` corresponds to ``factor = 1 / n``.

        Parameters
        ----------
        factor : float
            Resize factor, positive (0.5 halves the image size).

        Returns
        -------
        Intrinsics
            ``fx, fy`` times ``factor``; ``c -> (c + 0.5) * factor - 0.5`` so
            pixel centres stay at integer coordinates; width and height
            rounded, at least 1.

        Raises
        ------
        ValueError
            If ``factor`` is not positive (the focal lengths would not be).
        """
        s = float(factor)
        return Intrinsics(self.fx * s, self.fy * s, (self.cx + 0.5) * s - 0.5,
                          (self.cy + 0.5) * s - 0.5,
                          max(1, int(round(self.width * s))), max(1, int(round(self.height * s))))


def check_depth(depth_m, name: str = "depth_m", *, intrinsics: Intrinsics | None = None,
                require_valid: bool = True) -> np.ndarray:
    """Check a metric depth image; returns float64 with invalid pixels as NaN.

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        Depth in metres; NaN, 0 and negative values are invalid.
    intrinsics : Intrinsics, optional
        When given, the image shape must match.
    require_valid : bool
        Raise when no pixel holds valid depth.

    Raises
    ------
    ValueError
        Wrong dimensions or shape.
    TudorVisionError
        All pixels invalid (``require_valid``).

    Examples
    --------
    >>> check_depth([[0.0, 1.5]]).tolist()
    [[nan, 1.5]]
    """
    d = np.array(depth_m, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"{name}: expected a 2-D depth image (H, W), got shape {d.shape}")
    if intrinsics is not None and d.shape != intrinsics.shape:
        raise ValueError(f"{name}: shape {d.shape} does not match the intrinsics "
                         f"(height, width) = {intrinsics.shape}")
    with np.errstate(invalid="ignore"):
        d[~(d > 0) | ~np.isfinite(d)] = np.nan
    if require_valid and not np.any(np.isfinite(d)):
        raise TudorVisionError(f"{name}: depth image has no valid pixel (all zero or invalid)")
    return d


def _pixel_grid(intrinsics: Intrinsics):
    u = (np.arange(intrinsics.width, dtype=np.float64) - intrinsics.cx) / intrinsics.fx
    v = (np.arange(intrinsics.height, dtype=np.float64) - intrinsics.cy) / intrinsics.fy
    return u, v


def organized_points_cam_from_depth(depth_m, intrinsics: Intrinsics) -> np.ndarray:
    """Back-project every pixel; keeps the image layout.

    Returns
    -------
    points_cam : ndarray, shape (H, W, 3)
        Metres, camera optical frame; NaN where the depth is invalid.

    Examples
    --------
    >>> K = Intrinsics(100.0, 100.0, 1.0, 0.0, 3, 1)
    >>> organized_points_cam_from_depth([[2.0, 0.0, 1.0]], K)[0].tolist()
    [[-0.02, 0.0, 2.0], [nan, nan, nan], [0.01, 0.0, 1.0]]
    """
    d = check_depth(depth_m, intrinsics=intrinsics, require_valid=False)
    xu, yv = _pixel_grid(intrinsics)
    out = np.empty(d.shape + (3,))
    out[..., 0] = xu[None, :] * d
    out[..., 1] = yv[:, None] * d
    out[..., 2] = d
    return out


def points_cam_from_depth(depth_m, intrinsics: Intrinsics, mask=None) -> np.ndarray:
    """Back-project the valid pixels of a depth image to 3D points.

    ``x = (u - cx) z / fx``, ``y = (v - cy) z / fy``; rows in row-major pixel
    order (v, then u).

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        Depth (z) in metres; NaN or 0 = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth image (pixels); its ``(height,
        width)`` must match the depth image.
    mask : array_like of bool, shape (H, W), optional
        Only pixels where the mask is true.

    Returns
    -------
    points_cam : ndarray, shape (N, 3)
        Metres, camera optical frame.

    Raises
    ------
    ValueError
        If the depth image or the mask does not have the intrinsics' shape.
    TudorVisionError
        If the depth image has no valid pixel.

    Examples
    --------
    >>> K = Intrinsics(100.0, 100.0, 0.0, 0.0, 2, 1)
    >>> points_cam_from_depth([[1.0, 2.0]], K).tolist()
    [[0.0, 0.0, 1.0], [0.02, 0.0, 2.0]]
    """
    d = check_depth(depth_m, intrinsics=intrinsics)
    valid = np.isfinite(d)
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != d.shape:
            raise ValueError(f"mask: expected shape {d.shape}, got {m.shape}")
        valid &= m.astype(bool)
    v, u = np.nonzero(valid)
    z = d[v, u]
    return np.stack([(u - intrinsics.cx) * z / intrinsics.fx,
                     (v - intrinsics.cy) * z / intrinsics.fy, z], axis=1)


def uv_from_points_cam(points_cam, intrinsics: Intrinsics) -> np.ndarray:
    """Project camera-frame points to pixel coordinates.

    Parameters
    ----------
    points_cam : array_like, shape (N, 3) or (3,)
        Points in metres, camera optical frame (x right, y down, z
        forward); must be finite.
    intrinsics : Intrinsics
        Pinhole intrinsics (pixels); no distortion.

    Returns
    -------
    uv : ndarray, shape (N, 2)
        Pixels, ``u`` right, ``v`` down; NaN for points with z <= 0.

    Raises
    ------
    ValueError
        If ``points_cam`` is not shape (N, 3) or holds non-finite values.

    Examples
    --------
    >>> uv_from_points_cam([[0.1, -0.2, 2.0]], Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)).tolist()
    [[345.0, 190.0]]
    """
    p = check_points(points_cam, "points_cam")
    z = np.where(p[:, 2] > 0, p[:, 2], np.nan)
    return np.stack([intrinsics.fx * p[:, 0] / z + intrinsics.cx,
                     intrinsics.fy * p[:, 1] / z + intrinsics.cy], axis=1)


def rays_cam_from_uv(uv, intrinsics: Intrinsics) -> np.ndarray:
    """Unit viewing rays through pixels.

    Returns
    -------
    rays_cam : ndarray, shape (N, 3)
        Unit vectors, camera optical frame (positive z).

    Examples
    --------
    >>> rays_cam_from_uv([[320.0, 240.0]], Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)).tolist()
    [[0.0, 0.0, 1.0]]
    """
    q = check_points(uv, "uv", dim=2)
    r = np.stack([(q[:, 0] - intrinsics.cx) / intrinsics.fx,
                  (q[:, 1] - intrinsics.cy) / intrinsics.fy, np.ones(len(q))], axis=1)
    return r / np.linalg.norm(r, axis=1, keepdims=True)
