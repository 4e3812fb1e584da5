"""Sinusoidal-acceleration point-to-point planner (appendix B.6, after Wenz 2008).

A motion of one joint consists of three phases: a velocity transition from the
start velocity ``v0`` to a peak velocity ``vp``, a cruise at ``vp`` and a
transition from ``vp`` to rest. Each transition has the acceleration

    a(tau) = a_max sin^2(pi tau / T),   0 <= tau <= T,   T = 2 |dv| / a_max

(B.6.1), so acceleration is continuous, starts and ends at zero, and never
exceeds ``a_max``; the velocity never exceeds ``v_max``. When the distance is
too short to reach ``v_max`` the cruise vanishes and ``vp`` is lowered. If the
start velocity points away from the goal, or the joint cannot stop before the
goal, the first transition passes through zero velocity and the motion
approaches the goal from the other side, still without violating the limits.

Re-planning in motion (:class:`OnlinePlanner`) keeps angle and velocity
continuous; the acceleration restarts from the sin^2 shape (B.6 assumes zero
initial acceleration), so it may jump at the switching instant.

Joints are planned independently (each with its own limits), as in the seed.
Angles in radians, time in seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_array

__all__ = ["sinusoidal_transition", "JointMotion", "plan_motion", "OnlinePlanner"]


def sinusoidal_transition(tau, duration_s: float, v_start, dv):
    """Position increment, velocity and acceleration of one sin^2 velocity transition.

    Parameters
    ----------
    tau : array_like
        Time since the transition started, seconds (clipped to ``[0, duration_s]``).
    duration_s : float
        Transition time ``T > 0``.
    v_start, dv : float or array_like
        Start velocity and velocity change (rad/s).

    Returns
    -------
    dp, v, a : ndarray
        Position increment since the start (rad), velocity (rad/s) and
        acceleration (rad/s^2), per B.6.1–B.6.3.

    Examples
    --------
    >>> dp, v, a = sinusoidal_transition(1.0, 1.0, 0.0, 2.0)
    >>> float(dp), float(v), round(float(a), 12)
    (1.0, 2.0, 0.0)
    """
    T = float(duration_s)
    t = np.clip(np.asarray(tau, dtype=np.float64), 0.0, T)
    w = 2.0 * np.pi / T
    v = v_start + dv * (t / T - np.sin(w * t) / (2.0 * np.pi))
    dp = v_start * t + dv * (t * t / (2.0 * T) + T * (np.cos(w * t) - 1.0) / (4.0 * np.pi**2))
    a = (2.0 * dv / T) * np.sin(0.5 * w * t) ** 2
    return dp, v, a


@dataclass(frozen=True, kw_only=True)
class JointMotion:
    """A planned multi-joint point-to-point motion (each joint on its own profile).

    Attributes
    ----------
    t0 : float
        Start time, seconds.
    theta0, dtheta0, theta_goal : ndarray, shape (J,)
        Start angles (rad), start velocities (rad/s) and goal angles (rad).
    v_peak : ndarray, shape (J,)
        Peak (cruise) velocity per joint, rad/s.
    t_acc, t_cruise, t_dec : ndarray, shape (J,)
        Phase durations per joint, seconds.
    """

    t0: float
    theta0: np.ndarray
    dtheta0: np.ndarray
    theta_goal: np.ndarray
    v_peak: np.ndarray
    t_acc: np.ndarray
    t_cruise: np.ndarray
    t_dec: np.ndarray

    @property
    def duration_s(self) -> float:
        """Time until the last joint comes to rest."""
        return float(np.max(self.t_acc + self.t_cruise + self.t_dec))

    def sample(self, t):
        """Planned angles, velocities and accelerations at times ``t``.

        Parameters
        ----------
        t : float or array_like, shape (N,)
            Absolute times, seconds. Before ``t0`` the start state (angle and
            velocity) is returned; after the end the goal is held at rest.

        Returns
        -------
        theta, dtheta, ddtheta : ndarray, shape (J,) or (N, J)
        """
        scalar = np.ndim(t) == 0
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64))[:, None] - self.t0
        tt = np.maximum(tt, 0.0)
        th = np.empty((tt.shape[0], len(self.theta0)))
        dth, ddth = np.empty_like(th), np.empty_like(th)
        for j in range(len(self.theta0)):
            th[:, j], dth[:, j], ddth[:, j] = self._sample_joint(j, tt[:, 0])
        if scalar:
            return th[0], dth[0], ddth[0]
        return th, dth, ddth

    def sample_scalar(self, t: float):
        """Fast pure-Python :meth:`sample` for one time (for 2 kHz loops).

        Parameters
        ----------
        t : float
            Absolute time, seconds.

        Returns
        -------
        theta, dtheta, ddtheta : list of J floats
            Planned angles (rad), velocities (rad/s) and accelerations (rad/s^2).
        """
        tt = max(float(t) - self.t0, 0.0)
        th, dth, ddth = [], [], []
        for j in range(len(self.theta0)):
            p, v, a = _scalar_joint(tt, float(self.theta0[j]), float(self.dtheta0[j]), float(self.v_peak[j]),
                                    float(self.t_acc[j]), float(self.t_cruise[j]), float(self.t_dec[j]),
                                    float(self.theta_goal[j]))
            th.append(p); dth.append(v); ddth.append(a)
        return th, dth, ddth

    def _sample_joint(self, j: int, tt: np.ndarray):
        v0, vp = self.dtheta0[j], self.v_peak[j]
        t1, tc, t3 = self.t_acc[j], self.t_cruise[j], self.t_dec[j]
        p = np.full_like(tt, self.theta0[j])
        v = np.full_like(tt, v0)
        a = np.zeros_like(tt)
        if t1 > 0:
            dp, vv, aa = sinusoidal_transition(tt, t1, v0, vp - v0)
            m = tt < t1
            p[m] += dp[m]; v[m] = vv[m]; a[m] = aa[m]
            p1 = self.theta0[j] + sinusoidal_transition(t1, t1, v0, vp - v0)[0]
        else:
            p1 = self.theta0[j]
        m = (tt >= t1) & (tt < t1 + tc)
        p[m] = p1 + vp * (tt[m] - t1); v[m] = vp; a[m] = 0.0
        p2 = p1 + vp * tc
        m = tt >= t1 + tc
        if t3 > 0:
            dp, vv, aa = sinusoidal_transition(tt - t1 - tc, t3, vp, -vp)
            p[m] = p2 + dp[m]; v[m] = vv[m]; a[m] = aa[m]
        else:
            p[m] = p2; v[m] = 0.0; a[m] = 0.0
        # the goal is held exactly after the end
        done = tt >= t1 + tc + t3
        p[done] = self.theta_goal[j]; v[done] = 0.0; a[done] = 0.0
        return p, v, a


def _transition_scalar(tau: float, T: float, v0: float, dv: float):
    w = 2.0 * math.pi / T
    v = v0 + dv * (tau / T - math.sin(w * tau) / (2.0 * math.pi))
    dp = v0 * tau + dv * (tau * tau / (2.0 * T) + T * (math.cos(w * tau) - 1.0) / (4.0 * math.pi ** 2))
    a = (2.0 * dv / T) * math.sin(0.5 * w * tau) ** 2
    return dp, v, a


def _scalar_joint(tt, p0, v0, vp, t1, tc, t3, goal):
    if tt >= t1 + tc + t3:
        return goal, 0.0, 0.0
    if tt < t1:
        dp, v, a = _transition_scalar(tt, t1, v0, vp - v0)
        return p0 + dp, v, a
    p1 = p0 + (_transition_scalar(t1, t1, v0, vp - v0)[0] if t1 > 0 else 0.0)
    if tt < t1 + tc:
        return p1 + vp * (tt - t1), vp, 0.0
    dp, v, a = _transition_scalar(tt - t1 - tc, t3, vp, -vp)
    return p1 + vp * tc + dp, v, a


def _plan_1d(d: float, v0: float, vmax: float, amax: float):
    """Phases (vp, t_acc, t_cruise, t_dec) for distance d from velocity v0 to rest."""
    d_stop = v0 * abs(v0) / amax          # distance covered when braking from v0 at once
    s = 1.0 if d - d_stop > 0 else -1.0
    if abs(d - d_stop) < 1e-15:
        return 0.0, 2.0 * abs(v0) / amax, 0.0, 0.0
    # mirror so that the motion goes in +s direction
    d, v0 = s * d, s * v0
    vm = vmax
    if v0 > vm:                                # start faster than allowed: slow down to vm
        vp = vm
    else:
        # without cruise: distance (2 vp^2 - v0^2) / amax
        vp = min(vm, np.sqrt(max((amax * d + v0 * v0) / 2.0, 0.0)))
    t_acc = 2.0 * abs(vp - v0) / amax
    t_dec = 2.0 * vp / amax
    d_ramps = (v0 + vp) / 2.0 * t_acc + vp * t_dec / 2.0
    t_cruise = max(0.0, (d - d_ramps) / vp) if vp > 0 else 0.0
    return s * vp, t_acc, t_cruise, t_dec


def plan_motion(theta_start, theta_goal, *, v_max, a_max, dtheta_start=None,
                t0: float = 0.0) -> JointMotion:
    """Plan a point-to-point motion with the sinusoidal acceleration profile (B.6).

    Parameters
    ----------
    theta_start, theta_goal : array_like, shape (J,)
        Start and goal angles, radians.
    v_max, a_max : float or array_like, shape (J,)
        Speed (rad/s) and acceleration (rad/s^2) limits, > 0.
    dtheta_start : array_like, shape (J,), optional
        Start velocities (rad/s); default zero. Allows re-planning in motion.
    t0 : float
        Start time, seconds.

    Returns
    -------
    JointMotion

    Raises
    ------
    ValueError
        If shapes mismatch or a limit is not positive.

    Examples
    --------
    >>> m = plan_motion([0.0], [1.0], v_max=1.0, a_max=2.0)
    >>> round(m.duration_s, 6)   # two 1 s ramps cover the 1 rad, no cruise
    2.0
    >>> float(m.sample(2.0)[0][0])
    1.0
    """
    th0 = check_array(np.atleast_1d(theta_start), "theta_start", (None,))
    n = len(th0)
    goal = check_array(np.atleast_1d(theta_goal), "theta_goal", (n,))
    vmax = np.broadcast_to(np.asarray(v_max, dtype=np.float64), (n,)).copy()
    amax = np.broadcast_to(np.asarray(a_max, dtype=np.float64), (n,)).copy()
    if np.any(~(vmax > 0)) or np.any(~(amax > 0)):
        raise ValueError(f"v_max, a_max: expected positive limits, got {vmax.tolist()}, {amax.tolist()}")
    v0 = np.zeros(n) if dtheta_start is None else check_array(np.atleast_1d(dtheta_start),
                                                              "dtheta_start", (n,))
    vp, ta, tc, td = (np.zeros(n) for _ in range(4))
    for j in range(n):
        vp[j], ta[j], tc[j], td[j] = _plan_1d(goal[j] - th0[j], v0[j], vmax[j], amax[j])
    return JointMotion(t0=float(t0), theta0=th0, dtheta0=v0, theta_goal=goal, v_peak=vp,
                       t_acc=ta, t_cruise=tc, t_dec=td)


class OnlinePlanner:
    """Holds the current motion and re-plans when a new goal arrives (setpoint mode).

    Parameters
    ----------
    theta_start : array_like, shape (J,)
        Angles at rest at time ``t0``.
    v_max, a_max : float or array_like, shape (J,)
        Limits, rad/s and rad/s^2.
    t0 : float, optional
        Start time, seconds.

    Raises
    ------
    ValueError
        If a limit is not positive.

    Examples
    --------
    >>> pl = OnlinePlanner([0.0, 0.0], v_max=1.0, a_max=2.0)
    >>> pl.set_goal([0.5, -0.5], t=0.0)
    >>> th, dth, _ = pl.sample(10.0)
    >>> th.tolist()
    [0.5, -0.5]
    """

    def __init__(self, theta_start, *, v_max, a_max, t0: float = 0.0):
        th = check_array(np.atleast_1d(theta_start), "theta_start", (None,))
        self.v_max, self.a_max = v_max, a_max
        self.motion = plan_motion(th, th, v_max=v_max, a_max=a_max, t0=t0)

    def set_goal(self, theta_goal, t: float) -> None:
        """Start a new motion toward ``theta_goal`` from the planned state at time ``t``.

        Parameters
        ----------
        theta_goal : array_like, shape (J,)
            Goal angles, rad.
        t : float
            Absolute time of the new goal, seconds.

        Raises
        ------
        ValueError
            If ``theta_goal`` does not have shape (J,).
        """
        th, dth, _ = self.motion.sample(float(t))
        self.motion = plan_motion(th, theta_goal, v_max=self.v_max, a_max=self.a_max,
                                  dtheta_start=dth, t0=float(t))

    def sample(self, t):
        """Planned ``(theta, dtheta, ddtheta)`` at time(s) ``t`` (see :meth:`JointMotion.sample`).

        Parameters
        ----------
        t : float or array_like, shape (N,)
            Absolute times, seconds.

        Returns
        -------
        theta, dtheta, ddtheta : ndarray, shape (J,) or (N, J)
            Planned angles (rad), velocities (rad/s) and accelerations (rad/s^2).
        """
        return self.motion.sample(t)

    def sample_scalar(self, t: float):
        """Pure-Python sample at one time (lists of floats).

        Parameters
        ----------
        t : float
            Absolute time, seconds.

        Returns
        -------
        theta, dtheta, ddtheta : list of J floats
            Planned angles (rad), velocities (rad/s) and accelerations (rad/s^2).
        """
        return self.motion.sample_scalar(t)
