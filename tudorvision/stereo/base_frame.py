"""Robot base frame from a theta1 sweep seen by the stereo cameras (section 2.4).

The robot sweeps theta1 with theta2 = theta3 = 0 (arm stretched out
horizontally); the end effector draws a circle about the joint-1 axis. The
arm sags under gravity, so the circle lies *below* the rigid model's height
``h1`` (joint-2 axis above the base plate) by the sag ``s`` (and its radius is
a little shorter than ``l2 + l3``). The vertical posture [0, 90, 0] deg puts
the end effector on the joint-1 axis at ``h1 + l2 + l3`` with almost no
deformation, which fixes the height.

Construction implemented here (all measured points in the left camera frame):

1. Fit a circle to the sweep points (:func:`tudorvision.geometry.fit_circle_3d`):
   centre ``c``, unit normal ``n``, radius ``r``.
2. z axis = ``n``, oriented *up*: toward the vertical-posture point ``p_v``
   (``n . (p_v - c) > 0``). Without ``p_v`` the orientation comes from the
   joint angles (theta1 increases counter-clockwise about +z), else from the
   point order.
3. Height: ``H = n . (p_v - c)`` is the measured height of the vertical point
   above the circle plane. The rigid model puts it at
   ``z_v = h1 + l2 + l3`` above the base origin (:func:`fk_ee` at
   [0, 90, 0] deg), so the base origin lies on the circle axis at
   ``o = c + (H - z_v) n``, i.e. ``h1 - s`` below the circle centre, with the
   sag ``s = H - (l2 + l3)`` (positive when the arm droops). Without ``p_v``
   the sag is taken as 0 (``o = c - h1 n``) and reported as NaN.
4. x axis: toward the end effector at theta1 = 0. With joint angles, each
   point's azimuth ``phi_i`` about ``n`` satisfies ``phi_i = theta1_i + phi_0``
   (rigid rotation about the joint-1 axis); ``phi_0`` is the circular mean
   of ``phi_i - theta1_i`` over the inliers and x points at azimuth ``phi_0``.
   Without joint angles x points toward the first sweep point (which must
   then be theta1 = 0).
5. y = z x x; ``T_left_base = [x y z o]`` and ``T_base_left`` is its inverse.

Gravity is assumed parallel to the joint-1 axis (a level base), so the sag
moves the circle along the axis and does not tilt it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array, check_points
from ..geometry import CircleFit, fit_circle_3d, invert_transform, make_frame
from ..robot import fk_ee, load_robot_params

__all__ = ["BaseFrameReport", "base_frame_from_theta1_sweep"]

_VERTICAL = np.array([0.0, np.pi / 2, 0.0])


@dataclass(frozen=True, kw_only=True)
class BaseFrameReport:
    """Diagnostics of the base-frame calibration (metres, radians).

    Attributes
    ----------
    circle : CircleFit
        The fitted circle (left camera frame).
    circle_rmse_m : float
        RMS distance of the inlier sweep points to the circle.
    radius_m : float
        Fitted circle radius.
    rigid_reach_m : float
        ``l2 + l3`` of the rigid model, for comparison with the radius.
    sag_m : float
        How far the sweep circle lies below the rigid joint-2 height
        (``H - (l2 + l3)``); NaN without a vertical point.
    vertical_height_m : float
        Measured height ``H`` of the vertical point above the circle plane (NaN without one).
    vertical_axis_offset_m : float
        Distance of the vertical point from the fitted circle axis (ideally
        0; a large value means a bad vertical point or a tilted fit).
    azimuth_rms_rad : float
        RMS of the azimuth residuals ``phi_i - theta1_i - phi_0`` (NaN without
        joint angles); large values point at a timing offset between the
        joint log and the cameras.
    n_points, n_inliers : int
    warnings : tuple of str
    """

    circle: CircleFit
    circle_rmse_m: float
    radius_m: float
    rigid_reach_m: float
    sag_m: float
    vertical_height_m: float
    vertical_axis_offset_m: float
    azimuth_rms_rad: float
    n_points: int
    n_inliers: int
    warnings: tuple = ()

    def summary(self) -> str:
        """Human-readable lines (millimetres and degrees).

        Returns
        -------
        str
            Multi-line report: sweep points and inliers, circle fit RMSE and
            radius, the gravity sag removed and the azimuth residual.
        """
        lines = [f"sweep points: {self.n_points} ({self.n_inliers} inliers)",
                 f"circle RMSE: {self.circle_rmse_m * 1e3:.2f} mm, radius {self.radius_m * 1e3:.1f} mm "
                 f"(rigid reach {self.rigid_reach_m * 1e3:.1f} mm)"]
        if np.isfinite(self.sag_m):
            lines.append(f"gravity sag removed: {self.sag_m * 1e3:.1f} mm (vertical point "
                         f"{self.vertical_height_m * 1e3:.1f} mm above the circle plane, "
                         f"{self.vertical_axis_offset_m * 1e3:.1f} mm off the axis)")
        else:
            lines.append("no vertical posture: sag assumed 0")
        if np.isfinite(self.azimuth_rms_rad):
            lines.append(f"theta1 azimuth residual RMS: {np.rad2deg(self.azimuth_rms_rad):.3f} deg")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def base_frame_from_theta1_sweep(points_left, theta=None, vertical_point_left=None, params=None, *,
                          sweep_tol_rad: float = np.deg2rad(2.0),
                          loss: str = "soft_l1") -> tuple[np.ndarray, BaseFrameReport]:
    """Robot base pose in the left camera frame from a theta1 sweep.

    Parameters
    ----------
    points_left : array_like, shape (N, 3)
        End-effector positions during the sweep (theta2 = theta3 = 0), metres,
        left camera optical frame. N >= 3, not collinear.
    theta : array_like, shape (N, 3), optional
        Joint angles of each point, radians; theta2 and theta3 must be 0
        within ``sweep_tol_rad``. Gives the x axis (theta1 = 0) precisely.
    vertical_point_left : array_like, shape (3,), optional
        End-effector position in the vertical posture [0, 90, 0] deg, left
        camera frame; removes the gravity sag and orients z.
    params : RobotParams, optional
        Robot model (default: the packaged parameters).
    sweep_tol_rad : float
        Tolerance on theta2, theta3 for sweep points.
    loss : str
        Robust loss of the circle fit.

    Returns
    -------
    T_base_left : ndarray, shape (4, 4)
        ``p_base = T_base_left @ p_left``.
    report : BaseFrameReport

    Raises
    ------
    ValueError
        If the points are too few or collinear, shapes disagree, or the
        joint angles are not a theta1 sweep.

    Examples
    --------
    >>> th = np.column_stack([np.linspace(-2.5, 2.5, 40), np.zeros(40), np.zeros(40)])
    >>> T_left_base = np.eye(4); T_left_base[:3, 3] = [0.1, 0.5, 3.0]
    >>> pts = fk_ee(th) + T_left_base[:3, 3]
    >>> vert = fk_ee([0.0, np.pi / 2, 0.0]) + T_left_base[:3, 3]
    >>> T, rep = base_frame_from_theta1_sweep(pts, th, vert)
    >>> bool(np.allclose(T, invert_transform(T_left_base), atol=1e-9)), round(rep.sag_m, 9)
    (True, 0.0)
    """
    p = params if params is not None else load_robot_params()
    pts = check_points(points_left, "points_left")
    th = None
    if theta is not None:
        th = check_array(theta, "theta", (len(pts), 3))
        worst = float(np.max(np.abs(th[:, 1:])))
        if worst > sweep_tol_rad:
            raise ValueError(f"theta: a theta1 sweep needs theta2 = theta3 = 0, found "
                             f"{np.rad2deg(worst):.2f} deg (tolerance {np.rad2deg(sweep_tol_rad):.2f} deg)")
    pv = None if vertical_point_left is None else check_array(vertical_point_left, "vertical_point_left", (3,))

    circle = fit_circle_3d(pts, loss=loss)     # normal oriented by the point order
    c, n = circle.centre, circle.normal
    d = pts - c
    warnings = []
    if pv is not None:
        if n @ (pv - c) < 0:
            n = -n
    elif th is not None and _azimuth_slope(th[:, 0], d, n) < 0:
        n = -n
    u, w = _basis(n)
    phi = np.arctan2(d @ w, d @ u)
    if th is not None and pv is not None and _azimuth_slope(th[:, 0], d, n) < 0:
        warnings.append("theta1 turns clockwise about the upward circle normal: the joint-1 sign or "
                        "the camera handedness (left/right swapped?) is inconsistent")

    origin_height = fk_ee(_VERTICAL, p)[2]          # h1 + l2 + l3
    h1 = fk_ee(np.zeros(3), p)[2]
    reach = float(fk_ee(np.zeros(3), p)[0])         # l2 + l3
    if pv is not None:
        H = float(n @ (pv - c))
        origin = c + (H - origin_height) * n
        sag = H - (origin_height - h1)
        off = float(np.linalg.norm((pv - c) - H * n))
        if off > 0.05:
            warnings.append(f"vertical point lies {off * 1e3:.0f} mm off the circle axis")
    else:
        H = sag = off = float("nan")
        origin = c - h1 * n

    inl = circle.inliers
    if th is not None:
        phi0 = float(np.angle(np.mean(np.exp(1j * (phi[inl] - th[inl, 0])))))
        az_rms = float(np.sqrt(np.mean(_wrap(phi[inl] - th[inl, 0] - phi0) ** 2)))
    else:
        phi0 = float(phi[0])
        az_rms = float("nan")
    x = np.cos(phi0) * u + np.sin(phi0) * w
    T_left_base = make_frame(origin, n, x)
    report = BaseFrameReport(circle=circle, circle_rmse_m=circle.rmse, radius_m=circle.radius,
                             rigid_reach_m=reach, sag_m=float(sag), vertical_height_m=float(H),
                             vertical_axis_offset_m=float(off), azimuth_rms_rad=az_rms,
                             n_points=len(pts), n_inliers=int(inl.sum()), warnings=tuple(warnings))
    return invert_transform(T_left_base), report


def _azimuth_slope(theta1, d, n) -> float:
    """d phi / d theta1 of the points' azimuth about n (sign tells the turning sense)."""
    if np.ptp(theta1) < 1e-6:
        return 0.0
    u, w = _basis(n)
    order = np.argsort(theta1)
    phi = np.unwrap(np.arctan2(d[order] @ w, d[order] @ u))
    return float(np.polyfit(theta1[order], phi, 1)[0])


def _basis(n):
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)
