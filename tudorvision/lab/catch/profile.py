"""The joint layer's profile as the catching agent sees it: mirrored reference, overshoot, residual swing.

The layer plans every setpoint with its documented sin^2-acceleration planner
(:func:`tudorvision.joint.planner.plan_motion`) from its current reference
angle and velocity. :class:`ReferenceMirror` plans the same motions from the
setpoints the agent sent, so the agent knows the reference without reading
the layer's internals, and can ask two questions before it sends a setpoint:

* :meth:`ReferenceMirror.overshoot_rad`: a new setpoint restarts the
  acceleration from zero; sent while a joint brakes, it brakes later than the
  motion it replaces and passes its goal (by up to about 2 deg at the demo's
  profile). The agent lets such a refinement wait.
* :meth:`ReferenceMirror.pass_through_goal`: a joint that cannot reach its goal before the ball gets a
  goal beyond it, so that it passes the goal at the crossing still moving instead of braking to a stop
  after it (``DemoOptions.pass_through``).
* :meth:`ReferenceMirror.residual_rad`: how strongly the reference's
  acceleration since the arm last rested excites the arm's first bending mode
  (the spectrum of the joint accelerations at the mode's frequency, divided
  by its angular frequency: an equivalent joint angle, rad). On the
  seed-measured plant a 23 deg joint-3 move at the full profile speed leaves
  the net swinging by +-5 cm for more than 0.6 s (the strain damping hardly
  shortens it); the same move with its acceleration pulses one mode period
  (two, here) apart leaves 0.7 cm. :meth:`ReferenceMirror.choose_speed`
  picks the profile speed with the least residual that still arrives before
  the ball.

The first mode's frequency comes from :func:`mode_frequency_hz`: about 2.6 Hz
with the bare net at the catching poses (the lab's step responses, close to
0.8 times the linearised, spring-engaged modes of
:func:`tudorvision.lab.plant_modes.linear_modes`: backlash and the joint servo
lower it), falling with the payload like a mass on a spring.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["ReferenceMirror", "mode_frequency_hz", "net_modes", "elbow_frequency_factor", "overshoot_lead_target",
           "hedged_goal", "SPEED_CANDIDATES"]

#: Profile speeds tried by :meth:`ReferenceMirror.choose_speed`, fractions of the demo's profile speed.
SPEED_CANDIDATES = (1.0, 0.85, 0.72, 0.62, 0.54, 0.47, 0.41, 0.36, 0.31, 0.27, 0.23)


#: The first mode's frequency against the elbow angle |theta3| (deg, 0 to 100 in 10 deg steps), relative to the
#: ready pose's 62 deg: the lab's linearised modes (:func:`tudorvision.lab.plant_modes.linear_modes`, 120 g
#: plate, joint 2 at 60 deg; joint 2 does not change it), identified once as the seed measured its figure 4.8.
#: The same ratio holds within 4 % from 0 to 360 g of payload (the table is the 120 g one).
ELBOW_FACTOR = (0.902, 0.904, 0.912, 0.924, 0.941, 0.965, 0.993, 1.029, 1.071, 1.12, 1.177)


def elbow_frequency_factor(theta3_rad: float) -> float:
    """The first mode's frequency at elbow angle ``theta3_rad`` relative to the ready pose's (:data:`ELBOW_FACTOR`).

    A folded elbow (|theta3| near 100 deg) rings 18 % faster than the ready pose, a stretched arm 10 % slower.

    Examples
    --------
    >>> round(elbow_frequency_factor(math.radians(62.0)), 2), round(elbow_frequency_factor(math.radians(-100.0)), 3)
    (1.0, 1.177)
    """
    grid_deg = 10.0 * np.arange(len(ELBOW_FACTOR))
    return float(np.interp(abs(math.degrees(float(theta3_rad))), grid_deg, ELBOW_FACTOR))   # held beyond 100 deg


def mode_frequency_hz(payload_kg: float, f0_hz: float = 2.6, mass_kg: float = 0.26) -> float:
    """First bending mode of the loaded arm at the catching poses, Hz: ``f0 / sqrt(1 + m / mass_kg)``.

    Parameters
    ----------
    payload_kg : float
        Payload on top of the end-effector mount, kg (the agent's estimate).
    f0_hz : float
        Frequency with the bare mount, Hz.
    mass_kg : float
        Effective modal mass at the end effector, kg (the linearised modes fall from 3.2 to 2.3 Hz
        with 240 g at the catching poses).

    Returns
    -------
    float
        Hz.

    Examples
    --------
    >>> round(mode_frequency_hz(0.0), 2), round(mode_frequency_hz(0.24), 2)
    (2.6, 1.87)
    """
    return float(f0_hz) / math.sqrt(1.0 + max(float(payload_kg), 0.0) / float(mass_kg))


def net_modes(payload_kg: float, f0_hz: float = 2.6, mass_kg: float = 0.26,
              swing_hz: float = 0.0) -> tuple[tuple[float, float], ...]:
    """The loaded net's modes: ``((f_hz, weight), ...)``, the payload rigid or swinging in the net's bag.

    With ``swing_hz <= 0`` (or no payload) the payload is a rigid mass at the end effector: one mode,
    :func:`mode_frequency_hz`, weight 1. Else the payload hangs in the bag as a pendulum of ``swing_hz``
    on the arm's first mode (``f0_hz`` with the modal mass ``mass_kg``): two coupled modes, the balls
    swinging with the net (below both frequencies) and against it (above both). Their weights are what
    each puts into the net's own deflection when the arm's base accelerates (modal participation times
    the net's share of the mode shape); they sum to 1, the static deflection. The seed: "the previously
    caught balls behave as pendulums" (section 9.3); in the lab with seven balls the net rings at 1.3-1.5
    and 2.8-3.2 Hz after a move, not at the 1.9-2 Hz of the rigid payload.

    Parameters
    ----------
    payload_kg : float
        Payload on top of the end-effector mount, kg (the agent's estimate; all of it in the bag).
    f0_hz, mass_kg : float
        The arm's first mode with the bare mount, Hz, and its modal mass at the end effector, kg.
    swing_hz : float
        The bag's pendulum frequency with the arm held still, Hz (0: a rigid payload).

    Returns
    -------
    tuple of (float, float)
        ``(f_hz, weight)`` per mode, lowest first.

    Examples
    --------
    >>> net_modes(0.0, 3.0)
    ((3.0, 1.0),)
    >>> [(round(f, 2), round(w, 2)) for f, w in net_modes(0.21, 3.0, 0.26, 1.55)]
    [(1.37, 0.26), (3.38, 0.74)]
    """
    m2 = max(float(payload_kg), 0.0)
    if not (swing_hz > 0 and m2 > 0):
        return ((mode_frequency_hz(m2, f0_hz, mass_kg), 1.0),)
    m1 = float(mass_kg)
    k1, k2 = m1 * (2 * math.pi * float(f0_hz)) ** 2, m2 * (2 * math.pi * float(swing_hz)) ** 2
    M = np.diag([m1, m2])
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    w2, phi = np.linalg.eig(np.linalg.solve(M, K))
    out = []
    for k in np.argsort(w2.real):
        v = phi[:, k].real
        gamma = float(v @ M @ np.ones(2)) / float(v @ M @ v)        # participation in a base acceleration
        out.append((math.sqrt(float(w2[k].real)) / (2 * math.pi), abs(float(v[0]) * gamma)))
    return tuple(out)


def _as_modes(f_hz) -> tuple[tuple[float, float], ...]:
    """``f_hz`` as ``((f_hz, weight), ...)``: one frequency (Hz) is one mode of weight 1; modes pass through."""
    if np.ndim(f_hz) == 0:
        return ((float(f_hz), 1.0),)
    return tuple((float(f), float(w)) for f, w in f_hz)


def overshoot_lead_target(target_base, from_base, lead_m: float, margin_s: float, *, fade_s: float = 0.25,
                          full_move_m: float = 0.2) -> np.ndarray:
    """The net target moved back along the move by the overshoot expected at the crossing, metres (3,).

    A net that arrives shortly before the ball is still ahead of its goal along the move it made (the
    links and the joint servo carry on past it, then ring back): on seed 0's 840 crossing throws of the
    default demo, arriving less than 0.2 s before the crossing after a move of 0.2 m or more left the net
    9-15 mm beyond its target along the move (sd 8-21 mm), arriving 0.3 s or more before it 1-3 mm. The
    target is moved back towards ``from_base`` by
    ``lead_m * min(|move| / full_move_m, 1) * clip(1 - margin_s / fade_s, 0, 1)`` (at most half the move; a
    move of 1 nm or less, or a margin that is not finite, leaves the target unchanged).

    Parameters
    ----------
    target_base : array_like, shape (3,)
        The net target, metres, base frame.
    from_base : array_like, shape (3,)
        Where the move starts (the ready point), metres, base frame.
    lead_m : float
        The lead for a full move arriving at the crossing, metres (0: the target unchanged).
    margin_s : float
        How long before the predicted crossing the planned move ends, s (negative: late).
    fade_s : float
        The lead falls to zero for moves that end this long before the crossing, s.
    full_move_m : float
        Moves this long or longer get the full lead; shorter ones in proportion, metres.

    Returns
    -------
    ndarray, shape (3,)

    Examples
    --------
    >>> overshoot_lead_target([0.0, 0.4, 1.07], [0.0, 0.0, 1.07], 0.012, 0.05).round(4).tolist()
    [0.0, 0.3904, 1.07]
    >>> overshoot_lead_target([0.0, 0.4, 1.07], [0.0, 0.0, 1.07], 0.012, 0.3).round(4).tolist()
    [0.0, 0.4, 1.07]
    """
    p, o = np.asarray(target_base, float), np.asarray(from_base, float)
    d = p - o
    length = float(np.linalg.norm(d))
    if not (lead_m > 0.0 and length > 1e-9 and math.isfinite(margin_s)):
        return p.copy()
    share_time = min(1.0, max(0.0, 1.0 - float(margin_s) / float(fade_s)))
    s = float(lead_m) * min(length / float(full_move_m), 1.0) * share_time
    return p - min(s, 0.5 * length) * d / length


def hedged_goal(goal_rad, plausible_rad, theta_now_rad, min_spread_rad: float) -> np.ndarray:
    """A first setpoint that moves a steep joint only to the near edge of where the ball may need it.

    Near full stretch a few centimetres of the first, rough intercept estimate are tens of degrees of joint 2
    or 3: when the estimate is wrong, the first move goes the wrong way and its reversal comes late. A joint
    whose goals over the estimate's plausible points (``plausible_rad``) spread over more than
    ``2 min_spread_rad`` goes only to the point of that range nearest to where it is (it stays if it is
    inside); the others go to ``goal_rad``.

    Parameters
    ----------
    goal_rad : array_like, shape (3,)
        Joint goal for the estimate itself, rad.
    plausible_rad : array_like, shape (K, 3)
        Joint goals for the estimate moved by its uncertainty (e.g. one standard deviation along each
        principal direction), rad; the range per joint spans these and ``goal_rad``.
    theta_now_rad : array_like, shape (3,)
        The joints now, rad.
    min_spread_rad : float
        Half the range of a joint's plausible goals above which it is hedged, rad.

    Returns
    -------
    ndarray, shape (3,)
        The hedged goal, rad.

    Examples
    --------
    >>> g = hedged_goal([0.0, 1.0, 0.5], [[0.0, 0.9, 0.2], [0.0, 1.1, 0.8]], [0.0, 1.0, 0.0], 0.1)
    >>> g.round(3).tolist()          # joint 3's goals span 0.2-0.8 rad: it goes only to 0.2
    [0.0, 1.0, 0.2]
    """
    goal = np.asarray(goal_rad, float)
    pts = np.vstack([goal, np.reshape(plausible_rad, (-1, 3))])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    edge = np.clip(np.asarray(theta_now_rad, float), lo, hi)
    return np.where((hi - lo) / 2 > min_spread_rad, edge, goal)


class ReferenceMirror:
    """The joint layer's planned reference, mirrored from the setpoints sent (see the module notes).

    Parameters
    ----------
    v_max : float
        Default profile speed, rad/s (the demo's scalar bound, every joint).
    a_max : float
        Profile acceleration, rad/s^2.
    replan : {"restart", "blend"}
        How the layer re-plans a motion in flight (its ``ControlledArm(replan=...)``): the acceleration
        restarts from zero, or fades out (:func:`tudorvision.joint.planner.blend_replan`).

    Attributes
    ----------
    motion : JointMotion or None
        The reference motion now (None before the first setpoint).
    segments : list of tuple
        ``(motion, t_from, t_to)`` since the arm last rested: the reference's acceleration history, s.

    Examples
    --------
    >>> m = ReferenceMirror(1.0, 2.0)
    >>> m.sent([1.0, 0.0, 0.0], 0.0, theta_now=[0.0, 0.0, 0.0])
    >>> bool(m.overshoot_rad([1.0, 0.0, 0.0], 1.5)[0] > 0.05)     # mid-braking: a new plan passes the goal
    True
    >>> m.overshoot_rad([1.0, 0.0, 0.0], 0.5).round(3).tolist()     # accelerating: it still stops in time
    [0.0, 0.0, 0.0]
    """

    def __init__(self, v_max: float, a_max: float, replan: str = "restart"):
        self.v_max, self.a_max, self.replan = float(v_max), float(a_max), replan
        self.motion = None
        self.segments: list = []

    def reset(self, theta, t: float) -> None:
        """The reference rests at ``theta`` (rad, (3,)) from ``t`` (s) on (after a fault stop)."""
        from ...joint.planner import plan_motion

        th = np.asarray(theta, float)
        self.motion = plan_motion(th, th, v_max=self.v_max, a_max=self.a_max, t0=float(t))
        self.segments = []

    def state(self, t: float):
        """Reference angle (rad, (3,)) and velocity (rad/s, (3,)) at ``t`` (s); None before the first setpoint."""
        if self.motion is None:
            return None
        th, dth, _ = self.motion.sample(float(t))
        return np.asarray(th, float), np.asarray(dth, float)

    def plan(self, goal, t: float, v_max: float | None = None, a_max: float | None = None):
        """The motion the layer would plan for ``goal`` (rad, (3,)) sent at ``t`` (s) with speed ``v_max`` (rad/s).

        ``a_max``: the setpoint's profile acceleration, rad/s^2 (default the mirror's).
        """
        from ...joint.planner import blend_replan, plan_motion

        v = self.v_max if v_max is None else float(v_max)
        a = self.a_max if a_max is None else float(a_max)
        if self.replan == "blend":
            th, dth, ddth = self.motion.sample(float(t))
            return blend_replan(th, dth, ddth, np.asarray(goal, float), v_max=v, a_max=a, t0=float(t))
        th, dth = self.state(t)
        return plan_motion(th, np.asarray(goal, float), v_max=v, a_max=a, dtheta_start=dth, t0=float(t))

    def sent(self, goal, t: float, *, theta_now=None, v_max: float | None = None, a_max: float | None = None) -> None:
        """A setpoint ``goal`` (rad, (3,)) went out at ``t`` (s) with speed ``v_max`` (rad/s; default the mirror's).

        ``theta_now``: the rest pose before any setpoint (rad, (3,)); ``a_max``: its acceleration, rad/s^2.
        """
        if self.motion is None:
            self.reset(theta_now if theta_now is not None else goal, t)
        at_rest = t >= self.motion.t0 + self.motion.duration_s
        new = self.plan(goal, t, v_max, a_max)
        if at_rest:
            self.segments = []
        elif self.segments:
            m, t_from, _ = self.segments[-1]
            self.segments[-1] = (m, t_from, float(t))
        self.segments.append((new, float(t), float(t) + new.duration_s))
        self.motion = new

    def overshoot_rad(self, goal, t: float, *, v_max: float | None = None, samples: int = 200) -> np.ndarray:
        """How far each joint would pass ``goal`` (rad, (3,)) if it were sent at ``t`` (s), rad (>= 0).

        The layer's re-plan from the mirrored reference, sampled at ``samples`` points: its largest
        excursion beyond the goal, against the direction it approaches from.
        """
        if self.motion is None:
            return np.zeros(3)
        th, _ = self.state(t)
        g = np.asarray(goal, float)
        m = self.plan(g, t, v_max)
        path = np.asarray(m.sample(m.t0 + np.linspace(0.0, m.duration_s, max(int(samples), 2)))[0], float)
        ahead = np.sign(g - th)               # the side of the goal the joint comes from
        past = np.max((path - g) * ahead, axis=0)
        return np.where(ahead != 0.0, np.maximum(past, 0.0), 0.0)

    def path_range_rad(self, goal, t: float, *, v_max: float | None = None, samples: int = 200):
        """Lowest and highest angle (rad, two (3,) arrays) each joint passes if ``goal`` were sent at ``t`` (s).

        The layer's re-plan from the mirrored reference, sampled at ``samples`` points: sent while a
        joint still moves the other way, it first brakes (from zero acceleration) past where the
        current motion would have stopped. Before the first setpoint: ``goal`` itself.
        """
        g = np.asarray(goal, float)
        if self.motion is None:
            return g.copy(), g.copy()
        m = self.plan(g, t, v_max)
        path = np.asarray(m.sample(m.t0 + np.linspace(0.0, m.duration_s, max(int(samples), 2)))[0], float)
        return path.min(axis=0), path.max(axis=0)

    def residual_rad(self, goal, t: float, f_hz, *, v_max: float | None = None, a_max: float | None = None,
                     samples: int = 160):
        """Residual excitation of a mode at ``f_hz`` (Hz) if ``goal`` were sent at ``t`` (s) with ``v_max``, ``a_max``.

        ``sum_j |integral a_j(s) exp(-i w s) ds| / w`` over joints 2 and 3, ``a_j`` the reference's
        acceleration (rad/s^2) since the arm last rested up to the end of the new motion, ``w = 2 pi f``.
        ``f_hz`` may also be several modes, ``((f_hz, weight), ...)`` (:func:`net_modes`): the weighted sum.

        Returns
        -------
        tuple
            ``(residual_rad, t_end_s)``: the excitation (an equivalent joint angle, rad) and when the
            new motion ends (s).
        """
        modes = _as_modes(f_hz)
        w = 2.0 * math.pi * np.array([f for f, _ in modes])
        new = self.plan(goal, t, v_max, a_max)
        segs = [s for s in self.segments if s[2] > s[1]]
        if segs and segs[-1][2] > t:
            segs[-1] = (segs[-1][0], segs[-1][1], float(t))
        segs.append((new, float(t), float(t) + new.duration_s))
        A = np.zeros((len(modes), 3), complex)
        for m, a, b in segs:
            if b <= a:
                continue
            tt = np.linspace(a, b, max(int(samples), 2))
            acc = np.asarray(m.sample(tt)[2], float)
            A += np.trapezoid(acc[None] * np.exp(-1j * w[:, None] * tt[None])[:, :, None], tt, axis=1)
        r = np.sum(np.abs(A[:, 1:]), axis=1) / w
        return float(np.dot([wt for _, wt in modes], r)), float(t) + new.duration_s

    def choose_speed(self, goal, t: float, deadline_s: float, f_hz: float,
                     candidates=SPEED_CANDIDATES) -> float:
        """Profile speed (rad/s) for ``goal`` sent at ``t`` (s): the least residual swing arriving by ``deadline_s``.

        Among ``candidates`` (fractions of the mirror's speed) that end by ``deadline_s`` the one with the
        least :meth:`residual_rad` at ``f_hz`` (the faster on a tie within 2 %); if none ends in time, the
        fastest. ``f_hz <= 0``: the mirror's speed. :meth:`choose_profile` at the mirror's acceleration.
        """
        return self.choose_profile(goal, t, deadline_s, f_hz, speeds=candidates)[0]

    def choose_profile(self, goal, t: float, deadline_s: float, f_hz, *, speeds=SPEED_CANDIDATES,
                       accels=(1.0,), decay_per_s: float = 0.0, t_cross_s: float | None = None) -> tuple[float, float]:
        """Profile speed and acceleration (rad/s, rad/s^2) for ``goal`` sent at ``t`` (s): least swing by the deadline.

        Every pair of ``speeds`` and ``accels`` (fractions of the mirror's speed and acceleration): among those
        that end by ``deadline_s`` the one with the least :meth:`residual_rad` at ``f_hz`` (on a tie within 2 %
        the pair tried first: the full acceleration, then the faster speed); if none ends in time, the one that
        ends first. A small correction never reaches the profile speed, so only a lower acceleration can
        stretch it towards a whole period of the mode.
        ``f_hz <= 0``: the mirror's speed and acceleration; ``f_hz`` may also be several weighted modes
        (:meth:`residual_rad`). With ``decay_per_s`` > 0 and ``t_cross_s`` (s) the
        swing is weighed by ``exp(-decay_per_s (t_cross_s - t_end))``: what is left of it at the crossing when
        the arm's damping takes it down at that rate after the motion ends.

        Examples
        --------
        >>> m = ReferenceMirror(1.0, 4.0)
        >>> m.reset([0.0, 0.0, 0.0], 0.0)
        >>> v, a = m.choose_profile([0.0, 0.05, 0.0], 0.0, 5.0, 2.5, accels=(1.0, 0.5, 0.25))
        >>> slow = m.residual_rad([0.0, 0.05, 0.0], 0.0, 2.5, v_max=v, a_max=a)[0]
        >>> bool(a < 4.0 and slow < m.residual_rad([0.0, 0.05, 0.0], 0.0, 2.5)[0])
        True
        """
        if not min(f for f, _ in _as_modes(f_hz)) > 0 or self.motion is None:
            return self.v_max, self.a_max
        best, first = None, None
        for ca in accels:
            a = ca * self.a_max
            for c in speeds:
                v = c * self.v_max
                r, t_end = self.residual_rad(goal, t, f_hz, v_max=v, a_max=a)
                if decay_per_s > 0 and t_cross_s is not None:
                    r *= math.exp(-float(decay_per_s) * max(float(t_cross_s) - t_end, 0.0))
                if first is None or t_end < first[2] - 1e-9:
                    first = (v, a, t_end)
                if t_end <= deadline_s and (best is None or r < 0.98 * best[2]):
                    best = (v, a, r)
        return (best[0], best[1]) if best is not None else (first[0], first[1])

    def pass_through_goal(self, goal, t: float, t_pass_s: float, lower_rad, upper_rad, *,
                          v_max: float | None = None, a_max: float | None = None, grid: int = 48):
        """Goals (rad, (3,)) whose re-plan sent at ``t`` (s) passes ``goal`` by ``t_pass_s`` (s), joints late for it.

        A joint whose motion to ``goal`` would not reach it by ``t_pass_s`` gets a goal beyond it along its
        way, within ``[lower_rad, upper_rad]``: the nearest (of ``grid`` steps up to the bound, then halved
        eight times) whose reference is at ``goal`` at ``t_pass_s``, so it passes there moving instead of
        braking to a stop after it; the farthest when none is (it gets there as early as the profile
        allows). The other joints keep ``goal``. Joints are planned independently, as by the layer.

        Returns
        -------
        tuple
            ``(goals, late)``: the goals (rad, (3,)) and which joints were late (bool, (3,)).

        Examples
        --------
        >>> m = ReferenceMirror(1.0, 4.0)
        >>> m.reset([0.0, 0.0, 0.0], 0.0)
        >>> g, late = m.pass_through_goal([0.0, 1.0, 0.1], 0.0, 1.3, [-3.0] * 3, [3.0] * 3)
        >>> late.tolist(), round(float(g[2]), 3)                  # joint 2 passes 1 rad at 1.3 s; joint 3 stops
        ([False, True, False], 0.1)
        >>> bool(g[1] > 1.0), round(float(m.plan(g, 0.0).sample(1.3)[0][1]), 3)
        (True, 1.0)
        """
        g = np.asarray(goal, float)
        late = np.zeros(len(g), bool)
        if self.motion is None:
            return g.copy(), late
        th, _ = self.state(t)
        way = np.sign(g - th)

        def at_pass(goals):
            return np.asarray(self.plan(goals, t, v_max, a_max).sample(float(t_pass_s))[0], float)

        late = (way != 0.0) & ((g - at_pass(g)) * way > 1e-9)
        if not late.any():
            return g.copy(), late
        room = np.maximum(np.where(way > 0, np.asarray(upper_rad, float) - g, g - np.asarray(lower_rad, float)), 0.0)
        steps = np.linspace(0.0, 1.0, max(int(grid), 2))
        progress = np.array([(at_pass(np.where(late, g + way * room * s, g)) - g) * way for s in steps])
        reached = progress >= 0.0
        k = np.where(reached.any(axis=0), np.argmax(reached, axis=0), np.argmax(progress, axis=0))
        hi = steps[k]
        lo = np.where(reached.any(axis=0), steps[np.maximum(k - 1, 0)], hi)
        for _ in range(8):                      # between the last step short of goal and the first past it
            mid = 0.5 * (lo + hi)
            ok = (at_pass(np.where(late, g + way * room * mid, g)) - g) * way >= 0.0
            hi, lo = np.where(ok, mid, hi), np.where(ok, lo, mid)
        return np.where(late, g + way * room * hi, g), late

    def late_speed(self, goal, t: float, deadline_s: float, speed: float, late_speed: float) -> float:
        """``speed`` (rad/s) if ``goal`` sent at ``t`` with it ends by ``deadline_s`` (s), else ``late_speed``.

        For a setpoint that would arrive late at the demo's profile speed: the faster profile
        (``DemoOptions.late_speed_fraction``) is taken only then, as the links' swing at speeds near a
        joint's limit risks the layer's over-speed fault. ``late_speed`` at or below ``speed`` changes
        nothing.
        """
        if not late_speed > speed:
            return float(speed)
        t_end = t + self.plan(goal, t, speed).duration_s
        return float(speed) if t_end <= deadline_s else float(late_speed)
