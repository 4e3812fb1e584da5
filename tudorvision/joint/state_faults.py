"""Fault checks of the core's state: speed, range and acceleration limits.

The server runs :meth:`StateFaultMonitor.check` on every new
:class:`~tudorvision.joint.cores.CoreState`; a state it flags stops the core
and sets ``FAULT``. :func:`range_fault` is the pure range rule.

All angles in rad, speeds in rad/s, accelerations in rad/s², times in s.

Examples
--------
>>> import numpy as np
>>> from tudorvision.joint.safety import SafetyLimits
>>> lim = SafetyLimits.from_params()
>>> fault, outside = range_fault(lim.joint_limits_rad[:, 1] + 0.1, np.zeros(3), lim.joint_limits_rad,
...                              tol=0.01, rest_speed=1e-3, outside=np.zeros(3, dtype=bool))
>>> bool(fault), outside.tolist()
(True, [True, True, True])
"""
from __future__ import annotations

import collections

import numpy as np

from .safety import SafetyLimits

__all__ = ["range_fault", "StateFaultMonitor"]


def range_fault(theta, theta_dot, joint_limits_rad, *, tol: float, rest_speed: float,
                outside) -> tuple[bool, np.ndarray]:
    """A joint left its range (beyond the tolerance) now, or is outside and moving further out.

    A joint that is already outside and at rest or moving back does not
    fault again, so a reset fault sticks and a setpoint can bring the arm
    back into its range.

    Parameters
    ----------
    theta, theta_dot : array_like, shape (3,)
        Joint angles (rad) and speeds (rad/s) of the core's state.
    joint_limits_rad : ndarray, shape (3, 2)
        Range ``[lower, upper]`` per joint, rad.
    tol : float
        Tolerance beyond the range, rad.
    rest_speed : float
        Speed below which a joint is at rest, rad/s.
    outside : ndarray of bool, shape (3,)
        Joints outside range + tolerance at the previous check.

    Returns
    -------
    fault : bool
    outside : ndarray of bool, shape (3,)
        Joints outside range + tolerance now.
    """
    theta = np.asarray(theta)
    below, above = theta < joint_limits_rad[:, 0] - tol, theta > joint_limits_rad[:, 1] + tol
    v = np.asarray(theta_dot)
    outward = (below & (v < -rest_speed)) | (above & (v > rest_speed))
    entered = (below | above) & ~outside
    return bool(np.any(entered) or np.any(outward)), below | above


class StateFaultMonitor:
    """Checks each new core state against the limits; keeps what the checks need between ticks.

    Parameters
    ----------
    speed_factor : float
        A joint faster than this times its speed limit is a fault.
    range_tol_rad : float
        Tolerance of the range rule (:func:`range_fault`), rad.
    rest_speed_rad_s : float
        Speed below which a joint is at rest, rad/s.
    accel_factor : float or None
        A joint speed change faster than this times the acceleration limit
        (over ``accel_window_s``) is a fault; ``None``: not checked.
    accel_window_s : float
        Window of the acceleration estimate, s.
    """

    def __init__(self, *, speed_factor: float, range_tol_rad: float, rest_speed_rad_s: float,
                 accel_factor: float | None, accel_window_s: float):
        self.speed_factor, self.range_tol_rad = speed_factor, range_tol_rad
        self.rest_speed_rad_s = rest_speed_rad_s
        self.accel_factor, self.accel_window_s = accel_factor, accel_window_s
        self._outside = np.zeros(3, dtype=bool)    # joints beyond range + tolerance at the last check
        self._speeds = collections.deque()         # (t_core, theta_dot) for the acceleration check

    def check(self, cs, limits: SafetyLimits) -> str | None:
        """Run every check on a new state (each one updates its memory).

        Parameters
        ----------
        cs : CoreState
            The core's state after a step.
        limits : SafetyLimits
            The layer's limits.

        Returns
        -------
        str or None
            ``"speed"``, ``"range"`` or ``"acceleration"`` (the first that
            failed, in that order), or ``None``.
        """
        over_speed = np.any(np.abs(cs.theta_dot) > self.speed_factor * limits.max_speed_rad_s)
        out, self._outside = range_fault(cs.theta, cs.theta_dot, limits.joint_limits_rad,
                                         tol=self.range_tol_rad, rest_speed=self.rest_speed_rad_s,
                                         outside=self._outside)
        over_accel = self._accel_fault(cs, limits)
        if over_speed:
            return "speed"
        if out:
            return "range"
        return "acceleration" if over_accel else None

    def _accel_fault(self, cs, limits: SafetyLimits) -> bool:
        factor = self.accel_factor
        if factor is None:
            return False
        w = self._speeds
        w.append((float(cs.t), np.asarray(cs.theta_dot, dtype=float)))
        while len(w) > 2 and w[1][0] <= cs.t - self.accel_window_s:
            w.popleft()
        span = w[-1][0] - w[0][0]
        if span < 0.5 * self.accel_window_s:
            return False
        accel = np.abs(w[-1][1] - w[0][1]) / span
        return bool(np.any(accel > factor * limits.max_accel_rad_s2))
