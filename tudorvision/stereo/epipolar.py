"""Epipolar-consistent image centres: a sphere's two centres moved onto one epipolar plane.

The two image centres of a sphere are measured independently, one per view, so
with noise they do not lie on corresponding epipolar lines. The correction here
moves each centre by the least amount, weighted by how well that view's centre
is known, that makes the pair consistent (the Sampson first-order correction of
Hartley and Zisserman, section 12.4, with a weight per view, re-linearised at the
corrected pair, which converges to the constrained optimum). For
Gaussian pixel errors of standard deviations ``sigma_left`` and
``sigma_right`` the triangulated point of the corrected pair is the weighted
maximum-likelihood point: the error component perpendicular to the epipolar
lines is shared between the views in proportion to their variances, the
component along them (the disparity, that is the depth) is not changed.

Coordinates: ``x`` arrays are undistorted normalised image coordinates (N, 2)
(x right, y down, z forward); ``E`` the essential matrix with
``x_right^T E x_left = 0`` in homogeneous normalised coordinates.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..geometry import distort_normalized
from .triangulate import StereoRig

__all__ = ["epipolar_correction", "consistent_centres", "normalised_to_pixels"]

_ZERO3 = np.zeros(3)


def epipolar_correction(x_left, x_right, E, f_left: float, f_right: float, sigma_left, sigma_right, *,
                        iterations: int = 3) -> tuple:
    """Weighted least-squares move of each pair ``(x_left[i], x_right[i])`` onto the epipolar constraint.

    Minimises ``|d_left|^2 / sigma_left^2 + |d_right|^2 / sigma_right^2`` over the
    moves in pixels (normalised coordinates times ``f``) subject to the
    constraint linearised at the current pair, ``iterations`` times.

    Parameters
    ----------
    x_left, x_right : array_like, shape (N, 2)
        Undistorted normalised coordinates of the pairs.
    E : array_like, shape (3, 3)
        Essential matrix, ``x_right^T E x_left = 0``.
    f_left, f_right : float
        Focal lengths (pixels) that turn normalised moves into pixels.
    sigma_left, sigma_right : float or array_like, shape (N,)
        Standard deviations (pixels, or any common unit) of each view's centre.

    Returns
    -------
    x_left, x_right : ndarray, shape (N, 2)
        The corrected pairs.

    Examples
    --------
    Parallel cameras (``E`` of a baseline along x): the epipolar lines are rows, a
    right centre 1 px lower than the left moves up by 0.8 px when the left view
    is twice as certain (variances 1 : 4), and the left one moves down by 0.2 px.

    >>> E = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -0.1], [0.0, 0.1, 0.0]])
    >>> xl, xr = epipolar_correction([[0.0, 0.0]], [[-0.05, 0.001]], E, 1000.0, 1000.0, 1.0, 2.0)
    >>> (1000 * xl).round(6).tolist(), (1000 * xr).round(6).tolist()
    ([[0.0, 0.2]], [[-50.0, 0.2]])
    """
    xl = np.array(x_left, dtype=np.float64).reshape(-1, 2)
    xr = np.array(x_right, dtype=np.float64).reshape(-1, 2)
    (e00, e01, e02), (e10, e11, e12), (e20, e21, e22) = np.asarray(E, dtype=np.float64).tolist()
    sl, sr = (np.broadcast_to(np.asarray(v, np.float64), (len(xl),)).tolist() for v in (sigma_left, sigma_right))
    fl, fr = float(f_left), float(f_right)
    for i, ((ul0, vl0), (ur0, vr0)) in enumerate(zip(xl.tolist(), xr.tolist())):   # a few pairs per frame:
        vl_l, vr_r = sl[i] * sl[i], sr[i] * sr[i]                                  # plain floats, no arrays
        ul, vl, ur, vr = ul0, vl0, ur0, vr0
        for _ in range(iterations):     # linearised at the current pair, the whole move from the measured one
            l0, l1, l2 = e00 * ul + e01 * vl + e02, e10 * ul + e11 * vl + e12, e20 * ul + e21 * vl + e22
            g0, g1 = e00 * ur + e10 * vr + e20, e01 * ur + e11 * vr + e21     # (E^T x_right)[:2]
            a0, a1, b0, b1 = g0 / fl, g1 / fl, l0 / fr, l1 / fr               # gradient per pixel of each move
            # the residual at the measured pair, to first order from the current one
            c = -(ur * l0 + vr * l1 + l2) + (a0 * (ul - ul0) + a1 * (vl - vl0)) * fl \
                + (b0 * (ur - ur0) + b1 * (vr - vr0)) * fr
            den = (a0 * a0 + a1 * a1) * vl_l + (b0 * b0 + b1 * b1) * vr_r
            k = c / den if den > 0.0 else 0.0
            ul, vl = ul0 + k * vl_l * a0 / fl, vl0 + k * vl_l * a1 / fl
            ur, vr = ur0 + k * vr_r * b0 / fr, vr0 + k * vr_r * b1 / fr
        xl[i], xr[i] = (ul, vl), (ur, vr)
    return xl, xr


def consistent_centres(rig: StereoRig, uv_left, uv_right, sigma_left, sigma_right, *,
                       max_epipolar_px: float = float("inf")) -> tuple:
    """Raw (distorted) pixel centres of the pairs moved onto one epipolar plane each.

    :func:`epipolar_correction` on the undistorted centres of ``rig``'s two
    cameras, mapped back through each camera's distortion.

    Parameters
    ----------
    rig : StereoRig
        The calibrated pair.
    uv_left, uv_right : array_like, shape (N, 2)
        Raw pixel centres, finite.
    sigma_left, sigma_right : float or array_like, shape (N,)
        Standard deviations of each view's centre (pixels, or any common unit).
    max_epipolar_px : float
        Pairs farther apart than this (``rig.epipolar_px``) are left as they are.

    Returns
    -------
    uv_left, uv_right : ndarray, shape (N, 2)
        Raw pixel centres whose undistorted rays meet.
    moved : ndarray of bool, shape (N,)
        The pairs that were moved (within ``max_epipolar_px``).
    """
    a = np.array(uv_left, dtype=np.float64).reshape(-1, 2)
    b = np.array(uv_right, dtype=np.float64).reshape(-1, 2)
    xl, xr = rig.normalised(a, b)
    moved = rig.epipolar_px_normalised(xl, xr) <= max_epipolar_px
    if not moved.any():
        return a, b, moved
    sl, sr = (np.broadcast_to(np.asarray(v, np.float64), moved.shape)[moved] for v in (sigma_left, sigma_right))
    xl, xr = epipolar_correction(xl[moved], xr[moved], rig.E, rig.f_left_px, rig.f_right_px, sl, sr)
    for i, (cam, x, out) in enumerate(((rig.left, xl, a), (rig.right, xr, b))):
        px = normalised_to_pixels(x, cam.K, cam.dist)
        out[moved] = px
        rig.remember(px, x, i)      # triangulating the moved centres uses x itself
    return a, b, moved


def normalised_to_pixels(x, K, dist) -> np.ndarray:
    """Raw pixels (N, 2) of undistorted normalised coordinates ``x`` (N, 2): OpenCV's camera model.

    Up to five coefficients ``k1 k2 p1 p2 k3`` through :func:`tudorvision.geometry.distort_normalized` (a few
    points per frame: cheaper than a call into OpenCV); longer models go to :func:`cv2.projectPoints`.

    Examples
    --------
    >>> K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    >>> normalised_to_pixels(np.array([[0.1, -0.2]]), K, [0.1, 0, 0, 0, 0]).round(6).tolist()
    [[370.25, 139.5]]
    """
    d = np.asarray(dist, np.float64).ravel()
    x = np.asarray(x, np.float64).reshape(-1, 2)
    K = np.asarray(K, np.float64)
    if len(d) > 5:
        rays = np.concatenate([x, np.ones((len(x), 1))], axis=1)
        uv, _ = cv2.projectPoints(rays.reshape(-1, 1, 3), _ZERO3, _ZERO3, K, d)
        return uv.reshape(-1, 2)
    xd = distort_normalized(x, d if len(d) == 5 else np.concatenate([d, np.zeros(5 - len(d))]))
    return xd * np.diagonal(K)[:2] + K[:2, 2]        # as OpenCV: no skew term
