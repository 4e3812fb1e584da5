"""Shared 3D geometry: plane and circle fits, rigid-transform helpers, lens distortion.

Used by the stereo base-frame calibration (circle of the theta1 sweep) and by
the RGB-D wall-camera calibration (circle of the theta2 sweep). Everything is
frame-agnostic: points are ``(N, 3)`` rows in metres in whatever frame the
caller measured them; transforms are 4x4 homogeneous matrices with the
``T_a_b`` naming (``p_a = T_a_b @ p_b``).

Circle fit
----------
:func:`fit_circle_3d` works in three stages:

1. plane fit (SVD of the centred points) gives a first normal;
2. algebraic circle fit in that plane (Kasa: linear least squares on
   ``u^2 + v^2 = 2 a u + 2 b v + c``) gives a first centre and radius;
3. joint nonlinear refinement of centre (3), normal (2, tangent-plane
   parameters) and radius (1) with :func:`scipy.optimize.least_squares`.
   Each point contributes two residuals, its out-of-plane offset
   ``h = n . (p - c)`` and its in-plane radial offset ``rho - r``; their
   root sum square is the point's distance to the circle. A robust loss
   (``soft_l1`` by default) with a scale taken from the noise (1.4826 x the
   median absolute residual of the algebraic fit, or ``f_scale``) keeps
   outliers from pulling the circle.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import check_array, check_points, check_transform

__all__ = [
    "PlaneFit", "CircleFit", "fit_plane", "fit_circle_3d", "make_frame", "invert_transform",
    "transform_points", "rotation_angle", "transform_difference", "fit_rigid_transform", "distort_normalized",
]

_MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True, kw_only=True)
class PlaneFit:
    """Least-squares plane through points.

    Attributes
    ----------
    centroid : ndarray, shape (3,)
        Mean of the points (a point on the plane), same frame and unit as the input.
    normal : ndarray, shape (3,)
        Unit normal (smallest principal direction); its sign is arbitrary
        unless a hint was given.
    rmse : float
        Root mean square point-to-plane distance.
    """

    centroid: np.ndarray
    normal: np.ndarray
    rmse: float


@dataclass(frozen=True, kw_only=True)
class CircleFit:
    """A circle in 3D space.

    Attributes
    ----------
    centre : ndarray, shape (3,)
        Circle centre, input frame and unit.
    normal : ndarray, shape (3,)
        Unit normal of the circle plane (orientation: see :func:`fit_circle_3d`).
    radius : float
        Radius, input unit.
    rmse : float
        Root mean square distance of the inliers to the circle.
    rmse_all : float
        Same over all points.
    inliers : ndarray of bool, shape (N,)
        Points whose distance to the circle is below the inlier threshold.
    distances : ndarray, shape (N,)
        Distance of each point to the circle.
    """

    centre: np.ndarray
    normal: np.ndarray
    radius: float
    rmse: float
    rmse_all: float
    inliers: np.ndarray
    distances: np.ndarray


def _unit(v, name: str) -> np.ndarray:
    v = check_array(v, name, (3,))
    n = np.linalg.norm(v)
    if n < 1e-12:
        raise ValueError(f"{name}: must be a nonzero vector, got {v.tolist()}")
    return v / n


def fit_plane(points, *, normal_hint=None) -> PlaneFit:
    """Fit a plane to 3D points by SVD.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        N >= 3 points, not all collinear.
    normal_hint : array_like, shape (3,), optional
        The returned normal is flipped to have a positive dot product with it.

    Returns
    -------
    PlaneFit

    Raises
    ------
    ValueError
        If ``points`` has fewer than 3 rows, non-finite entries, or is collinear.

    Examples
    --------
    >>> fit = fit_plane([[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]], normal_hint=[0, 0, 1])
    >>> fit.normal.tolist(), round(fit.rmse, 12)
    ([0.0, 0.0, 1.0], 0.0)
    """
    pts = _check_point_set(points, "points")
    centroid = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - centroid, full_matrices=False)
    normal = vt[2]
    if normal_hint is not None and normal @ _unit(normal_hint, "normal_hint") < 0:
        normal = -normal
    normal = normal + 0.0   # no negative zeros
    rmse = float(np.sqrt(np.mean(((pts - centroid) @ normal) ** 2)))
    return PlaneFit(centroid=centroid, normal=normal, rmse=rmse)


def _check_point_set(points, name: str) -> np.ndarray:
    pts = check_points(points, name)
    if len(pts) < 3:
        raise ValueError(f"{name}: need at least 3 points, got {len(pts)}")
    centred = pts - pts.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[0] == 0 or s[1] <= 1e-9 * s[0]:
        raise ValueError(f"{name}: points are collinear or coincident; a plane or circle needs "
                         "3 non-collinear points")
    return pts


def _plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, v with (u, v, normal) right-handed and orthonormal."""
    a = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, a)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    return u, v


def _kasa(uv: np.ndarray) -> tuple[np.ndarray, float]:
    """Algebraic (Kasa) circle fit in 2D: centre (2,), radius."""
    A = np.column_stack([2 * uv[:, 0], 2 * uv[:, 1], np.ones(len(uv))])
    b = (uv ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    centre = sol[:2]
    r2 = sol[2] + centre @ centre
    return centre, float(np.sqrt(max(r2, 0.0)))


def _circle_residuals(pts, centre, normal, radius) -> np.ndarray:
    d = pts - centre
    h = d @ normal
    rho = np.linalg.norm(d - h[:, None] * normal, axis=1)
    return np.column_stack([h, rho - radius])


def fit_circle_3d(points, *, loss: str = "soft_l1", f_scale: float | None = None,
                  inlier_factor: float = 3.5, normal_hint=None) -> CircleFit:
    """Fit a circle to 3D points (plane fit, Kasa fit, robust joint refinement).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        N >= 3 non-collinear points on (or near) a circle or an arc of it.
    loss : str
        Robust loss of :func:`scipy.optimize.least_squares` (``"linear"``,
        ``"soft_l1"``, ``"huber"``, ``"cauchy"``, ``"arctan"``).
    f_scale : float, optional
        Residual scale where the robust loss starts to saturate, input unit.
        Default: 1.4826 x the median absolute residual of the algebraic fit
        (a robust noise estimate), floored at 1e-9 x the radius.
    inlier_factor : float
        A point is an inlier when its distance to the refined circle is below
        ``inlier_factor`` x the robust per-component noise sigma.
    normal_hint : array_like, shape (3,), optional
        Orient the normal to have a positive dot product with this vector.
        Without it the normal follows the right-hand rule of the point order:
        points listed counter-clockwise about the normal (the net signed angle
        swept from the first to the last point is positive).

    Returns
    -------
    CircleFit

    Raises
    ------
    ValueError
        If ``points`` has fewer than 3 rows, non-finite entries, or is collinear;
        if ``loss`` is unknown.

    Examples
    --------
    >>> a = np.linspace(0.0, 3.0, 20)
    >>> pts = np.column_stack([2 + 0.5 * np.cos(a), 1 + 0.5 * np.sin(a), np.full(20, 3.0)])
    >>> fit = fit_circle_3d(pts)
    >>> np.round(fit.centre, 6).tolist(), round(fit.radius, 6), np.round(fit.normal, 6).tolist()
    ([2.0, 1.0, 3.0], 0.5, [0.0, 0.0, 1.0])
    """
    from scipy.optimize import least_squares

    if loss not in ("linear", "soft_l1", "huber", "cauchy", "arctan"):
        raise ValueError(f"loss: expected one of linear, soft_l1, huber, cauchy, arctan; got {loss!r}")
    pts = _check_point_set(points, "points")
    plane = fit_plane(pts)
    n0 = plane.normal
    u, v = _plane_basis(n0)
    local = pts - plane.centroid
    c2, r0 = _kasa(np.column_stack([local @ u, local @ v]))
    c0 = plane.centroid + c2[0] * u + c2[1] * v

    res0 = _circle_residuals(pts, c0, n0, r0)
    sigma0 = _MAD_TO_SIGMA * float(np.median(np.abs(res0)))
    scale = float(f_scale) if f_scale is not None else max(sigma0, 1e-9 * max(r0, 1e-12))
    if not scale > 0:
        raise ValueError(f"f_scale: must be positive, got {f_scale}")

    def unpack(x):
        n = n0 + x[3] * u + x[4] * v
        return x[:3], n / np.linalg.norm(n), x[5]

    def fun(x):
        c, n, r = unpack(x)
        return _circle_residuals(pts, c, n, r).ravel()

    x0 = np.concatenate([c0, [0.0, 0.0, r0]])
    # x_scale keeps the tangent-plane normal parameters comparable with lengths
    xs = np.array([r0, r0, r0, 1.0, 1.0, r0]) if r0 > 0 else 1.0
    sol = least_squares(fun, x0, loss=loss, f_scale=scale, x_scale=xs, method="trf")
    centre, normal, radius = unpack(sol.x)
    if radius < 0:
        radius = -radius
    res = _circle_residuals(pts, centre, normal, radius)
    dist = np.hypot(res[:, 0], res[:, 1])
    sigma = _MAD_TO_SIGMA * float(np.median(np.abs(res)))
    thresh = inlier_factor * sigma
    inliers = dist <= thresh if thresh > 0 else np.ones(len(pts), bool)
    if inliers.sum() < 3:
        inliers = np.ones(len(pts), bool)

    if normal_hint is not None:
        if normal @ _unit(normal_hint, "normal_hint") < 0:
            normal = -normal
    else:
        bu, bv = _plane_basis(normal)
        d = pts - centre
        ang = np.unwrap(np.arctan2(d @ bv, d @ bu))
        if ang[-1] - ang[0] < 0:
            normal = -normal
    normal = normal + 0.0
    return CircleFit(centre=centre, normal=normal, radius=float(radius),
                     rmse=float(np.sqrt(np.mean(dist[inliers] ** 2))),
                     rmse_all=float(np.sqrt(np.mean(dist ** 2))),
                     inliers=inliers, distances=dist)


def make_frame(origin, z_axis, x_hint) -> np.ndarray:
    """Build the pose of a frame from its origin, z axis and a hint for x.

    z is ``z_axis`` normalised; x is ``x_hint`` with its z component removed,
    normalised; y = z x x (right-handed).

    Parameters
    ----------
    origin : array_like, shape (3,)
        Origin of the new frame, expressed in the reference frame ``ref``.
    z_axis : array_like, shape (3,)
        Direction of the new z axis in ``ref`` (any length > 0).
    x_hint : array_like, shape (3,)
        Approximate x direction in ``ref``; must not be parallel to ``z_axis``.

    Returns
    -------
    T_ref_new : ndarray, shape (4, 4)
        Maps points from the new frame into ``ref``: columns are x, y, z, origin.

    Raises
    ------
    ValueError
        If an axis is zero or ``x_hint`` is parallel to ``z_axis``.

    Examples
    --------
    >>> T = make_frame([1, 2, 3], [0, 0, 2], [1, 1, 0])
    >>> np.round(T, 3)[:3].tolist()
    [[0.707, -0.707, 0.0, 1.0], [0.707, 0.707, 0.0, 2.0], [0.0, 0.0, 1.0, 3.0]]
    """
    o = check_array(origin, "origin", (3,))
    z = _unit(z_axis, "z_axis")
    xh = check_array(x_hint, "x_hint", (3,))
    x = xh - (xh @ z) * z
    nx = np.linalg.norm(x)
    if nx < 1e-9 * max(np.linalg.norm(xh), 1e-300):
        raise ValueError(f"x_hint: {xh.tolist()} is parallel to z_axis {z.tolist()}")
    x /= nx
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, o
    return T + 0.0


def invert_transform(T) -> np.ndarray:
    """Inverse of a rigid transform: ``T_b_a`` from ``T_a_b``.

    Parameters
    ----------
    T : array_like, shape (4, 4)
        Rigid transform ``T_a_b`` (maps frame-b points into frame a).

    Returns
    -------
    T_b_a : ndarray, shape (4, 4)
        The inverse transform ``[R^T, -R^T t; 0, 1]``.

    Raises
    ------
    ValueError
        If ``T`` is not a 4x4 rigid transform.

    Examples
    --------
    >>> T = make_frame([1, 0, 0], [0, 0, 1], [0, 1, 0])
    >>> bool(np.allclose(invert_transform(T) @ T, np.eye(4)))
    True
    """
    T = check_transform(T, "T")
    R, t = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ t
    return out


def transform_points(T, points) -> np.ndarray:
    """Apply ``T_a_b`` to points in frame b: returns ``p_a = R p_b + t`` as rows.

    NaN rows stay NaN (missing measurements pass through).

    Parameters
    ----------
    T : array_like, shape (4, 4)
        Rigid transform ``T_a_b``.
    points : array_like, shape (N, 3) or (3,)
        Points in frame b.

    Returns
    -------
    ndarray, shape (N, 3) or (3,)
        Points in frame a (same shape as the input).

    Examples
    --------
    >>> T = make_frame([1, 0, 0], [0, 0, 1], [0, 1, 0])
    >>> transform_points(T, [1.0, 0.0, 0.0]).round(12).tolist()
    [1.0, 1.0, 0.0]
    """
    T = check_transform(T, "T")
    arr = np.asarray(points, dtype=np.float64)
    single = arr.ndim == 1
    pts = check_points(arr, "points", finite=False)
    out = pts @ T[:3, :3].T + T[:3, 3]
    return out[0] if single else out


def rotation_angle(R) -> float:
    """Rotation angle (radians, in [0, pi]) of a 3x3 rotation matrix.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Rotation matrix.

    Returns
    -------
    float
        Rotation angle in radians, in [0, pi].

    Raises
    ------
    ValueError
        If ``R`` is not 3x3.

    Examples
    --------
    >>> round(rotation_angle(make_frame([0, 0, 0], [0, 0, 1], [0, 1, 0])[:3, :3]), 6)
    1.570796
    """
    R = check_array(R, "R", (3, 3))
    c = (np.trace(R) - 1.0) / 2.0
    # arccos is ill-conditioned near 0; use atan2 of the skew part
    s = np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    return float(np.arctan2(s, c))


def transform_difference(T_a, T_b) -> tuple[float, float]:
    """Translation distance and rotation angle between two poses of the same frame.

    Parameters
    ----------
    T_a, T_b : array_like, shape (4, 4)
        Two rigid transforms of the same frame into the same reference frame.

    Returns
    -------
    dt : float
        ``|t_a - t_b|`` in the unit of the transforms.
    dangle : float
        Angle of ``R_a^T R_b`` in radians.

    Examples
    --------
    >>> transform_difference(np.eye(4), np.eye(4))
    (0.0, 0.0)
    """
    Ta = check_transform(T_a, "T_a")
    Tb = check_transform(T_b, "T_b")
    return float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3])), rotation_angle(Ta[:3, :3].T @ Tb[:3, :3])


def fit_rigid_transform(points_b, points_a) -> np.ndarray:
    """Least-squares rigid transform ``T_a_b`` with ``points_a ~ T_a_b @ points_b`` (Kabsch).

    Parameters
    ----------
    points_b, points_a : array_like, shape (N, 3)
        Corresponding points in frames b and a, N >= 3 and not collinear.

    Returns
    -------
    T_a_b : ndarray, shape (4, 4)

    Raises
    ------
    ValueError
        If shapes differ or the points are degenerate.

    Examples
    --------
    >>> T = make_frame([0.1, 0.2, 0.3], [0, 1, 1], [1, 0, 0])
    >>> pb = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> bool(np.allclose(fit_rigid_transform(pb, transform_points(T, pb)), T))
    True
    """
    pb = _check_point_set(points_b, "points_b")
    pa = check_points(points_a, "points_a")
    if pa.shape != pb.shape:
        raise ValueError(f"points_a: expected shape {pb.shape} like points_b, got {pa.shape}")
    cb, ca = pb.mean(axis=0), pa.mean(axis=0)
    H = (pb - cb).T @ (pa - ca)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = ca - R @ cb
    return T


def distort_normalized(xy, dist) -> np.ndarray:
    """Apply Brown–Conrady distortion to normalized coordinates.

    Parameters
    ----------
    xy : ndarray, shape (..., 2)
        Undistorted normalized coordinates ``(X/Z, Y/Z)``.
    dist : array_like, shape (5,)
        ``(k1, k2, p1, p2, k3)``.

    Returns
    -------
    ndarray, shape (..., 2)
        Distorted normalized coordinates.

    Examples
    --------
    >>> distort_normalized(np.array([0.1, 0.0]), [0.1, 0, 0, 0, 0]).round(6).tolist()
    [0.1001, 0.0]
    """
    k1, k2, p1, p2, k3 = np.asarray(dist, dtype=np.float64)
    x, y = xy[..., 0], xy[..., 1]
    x2, y2, xy_ = x * x, y * y, x * y
    r2 = x2 + y2
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * xy_ + p2 * (r2 + 2.0 * x2)
    yd = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy_
    return np.stack([xd, yd], axis=-1)
