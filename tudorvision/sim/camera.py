"""Pinhole camera with Brown–Conrady distortion for the virtual lab.

Conventions
-----------
Camera optical frame ``cam``: x right, y down, z forward (OpenCV).
``T_world_cam`` maps camera points into the world: ``p_world = T_world_cam @ p_cam``.
Pixel coordinates ``(u, v)``: u to the right, v down, the centre of the
top-left pixel is ``(0, 0)`` (OpenCV's convention).

Distortion follows OpenCV's five-coefficient order ``(k1, k2, p1, p2, k3)``::

    r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    x_d = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    y_d = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
    u = fx x_d + cx,  v = fy y_d + cy

(the skew ``K[0, 1]`` is honoured as in OpenCV: ``u = fx x_d + s y_d + cx``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .._checks import check_array, check_points, check_transform, check_vector
from ..geometry import distort_normalized

__all__ = [
    "PinholeCamera", "intrinsic_matrix", "look_at", "distort_normalized",
    "undistort_normalized", "project_points", "points_cam_from_world",
    "ray_directions_cam", "ray_directions_world", "camera_center_world", "with_pose", "ray_directions_world_soa",
    "sphere_silhouette_centroid",
]


@dataclass(frozen=True, kw_only=True, eq=False)
class PinholeCamera:
    """A calibrated pinhole camera with lens distortion and a world pose.

    Parameters
    ----------
    K : ndarray, shape (3, 3)
        Intrinsic matrix in pixels (``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``).
    dist : ndarray, shape (5,)
        Brown–Conrady coefficients ``(k1, k2, p1, p2, k3)`` (OpenCV order).
    width, height : int
        Image size in pixels.
    T_world_cam : ndarray, shape (4, 4)
        Pose of the optical frame in the world (``p_world = T_world_cam @ p_cam``).

    Notes
    -----
    Instances are immutable; per-pixel ray directions are cached on the
    instance (compare cameras with ``is``, not ``==``). Use
    ``dataclasses.replace(cam, T_world_cam=...)`` for a moved copy.

    Examples
    --------
    >>> cam = PinholeCamera(K=intrinsic_matrix(700.0, 320.0, 240.0), dist=np.zeros(5),
    ...                     width=640, height=480, T_world_cam=np.eye(4))
    >>> project_points(cam, [[0.0, 0.0, 2.0]]).round(6).tolist()
    [[320.0, 240.0]]
    """

    K: np.ndarray
    dist: np.ndarray
    width: int
    height: int
    T_world_cam: np.ndarray
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        K = check_array(self.K, "K", (3, 3))
        if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:
            raise ValueError(f"K: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, got {K.tolist()}")
        dist = check_vector(self.dist, "dist", 5)
        for name in ("width", "height"):
            val = getattr(self, name)
            if int(val) != val or val < 1:
                raise ValueError(f"{name}: expected a positive integer, got {val!r}")
        T = check_transform(self.T_world_cam, "T_world_cam")
        for name, arr in (("K", K), ("dist", dist), ("T_world_cam", T)):
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))

    def cached(self, key: str, make: Callable[[], Any]) -> Any:
        """Data derived from this camera, computed by ``make()`` on first use and kept on the instance.

        The per-pixel ray grids and the field-of-view box live here, so a
        camera is set up once however many frames it renders.

        Parameters
        ----------
        key : str
            Name of the derived data (e.g. ``"rays_cam"``, ``"fov_box"``).
        make : callable
            ``make() -> value``, called only when ``key`` is not cached yet.

        Returns
        -------
        object
            The cached value (treat it as read-only).
        """
        value = self._cache.get(key)
        if value is None:
            value = make()
            self._cache[key] = value
        return value


def intrinsic_matrix(f_px: float, cx: float, cy: float, *, fy_px: float | None = None) -> np.ndarray:
    """Intrinsic matrix ``[[f, 0, cx], [0, fy, cy], [0, 0, 1]]`` (pixels).

    Parameters
    ----------
    f_px : float
        Focal length along u, pixels (> 0).
    cx, cy : float
        Principal point, pixels (u right, v down).
    fy_px : float, optional
        Focal length along v, pixels; default ``f_px`` (square pixels).

    Returns
    -------
    K : ndarray, shape (3, 3)
        The intrinsic matrix.

    Raises
    ------
    ValueError
        If a focal length is not positive.

    Examples
    --------
    >>> intrinsic_matrix(700.0, 319.5, 239.5)[0].tolist()
    [700.0, 0.0, 319.5]
    """
    fy = f_px if fy_px is None else fy_px
    if not (f_px > 0 and fy > 0):
        raise ValueError(f"f_px: expected positive focal lengths, got {f_px}, {fy}")
    return np.array([[f_px, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def camera_center_world(camera: PinholeCamera) -> np.ndarray:
    """Optical centre in the world frame, shape (3,), metres."""
    return camera.T_world_cam[:3, 3].copy()


def look_at(eye_world, target_world, *, K, dist=None, width: int = 640, height: int = 480,
            up_world=(0.0, 0.0, 1.0)) -> PinholeCamera:
    """Camera at ``eye_world`` whose optical axis points at ``target_world``.

    The image's "up" (−y of the optical frame) is the projection of
    ``up_world`` onto the image plane, so a camera looking horizontally with
    the default z-up world sees the floor at the bottom of the image.

    Parameters
    ----------
    eye_world, target_world : array_like, shape (3,)
        Metres, world frame.
    K : array_like, shape (3, 3)
        Intrinsic matrix, pixels.
    dist : array_like, shape (5,), optional
        Brown–Conrady coefficients ``(k1, k2, p1, p2, k3)``; zero distortion by default.
    width, height : int
        Image size, pixels.
    up_world : array_like, shape (3,)
        World direction that appears up in the image; must not be parallel
        to the viewing direction.

    Returns
    -------
    PinholeCamera
        The camera; its ``T_world_cam`` maps optical-frame points (x right,
        y down, z forward) into the world frame.

    Raises
    ------
    ValueError
        If eye and target coincide or ``up_world`` is parallel to the axis.

    Examples
    --------
    >>> cam = look_at([0, -2, 1], [0, 0, 1], K=intrinsic_matrix(500, 320, 240))
    >>> project_points(cam, [[0.0, 0.0, 1.5]]).round(3).tolist()
    [[320.0, 115.0]]
    """
    eye = check_vector(eye_world, "eye_world", 3)
    target = check_vector(target_world, "target_world", 3)
    up = check_vector(up_world, "up_world", 3)
    z = target - eye
    n = np.linalg.norm(z)
    if n < 1e-12:
        raise ValueError("target_world: coincides with eye_world")
    z = z / n
    x = np.cross(z, up)
    nx = np.linalg.norm(x)
    if nx < 1e-9 * max(np.linalg.norm(up), 1.0):
        raise ValueError("up_world: parallel to the viewing direction")
    x = x / nx
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return PinholeCamera(K=K, dist=np.zeros(5) if dist is None else dist, width=width,
                         height=height, T_world_cam=T)


def undistort_normalized(xy_d, dist, *, iterations: int = 20) -> np.ndarray:
    """Invert :func:`distort_normalized` (fixed-point start, Newton refinement).

    Parameters
    ----------
    xy_d : ndarray, shape (..., 2)
        Distorted normalized coordinates.
    dist : array_like, shape (5,)
    iterations : int
        Newton steps after five fixed-point steps; converges to ~1e-12 for the
        mild lens distortions of the lab.

    Returns
    -------
    ndarray, shape (..., 2)

    Examples
    --------
    >>> d = [-0.2, 0.05, 1e-3, -1e-3, 0.0]
    >>> x = np.array([[0.3, -0.2]])
    >>> bool(np.allclose(undistort_normalized(distort_normalized(x, d), d), x, atol=1e-12))
    True
    """
    dist = np.asarray(dist, dtype=np.float64)
    xy_d = np.asarray(xy_d, dtype=np.float64)
    if not np.any(dist):
        return xy_d.copy()
    k1, k2, p1, p2, k3 = dist
    xd, yd = xy_d[..., 0], xy_d[..., 1]
    x, y = xd.copy(), yd.copy()
    for _ in range(5):  # fixed point, as OpenCV's undistortPoints
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x, y = (xd - dx) / radial, (yd - dy) / radial
    for _ in range(iterations):  # Newton on F(x) = distort(x) - xd
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
        fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
        a = radial + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x
        b = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y
        d = radial + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x
        det = a * d - b * b
        x = x - (d * fx - b * fy) / det
        y = y - (a * fy - b * fx) / det
    return np.stack([x, y], axis=-1)


def points_cam_from_world(camera: PinholeCamera, points_world) -> np.ndarray:
    """Transform world points into the optical frame, shape (N, 3)."""
    p = check_points(points_world, "points_world")
    T = camera.T_world_cam
    return (p - T[:3, 3]) @ T[:3, :3]


def project_points(camera: PinholeCamera, points_world) -> np.ndarray:
    """Project world points to distorted pixel coordinates.

    Parameters
    ----------
    camera : PinholeCamera
        Intrinsics, distortion and pose ``T_world_cam``.
    points_world : array_like, shape (N, 3)
        Metres, world frame.

    Returns
    -------
    uv : ndarray, shape (N, 2)
        Pixels (u right, v down). Points at or behind the optical centre
        (z <= 0) give NaN.

    Raises
    ------
    ValueError
        If ``points_world`` does not have shape (N, 3).

    Examples
    --------
    >>> cam = PinholeCamera(K=intrinsic_matrix(700.0, 320.0, 240.0), dist=np.zeros(5),
    ...                     width=640, height=480, T_world_cam=np.eye(4))
    >>> project_points(cam, [[0.1, -0.2, 1.0]]).tolist()
    [[390.0, 100.0]]
    """
    p = points_cam_from_world(camera, points_world)
    z = p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = p[:, :2] / np.where(z > 0, z, np.nan)[:, None]
    return pixels_from_normalized(camera, distort_normalized(xy, camera.dist))


def pixels_from_normalized(camera: PinholeCamera, xy_d: np.ndarray) -> np.ndarray:
    """Pixel coordinates ``(..., 2)`` (u right, v down) of distorted normalised coordinates ``xy_d`` (..., 2)."""
    K = camera.K
    u = K[0, 0] * xy_d[..., 0] + K[0, 1] * xy_d[..., 1] + K[0, 2]
    v = K[1, 1] * xy_d[..., 1] + K[1, 2]
    return np.stack([u, v], axis=-1)


def _normalized_from_pixels(camera: PinholeCamera, uv: np.ndarray) -> np.ndarray:
    K = camera.K
    y = (uv[..., 1] - K[1, 2]) / K[1, 1]
    x = (uv[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return np.stack([x, y], axis=-1)


def ray_directions_cam(camera: PinholeCamera) -> np.ndarray:
    """Unit ray directions through every pixel centre, optical frame.

    Distortion is inverted per pixel (:func:`undistort_normalized`), so the ray
    through pixel ``(u, v)`` projects back onto ``(u, v)``. The result is
    cached on the camera and read-only.

    Returns
    -------
    ndarray, shape (height, width, 3), float64
        ``rays[v, u]`` is the unit direction for pixel ``(u, v)``.

    Examples
    --------
    >>> cam = PinholeCamera(K=intrinsic_matrix(100.0, 1.0, 1.0), dist=np.zeros(5),
    ...                     width=3, height=3, T_world_cam=np.eye(4))
    >>> ray_directions_cam(cam)[1, 1].tolist()
    [0.0, 0.0, 1.0]
    """
    rays = camera._cache.get("rays_cam")
    if rays is None:
        v, u = np.mgrid[0:camera.height, 0:camera.width].astype(np.float64)
        xy = undistort_normalized(_normalized_from_pixels(camera, np.stack([u, v], axis=-1)), camera.dist)
        rays = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
        rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
        rays.setflags(write=False)
        camera._cache["rays_cam"] = rays
    return rays


def ray_directions_world(camera: PinholeCamera) -> np.ndarray:
    """Unit ray directions through every pixel centre in the world frame.

    Returns
    -------
    ndarray, shape (height, width, 3)
        Cached and read-only; the rays start at :func:`camera_center_world`.
    """
    rays = camera._cache.get("rays_world")
    if rays is None:
        rays = np.ascontiguousarray(np.moveaxis(ray_directions_world_soa(camera), 0, -1))
        rays.setflags(write=False)
        camera._cache["rays_world"] = rays
    return rays


def ray_directions_world_soa(camera: PinholeCamera) -> np.ndarray:
    """World ray directions stored component-first, shape (3, height, width), cached and read-only.

    The renderer's layout: ``rays[:, v, u]`` is the direction of pixel (u, v).
    Computed from the cached camera-frame rays with nine scalar multiply-adds
    (numpy's threaded matmul is slow for an inner dimension of 3).
    """
    rays = camera._cache.get("rays_world_soa")
    if rays is None:
        cam = camera._cache.get("rays_cam_soa")
        if cam is None:
            cam = np.ascontiguousarray(np.moveaxis(ray_directions_cam(camera), -1, 0))
            camera._cache["rays_cam_soa"] = cam
        R = camera.T_world_cam[:3, :3]
        rays = np.empty_like(cam)
        for i in range(3):
            np.multiply(cam[0], R[i, 0], out=rays[i])
            rays[i] += R[i, 1] * cam[1]
            rays[i] += R[i, 2] * cam[2]
        rays.setflags(write=False)
        camera._cache["rays_world_soa"] = rays
    return rays


def with_pose(camera: PinholeCamera, T_world_cam) -> PinholeCamera:
    """Copy of ``camera`` at a new pose (intrinsics and the camera-frame ray cache kept).

    Use it for a moving camera (eye-in-hand): the per-pixel undistortion is
    not repeated.

    Parameters
    ----------
    camera : PinholeCamera
        The camera to copy.
    T_world_cam : array_like, shape (4, 4)
        New pose: ``p_world = T_world_cam @ p_cam`` (optical frame x right,
        y down, z forward), metres.

    Returns
    -------
    PinholeCamera
        The copy at the new pose.
    """
    new = dataclasses.replace(camera, T_world_cam=T_world_cam)
    for key in ("rays_cam", "rays_cam_soa", "fov_box"):
        if key in camera._cache:
            new._cache[key] = camera._cache[key]
    return new


def sphere_silhouette_centroid(camera: PinholeCamera, center_world, radius: float, *,
                               n_radial: int = 48, n_angular: int = 96) -> np.ndarray:
    """Exact area centroid (pixels) of a sphere's silhouette, lens distortion included.

    Under perspective the silhouette is an ellipse in the undistorted
    normalized image plane whose centre is *not* the projection of the sphere
    centre (the offset grows with the off-axis angle and the apparent size).
    This integrates pixel position over that ellipse, mapped through the
    distortion and weighted by the Jacobian determinant of the mapping
    (Gauss–Legendre in radius, uniform in angle): the continuous centroid a
    binary silhouette converges to. It does not cast rays, so it is an
    independent oracle for the renderer.

    Parameters
    ----------
    camera : PinholeCamera
    center_world : array_like, shape (3,)
        Sphere centre, metres, world frame.
    radius : float
        Metres.

    Returns
    -------
    ndarray, shape (2,)
        ``(u, v)`` pixels. The image border is ignored (the whole silhouette
        counts even where it leaves the image).

    Raises
    ------
    ValueError
        If the sphere is not entirely in front of the camera.

    Examples
    --------
    >>> cam = PinholeCamera(K=intrinsic_matrix(700.0, 320.0, 240.0), dist=np.zeros(5),
    ...                     width=640, height=480, T_world_cam=np.eye(4))
    >>> sphere_silhouette_centroid(cam, [0.0, 0.0, 2.0], 0.1).round(6).tolist()
    [320.0, 240.0]
    """
    c = points_cam_from_world(camera, check_vector(center_world, "center_world", 3))[0]
    if not radius > 0:
        raise ValueError(f"radius: expected > 0, got {radius!r}")
    if c[2] <= radius:
        raise ValueError("center_world: the sphere must lie entirely in front of the camera")
    # silhouette cone: (x . c)^2 >= |x|^2 (|c|^2 - r^2) for x = (x, y, 1)
    Q = np.outer(c, c) - (c @ c - radius ** 2) * np.eye(3)
    M, b, F = Q[:2, :2], Q[:2, 2], Q[2, 2]
    x0 = -np.linalg.solve(M, b)
    k = F + b @ x0
    S = -M / k                         # (x - x0)^T S (x - x0) <= 1
    L = np.linalg.cholesky(np.linalg.inv(S))
    g, w = np.polynomial.legendre.leggauss(n_radial)
    rho, w_rho = 0.5 * (g + 1.0), 0.5 * w * 0.5 * (g + 1.0)  # weight rho d rho on [0, 1]
    phi = 2 * np.pi * np.arange(n_angular) / n_angular
    unit = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    pts = x0 + (rho[:, None, None] * unit[None]) @ L.T          # (n_radial, n_angular, 2)
    weights = np.broadcast_to(w_rho[:, None], pts.shape[:2])
    h = 1e-6
    dx = (distort_normalized(pts + [h, 0], camera.dist) - distort_normalized(pts - [h, 0], camera.dist)) / (2 * h)
    dy = (distort_normalized(pts + [0, h], camera.dist) - distort_normalized(pts - [0, h], camera.dist)) / (2 * h)
    jac = np.abs(dx[..., 0] * dy[..., 1] - dx[..., 1] * dy[..., 0]) * weights
    uv = pixels_from_normalized(camera, distort_normalized(pts, camera.dist))
    return (uv * jac[..., None]).sum(axis=(0, 1)) / jac.sum()
