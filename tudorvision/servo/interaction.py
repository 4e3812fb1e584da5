"""Interaction matrices for translational visual servoing (section 9.1).

Sign convention (read this before changing anything)
----------------------------------------------------
Camera frame: x right, y down, z forward (optical axis). Image coordinates
are taken relative to the principal point, in pixels: ``x = u - c_u``,
``y = v - c_v`` (u right, v down); ``f`` is the focal length in pixels
(the seed's Lambda) and ``Z`` the depth of the point along the optical axis.
``v_c`` is the camera's translational velocity expressed in the camera frame.

For a *static* scene point the camera motion gives ``dP_cam/dt = -v_c``, and
the standard (Chaumette-Hutchinson) point interaction matrix, translational
columns only, is ::

    d[x, y]/dt = L_xy v_c,   L_xy = [[-f/Z, 0, x/Z],
                                     [0, -f/Z, y/Z]]
    dZ/dt = [0, 0, -1] v_c

The seed's image Jacobian (9.1.3) ``J_c = [[f/z, 0, -u/z], [0, f/z, -v/z]]``
is ``-L_xy``, and its hybrid matrix (9.1.4) ``L_c = diag(f/z, f/z, 1)`` is the
negative of ``[L_xy; 0 0 -1]`` at the principal point. Both are consistent
with the *seed error* ::

    e = s* - s          (goal minus current: e_u = u* - u, e_v = v* - v, e_z = z* - z)

because then ``de/dt = -ds/dt = J_c v_c`` (resp. ``L_c v_c`` at the principal
point) and the laws ``v_c = -K J_c^+ e`` and ``v_c = -K L_c^-1 e`` give
``de/dt = -K e``. With the standard error ``s - s*`` one uses the standard
matrix: ``v_c = -K L^+ (s - s*)``, the same command. The tests check these
matrices against finite differences of the projection of a static point.
"""
from __future__ import annotations

import numpy as np

from .._checks import check_array

__all__ = ["point_interaction", "stacked_interaction", "seed_image_jacobian", "hybrid_matrix",
           "hybrid_error", "project_cam"]


def project_cam(p_cam, f_px: float) -> np.ndarray:
    """Pinhole projection relative to the principal point, pixels.

    Parameters
    ----------
    p_cam : array_like, shape (N, 3) or (3,)
        Points in the camera frame (x right, y down, z forward), metres.
    f_px : float
        Focal length, pixels.

    Returns
    -------
    xy : ndarray, shape (N, 2) or (2,)

    Examples
    --------
    >>> project_cam([0.1, -0.2, 2.0], 500.0).tolist()
    [25.0, -50.0]
    """
    p = np.asarray(p_cam, dtype=np.float64)
    return f_px * p[..., :2] / p[..., 2:3]


def point_interaction(xy, Z, f_px: float) -> np.ndarray:
    """Standard interaction matrix of image points, translational columns.

    Parameters
    ----------
    xy : array_like, shape (N, 2) or (2,)
        Image coordinates relative to the principal point, pixels.
    Z : array_like, shape (N,) or scalar
        Depth along the optical axis, metres (> 0).
    f_px : float
        Focal length, pixels.

    Returns
    -------
    L : ndarray, shape (N, 2, 3) or (2, 3)
        ``d xy / dt = L v_c`` for a static point (``v_c`` in the camera frame).

    Raises
    ------
    ValueError
        If a depth is not positive and finite.

    Examples
    --------
    >>> point_interaction([0.0, 0.0], 2.0, 500.0).tolist()
    [[-250.0, 0.0, 0.0], [0.0, -250.0, 0.0]]
    """
    p = np.asarray(xy, dtype=np.float64)
    single = p.ndim == 1
    p = p.reshape(-1, 2)
    z = np.broadcast_to(np.asarray(Z, dtype=np.float64), (len(p),))
    if not np.all(np.isfinite(z) & (z > 0)):
        raise ValueError(f"Z: expected positive finite depths, got {np.asarray(Z).tolist()}")
    L = np.zeros((len(p), 2, 3))
    L[:, 0, 0] = -f_px / z
    L[:, 1, 1] = -f_px / z
    L[:, 0, 2] = p[:, 0] / z
    L[:, 1, 2] = p[:, 1] / z
    return L[0] if single else L


def stacked_interaction(xy, Z, f_px: float) -> np.ndarray:
    """Point interaction matrices stacked into shape (2N, 3) (rows x0, y0, x1, y1, ...)."""
    L = point_interaction(np.asarray(xy, float).reshape(-1, 2), Z, f_px)
    return L.reshape(-1, 3)


def seed_image_jacobian(xy, Z, f_px: float) -> np.ndarray:
    """The seed's image Jacobian (9.1.3) ``J_c = -L``, shape (2N, 3); use with ``e = s* - s``.

    Examples
    --------
    >>> (seed_image_jacobian([[10.0, 0.0]], 2.0, 500.0) + 0.0).tolist()
    [[250.0, 0.0, -5.0], [0.0, 250.0, 0.0]]
    """
    return -stacked_interaction(xy, Z, f_px)


def hybrid_matrix(Z: float, f_px: float) -> np.ndarray:
    """The seed's hybrid interaction matrix (9.1.4) ``L_c = diag(f/z, f/z, 1)``, shape (3, 3).

    Use with the seed error ``e = s* - s`` (see the module notes).

    Parameters
    ----------
    Z : float
        Depth of the feature along the optical axis, metres (> 0).
    f_px : float
        Focal length in pixels.

    Returns
    -------
    L_c : ndarray, shape (3, 3)
        ``diag(f/Z, f/Z, 1)``: maps the camera velocity (m/s, camera frame)
        to the rate of ``[u px, v px, z m]`` with the seed's sign convention.

    Raises
    ------
    ValueError
        If ``Z`` is not positive and finite.

    Examples
    --------
    >>> np.diag(hybrid_matrix(0.5, 500.0)).tolist()
    [1000.0, 1000.0, 1.0]
    """
    if not (np.isfinite(Z) and Z > 0):
        raise ValueError(f"Z: expected a positive finite depth, got {Z!r}")
    return np.diag([f_px / Z, f_px / Z, 1.0])


def hybrid_error(s, s_star) -> np.ndarray:
    """Seed error ``e = s* - s`` of the hybrid features ``s = [u, v, z]`` (pixels, pixels, metres).

    Examples
    --------
    >>> hybrid_error([330.0, 240.0, 0.8], [320.0, 240.0, 0.7]).round(3).tolist()
    [-10.0, 0.0, -0.1]
    """
    return check_array(s_star, "s_star", (3,)) - check_array(s, "s", (3,))
