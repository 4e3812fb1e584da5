"""Stereo consistency of a sphere's apparent radius in the two cameras (issue 15).

A sphere of radius ``R`` at depth ``Z`` in a camera of focal length ``f``
appears with a radius of about ``f R / Z`` pixels (off the optical axis the
silhouette is an ellipse whose minor semi-axis is ``f R / Z`` for a distant
sphere; a circle fitted to it lies between the axes). Both cameras see the
same sphere, so once its centre is triangulated the two image radii must
agree up to the ratio of ``f / Z``:

``rho = (r_left Z_left / f_left) / (r_right Z_right / f_right)`` is 1 for a
consistent pair. A view in which the segmentation took only part of the
sphere (a link across a small sphere splits its colour region, a background
of the sphere's colour swallows part of the rim) usually has a circle that is
too small or off-centre, so ``rho`` departs from 1; the epipolar check cannot
see the error along the epipolar line, which is the one that costs depth.

:func:`radius_ratio` computes ``rho``; :class:`~tudorvision.stereo.pipeline.StereoPipeline`
uses it (``PipelineOptions.max_radius_mismatch``) to re-measure the view
whose radius disagrees, on the sphere's chroma edge from a circle of the
radius the other view predicts, and to refuse the pair when that does not
make the two agree.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["radius_ratio", "implied_radii_m", "predicted_radius_px"]


def _depths(p_left, R, T) -> tuple:
    p = np.asarray(p_left, np.float64).reshape(3)
    p_right = np.asarray(R, np.float64).reshape(3, 3) @ p + np.asarray(T, np.float64).reshape(3)
    return float(p[2]), float(p_right[2])


def implied_radii_m(p_left, r_left_px: float, r_right_px: float, f_left_px: float, f_right_px: float, R, T):
    """The sphere's metric radius each view implies, ``r Z / f`` per camera, metres.

    Parameters are those of :func:`radius_ratio`.

    Returns
    -------
    tuple of float
        ``(left, right)``; NaN for both when a radius or a depth is not positive and finite.

    Examples
    --------
    >>> R, T = np.eye(3), np.array([-0.2, 0.0, 0.0])
    >>> [round(x, 4) for x in implied_radii_m([0.1, 0.0, 2.0], 15.0, 9.0, 600.0, 600.0, R, T)]
    [0.05, 0.03]
    """
    zl, zr = _depths(p_left, R, T)
    vals = (float(r_left_px), float(r_right_px), zl, zr, float(f_left_px), float(f_right_px))
    if not all(math.isfinite(v) and v > 0 for v in vals):
        return float("nan"), float("nan")
    return vals[0] * zl / vals[4], vals[1] * zr / vals[5]


def radius_ratio(p_left, r_left_px: float, r_right_px: float, f_left_px: float, f_right_px: float, R, T) -> float:
    """Ratio of the sphere radii the two views imply, ``(r_l Z_l / f_l) / (r_r Z_r / f_r)``.

    Parameters
    ----------
    p_left : array_like, shape (3,)
        Triangulated sphere centre in the left camera frame, metres.
    r_left_px, r_right_px : float
        Apparent radius in each image (the fitted circle's), pixels.
    f_left_px, f_right_px : float
        Focal lengths, pixels.
    R : array_like, shape (3, 3)
        Rotation from the left to the right camera frame (``X_r = R X_l + T``).
    T : array_like, shape (3,)
        Translation of that transform, metres.

    Returns
    -------
    float
        1 for views that agree; NaN when a radius or a depth is not positive
        and finite.

    Examples
    --------
    >>> R, T = np.eye(3), np.array([-0.2, 0.0, 0.0])      # right camera 0.2 m to the right
    >>> round(radius_ratio([0.1, 0.0, 2.0], 15.0, 15.0, 600.0, 600.0, R, T), 6)
    1.0
    >>> round(radius_ratio([0.1, 0.0, 2.0], 9.0, 15.0, 600.0, 600.0, R, T), 2)   # left view took 60 %
    0.6
    """
    left, right = implied_radii_m(p_left, r_left_px, r_right_px, f_left_px, f_right_px, R, T)
    return left / right


def predicted_radius_px(p_left, r_other_px: float, f_other_px: float, f_this_px: float, R, T, *,
                        this: str) -> float:
    """Apparent radius in one camera predicted from the other camera's radius and the sphere's centre.

    Parameters
    ----------
    p_left : array_like, shape (3,)
        Sphere centre in the left camera frame, metres.
    r_other_px, f_other_px : float
        Radius in the other image and that camera's focal length, pixels.
    f_this_px : float
        Focal length of the camera to predict for, pixels.
    R, T : array_like
        Left-to-right transform, as for :func:`radius_ratio`.
    this : {"left", "right"}
        The camera to predict for.

    Returns
    -------
    float
        Pixels; NaN when a depth is not positive.

    Examples
    --------
    >>> R, T = np.eye(3), np.array([-0.2, 0.0, 0.0])
    >>> round(predicted_radius_px([0.1, 0.0, 2.0], 15.0, 600.0, 900.0, R, T, this="right"), 6)
    22.5
    """
    zl, zr = _depths(p_left, R, T)
    if not (zl > 0 and zr > 0):
        return float("nan")
    z_this, z_other = (zl, zr) if this == "left" else (zr, zl)
    return float(r_other_px) * (z_other / float(f_other_px)) * (float(f_this_px) / z_this)
