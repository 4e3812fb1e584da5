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

A view without a fitted circle (motion blur, a region too ragged for the
rim fit: its centre is the region's moment) has only its area:
:func:`region_is_part` says when such a region is too small for the sphere
the other view (or the known radius) predicts, so that its moment is off
the centre. :func:`known_radius_verdict` judges a pair against a known
metric radius (``PipelineOptions.sphere_radius_m``).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["radius_ratio", "implied_radii_m", "predicted_radius_px", "view_radius_px", "region_is_part",
           "known_radius_verdict", "region_is_larger", "KNOWN_RADIUS_TOL", "PART_MIN_PX"]

#: Log-ratio tolerance of the known-radius check (``PipelineOptions.sphere_radius_m``): 0.15, 16 %, and at least
#: 1.5 px (the rim circle of a small sphere reads about 0.7 px small); a circle fitted to an off-axis sphere's
#: elliptic silhouette reads up to about 7 % large at 30 deg off the axis.
KNOWN_RADIUS_TOL = 0.15
#: Smallest predicted radius (px) at which a region without a circle is judged by its area: below it the region is
#: the sphere's colour core, smaller than the sphere but about centred (two good 4.7 px spheres, seed 0).
PART_MIN_PX = 8.0
#: Radius differences up to this many pixels never count (radius noise of a small sphere's rim, seeds 0 and 1).
MIN_GAP_PX = 1.5


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


def view_radius_px(circle_radius_px: float, area_px: float) -> tuple:
    """The radius a view shows: its fitted circle's, else its region's area radius ``sqrt(A / pi)``.

    Parameters
    ----------
    circle_radius_px : float
        Fitted circle radius, pixels; NaN when the centre is the region's moment.
    area_px : float
        Region area, pixels.

    Returns
    -------
    tuple
        ``(radius_px, by_area)``; ``by_area`` is True when the radius is the area's.

    Examples
    --------
    >>> view_radius_px(12.5, 400.0)
    (12.5, False)
    >>> r, by_area = view_radius_px(float("nan"), 100.0 * np.pi)
    >>> round(r, 6), by_area
    (10.0, True)
    """
    if math.isfinite(circle_radius_px):
        return float(circle_radius_px), False
    return math.sqrt(max(float(area_px), 0.0) / math.pi), True


def region_is_part(r_area_px: float, want_px: float, tol: float) -> bool:
    """Whether a region without a circle is only part of a sphere predicted ``want_px`` in radius.

    True when the prediction is at least :data:`PART_MIN_PX`, and the area radius is short of it by more
    than :data:`MIN_GAP_PX` and by more than ``tol`` in log ratio. A region larger than the prediction never
    counts (motion blur smears a sphere over a larger area); NaN never counts.

    Parameters
    ----------
    r_area_px : float
        The region's area radius, pixels.
    want_px : float
        Radius the other view or the known metric radius predicts in this view, pixels.
    tol : float
        Log-ratio tolerance.

    Returns
    -------
    bool

    Examples
    --------
    >>> region_is_part(19.7, 25.4, 0.12), region_is_part(24.0, 25.4, 0.12), region_is_part(4.0, 6.0, 0.12)
    (True, False, False)
    """
    return _apart(float(r_area_px), float(want_px), float(want_px), tol)


def region_is_larger(r_area_px: float, want_px: float, tol: float) -> bool:
    """Whether a region without a circle is larger than a sphere predicted ``want_px`` in radius.

    The mirror of :func:`region_is_part`: the area radius exceeds the prediction (at least
    :data:`PART_MIN_PX`) by more than :data:`MIN_GAP_PX` and by more than ``tol`` in log ratio. Such a region
    took something of the sphere's colour beside it, unless the sphere is motion-blurred.

    Parameters
    ----------
    r_area_px, want_px, tol
        As for :func:`region_is_part`.

    Returns
    -------
    bool

    Examples
    --------
    >>> region_is_larger(17.6, 15.2, 0.12), region_is_larger(16.0, 15.2, 0.12), region_is_larger(9.0, 6.0, 0.12)
    (True, False, False)
    """
    return _apart(float(want_px), float(r_area_px), float(want_px), tol)


def _apart(low: float, high: float, want: float, tol: float) -> bool:
    """``high`` exceeds ``low`` by more than MIN_GAP_PX and ``tol`` in log ratio, on a prediction >= PART_MIN_PX."""
    return bool(want >= PART_MIN_PX and high - low > MIN_GAP_PX and low > 0 and math.log(high / low) > tol)


def known_radius_verdict(p_left, views, radius_m: float, f_left_px: float, f_right_px: float, R, T,
                         tol: float = KNOWN_RADIUS_TOL) -> str:
    """Why a sphere's two views disagree with its known metric radius, or ``""`` when they agree.

    Each view implies ``r Z / f`` (:func:`implied_radii_m`). A view without a circle counts with its area
    radius: alone, when :func:`region_is_part` of the predicted ``f R / Z``; otherwise never as too large
    (blur), and not at all below :data:`PART_MIN_PX`. The pair is refused when the views' mean implied radius
    is off by more than ``tol`` in log ratio and :data:`MIN_GAP_PX` on average.

    Parameters
    ----------
    p_left : array_like, shape (3,)
        Triangulated centre, left camera frame, metres.
    views : sequence of tuple
        ``((circle_radius_px, area_px) left, (circle_radius_px, area_px) right)``; circle NaN for a moment view.
    radius_m : float
        The sphere's known radius, metres.
    f_left_px, f_right_px, R, T
        As for :func:`radius_ratio`.
    tol : float
        Log-ratio tolerance.

    Returns
    -------
    str
        ``""`` when consistent or not measurable (no depth), else the reason, e.g. ``"radius 32.7 mm, the
        sphere's is 39.7 mm"``.

    Examples
    --------
    >>> R, T = np.eye(3), np.array([-0.2, 0.0, 0.0])
    >>> known_radius_verdict([0.1, 0.0, 2.0], [(15.0, 700.0), (15.0, 700.0)], 0.05, 600.0, 600.0, R, T)
    ''
    >>> known_radius_verdict([0.1, 0.0, 2.0], [(12.0, 450.0), (12.0, 450.0)], 0.05, 600.0, 600.0, R, T)
    "radius 40.0 mm, the sphere's is 50.0 mm"
    """
    r_px, by_area = zip(*(view_radius_px(c, a) for c, a in views))
    R_s = float(radius_m)
    measured = implied_radii_m(p_left, r_px[0], r_px[1], f_left_px, f_right_px, R, T)
    if not all(math.isfinite(m) and m > 0 for m in measured):
        return ""
    want_px = [r * R_s / m for r, m in zip(r_px, measured)]       # f R_s / Z per view
    for i in (0, 1):
        if by_area[i] and region_is_part(r_px[i], want_px[i], tol):
            return (f"the {('left', 'right')[i]} view's region is part of the sphere (its area gives "
                    f"{1e3 * measured[i]:.1f} mm), the sphere's is {1e3 * R_s:.1f} mm")
    implied = [(min(m, R_s) if w >= PART_MIN_PX else R_s) if a else m
               for a, m, w in zip(by_area, measured, want_px)]
    r_m = 0.5 * (implied[0] + implied[1])
    off_px = 0.5 * sum(abs(r * (1.0 - R_s / m)) for r, m in zip(r_px, implied))
    if abs(math.log(r_m / R_s)) > tol and off_px > MIN_GAP_PX:
        return f"radius {1e3 * r_m:.1f} mm, the sphere's is {1e3 * R_s:.1f} mm"
    return ""
