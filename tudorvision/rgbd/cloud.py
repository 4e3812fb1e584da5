"""Point clouds from RGB-D frames (Open3D) and PLY export.

Open3D is imported inside the functions that need it, so ``tudorvision.rgbd``
imports without it. Colour images are RGB, uint8, shape (H, W, 3), registered
to the depth image. Point colours are floats in [0, 1].
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .._checks import TudorVisionError, check_points
from ..io.atomic import atomic_path
from .frames import Intrinsics, check_depth, points_cam_from_depth

__all__ = [
    "o3d_intrinsic_from", "cloud_from_rgbd", "cloud_from_points", "points_colors_from_cloud",
    "colored_points_cam_from_rgbd", "write_ply", "read_ply",
]


def _open3d():
    try:
        import open3d as o3d
    except ImportError as exc:   # pragma: no cover - depends on the installation
        raise TudorVisionError(f"Open3D is needed for point clouds: pip install open3d ({exc})") from None
    return o3d


def _check_color(color, shape: tuple[int, int]) -> np.ndarray:
    c = np.asarray(color)
    if c.ndim != 3 or c.shape[2] != 3 or c.shape[:2] != tuple(shape):
        raise ValueError(f"color: expected an RGB image of shape ({shape[0]}, {shape[1]}, 3), got {c.shape}")
    if c.dtype != np.uint8:
        raise ValueError(f"color: expected dtype uint8, got {c.dtype}")
    return np.ascontiguousarray(c)


def o3d_intrinsic_from(intrinsics: Intrinsics):
    """Open3D ``PinholeCameraIntrinsic`` with the same parameters."""
    o3d = _open3d()
    return o3d.camera.PinholeCameraIntrinsic(int(intrinsics.width), int(intrinsics.height),
                                             float(intrinsics.fx), float(intrinsics.fy),
                                             float(intrinsics.cx), float(intrinsics.cy))


def cloud_from_rgbd(color, depth_raw, intrinsics: Intrinsics, *, depth_scale: float,
                    depth_trunc: float = 6.0):
    """Open3D point cloud of one RGB-D frame, camera optical frame.

    Uses ``RGBDImage.create_from_color_and_depth`` and
    ``PointCloud.create_from_rgbd_image`` (identity extrinsic).

    Parameters
    ----------
    color : ndarray, shape (H, W, 3), uint8, or None
        Registered RGB image; ``None`` gives an uncoloured cloud
        (``create_from_depth_image``).
    depth_raw : ndarray, shape (H, W), uint16
        Raw depth, 0 = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics of the registered depth and colour images
        (pixels); its ``(height, width)`` must match both.
    depth_scale : float
        Raw units per metre (1000 mm, 5000 TUM).
    depth_trunc : float
        Points farther than this (metres) are dropped.

    Returns
    -------
    open3d.geometry.PointCloud
        Points in metres, camera optical frame (x right, y down, z forward).

    Raises
    ------
    ValueError
        If ``depth_raw`` or ``color`` does not match the intrinsics' shape,
        or ``color`` is not uint8 RGB.
    TudorVisionError
        If no pixel has valid depth below ``depth_trunc``, or Open3D is not
        installed.
    """
    o3d = _open3d()
    raw = np.asarray(depth_raw)
    if raw.ndim != 2 or raw.shape != intrinsics.shape:
        raise ValueError(f"depth_raw: expected shape {intrinsics.shape}, got {raw.shape}")
    if raw.dtype not in (np.uint16, np.float32):
        raw = raw.astype(np.float32)
    valid = (raw > 0) & (raw.astype(np.float64) / depth_scale <= depth_trunc)
    if not np.any(valid):
        raise TudorVisionError(f"depth_raw: no valid depth below depth_trunc={depth_trunc:g} m "
                               f"(all zero, or wrong depth_scale={depth_scale:g}?)")
    depth_img = o3d.geometry.Image(np.ascontiguousarray(raw))
    K = o3d_intrinsic_from(intrinsics)
    if color is None:
        return o3d.geometry.PointCloud.create_from_depth_image(
            depth_img, K, np.eye(4), depth_scale=float(depth_scale), depth_trunc=float(depth_trunc))
    c = _check_color(color, intrinsics.shape)
    rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
        o3d.geometry.Image(c), depth_img, depth_scale=float(depth_scale),
        depth_trunc=float(depth_trunc), convert_rgb_to_intensity=False)
    return o3d.geometry.PointCloud.create_from_rgbd_image(rgbd, K)


def colored_points_cam_from_rgbd(color, depth_m, intrinsics: Intrinsics, *,
                                 depth_trunc: float = np.inf):
    """NumPy back-projection with colours (no Open3D needed).

    Returns
    -------
    points_cam : ndarray, shape (N, 3)
        Metres, camera optical frame, row-major pixel order.
    colors : ndarray, shape (N, 3) or None
        RGB in [0, 1]; ``None`` when ``color`` is ``None``.
    """
    d = check_depth(depth_m, intrinsics=intrinsics)
    keep = np.isfinite(d) & (d <= depth_trunc)
    pts = points_cam_from_depth(d, intrinsics, mask=keep)
    if color is None:
        return pts, None
    c = _check_color(color, intrinsics.shape)
    return pts, c[keep].astype(np.float64) / 255.0


def cloud_from_points(points, colors=None):
    """Open3D point cloud from ``(N, 3)`` points and optional ``(N, 3)`` colours in [0, 1].

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Finite points, metres, in whatever frame the cloud is to be in
        (usually the camera optical frame).
    colors : array_like, shape (N, 3), optional
        RGB per point, floats in [0, 1].

    Returns
    -------
    open3d.geometry.PointCloud
        The points (and colours) as given.

    Raises
    ------
    ValueError
        If ``points`` or ``colors`` is not a finite (N, 3) array, the row
        counts differ, or a colour lies outside [0, 1].
    TudorVisionError
        If Open3D is not installed.
    """
    o3d = _open3d()
    p = check_points(points, "points")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    if colors is not None:
        c = check_points(colors, "colors")
        if len(c) != len(p):
            raise ValueError(f"colors: expected {len(p)} rows like points, got {len(c)}")
        if c.min(initial=0.0) < 0 or c.max(initial=0.0) > 1:
            raise ValueError("colors: expected values in [0, 1]")
        pcd.colors = o3d.utility.Vector3dVector(c)
    return pcd


def points_colors_from_cloud(pcd):
    """``(points (N, 3), colors (N, 3) or None)`` of an Open3D point cloud."""
    pts = np.asarray(pcd.points, dtype=np.float64).reshape(-1, 3)
    cols = np.asarray(pcd.colors, dtype=np.float64).reshape(-1, 3) if pcd.has_colors() else None
    return pts, cols


def write_ply(path, points, colors=None, *, binary: bool = True) -> Path:
    """Write points (and colours in [0, 1]) to a PLY file with Open3D.

    Parameters
    ----------
    path : str or Path
        Output file; parent folders must exist.
    points : array_like, shape (N, 3)
        Metres.
    colors : array_like, shape (N, 3), optional
        RGB in [0, 1].
    binary : bool
        Binary PLY (default); ``False`` writes ASCII.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    FileNotFoundError
        If the parent folder of ``path`` does not exist.
    ValueError
        If ``points`` or ``colors`` is malformed (see :func:`cloud_from_points`).
    TudorVisionError
        If the file cannot be written (the previous file stays intact), or
        Open3D is not installed.
    """
    o3d = _open3d()
    path = Path(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(2, "folder does not exist", str(path.parent))
    pcd = cloud_from_points(points, colors)
    with atomic_path(path, mkdir=False) as tmp:   # a failed write leaves the previous file intact
        if not o3d.io.write_point_cloud(str(tmp), pcd, write_ascii=not binary):
            raise TudorVisionError(f"{path}: Open3D could not write the point cloud")
    return path


def read_ply(path):
    """Read a PLY point cloud: ``(points (N, 3), colors (N, 3) or None)``.

    Parameters
    ----------
    path : str or Path
        PLY file, e.g. one written by :func:`write_ply`.

    Returns
    -------
    points : ndarray, shape (N, 3)
        Points as stored (metres, in the frame they were written in).
    colors : ndarray, shape (N, 3) or None
        RGB in [0, 1]; ``None`` when the file has no colours.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    TudorVisionError
        If Open3D is not installed.
    """
    o3d = _open3d()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(2, "no such file", str(path))
    return points_colors_from_cloud(o3d.io.read_point_cloud(str(path)))
