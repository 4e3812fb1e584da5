"""Actuator model of TUDOR's joints, referred to the gear output (section 3.1).

The amplifier with its current loop is fast (833 Hz) compared to the
mechanics and is merged into one gain (3.1.2)::

    tau_E = n_M k_tau k_amp v_M = k_M v_M

Friction follows Zeng's direction-dependent model (3.1.3). The seed lists the
Coulomb coefficients as magnitudes; here they always oppose the motion::

    tau_F = k_v+ dtheta + k_c+      (dtheta > 0)
    tau_F = k_v- dtheta - k_c-      (dtheta < 0)

with the motor-side coefficients of appendix A.3 reflected through the gear:
viscous ``n_M^2 k_v``, Coulomb ``n_M k_c``, inertia ``n_M^2 I_M``. Both the
joint controller (:mod:`tudorvision.joint.cascade`) and the simulated plant
(:mod:`tudorvision.sim.arm`) use these physical quantities.
"""
from __future__ import annotations

import numpy as np

from .params import RobotParams

__all__ = ["motor_gain", "reflected_inertia", "reflected_viscous", "friction_torque"]


def motor_gain(params: RobotParams) -> np.ndarray:
    """``k_M = n_M k_tau k_amp`` per joint (N m per volt at the gear output), eq. 3.1.2.

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> np.round(motor_gain(load_robot_params()), 2)
    array([ 9.71, 14.32,  4.41])
    """
    return (np.asarray(params.gear_ratio, float) * np.asarray(params.torque_constant_Nm_A, float)
            * np.asarray(params.amplifier_gain_A_V, float))


def reflected_inertia(params: RobotParams) -> np.ndarray:
    """Rotor and gear inertia at the gear output ``n_M^2 I_M``, kg m^2, shape (3,)."""
    return np.asarray(params.gear_ratio, float) ** 2 * np.asarray(params.rotor_inertia_kg_m2, float)


def reflected_viscous(params: RobotParams) -> np.ndarray:
    """Symmetric viscous friction at the output (mean of k_v+ and k_v-, 3.1.6), N m s/rad."""
    n2 = np.asarray(params.gear_ratio, float) ** 2
    return n2 * 0.5 * (np.asarray(params.viscous_pos_Nms_rad, float)
                       + np.asarray(params.viscous_neg_Nms_rad, float))


def friction_torque(dtheta, params: RobotParams) -> np.ndarray:
    """Joint friction torque at the gear output, model (3.1.3) with opposing Coulomb terms.

    Parameters
    ----------
    dtheta : array_like, shape (3,) or (N, 3)
        Joint velocities, rad/s.

    Returns
    -------
    tau_F : ndarray, same shape
        N m; positive values oppose positive motion. Zero velocity gives zero
        (the plant treats sticking separately).

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> p = load_robot_params()
    >>> t = friction_torque([0.1, -0.1, 0.0], p)
    >>> bool(t[0] > 0 and t[1] < 0 and t[2] == 0)
    True
    """
    v = np.asarray(dtheta, dtype=np.float64)
    n = np.asarray(params.gear_ratio, float)
    kvp, kvn = n**2 * params.viscous_pos_Nms_rad, n**2 * params.viscous_neg_Nms_rad
    kcp, kcn = n * params.coulomb_pos_Nm, n * params.coulomb_neg_Nm
    return np.where(v > 0, kvp * v + kcp, np.where(v < 0, kvn * v - kcn, 0.0))
