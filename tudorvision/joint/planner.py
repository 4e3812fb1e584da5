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
initial acceleration), so it may jump at the switching instant. With
``replan="blend"`` (:func:`blend_replan`, :class:`BlendedMotion`) the
acceleration at the switch fades out as ``a0 cos^2`` while the new profile
starts, so angle, velocity and acceleration stay continuous and the limits hold.

Joints are planned independently (each with its own limits), as in the seed.
Angles in radians, time in seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_array

__all__ = ["sinusoidal_transition", "JointMotion", "plan_motion", "OnlinePlanner", "BlendedMotion", "blend_replan",
           "REPLAN_MODES"]

#: How a motion is re-planned in flight: the acceleration restarts from zero, or fades out (continuous).
REPLAN_MODES = ("restart", "blend")


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


def _limits(v_max, a_max, n: int):
    """Speed and acceleration limits as (n,) arrays; ValueError unless all positive."""
    vmax = np.broadcast_to(np.asarray(v_max, dtype=np.float64), (n,)).copy()
    amax = np.broadcast_to(np.asarray(a_max, dtype=np.float64), (n,)).copy()
    if np.any(~(vmax > 0)) or np.any(~(amax > 0)):
        raise ValueError(f"v_max, a_max: expected positive limits, got {vmax.tolist()}, {amax.tolist()}")
    return vmax, amax


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
    vmax, amax = _limits(v_max, a_max, n)
    v0 = np.zeros(n) if dtheta_start is None else check_array(np.atleast_1d(dtheta_start),
                                                              "dtheta_start", (n,))
    vp, ta, tc, td = (np.zeros(n) for _ in range(4))
    for j in range(n):
        vp[j], ta[j], tc[j], td[j] = _plan_1d(goal[j] - th0[j], v0[j], vmax[j], amax[j])
    return JointMotion(t0=float(t0), theta0=th0, dtheta0=v0, theta_goal=goal, v_peak=vp,
                       t_acc=ta, t_cruise=tc, t_dec=td)


def _fade(u, a0, blend_s, cos, sin):
    """The fade's ``(dp, dv, a)`` at ``u`` in ``[0, blend_s]`` (see :func:`_blend_terms`); ``cos``, ``sin``
    from :mod:`math` (floats) or numpy (arrays)."""
    k = math.pi / blend_s
    c = cos(k * u)
    return (0.5 * a0 * (0.5 * u * u + (1.0 - c) / (k * k)) - 0.5 * a0 * blend_s * u,
            0.5 * a0 * (u + sin(k * u) / k) - 0.5 * a0 * blend_s,
            0.5 * a0 * (1.0 + c))


def _fade_offset(a0, blend_s):
    """Where the fade leaves the angle against an instant velocity step ``a0 blend_s / 2``, rad."""
    return a0 * blend_s * blend_s * (1.0 / math.pi ** 2 - 0.25)


def _blend_terms(tau, a0, blend_s):
    """Offset of a ``a0 cos^2`` fade over ``blend_s`` from an instant velocity step ``a0 blend_s / 2``.

    Returns ``(dp, dv, a)`` (rad, rad/s, rad/s^2) at times ``tau`` (s, clipped to ``[0, blend_s]``):
    zero at ``tau = 0`` for ``dp``, ``-a0 blend_s / 2`` for ``dv`` and ``a0`` for ``a``; constant
    ``a0 blend_s^2 (1/pi^2 - 1/4)`` (:func:`_fade_offset`), 0 and 0 from ``blend_s`` on. ``blend_s`` must be
    positive.
    """
    return _fade(np.clip(tau, 0.0, blend_s), a0, blend_s, np.cos, np.sin)


@dataclass(frozen=True, kw_only=True)
class BlendedMotion:
    """A motion re-planned in flight with continuous acceleration (see :func:`blend_replan`).

    The reference is ``base`` plus, per joint, the fade of the acceleration ``a0`` held at the switch
    (``a0 cos^2(pi tau / (2 T_b))`` for ``tau < T_b``) less the velocity step ``a0 T_b / 2`` that
    ``base`` already starts with; ``base`` aims at ``theta_goal`` less the fade's constant offset.

    Attributes
    ----------
    base : JointMotion
        The sin^2 motion from the switch, started at the faded velocity.
    a0 : ndarray, shape (J,)
        Acceleration at the switch, rad/s^2.
    blend_s : ndarray, shape (J,)
        Fade time ``T_b`` per joint, seconds (0: the acceleration restarts from zero for that joint).
    theta_goal : ndarray, shape (J,)
        Goal angles, rad.
    """

    base: JointMotion
    a0: np.ndarray
    blend_s: np.ndarray
    theta_goal: np.ndarray

    @property
    def t0(self) -> float:
        """Switching time, seconds."""
        return self.base.t0

    @property
    def duration_s(self) -> float:
        """Time until the last joint comes to rest."""
        return max(self.base.duration_s, float(np.max(self.blend_s)))

    def sample(self, t):
        """Planned angles, velocities and accelerations at times ``t`` (see :meth:`JointMotion.sample`).

        Parameters
        ----------
        t : float or array_like, shape (N,)
            Absolute times, seconds.

        Returns
        -------
        theta, dtheta, ddtheta : ndarray, shape (J,) or (N, J)
        """
        th, dth, ddth = (np.array(x, dtype=np.float64) for x in self.base.sample(t))
        tau = np.maximum(np.asarray(t, dtype=np.float64) - self.t0, 0.0)
        tau = tau[..., None] if np.ndim(tau) else tau
        on = self.blend_s > 0
        if np.any(on):
            dp, dv, a = _blend_terms(tau, self.a0, np.where(on, self.blend_s, 1.0))
            th += np.where(on, dp, 0.0); dth += np.where(on, dv, 0.0); ddth += np.where(on, a, 0.0)
        done = tau >= self.duration_s
        if np.any(done):
            th = np.where(done, self.theta_goal, th)
            dth, ddth = np.where(done, 0.0, dth), np.where(done, 0.0, ddth)
        return th, dth, ddth

    def sample_scalar(self, t: float):
        """Fast pure-Python :meth:`sample` for one time (lists of J floats).

        Parameters
        ----------
        t : float
            Absolute time, seconds.

        Returns
        -------
        theta, dtheta, ddtheta : list of J floats
        """
        th, dth, ddth = self.base.sample_scalar(t)
        tau = max(float(t) - self.base.t0, 0.0)
        if tau >= self.duration_s:
            return [float(g) for g in self.theta_goal], [0.0] * len(th), [0.0] * len(th)
        for j in range(len(th)):
            tb = float(self.blend_s[j])
            if tb <= 0.0:
                continue
            dp, dv, a = _fade(min(tau, tb), float(self.a0[j]), tb, math.cos, math.sin)
            th[j] += dp; dth[j] += dv; ddth[j] += a
        return th, dth, ddth


def _blend_joint(p0, v0, a0, goal, vmax, amax, tb, a_base, samples):
    """Base phases of one joint blended over ``tb`` with base acceleration ``a_base``, or None (limits)."""
    c = _fade_offset(a0, tb)
    vb = v0 + 0.5 * a0 * tb
    vp, t1, tc, t3 = _plan_1d(goal - c - p0, vb, vmax, a_base)
    one = JointMotion(t0=0.0, theta0=np.array([p0]), dtheta0=np.array([vb]), theta_goal=np.array([goal - c]),
                      v_peak=np.array([vp]), t_acc=np.array([t1]), t_cruise=np.array([tc]), t_dec=np.array([t3]))
    edges = np.minimum([0.0, t1, t1 + tc, t1 + tc + t3, tb], tb)   # every base phase inside the fade, densely
    tau = np.concatenate([np.linspace(a, b, samples) for a, b in zip(edges[:-1], edges[1:]) if b > a] or [[0.0]])
    _, v, a = one._sample_joint(0, tau)
    _, dv, da = _blend_terms(tau, a0, tb)
    ok = (np.max(np.abs(a + da)) <= amax * (1.0 + 1e-9) + 1e-12
          and np.max(np.abs(v + dv)) <= max(vmax, abs(v0)) * (1.0 + 1e-9) + 1e-12)
    return (vb, goal - c, vp, t1, tc, t3) if ok else None


def _fit_fade(p0, v0, a0, goal, vmax, amax, tb0, samples):
    """Fade time and base phases of one joint (``(tb, row)``; ``row`` None: no fade fits the limits).

    Tried in turn, the base at the full ``amax`` unless said: the nominal fade ``tb0``; the fade that
    ends at the base's peak velocity (no first base transition; a few fixed-point steps); half and a
    quarter of ``tb0``; ``tb0`` with the base's acceleration lowered (bisection down to ``amax / 2``).
    """
    row = _blend_joint(p0, v0, a0, goal, vmax, amax, tb0, amax, samples)
    if row is not None:
        return tb0, row
    tb = tb0
    for _ in range(4):                                   # fade straight into the base's peak velocity
        vp = _plan_1d(goal - _fade_offset(a0, tb) - p0, v0 + 0.5 * a0 * tb, vmax, amax)[0]
        if not (vp - v0) * a0 > 0:
            break
        tb = 2.0 * (vp - v0) / a0
        if tb > 4.0 * tb0:
            break
        row = _blend_joint(p0, v0, a0, goal, vmax, amax, tb, amax, samples)
        if row is not None:
            return tb, row
    for tb in (0.5 * tb0, 0.25 * tb0):
        row = _blend_joint(p0, v0, a0, goal, vmax, amax, tb, amax, samples)
        if row is not None:
            return tb, row
    lo, hi = 0.5 * amax, amax
    best = _blend_joint(p0, v0, a0, goal, vmax, amax, tb0, lo, samples)
    if best is not None:
        for _ in range(6):
            mid = 0.5 * (lo + hi)
            r = _blend_joint(p0, v0, a0, goal, vmax, amax, tb0, mid, samples)
            lo, hi, best = (mid, hi, r) if r is not None else (lo, mid, best)
    return tb0, best


def blend_replan(theta, dtheta, ddtheta, theta_goal, *, v_max, a_max, t0: float = 0.0,
                 samples: int = 65) -> BlendedMotion:
    """Re-plan in flight keeping the acceleration continuous (``replan="blend"``).

    Per joint the acceleration ``a0`` at the switch fades as ``a0 cos^2(pi tau / (2 T_b))`` over
    ``T_b = |a0| v_max / a_max^2`` (the jerk of a sin^2 transition to half the speed limit; shorter
    where the faded velocity would pass ``v_max``), on top of a sin^2 motion (:func:`plan_motion`)
    from the faded velocity ``v0 + a0 T_b / 2`` to the goal less the fade's offset. Where the sum
    would exceed ``a_max`` the fade is fitted to end at the base's peak velocity, then shortened (to a
    half and a quarter), then the base's acceleration lowered (down to half of ``a_max``); where the
    sum still would, or ``a0`` is zero, that joint restarts from zero acceleration as
    :func:`plan_motion` does. The sum is checked at ``samples`` points of every base phase inside the fade
    (between them it may pass ``a_max`` by a little: 4e-5 of it at most over 3000 random switches).

    Parameters
    ----------
    theta, dtheta, ddtheta : array_like, shape (J,)
        Reference angle (rad), velocity (rad/s) and acceleration (rad/s^2) at the switch.
    theta_goal : array_like, shape (J,)
        Goal angles, rad.
    v_max, a_max : float or array_like, shape (J,)
        Speed (rad/s) and acceleration (rad/s^2) limits, > 0.
    t0 : float
        Switching time, seconds.
    samples : int
        Points of the fade at which the limits are checked (>= 2).

    Returns
    -------
    BlendedMotion

    Raises
    ------
    ValueError
        If shapes mismatch or a limit is not positive.

    Examples
    --------
    >>> m = blend_replan([0.0], [0.5], [2.0], [1.0], v_max=1.0, a_max=2.0)
    >>> [round(float(x[0]), 6) for x in m.sample(0.0)]     # angle, velocity and acceleration carry over
    [0.0, 0.5, 2.0]
    >>> round(float(m.sample(m.duration_s)[0][0]), 9)
    1.0
    """
    th0 = check_array(np.atleast_1d(theta), "theta", (None,))
    n = len(th0)
    goal = check_array(np.atleast_1d(theta_goal), "theta_goal", (n,))
    v0 = check_array(np.atleast_1d(dtheta), "dtheta", (n,))
    acc0 = check_array(np.atleast_1d(ddtheta), "ddtheta", (n,))
    vmax, amax = _limits(v_max, a_max, n)
    samples = max(int(samples), 2)
    rows, tbs, a_used = [], np.zeros(n), np.zeros(n)
    for j in range(n):
        a, v = float(acc0[j]), float(v0[j])
        tb = abs(a) * vmax[j] / amax[j] ** 2 if abs(a) > 1e-9 else 0.0
        if tb > 0.0:
            tb = min(tb, 2.0 * max(vmax[j] - math.copysign(1.0, a) * v, 0.0) / abs(a))
        row, tb0 = None, tb
        if tb0 > 1e-6:
            tb, row = _fit_fade(th0[j], v, a, goal[j], vmax[j], amax[j], tb0, samples)
        if row is None:
            tb, a = 0.0, 0.0
            row = (v, goal[j]) + _plan_1d(goal[j] - th0[j], v, vmax[j], amax[j])
        rows.append(row)
        tbs[j], a_used[j] = tb, a
    vb, gb, vp, ta, tc, td = (np.array(col, dtype=np.float64) for col in zip(*rows))
    base = JointMotion(t0=float(t0), theta0=th0, dtheta0=vb, theta_goal=gb, v_peak=vp, t_acc=ta, t_cruise=tc,
                       t_dec=td)
    return BlendedMotion(base=base, a0=a_used, blend_s=tbs, theta_goal=goal)


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
    replan : {"restart", "blend"}
        How a new goal re-plans a motion in flight: the acceleration restarts from zero
        (:func:`plan_motion`, the seed's B.6) or fades out continuously (:func:`blend_replan`).

    Raises
    ------
    ValueError
        If a limit is not positive or ``replan`` is unknown.

    Examples
    --------
    >>> pl = OnlinePlanner([0.0, 0.0], v_max=1.0, a_max=2.0)
    >>> pl.set_goal([0.5, -0.5], t=0.0)
    >>> th, dth, _ = pl.sample(10.0)
    >>> th.tolist()
    [0.5, -0.5]
    """

    def __init__(self, theta_start, *, v_max, a_max, t0: float = 0.0, replan: str = "restart"):
        th = check_array(np.atleast_1d(theta_start), "theta_start", (None,))
        if replan not in REPLAN_MODES:
            raise ValueError(f"replan: expected one of {REPLAN_MODES}, got {replan!r}")
        self.v_max, self.a_max, self.replan = v_max, a_max, replan
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
        th, dth, ddth = self.motion.sample(float(t))
        if self.replan == "blend":
            self.motion = blend_replan(th, dth, ddth, theta_goal, v_max=self.v_max, a_max=self.a_max, t0=float(t))
        else:
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
