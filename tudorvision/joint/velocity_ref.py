"""The velocity-mode reference of the joint layer: watchdog, braking before the range limits, ramp, hold.

In velocity mode the server passes each accepted
:class:`~tudorvision.joint.messages.JointVelocityCommand` to
:meth:`VelocityReference.command`; every control tick it expires the command
after ``watchdog_s`` of control time, brakes the target so every joint still
stops inside its range (:func:`~tudorvision.joint.safety.brake_velocity`),
ramps the reference at the acceleration limits
(:func:`~tudorvision.joint.safety.ramp_velocity`), and tells the server
whether to track it or to hold position. Speeds in rad/s, times in s.

Examples
--------
>>> import numpy as np
>>> from tudorvision.joint.safety import SafetyLimits
>>> ref, lim = VelocityReference(watchdog_s=0.1), SafetyLimits.from_params()
>>> ref.command(np.array([0.1, 0.0, 0.0]), t_ctrl=0.0)
>>> v, limited = ref.next_reference(np.array([0.0, np.pi / 2, 0.0]), lim, dt=0.002)
>>> ref.advance(v), bool(limited), ref.expire(t_ctrl=0.1)
('track', False, True)
"""
from __future__ import annotations

import numpy as np

from .safety import SafetyLimits, brake_velocity, ramp_velocity

__all__ = ["VelocityReference"]


class VelocityReference:
    """The velocity reference sent to the core in velocity mode, and the watchdog of the commands.

    Parameters
    ----------
    watchdog_s : float
        Lifetime of a velocity command in control time, s.

    Attributes
    ----------
    v_target : ndarray, shape (3,)
        The last accepted command (zero after the watchdog expired), rad/s.
    v_ref : ndarray, shape (3,)
        The braked and ramped reference of the last tick, rad/s.
    deadline : float
        Control time in s at which the live command expires.
    armed : bool
        A command is live.
    holding : bool
        At rest without a live command: the core holds position (``stop()``).
    """

    def __init__(self, watchdog_s: float):
        self.watchdog_s = float(watchdog_s)
        self.v_target = np.zeros(3)
        self.v_ref = np.zeros(3)
        self.deadline = -np.inf
        self.armed = False
        self.holding = False

    def enter(self, theta_dot_now) -> None:
        """Enter velocity mode: ramp down from the current joint speeds, no live command.

        Parameters
        ----------
        theta_dot_now : array_like, shape (3,)
            The core's joint speeds, rad/s.
        """
        self.v_ref = np.asarray(theta_dot_now, dtype=float).copy()
        self.v_target = np.zeros(3)
        self.armed = False
        self.holding = False

    def clear(self) -> None:
        """Leave velocity mode (or stop on a fault): zero reference and target, no live command."""
        self.v_ref = np.zeros(3)
        self.v_target = np.zeros(3)
        self.armed = False

    def command(self, theta_dot: np.ndarray, t_ctrl: float) -> None:
        """Accept a checked velocity command; it lives until ``t_ctrl + watchdog_s``.

        Parameters
        ----------
        theta_dot : ndarray, shape (3,)
            Checked joint velocity, rad/s.
        t_ctrl : float
            Control time now, s.
        """
        self.v_target = theta_dot
        self.deadline = t_ctrl + self.watchdog_s
        self.armed = True

    def expire(self, t_ctrl: float) -> bool:
        """End a live command whose deadline has passed; True if this happened now.

        Parameters
        ----------
        t_ctrl : float
            Control time now, s.

        Returns
        -------
        bool
        """
        if self.armed and t_ctrl >= self.deadline:
            self.armed = False
            self.v_target = np.zeros(3)
            return True
        return False

    def next_reference(self, theta, limits: SafetyLimits, dt: float) -> tuple[np.ndarray, bool]:
        """The reference for the next tick: target braked before the range limits, ramped (not stored).

        Parameters
        ----------
        theta : array_like, shape (3,)
            Joint angles now, rad.
        limits : SafetyLimits
            The layer's limits.
        dt : float
            Control period, s.

        Returns
        -------
        v_ref : ndarray, shape (3,)
            Reference, rad/s (may be non-finite if the inputs were).
        limited : bool
            The brake reduced the target.
        """
        braked = brake_velocity(theta, self.v_target, limits, dt, theta_dot_now=self.v_ref)
        limited = not np.array_equal(braked, self.v_target)
        return ramp_velocity(self.v_ref, braked, limits.max_accel_rad_s2, dt), limited

    def advance(self, v_ref: np.ndarray) -> str:
        """Store the reference of this tick and say what the core should do with it.

        Parameters
        ----------
        v_ref : ndarray, shape (3,)
            Finite reference from :meth:`next_reference`, rad/s.

        Returns
        -------
        str
            ``"track"`` (apply ``v_ref``), ``"hold"`` (at rest without a live
            command: stop and hold position, once) or ``"held"`` (already holding).
        """
        self.v_ref = v_ref
        if not self.armed and not np.any(v_ref):
            if self.holding:
                return "held"
            self.holding = True
            return "hold"
        self.holding = False
        return "track"
