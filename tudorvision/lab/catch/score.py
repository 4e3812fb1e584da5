"""Scoring the catching demo from ground truth: one :class:`ThrowResult` per throw, and the summary.

A throw *crosses the workspace* if its true crossing of the working plane is
reachable by the rigid arm within the joint ranges. It is *caught* if the
ball centre at the crossing lies within the net radius
(``DemoOptions.net_radius_m``) of the net centre (the deflected end effector
at that instant). A secondary, stricter count asks whether the arm could get
there at all, leaving its pose at the release once the first three
detections are in (a lower bound on the move time: trapezoidal profile).
"""
from __future__ import annotations

import math
from dataclasses import asdict, astuple, dataclass, fields

import numpy as np

__all__ = ["ThrowResult", "PER_THROW_COLUMNS", "MISS_REASONS", "min_move_time", "miss_reason", "score_throw",
           "summarize_throws"]

#: Why a throw was missed, in the order they are tested (the first that applies is reported).
MISS_REASONS = ("does not reach the working plane", "outside the reachable workspace", "not tracked",
                "not released (intercept uncertain or predicted unreachable)", "prediction error", "arm late",
                "deflection or vibration")


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
        Distance from the net centre to the ball centre at the crossing, m.
    time_margin_s : float
        Time from the arm's arrival (within 1 deg of its last setpoint) to the crossing, s.
    payload_true_kg : float
        True payload on top of the mount (balls in the net) during the throw, kg.
    payload_est_kg : float
        The agent's payload estimate during the throw, kg.
    caught : bool
        The ball passed within the net radius of the net centre.
    t_move_min_s : float
        Shortest move from the pose at the release to the crossing (trapezoidal profile), s; ``inf``: unreachable.
    in_time : bool
        Crossing the workspace, and that move fits before the crossing, less three frames.
    reason : str
        Why it was missed (one of :data:`MISS_REASONS`), empty if caught.
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
                pred_error_m: float, net_radius_m: float, arrived: bool) -> str:
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
    checks = (not crosses, not in_workspace, detections < n_init, not released, pred_error_m > net_radius_m,
              not arrived)
    if caught:
        return ""
    for why, failed in zip(MISS_REASONS, checks):
        if failed:
            return why
    return MISS_REASONS[-1]


def score_throw(throw, log, *, net_at_cross, theta_at_release, payload_true_kg: float, options, params,
                theta1_rad: float, max_speed: float, max_accel: float, frame_rate_hz: float) -> ThrowResult:
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
        The demo's options (net radius, the filter's ``n_init``).
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

    Returns
    -------
    ThrowResult
        The throw's row.
    """
    from ...catch.intercept import reachable_solutions

    nan = math.nan
    crosses = throw.crosses
    p_cross = throw.p_cross_base
    t_rel, t_cross = throw.t_release_s, throw.t_cross_s
    sols = reachable_solutions(p_cross, theta1_rad, params) if crosses else np.zeros((0, 3))
    in_ws = len(sols) > 0
    t_move = min_move_time(sols, np.asarray(theta_at_release), max_speed, max_accel)
    in_time = bool(in_ws and t_move <= throw.t_cross_rel_s - 3.0 / frame_rate_hz)
    it, bal, first = log.last_intercept, log.last_ballistic_base, log.t_first_setpoint_s
    miss = float(np.linalg.norm(net_at_cross - p_cross)) if crosses else nan
    caught = bool(crosses and miss <= options.net_radius_m)
    pred_err = float(np.linalg.norm(it.p_base - p_cross)) if (crosses and it is not None) else nan
    bal_err = float(np.linalg.norm(bal - p_cross)) if (crosses and bal is not None) else nan
    reason = miss_reason(caught=caught, crosses=crosses, in_workspace=in_ws, detections=log.detections,
                         n_init=options.ekf.n_init, released=first is not None, pred_error_m=pred_err,
                         net_radius_m=options.net_radius_m, arrived=log.t_arrived_s is not None)
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
        t_move_min_s=float(t_move), in_time=in_time, reason=reason)


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
        those crossing the workspace; None without any), ``crossing_in_time``, ``caught_in_time``,
        ``success_rate_in_time``, ``median_pred_error_m``, ``median_ballistic_error_m`` (None
        without any), ``misses`` (``{reason: count}``, sorted by reason).

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
    return {
        "crossing_workspace": int(n_ws), "caught": int(sum(r.caught for r in results)),
        "caught_in_workspace": int(caught_ws), "success_rate": (caught_ws / n_ws) if n_ws else None,
        "crossing_in_time": int(n_it), "caught_in_time": int(caught_it),
        "success_rate_in_time": (caught_it / n_it) if n_it else None,
        "median_pred_error_m": _median([r.pred_error_m for r in results]),
        "median_ballistic_error_m": _median([r.ballistic_pred_error_m for r in results]),
        "misses": {why: sum(1 for r in results if r.reason == why) for why in reasons},
    }
