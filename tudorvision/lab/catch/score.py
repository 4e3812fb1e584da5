"""Scoring the catching demo from ground truth: one :class:`ThrowResult` per throw, and the summary.

A throw *crosses the workspace* if its true crossing of the working plane is
reachable by the rigid arm within the joint ranges. It is *caught* if the
whole ball (a sphere of ``DemoOptions.ball_radius_m``, 4.5 cm) enters the
net's ring (radius ``DemoOptions.net_radius_m``, 9 cm; centred on the deflected
end effector at the crossing, in the plane through it parallel to the
working plane): its centre crosses the ring plane within ``net_radius_m -
ball_radius_m`` of the ring centre and the ball never touches the rim on the
way (:func:`ring_passage`; a ball that touches it bounces off). The earlier,
lenient count (the ball *centre* within the net radius of the net centre at
the crossing: a ball 8 cm off hits the rim) stays as ``caught_centre`` /
``success_rate_centre``. A secondary, stricter count asks whether the arm
could get there at all, leaving its pose at the release once the first three
detections are in (a lower bound on the move time: trapezoidal profile).
"""
from __future__ import annotations

import math
from dataclasses import asdict, astuple, dataclass, fields

import numpy as np

__all__ = ["ThrowResult", "PER_THROW_COLUMNS", "MISS_REASONS", "RingPassage", "ring_passage", "min_move_time",
           "miss_reason", "score_throw", "summarize_throws"]

#: Why a throw was missed, in the order they are tested (the first that applies is reported).
MISS_REASONS = ("does not reach the working plane", "outside the reachable workspace", "not tracked",
                "not released (intercept uncertain or predicted unreachable)", "prediction error", "arm late",
                "ball hit the rim", "deflection or vibration")


@dataclass(frozen=True, kw_only=True)
class ThrowResult:
    """The outcome of one throw (one row of ``throws.csv``; times on the demo's clock, base frame).

    ``nan`` marks a value that does not exist for the throw (no crossing, no setpoint sent).

    Parameters
    ----------
    throw : int
        Throw number in the run.
    t_release_s : float
        Release time, s.
    crosses_plane : bool
        The flight crosses the working plane above the floor.
    crossing_workspace : bool
        ... at a point the rigid arm reaches within its joint ranges.
    t_cross_true_s : float
        Time from the release to the true crossing, s.
    x_cross_true_m, z_cross_true_m : float
        True crossing point in the working plane, m.
    detections : int
        Ball detections during the throw.
    released : bool
        At least one intercept setpoint was sent.
    t_first_setpoint_s : float
        Time from the release to the first setpoint, s.
    lead_time_s : float
        Time from the first setpoint to the true crossing, s.
    x_pred_m, z_pred_m : float
        The last intercept prediction (EKF), m.
    pred_error_m : float
        Distance of the last EKF prediction from the true crossing, m.
    ballistic_pred_error_m : float
        Same for the drag-free ballistic peer, m.
    x_net_m, z_net_m : float
        Net centre (deflected end effector) at the true crossing, m.
    miss_m : float
        Distance from the net centre to the ball centre at the crossing, m (on a turned plane, ``yaw_deg``: the
        net at the fixed plane's crossing time against where the ball crossed the turned plane).
    time_margin_s : float
        Time from the arm's arrival (within 1 deg of its last setpoint) to the crossing, s.
    payload_true_kg : float
        True payload on top of the mount (balls in the net) during the throw, kg.
    payload_est_kg : float
        The agent's payload estimate during the throw, kg.
    caught : bool
        The whole ball entered the ring without touching the rim (:func:`ring_passage`).
    t_move_min_s : float
        Shortest move from the pose at the release to the crossing (trapezoidal profile), s; ``inf``: unreachable.
    in_time : bool
        Crossing the workspace, and that move fits before the crossing, less three frames.
    reason : str
        Why it was missed (one of :data:`MISS_REASONS`), empty if caught.
    caught_centre : bool
        The earlier, lenient criterion: the ball centre passed within the net radius of the net centre
        (``miss_m <= net_radius_m``).
    ring_offset_m : float
        Distance from the ring centre, in the ring plane, at which the ball centre crossed that plane, m.
    rim_clearance_m : float
        Smallest gap between the ball's surface and the rim during the passage, m; negative: contact.
    rim_contact : bool
        The ball touched the rim (and bounced off).
    yaw_deg : float
        The agent's working plane for the throw turned from the fixed one, degrees (``DemoOptions.yaw_max_rad``;
        the ring faces the ball from there; the crossing, workspace and in-time columns keep the fixed plane).
    """

    throw: int
    t_release_s: float
    crosses_plane: bool
    crossing_workspace: bool
    t_cross_true_s: float
    x_cross_true_m: float
    z_cross_true_m: float
    detections: int
    released: bool
    t_first_setpoint_s: float
    lead_time_s: float
    x_pred_m: float
    z_pred_m: float
    pred_error_m: float
    ballistic_pred_error_m: float
    x_net_m: float
    z_net_m: float
    miss_m: float
    time_margin_s: float
    payload_true_kg: float
    payload_est_kg: float
    caught: bool
    t_move_min_s: float
    in_time: bool
    reason: str
    caught_centre: bool = False
    ring_offset_m: float = math.nan
    rim_clearance_m: float = math.nan
    rim_contact: bool = False
    yaw_deg: float = 0.0

    def as_row(self) -> tuple:
        """The values in :data:`PER_THROW_COLUMNS` order.

        Returns
        -------
        tuple
            One value per column.
        """
        return astuple(self)

    def as_dict(self) -> dict:
        """The values by column name (the ``per_throw`` entries of :func:`~tudorvision.lab.catch.run.run_demo`).

        Returns
        -------
        dict
            ``{column: value}``.
        """
        return asdict(self)


#: Columns of ``throws.csv``, in order (the fields of :class:`ThrowResult`).
PER_THROW_COLUMNS = [f.name for f in fields(ThrowResult)]


@dataclass(frozen=True)
class RingPassage:
    """How a ball (sphere) passes the net's ring (:func:`ring_passage`).

    Parameters
    ----------
    crosses : bool
        The ball centre crosses the ring plane (from the thrower's side).
    offset_m : float
        Distance from the ring centre, in the ring plane, where the ball centre crosses it, m (nan: no crossing).
    clearance_m : float
        Smallest distance from the ball's surface to the rim circle while the ball is within a ball
        radius of the ring plane, m (negative: contact; ``inf`` if it never comes that near the plane).
    rim_contact : bool
        ``clearance_m < 0``: the ball touches the rim and bounces off.
    caught : bool
        It crosses within ``ring_radius - ball_radius`` of the centre without touching the rim.
    """

    crosses: bool
    offset_m: float
    clearance_m: float
    rim_contact: bool
    caught: bool


def ring_passage(points_rel_m, *, ring_radius_m: float, ball_radius_m: float, normal=(0.0, 1.0, 0.0),
                 substeps: int = 16) -> RingPassage:
    """Whether a ball, a sphere, passes wholly through a ring (the catching net's rim, a thin circle).

    The path is the polyline through the samples (each segment split into
    ``substeps``); the ring is the circle of ``ring_radius_m`` about the origin
    in the plane normal to ``normal``. The ball comes from the negative side.
    It touches the rim where its centre is nearer than ``ball_radius_m`` to the
    circle (``sqrt((rho - R)^2 + h^2) < r``, ``rho`` the in-plane distance and
    ``h`` the height over the plane), up to where it is a ball radius past the
    plane (then it is in the net, or has passed it). It is caught when its
    centre crosses the plane within ``R - r`` of the centre and it never touches
    the rim (a head-on ball exactly ``R - r`` off just grazes it: caught).

    Parameters
    ----------
    points_rel_m : array_like, shape (N, 3)
        Ball centre along its flight relative to the ring centre, metres, in time order.
    ring_radius_m : float
        Ring radius ``R``, m.
    ball_radius_m : float
        Ball radius ``r``, m (0: a point, the lenient criterion).
    normal : array_like, shape (3,)
        Ring-plane normal, pointing the way the ball goes (normalised here).
    substeps : int
        Linear interpolation steps per sample interval for the contact test.

    Returns
    -------
    RingPassage

    Examples
    --------
    >>> path = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])        # head-on through the centre
    >>> ring_passage(path, ring_radius_m=0.09, ball_radius_m=0.045).caught
    True
    >>> p = ring_passage(path + [0.06, 0.0, 0.0], ring_radius_m=0.09, ball_radius_m=0.045)
    >>> p.caught, p.rim_contact, round(p.offset_m, 3), round(p.clearance_m, 3)     # 6 cm off: on the rim
    (False, True, 0.06, -0.015)
    """
    R, r = float(ring_radius_m), float(ball_radius_m)
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    pts = np.asarray(points_rel_m, float).reshape(-1, 3)
    h = pts @ n
    cross = np.nonzero((h[:-1] < 0.0) & (h[1:] >= 0.0))[0]
    if len(cross) == 0:
        return RingPassage(crosses=False, offset_m=math.nan, clearance_m=math.inf, rim_contact=False, caught=False)
    i = int(cross[0])
    a = -h[i] / (h[i + 1] - h[i])
    p_cross = pts[i] + a * (pts[i + 1] - pts[i])
    offset = float(np.linalg.norm(p_cross - (p_cross @ n) * n))
    # the passage: from the crossing back to where the ball was a radius before the plane, forward to a radius past
    lo = i
    while lo > 0 and h[lo] > -r:
        lo -= 1
    hi = i + 1
    while hi < len(h) - 1 and h[hi] < r:
        hi += 1
    seg = pts[lo:hi + 1]
    s = np.linspace(0.0, 1.0, max(int(substeps), 1) + 1)[:-1]
    dense = np.concatenate([(seg[:-1, None, :] + s[None, :, None] * np.diff(seg, axis=0)[:, None, :]).reshape(-1, 3),
                            seg[-1:]])
    hh = dense @ n
    near = np.abs(hh) <= r
    if not np.any(near):
        clearance = math.inf
    else:
        rho = np.linalg.norm(dense[near] - hh[near, None] * n, axis=1)
        clearance = float(np.min(np.hypot(rho - R, hh[near]))) - r
    contact = clearance < 0.0
    return RingPassage(crosses=True, offset_m=offset, clearance_m=clearance, rim_contact=bool(contact),
                       caught=bool(offset <= R - r and not contact))


def min_move_time(solutions, theta_now, max_speed: float, max_accel: float) -> float:
    """Shortest time to reach any of ``solutions`` from ``theta_now`` with a trapezoidal profile per joint.

    Parameters
    ----------
    solutions : array_like, shape (K, 3)
        Candidate joint angles, rad (K may be 0).
    theta_now : array_like, shape (3,)
        Current joint angles, rad.
    max_speed : float
        Profile speed, rad/s.
    max_accel : float
        Profile acceleration, rad/s^2.

    Returns
    -------
    float
        The slowest joint's time to the best solution, s; ``inf`` without solutions.

    Examples
    --------
    >>> min_move_time([[1.0, 0.0, 0.0]], [0.0, 0.0, 0.0], 1.0, 1.0)      # triangular: 2 sqrt(1 / 1)
    2.0
    >>> min_move_time(np.zeros((0, 3)), [0.0, 0.0, 0.0], 1.0, 1.0)
    inf
    """
    best = np.inf
    for th in np.reshape(solutions, (-1, 3)):
        d = np.abs(np.asarray(th) - theta_now)
        t = np.where(d >= max_speed ** 2 / max_accel, d / max_speed + max_speed / max_accel,
                     2.0 * np.sqrt(d / max_accel))
        best = min(best, float(np.max(t)))
    return best


def miss_reason(*, caught: bool, crosses: bool, in_workspace: bool, detections: int, n_init: int, released: bool,
                pred_error_m: float, net_radius_m: float, arrived: bool, rim_contact: bool = False,
                ball_radius_m: float = 0.0) -> str:
    """The first reason (of :data:`MISS_REASONS`) that explains a miss; empty for a catch.

    Parameters
    ----------
    caught : bool
        The ball was caught.
    crosses : bool
        The flight crosses the working plane.
    in_workspace : bool
        ... within the rigid arm's reach.
    detections : int
        Ball detections during the throw.
    n_init : int
        Detections the ball filter needs to start.
    released : bool
        A setpoint was sent.
    pred_error_m : float
        Error of the last intercept prediction, m.
    net_radius_m : float
        Net radius, m.
    arrived : bool
        The arm reached its last setpoint (within 1 deg) before the throw ended.
    rim_contact : bool, optional
        The ball touched the rim.
    ball_radius_m : float, optional
        Ball radius, m: a prediction more than ``net_radius_m - ball_radius_m`` off is a prediction error.

    Returns
    -------
    str
        The reason, or ``""``.

    Examples
    --------
    >>> miss_reason(caught=False, crosses=True, in_workspace=True, detections=20, n_init=3, released=True,
    ...             pred_error_m=0.01, net_radius_m=0.09, arrived=False)
    'arm late'
    """
    checks = (not crosses, not in_workspace, detections < n_init, not released,
              pred_error_m > net_radius_m - ball_radius_m, not arrived, rim_contact)
    if caught:
        return ""
    for why, failed in zip(MISS_REASONS, checks):
        if failed:
            return why
    return MISS_REASONS[-1]


def score_throw(throw, log, *, net_at_cross, theta_at_release, payload_true_kg: float, options, params,
                theta1_rad: float, max_speed: float, max_accel: float, frame_rate_hz: float,
                net_velocity_at_cross=None, latency_s: float = 0.0,
                ring_theta1_rad: float | None = None) -> ThrowResult:
    """Score one throw from its ground truth and what the agent did.

    Parameters
    ----------
    throw : Throw
        The throw and its true crossing (:class:`~tudorvision.lab.catch.scenario.Throw`).
    log : ThrowLog
        What the agent saw and sent during the throw (:class:`~tudorvision.lab.catch.agent.ThrowLog`).
    net_at_cross : ndarray, shape (3,), or None
        True net centre at the crossing, metres, base frame (None without a crossing).
    theta_at_release : array_like, shape (3,)
        Joint angles at the release, rad.
    payload_true_kg : float
        Balls in the net during the throw, kg.
    options : DemoOptions
        The demo's options (net and ball radii, the filter's ``n_init``).
    params : RobotParams
        The robot's parameters (joint ranges).
    theta1_rad : float
        Angle of the working plane, rad.
    max_speed : float
        The agent's setpoint profile speed, rad/s.
    max_accel : float
        The agent's setpoint profile acceleration, rad/s^2.
    frame_rate_hz : float
        Camera frame rate, Hz (the in-time count leaves three frames for the first detections).
    net_velocity_at_cross : array_like, shape (3,), optional
        True net velocity at the crossing, m/s, base frame: the ring moves with it during the
        passage (a few hundredths of a second). Default: the ring stands still at ``net_at_cross``.
    latency_s : float
        The camera's mean latency, s (``DemoOptions.camera_latency_s`` and half its jitter): the in-time count
        leaves it too.
    ring_theta1_rad : float, optional
        Joint 1's true angle at the crossing, rad: the ring faces along that plane's normal (default
        ``theta1_rad``; an agent that turned the plane for the throw has it elsewhere).

    Returns
    -------
    ThrowResult
        The throw's row. ``caught`` is the strict criterion (the whole ball through the ring,
        :func:`ring_passage` along the throw's flight), ``caught_centre`` the earlier one.
        A :class:`~tudorvision.lab.catch.scenario.Throw` without a flight across the ring plane
        (a synthetic one) passes it head-on at ``p_cross_base``.
    """
    from ...catch.intercept import reachable_solutions

    nan = math.nan
    crosses = throw.crosses
    p_cross = throw.p_cross_base
    t_rel, t_cross = throw.t_release_s, throw.t_cross_s
    sols = reachable_solutions(p_cross, theta1_rad, params) if crosses else np.zeros((0, 3))
    in_ws = len(sols) > 0
    t_move = min_move_time(sols, np.asarray(theta_at_release), max_speed, max_accel)
    in_time = bool(in_ws and t_move <= throw.t_cross_rel_s - 3.0 / frame_rate_hz - float(latency_s))
    it, bal, first = log.last_intercept, log.last_ballistic_base, log.t_first_setpoint_s
    # a throw caught on a turned plane: its estimate and the net are judged where the ball crossed that plane
    yaw = float(getattr(log, "yaw_rad", 0.0))
    p_ref = _turned_crossing(throw, theta1_rad + yaw) if (crosses and yaw != 0.0) else p_cross
    miss = float(np.linalg.norm(net_at_cross - p_ref)) if (crosses and p_ref is not None) else nan
    caught_centre = bool(crosses and miss <= options.net_radius_m)
    ball_r = float(throw.ball_radius_m)
    ring_t1 = theta1_rad if ring_theta1_rad is None else float(ring_theta1_rad)
    ring = _ring_passage_of(throw, net_at_cross, net_velocity_at_cross, ring_t1, options.net_radius_m, ball_r) \
        if crosses else None
    caught = bool(ring is not None and ring.caught)
    pred_err = float(np.linalg.norm(it.p_base - p_ref)) if (p_ref is not None and it is not None) else nan
    bal_err = float(np.linalg.norm(bal - p_cross)) if (crosses and bal is not None) else nan
    reason = miss_reason(caught=caught, crosses=crosses, in_workspace=in_ws, detections=log.detections,
                         n_init=options.ekf.n_init, released=first is not None, pred_error_m=pred_err,
                         net_radius_m=options.net_radius_m, arrived=log.t_arrived_s is not None,
                         rim_contact=bool(ring is not None and ring.rim_contact), ball_radius_m=ball_r)
    return ThrowResult(
        throw=int(throw.index), t_release_s=float(t_rel), crosses_plane=crosses, crossing_workspace=in_ws,
        t_cross_true_s=float(t_cross - t_rel) if crosses else nan,
        x_cross_true_m=float(p_cross[0]) if crosses else nan, z_cross_true_m=float(p_cross[2]) if crosses else nan,
        detections=int(log.detections), released=first is not None,
        t_first_setpoint_s=float(first - t_rel) if first is not None else nan,
        lead_time_s=float(t_cross - first) if first is not None else nan,
        x_pred_m=float(it.p_base[0]) if it is not None else nan, z_pred_m=float(it.p_base[2]) if it is not None else nan,
        pred_error_m=pred_err, ballistic_pred_error_m=bal_err,
        x_net_m=float(net_at_cross[0]) if net_at_cross is not None else nan,
        z_net_m=float(net_at_cross[2]) if net_at_cross is not None else nan,
        miss_m=miss, time_margin_s=float(t_cross - log.t_arrived_s) if log.t_arrived_s is not None else nan,
        payload_true_kg=float(payload_true_kg), payload_est_kg=float(log.payload_est_kg), caught=caught,
        t_move_min_s=float(t_move), in_time=in_time, reason=reason, caught_centre=caught_centre,
        ring_offset_m=ring.offset_m if ring is not None else nan,
        rim_clearance_m=ring.clearance_m if ring is not None else nan,
        rim_contact=bool(ring is not None and ring.rim_contact),
        yaw_deg=float(np.degrees(getattr(log, "yaw_rad", 0.0))))


def _turned_crossing(throw, theta1_rad: float):
    """Where the throw's sampled flight crosses the working plane at azimuth ``theta1_rad`` (m), or None."""
    from ...catch.intercept import working_plane_normal
    from .scenario import true_crossing

    return true_crossing(throw.times_s, throw.points_base, normal=working_plane_normal(theta1_rad))[1]


def _ring_passage_of(throw, net_at_cross, net_velocity, theta1_rad: float, ring_radius_m: float,
                     ball_radius_m: float) -> RingPassage:
    """The throw's ball through the net's ring (plane through the net centre, parallel to the working plane)."""
    normal = np.array([-np.sin(theta1_rad), np.cos(theta1_rad), 0.0])
    c = np.asarray(net_at_cross, float)
    pts = np.asarray(throw.points_base, float).reshape(-1, 3)
    tt = np.asarray(throw.times_s, float).reshape(-1)
    if len(pts) >= 2 and len(tt) == len(pts):
        rel = pts - c
        if net_velocity is not None:
            rel = rel - (tt - float(throw.t_cross_rel_s))[:, None] * np.asarray(net_velocity, float)
        h = rel @ normal
        if np.any((h[:-1] < 0.0) & (h[1:] >= 0.0)):
            return ring_passage(rel, ring_radius_m=ring_radius_m, ball_radius_m=ball_radius_m, normal=normal)
    # no sampled flight across the ring plane: head-on through the true crossing
    off = np.asarray(throw.p_cross_base, float) - c
    off = off - (off @ normal) * normal
    path = off + np.outer([-1.0, 1.0], normal)
    return ring_passage(path, ring_radius_m=ring_radius_m, ball_radius_m=ball_radius_m, normal=normal)


def _median(values) -> float | None:
    v = np.asarray(values, float)
    return float(np.nanmedian(v)) if np.any(np.isfinite(v)) else None


def summarize_throws(results) -> dict:
    """Success counts and rates, median prediction errors and misses by reason.

    Parameters
    ----------
    results : sequence of ThrowResult
        The throws of a run.

    Returns
    -------
    dict
        ``crossing_workspace``, ``caught``, ``caught_in_workspace``, ``success_rate`` (caught of
        those crossing the workspace, the whole ball through the ring; None without any),
        ``crossing_in_time``, ``caught_in_time``, ``success_rate_in_time``, ``median_pred_error_m``,
        ``median_ballistic_error_m`` (None without any), ``misses`` (``{reason: count}``, sorted by
        reason); the earlier, lenient criterion (ball centre within the net radius):
        ``caught_centre``, ``caught_centre_in_workspace``, ``success_rate_centre``; and
        ``rim_contacts_in_workspace`` (crossing throws whose ball touched the rim).

    Examples
    --------
    >>> summarize_throws([])["success_rate"] is None
    True
    """
    n_ws = sum(r.crossing_workspace for r in results)
    caught_ws = sum(r.crossing_workspace and r.caught for r in results)
    n_it = sum(r.in_time for r in results)
    caught_it = sum(r.in_time and r.caught for r in results)
    reasons = sorted({r.reason for r in results if r.reason})
    caught_c_ws = sum(r.crossing_workspace and r.caught_centre for r in results)
    return {
        "crossing_workspace": int(n_ws), "caught": int(sum(r.caught for r in results)),
        "caught_in_workspace": int(caught_ws), "success_rate": (caught_ws / n_ws) if n_ws else None,
        "crossing_in_time": int(n_it), "caught_in_time": int(caught_it),
        "success_rate_in_time": (caught_it / n_it) if n_it else None,
        "median_pred_error_m": _median([r.pred_error_m for r in results]),
        "median_ballistic_error_m": _median([r.ballistic_pred_error_m for r in results]),
        "misses": {why: sum(1 for r in results if r.reason == why) for why in reasons},
        "caught_centre": int(sum(r.caught_centre for r in results)), "caught_centre_in_workspace": int(caught_c_ws),
        "success_rate_centre": (caught_c_ws / n_ws) if n_ws else None,
        "rim_contacts_in_workspace": int(sum(r.crossing_workspace and r.rim_contact for r in results)),
    }
