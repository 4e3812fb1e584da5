"""Joint velocities from a camera velocity (9.1.1) with the rigid-equivalent kinematics.

``theta_dot = J_r^-1(theta) R_base_cam(theta) v_cam``, where ``v_cam`` is the
camera's translational velocity in its own frame, ``R_base_cam =
R_base_ee(theta) R_ee_cam`` uses the rigid kinematics and the hand-eye
rotation, and ``J_r`` is the Jacobian of the camera origin (the
end-effector Jacobian of :func:`tudorvision.robot.jacobian_ee` plus the lever
of the hand-eye offset; with a zero offset it is exactly the seed's
``E J_r``). The arm's static deflection is not modelled: the servo loop
corrects it through the image.

Near singularities the inverse is damped (least squares with a damping that
grows as the smallest singular value falls below ``sigma_damp``), below
``sigma_stop`` the command is zero; a joint within ``limit_margin_rad`` of a
range end that would move further out also stops the arm. Finally the joint
speeds are scaled (direction kept) to the speed limits.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array, check_transform
from ..robot import T_base_ee, jacobian_ee, load_robot_params
from ..robot.params import RobotParams

__all__ = ["JointMapConfig", "JointCommand", "point_jacobian", "joint_velocity", "base_from_cam_velocity"]


@dataclass(frozen=True, kw_only=True)
class JointMapConfig:
    """Options of :func:`joint_velocity`.

    Attributes
    ----------
    sigma_damp : float
        Smallest singular value (m/rad) below which the inverse is damped.
    sigma_stop : float
        Smallest singular value below which the command is zero.
    damping_max : float
        Damping factor at ``sigma = 0`` (m/rad).
    limit_margin_rad : float
        Stop a joint heading out of its range this close to the end.
    speed_fraction : float
        Fraction of the hardware speed limits usable by the servo.
    """

    sigma_damp: float = 0.08
    sigma_stop: float = 0.02
    damping_max: float = 0.05
    limit_margin_rad: float = np.deg2rad(3.0)
    speed_fraction: float = 0.5

    def __post_init__(self):
        if not 0 <= self.sigma_stop < self.sigma_damp:
            raise ValueError(f"sigma_stop, sigma_damp: expected 0 <= stop < damp, got {self.sigma_stop}, "
                             f"{self.sigma_damp}")


@dataclass(frozen=True, kw_only=True, eq=False)
class JointCommand:
    """Joint velocity command (rad/s, shape (3,)); zero with a reason when not ok.

    Parameters
    ----------
    theta_dot : ndarray, shape (3,)
        Joint velocities, rad/s.
    ok : bool
        False when the command was zeroed (singularity, joint-range end).
    reason : str, optional
        Why the command was zeroed; empty when ``ok``.
    sigma_min : float, optional
        Smallest singular value of the Jacobian used (NaN if not computed).
    """

    theta_dot: np.ndarray
    ok: bool
    reason: str = ""
    sigma_min: float = float("nan")


def point_jacobian(theta, offset_ee=(0.0, 0.0, 0.0), params: RobotParams | None = None) -> np.ndarray:
    """Jacobian of a point fixed to the end effector, ``d p_base / d theta``, shape (3, 3).

    Parameters
    ----------
    theta : array_like, shape (3,)
        Joint angles, radians.
    offset_ee : array_like, shape (3,)
        The point in the end-effector frame, metres (hand-eye translation for
        the camera origin).

    Examples
    --------
    >>> from tudorvision.robot import jacobian_ee
    >>> th = [0.2, 0.4, -0.9]
    >>> bool(np.allclose(point_jacobian(th), jacobian_ee(th)))
    True
    """
    th = check_array(theta, "theta", (3,))
    off = check_array(offset_ee, "offset_ee", (3,))
    return _point_jacobian(th, off, params, None)


def _point_jacobian(th, off, params, T_be):
    """:func:`point_jacobian` for checked inputs; ``T_be`` is ``T_base_ee(th)`` if already known."""
    J = jacobian_ee(th, params)
    if not np.any(off):
        return J
    T = T_base_ee(th, params) if T_be is None else T_be
    r = T[:3, :3] @ off
    z_ee = T[:3, 2]                               # joint-2/3 axis: positive theta2 turns x_ee toward y_ee
    J_w = np.stack([[0.0, 0.0, 1.0], z_ee, z_ee], axis=1)
    return J + np.cross(J_w.T, r).T               # omega x r per column


def base_from_cam_velocity(v_cam, theta, T_ee_cam, params: RobotParams | None = None) -> np.ndarray:
    """Rotate a camera-frame velocity into the base frame with the rigid kinematics, shape (3,)."""
    R = T_base_ee(check_array(theta, "theta", (3,)), params)[:3, :3] @ check_transform(T_ee_cam, "T_ee_cam")[:3, :3]
    return R @ check_array(v_cam, "v_cam", (3,))


def joint_velocity(v_cam, theta, T_ee_cam, *, params: RobotParams | None = None,
                   config: JointMapConfig = JointMapConfig()) -> JointCommand:
    """Joint velocities realising a camera translation velocity (rigid-equivalent model).

    Parameters
    ----------
    v_cam : array_like, shape (3,)
        Camera velocity, m/s, camera frame.
    theta : array_like, shape (3,)
        Measured joint angles, radians.
    T_ee_cam : array_like, shape (4, 4)
        Hand-eye transform (``p_ee = T_ee_cam @ p_cam``).
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    config : JointMapConfig
        Damping, singularity stop, joint-range margin and speed limits.

    Returns
    -------
    JointCommand
        Zero with ``ok=False`` near a singularity or a joint-range end.

    Raises
    ------
    ValueError
        For malformed inputs.

    Examples
    --------
    >>> cmd = joint_velocity([0.0, 0.0, 0.0], [0.0, 0.3, -1.2], np.eye(4))
    >>> cmd.ok, cmd.theta_dot.tolist()
    (True, [0.0, 0.0, 0.0])
    """
    p = params or load_robot_params()
    return joint_velocity_checked(check_array(v_cam, "v_cam", (3,)), check_array(theta, "theta", (3,)),
                           check_transform(T_ee_cam, "T_ee_cam"), p, config)


def joint_velocity_checked(v_cam, th, T, p, config) -> JointCommand:
    """:func:`joint_velocity` for checked inputs (the servo checks its hand-eye transform once)."""
    T_be = T_base_ee(th, p)
    v_base = T_be[:3, :3] @ (T[:3, :3] @ v_cam)
    J = _point_jacobian(th, T[:3, 3], p, T_be)
    U, S, Vt = np.linalg.svd(J)
    smin = float(S[-1])
    if smin < config.sigma_stop:
        return JointCommand(theta_dot=np.zeros(3), ok=False, reason=f"near a singularity (sigma {smin:.3f})",
                            sigma_min=smin)
    lam2 = 0.0
    if smin < config.sigma_damp:
        lam2 = (1.0 - (smin / config.sigma_damp) ** 2) * config.damping_max ** 2
    qd = Vt.T @ ((S / (S * S + lam2)) * (U.T @ v_base))
    lo, hi = p.joint_limits_rad[:, 0], p.joint_limits_rad[:, 1]
    m = config.limit_margin_rad
    out = ((th <= lo + m) & (qd < 0)) | ((th >= hi - m) & (qd > 0))
    if np.any(out):
        j = int(np.argmax(out)) + 1
        return JointCommand(theta_dot=np.zeros(3), ok=False, reason=f"joint {j} at its range end",
                            sigma_min=smin)
    vmax = config.speed_fraction * np.asarray(p.max_speed_rad_s, float)
    scale = float(np.max(np.abs(qd) / vmax))
    if scale > 1.0:
        qd = qd / scale
    return JointCommand(theta_dot=qd, ok=True, sigma_min=smin)
