"""Intercept: where the predicted flight crosses the robot's vertical working plane (section 9.3).

The working plane is the vertical plane through the base z axis at azimuth
``theta1`` (the plane the arm moves in): it contains ``[cos t1, sin t1, 0]``
and ``[0, 0, 1]``; its normal is ``n = [-sin t1, cos t1, 0]`` (base frame).

The filter state is propagated (with its covariance) to the crossing; the
crossing point's covariance is the position covariance projected along the
flight direction onto the plane, ``C = M P_pp M^T`` with
``M = I - v n^T / (n . v)`` (an error along the flight moves the crossing time,
not the point). The setpoint is released once the crossing lies in the
reachable workspace and its largest in-plane standard deviation is below
``release_sigma_m``; after that each better estimate refines it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .._checks import check_array
from .ball_model import BallModel, propagate_state
from .ekf import predict

__all__ = ["working_plane_normal", "PlaneCrossing", "plane_crossing", "planar_coordinates", "reachable_solutions",
           "inner_reach_m", "net_target",
           "InterceptOptions", "Intercept", "InterceptPlanner"]


def working_plane_normal(theta1: float) -> np.ndarray:
    """Unit normal ``[-sin t1, cos t1, 0]`` of the working plane at azimuth ``theta1`` (rad), base frame.

    Parameters
    ----------
    theta1 : float
        Azimuth of the working plane (joint 1 angle), rad.

    Returns
    -------
    n : ndarray, shape (3,)
        Unit normal, base frame (z up).

    Examples
    --------
    >>> (working_plane_normal(0.0) + 0.0).tolist()
    [0.0, 1.0, 0.0]
    """
    return np.array([-np.sin(theta1), np.cos(theta1), 0.0])


def planar_coordinates(p_base, theta1: float) -> tuple[float, float]:
    """Signed reach ``r`` along ``[cos t1, sin t1, 0]`` and height ``z`` of a point, metres.

    Parameters
    ----------
    p_base : array_like, shape (3,)
        Point, metres, base frame.
    theta1 : float
        Azimuth of the working plane, rad.

    Returns
    -------
    r, z : float
        Signed in-plane reach and height, metres.

    Raises
    ------
    ValueError
        If ``p_base`` does not have shape (3,).

    Examples
    --------
    >>> planar_coordinates([-0.3, 0.0, 1.0], 0.0)
    (-0.3, 1.0)
    """
    p = check_array(p_base, "p_base", (3,))
    return float(p[0] * np.cos(theta1) + p[1] * np.sin(theta1)), float(p[2])


@dataclass(frozen=True)
class PlaneCrossing:
    """The predicted crossing of the working plane.

    Attributes
    ----------
    dt_s : float
        Time from the state's time to the crossing, seconds.
    x : ndarray, shape (6,)
        Filter state ``[x, y, z, vx, vy, vz]`` at the crossing, m and m/s, base frame.
    P : ndarray, shape (6, 6)
        Covariance of ``x``.
    p_base : ndarray, shape (3,)
        Crossing point, metres, base frame.
    cov_base : ndarray, shape (3, 3)
        Covariance of the crossing point within the plane, m^2, base frame.
    sigma_m : float
        Largest standard deviation of ``cov_base``, metres.
    """

    dt_s: float
    x: np.ndarray
    P: np.ndarray
    p_base: np.ndarray
    cov_base: np.ndarray
    sigma_m: float


def plane_crossing(x, P, normal, *, point=(0.0, 0.0, 0.0), model: BallModel = BallModel(),
                   q_m2_s3: float = 0.001, max_time_s: float = 3.0,
                   min_height_m: float = -np.inf) -> PlaneCrossing | None:
    """Propagate the state to the plane ``n . (p - point) = 0``.

    Parameters
    ----------
    x : array_like, shape (6,)
        ``[x, y, z, vx, vy, vz]``, m and m/s, base frame (z up).
    P : array_like, shape (6, 6)
        Covariance of ``x``.
    normal : array_like, shape (3,)
        Plane normal, base frame (need not be unit).
    point : array_like, shape (3,)
        A point on the plane, metres, base frame (default the origin).
    model : BallModel, optional
        Flight model (gravity and drag) used to propagate the state.
    q_m2_s3 : float, optional
        White acceleration noise spectral density per axis, m^2/s^3, for the
        covariance propagation.
    max_time_s : float
        Search horizon, seconds.
    min_height_m : float
        The flight ends when ``z`` falls below this (the floor), metres, base frame.

    Returns
    -------
    PlaneCrossing or None
        None if the ball moves away from the plane or does not reach it in time.

    Raises
    ------
    ValueError
        If ``x``, ``P``, ``normal`` or ``point`` has the wrong shape.

    Examples
    --------
    >>> c = plane_crossing([0, -2.0, 1.0, 0, 4.0, 0], np.eye(6) * 1e-4, [0, 1, 0],
    ...                    model=BallModel(drag_k_per_m=0.0), q_m2_s3=0.0)
    >>> round(c.dt_s, 6), np.round(c.p_base, 3).tolist()
    (0.5, [0.0, 0.0, -0.226])
    """
    x = check_array(x, "x", (6,))
    P = check_array(P, "P", (6, 6))
    n = check_array(normal, "normal", (3,))
    n = n / np.linalg.norm(n)
    c = check_array(point, "point", (3,))
    d0 = float(n @ (x[:3] - c))
    vn0 = float(n @ x[3:])
    if d0 != 0.0 and (vn0 == 0.0 or -d0 / vn0 < 0):
        return None                      # moving away from (or along) the plane
    # Newton on the crossing time from the straight-line guess (the plane is vertical: gravity
    # does not move the ball across it; drag only slows the approach)
    t = 0.0 if d0 == 0.0 else -d0 / vn0
    xi, h = x, t
    for _ in range(8):
        t_new = t if xi is x else t + h
        if t_new > max_time_s or t_new < 0:
            return None
        xi = propagate_state(xi, h, model)
        t = t_new
        di = float(n @ (xi[:3] - c))
        vn = float(n @ xi[3:])
        if vn == 0.0:
            return None
        h = -di / vn
        if abs(di) < 1e-7:
            break
    else:
        return None
    if xi[2] < min_height_m or t > max_time_s:
        return None
    # covariance on a coarser grid (0.1 s steps: F needs less accuracy than the state)
    _, Pc = predict(x, P, t, replace(model, max_step_s=max(model.max_step_s, 0.1)), q_m2_s3) \
        if t != 0.0 else (x, P.copy())
    xc = xi
    v = xc[3:]
    vn = float(n @ v)
    if vn == 0.0:
        return None
    M = np.eye(3) - np.outer(v, n) / vn
    C = M @ Pc[:3, :3] @ M.T
    C = 0.5 * (C + C.T)
    sigma = float(np.sqrt(max(np.linalg.eigvalsh(C)[-1], 0.0)))
    return PlaneCrossing(dt_s=float(t), x=xc, P=Pc, p_base=xc[:3].copy(), cov_base=C, sigma_m=sigma)


def reachable_solutions(p_base, theta1: float, params=None, *, margin_rad: float = 0.0) -> np.ndarray:
    """Rigid IK solutions reaching ``p_base`` with joint 1 at ``theta1`` (within the ranges shrunk by margin).

    Parameters
    ----------
    p_base : array_like, shape (3,)
        Target point, metres, base frame.
    theta1 : float
        Required joint 1 angle (azimuth of the working plane), rad.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    margin_rad : float, optional
        Joint-range margin, rad: solutions closer than this to a limit are dropped.

    Returns
    -------
    thetas : ndarray, shape (K, 3)
        Joint angles, rad, K in 0..2 (elbow up / down); empty when not
        reachable in that plane.

    Examples
    --------
    >>> from tudorvision.robot import fk_ee
    >>> sols = reachable_solutions(fk_ee([0.0, 1.2, 0.6]), 0.0)
    >>> len(sols)
    2
    """
    from ..robot import ik_all, within_limits

    sols = ik_all(p_base, params)
    if len(sols) == 0:
        return sols
    d1 = (sols[:, 0] - theta1 + np.pi) % (2 * np.pi) - np.pi
    sols = sols[np.abs(d1) < 1e-6]
    if margin_rad > 0 and len(sols):
        sols = sols[within_limits(sols, params, margin_rad=margin_rad)]
    return sols


def net_target(p_base, theta1: float, params=None, *, reach_margin_m: float = 0.05,
               inner_reach_m: float = 0.0) -> np.ndarray:
    """Where to put the net for a crossing at ``p_base``: pulled in from the edges of the reach.

    Near full stretch the inverse kinematics is nearly singular: a few
    centimetres of intercept refinement swing joint 3 by tens of degrees, and
    the joints overshoot on the reversals. A crossing farther than
    ``reach - reach_margin_m`` from the shoulder (joint 2 axis) is moved
    radially onto that circle; with an 18 cm net (9 cm radius) a ball up to
    the margin away still lands in it. At the inner edge, where the elbow
    runs out of range, a crossing nearer than ``inner_reach_m`` is moved out
    onto that circle (:func:`inner_reach_m`): else the only solution left is
    the other elbow branch, a swing of joint 3 through most of its range.
    Points in between are returned unchanged.

    Parameters
    ----------
    p_base : array_like, shape (3,)
        Crossing point in the working plane at azimuth ``theta1``, base frame, metres.
    theta1 : float
        Azimuth of the working plane, rad.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    reach_margin_m : float
        Distance kept from full stretch (link 2 + link 3), metres.
    inner_reach_m : float
        Smallest distance from the shoulder the net is sent to, metres (0: none).

    Returns
    -------
    p_net : ndarray, shape (3,)
        Net target, metres, base frame.

    Raises
    ------
    ValueError
        If ``p_base`` does not have shape (3,).

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> p = load_robot_params()
    >>> reach = p.link2_length_m + p.link3_length_m
    >>> q = net_target([reach, 0.0, p.link1_height_m], 0.0, p, reach_margin_m=0.05)
    >>> round(float(q[0]), 3) == round(reach - 0.05, 3), float(q[2]) == p.link1_height_m
    (True, True)
    >>> q = net_target([0.3, 0.0, p.link1_height_m], 0.0, p, inner_reach_m=0.55)
    >>> round(float(q[0]), 3)
    0.55
    """
    from ..robot import load_robot_params

    p = params or load_robot_params()
    q = check_array(p_base, "p_base", (3,)).copy()
    r, z = planar_coordinates(q, theta1)
    dz = z - p.link1_height_m
    d = float(np.hypot(r, dz))
    lim = p.link2_length_m + p.link3_length_m - float(reach_margin_m)
    if 0.0 < d < float(inner_reach_m):
        lim = float(inner_reach_m)
    elif d <= lim or d == 0.0:
        return q
    s = lim / d
    u = np.array([np.cos(theta1), np.sin(theta1), 0.0])
    off = q - r * u - np.array([0.0, 0.0, z])          # the part off the plane (kept)
    return off + s * r * u + np.array([0.0, 0.0, p.link1_height_m + s * dz])


def inner_reach_m(params=None, joint3_margin_rad: float = 0.0) -> float:
    """Distance from the shoulder at which the elbow (joint 3) reaches its range less a margin, metres.

    Nearer crossings need joint 3 beyond ``min(hi, -lo) - joint3_margin_rad`` on either elbow branch:
    ``sqrt(l2^2 + l3^2 + 2 l2 l3 cos(theta3))``.

    Parameters
    ----------
    params : RobotParams, optional
        Link lengths and joint ranges; default the packaged ``tudor.yaml``.
    joint3_margin_rad : float
        Margin kept inside joint 3's range, rad.

    Returns
    -------
    float

    Examples
    --------
    >>> round(inner_reach_m(None, np.deg2rad(3.0)), 3)
    0.546
    """
    from ..robot import load_robot_params

    p = params or load_robot_params()
    lo, hi = (float(x) for x in p.joint_limits_rad[2])
    t3 = min(hi, -lo) - float(joint3_margin_rad)
    l2, l3 = p.link2_length_m, p.link3_length_m
    return math.sqrt(max(l2 * l2 + l3 * l3 + 2.0 * l2 * l3 * math.cos(t3), 0.0))


@dataclass(frozen=True, kw_only=True)
class InterceptOptions:
    """Release policy of :class:`InterceptPlanner`.

    Attributes
    ----------
    theta1_rad : float
        Azimuth of the working plane (joint 1 is kept there).
    release_sigma_m : float
        Release the setpoint once the crossing's largest in-plane standard
        deviation is below this.
    refine_tol_m : float
        After release, a new setpoint is sent when the intercept moved more than this
        (and more than ``refine_sigma_factor`` times its current standard deviation), metres ...
    refine_sigma_factor : float
        Multiple of the current standard deviation the intercept must move
        before a refinement is sent (0: only ``refine_tol_m`` counts).
    min_interval_s : float
        ... and at least this long after the previous one (every new setpoint re-plans the
        joint layer's smooth point-to-point profile; re-planning at the camera rate would
        keep the arm in the slow start of the profile), seconds.
    refine_sharper : float
        ... unless the new estimate's standard deviation is at most this fraction of the released
        one's: an early, rough release is then corrected at once instead of after ``min_interval_s``
        (0: the interval always applies). In [0, 1).
    margin_rad : float
        Joint-range margin for reachability.
    reach_tol_m : float
        A crossing up to this far beyond full stretch (link 2 + link 3 from the shoulder) still
        counts as reachable, judged at full stretch: a net held there (or pulled in by
        :func:`net_target`'s margin) still takes a ball passing this far out when the tolerance is
        at most ``net radius - ball radius - reach margin``; metres, >= 0.
    inner_reach_m : float
        A crossing up to ``inner_reach_tol_m`` nearer the shoulder than this counts as reachable,
        judged at this distance (where :func:`net_target` with the same ``inner_reach_m`` sends the
        net); metres, 0: none.
    inner_reach_tol_m : float or None
        How far inside ``inner_reach_m`` a crossing still counts as reachable, metres (>= 0); None:
        ``reach_tol_m``. The net sits on that circle itself (no reach margin there), so up to
        ``net radius - ball radius`` still lets the ball pass the ring.
    min_height_m : float
        Floor height in the base frame (the flight ends below it), metres.

    Raises
    ------
    ValueError
        If ``release_sigma_m <= 0``, or ``refine_tol_m``, ``reach_tol_m`` or ``inner_reach_m`` is negative.
    """

    theta1_rad: float = 0.0
    release_sigma_m: float = 0.03
    refine_tol_m: float = 0.02
    refine_sigma_factor: float = 0.0
    min_interval_s: float = 0.2
    refine_sharper: float = 0.0
    margin_rad: float = np.deg2rad(2.0)
    reach_tol_m: float = 0.0
    inner_reach_m: float = 0.0
    inner_reach_tol_m: float | None = None
    min_height_m: float = -0.3

    def __post_init__(self):
        if self.inner_reach_tol_m is not None and not self.inner_reach_tol_m >= 0:
            raise ValueError(f"inner_reach_tol_m: expected None or >= 0, got {self.inner_reach_tol_m}")
        if (not self.release_sigma_m > 0 or not self.refine_tol_m >= 0 or not self.reach_tol_m >= 0
                or not self.inner_reach_m >= 0 or not 0.0 <= self.refine_sharper < 1.0):
            raise ValueError(f"release_sigma_m, refine_tol_m, reach_tol_m, inner_reach_m, refine_sharper: expected "
                             f"> 0, >= 0, >= 0, >= 0 and in [0, 1), got {self.release_sigma_m}, {self.refine_tol_m}, "
                             f"{self.reach_tol_m}, {self.inner_reach_m}, {self.refine_sharper}")


@dataclass(frozen=True)
class Intercept:
    """One intercept estimate of :class:`InterceptPlanner`.

    Attributes
    ----------
    t : float
        Time of the filter state it was computed from, seconds.
    t_cross : float
        Absolute predicted crossing time, seconds.
    p_base : ndarray, shape (3,)
        Predicted crossing point, metres, base frame.
    cov_base : ndarray, shape (3, 3)
        In-plane covariance of ``p_base``, m^2.
    sigma_m : float
        Largest standard deviation of ``cov_base``, metres.
    reachable : bool
        Whether the arm can reach ``p_base`` in the working plane.
    send : bool
        Whether a setpoint was (re)sent for this estimate.
    """

    t: float
    t_cross: float
    p_base: np.ndarray
    cov_base: np.ndarray
    sigma_m: float
    reachable: bool
    send: bool


class InterceptPlanner:
    """Decides when to release and refine the intercept setpoint for one throw.

    Call :meth:`update` after each filter step with the filter's state;
    it returns the :class:`Intercept` (or None without a crossing), whose
    ``send`` tells whether a (new) setpoint should go out now.

    Parameters
    ----------
    options : InterceptOptions, optional
        Working plane and release policy.
    model : BallModel, optional
        Flight model used to propagate the state to the plane.
    q_m2_s3 : float, optional
        White acceleration noise spectral density per axis, m^2/s^3.
    params : RobotParams, optional
        Robot parameters for reachability; default the packaged ``tudor.yaml``.

    Attributes
    ----------
    theta1_rad : float
        This throw's working plane (``options.theta1_rad`` unless :meth:`use_plane` chose another), rad.
    """

    def __init__(self, options: InterceptOptions = InterceptOptions(), *, model: BallModel = BallModel(),
                 q_m2_s3: float = 0.001, params=None):
        self.options = options
        self.model = model
        self.q_m2_s3 = float(q_m2_s3)
        self.params = params
        self._lims = None
        self.reset()

    def _inner_tol(self) -> float:
        o = self.options
        return o.reach_tol_m if o.inner_reach_tol_m is None else o.inner_reach_tol_m

    def _reachable(self, p_base, t1: float | None = None) -> bool:
        # reachable_solutions(p_base, t1, params, margin_rad) is not empty, on floats (per frame); t1: this throw's
        t1 = self.theta1_rad if t1 is None else t1
        if self._lims is None:
            from ..robot import load_robot_params

            prm = self.params or load_robot_params()
            m = self.options.margin_rad
            self._lims = (prm.link1_height_m, prm.link2_length_m, prm.link3_length_m,
                          [(float(a) + m, float(b) - m) for a, b in prm.joint_limits_rad])
        h1, l2, l3, lims = self._lims
        r = float(p_base[0]) * math.cos(t1) + float(p_base[1]) * math.sin(t1)
        zz = float(p_base[2]) - h1
        d = math.hypot(r, zz)
        if l2 + l3 < d <= l2 + l3 + self.options.reach_tol_m:
            r, zz = r * (l2 + l3) / d, zz * (l2 + l3) / d          # judged at full stretch
        elif 0.0 < self.options.inner_reach_m - self._inner_tol() <= d < self.options.inner_reach_m:
            r, zz = r * self.options.inner_reach_m / d, zz * self.options.inner_reach_m / d   # at the inner edge
        c3 = (r * r + zz * zz - l2 * l2 - l3 * l3) / (2 * l2 * l3)
        if c3 > 1.0 + 1e-12 or c3 < -1.0 - 1e-12:
            return False
        if not lims[0][0] <= t1 <= lims[0][1]:
            return False
        c3 = min(1.0, max(-1.0, c3))
        (lo2, hi2), (lo3, hi3) = lims[1], lims[2]
        lo2_raw = lo2 - self.options.margin_rad
        for sgn in (1.0, -1.0):
            t3 = sgn * math.acos(c3)
            t2 = math.atan2(zz, r) - math.atan2(l3 * math.sin(t3), l2 + l3 * math.cos(t3))
            t2 = (t2 + math.pi) % (2 * math.pi) - math.pi
            if t2 < lo2_raw and t2 + 2 * math.pi <= hi2 + self.options.margin_rad:
                t2 += 2 * math.pi
            if lo2 <= t2 <= hi2 and lo3 <= t3 <= hi3:
                return True
        return False

    def reset(self) -> None:
        """New throw: nothing released, the working plane back at ``options.theta1_rad``."""
        self.released: Intercept | None = None
        self.history: list[Intercept] = []
        self.theta1_rad = float(self.options.theta1_rad)

    def on_plane(self, t: float, x, P, theta1_rad: float) -> Intercept | None:
        """The estimate for the state ``(x, P)`` at ``t`` (s) on the working plane at azimuth ``theta1_rad``.

        The planner is unchanged (``send`` is False); :meth:`use_plane` takes the plane for the throw.

        Parameters
        ----------
        t, x, P : float, ndarray (6,), ndarray (6, 6)
            The filter's time (s), state and covariance, as for :meth:`update`.
        theta1_rad : float
            Azimuth of the plane (joint 1's angle), rad.

        Returns
        -------
        Intercept or None
            The crossing of that plane (``reachable`` judged there), or None when the flight does not cross it.

        Examples
        --------
        >>> pl = InterceptPlanner(InterceptOptions(release_sigma_m=1.0))
        >>> x, P = np.array([0.3, -3.0, 1.3, 0.0, 6.0, 2.0]), np.diag([1e-4] * 3 + [1e-2] * 3)
        >>> a, b = pl.update(0.0, x, P), pl.on_plane(0.0, x, P, np.radians(-30.0))
        >>> bool(b.t_cross < a.t_cross), bool(b.p_base[2] > a.p_base[2]), b.send, pl.theta1_rad   # met sooner, higher
        (True, True, False, 0.0)
        """
        o = self.options
        c = plane_crossing(x, P, working_plane_normal(theta1_rad), model=self.model, q_m2_s3=self.q_m2_s3,
                           min_height_m=o.min_height_m)
        if c is None:
            return None
        return Intercept(t=float(t), t_cross=float(t) + c.dt_s, p_base=c.p_base, cov_base=c.cov_base,
                         sigma_m=c.sigma_m, reachable=self._reachable(c.p_base, float(theta1_rad)), send=False)

    def use_plane(self, theta1_rad: float, released: Intercept) -> None:
        """Estimate and refine this throw on the plane at ``theta1_rad`` from now on (:meth:`reset` ends it).

        Parameters
        ----------
        theta1_rad : float
            The plane's azimuth, rad.
        released : Intercept
            An estimate of :meth:`on_plane` on that plane: the released setpoint later ones are compared with.
        """
        self.theta1_rad = float(theta1_rad)
        self.released = replace(released, send=True)
        self.history.append(self.released)

    def update(self, t: float, x, P) -> Intercept | None:
        """Intercept for the state ``(x, P)`` at time ``t`` (s).

        Parameters
        ----------
        t : float
            Time of the state, seconds.
        x : array_like, shape (6,)
            Filter state ``[x, y, z, vx, vy, vz]``, m and m/s, base frame.
        P : array_like, shape (6, 6)
            Covariance of ``x``.

        Returns
        -------
        Intercept or None
            The estimate (its ``send`` says whether a setpoint goes out now),
            or None when the flight does not cross the working plane.

        Raises
        ------
        ValueError
            If ``x`` or ``P`` has the wrong shape.
        """
        o = self.options
        it = self.on_plane(t, x, P, self.theta1_rad)
        if it is None:
            return None
        send = False
        if it.reachable and it.sigma_m <= o.release_sigma_m:
            tol = max(o.refine_tol_m, o.refine_sigma_factor * it.sigma_m)
            r = self.released
            send = r is None or (np.linalg.norm(it.p_base - r.p_base) > tol
                                 and (t - r.t >= o.min_interval_s or it.sigma_m <= o.refine_sharper * r.sigma_m))
        it = replace(it, send=send)
        if send:
            self.released = it
        self.history.append(it)
        return it

    def due(self, t: float, *, tol_m: float = 0.0) -> Intercept | None:
        """The latest estimate as a refinement due at ``t`` (s), a time without a new filter state.

        :meth:`update` applies the refinement rule only when a detection brings a new state; when the ball is
        out of view for a moment (high throws leave the top of the image), a refinement the interval held back
        would wait for the ball to come back. This applies the rule of :meth:`update` again at ``t`` to the
        latest estimate: reachable, released-worthy, its crossing still ahead, farther than the tolerance from
        the released one, and the interval since the release passed.

        Parameters
        ----------
        t : float
            Time now (a frame without a detection), seconds.
        tol_m : float
            A larger tolerance than the rule's for these refinements, metres (the estimate before the ball left
            the image is the filter's latest, not its best: only a large change is worth a re-plan now).

        Returns
        -------
        Intercept or None
            The latest estimate marked ``send`` (now the released one), or None when no refinement is due.

        Examples
        --------
        >>> pl = InterceptPlanner(InterceptOptions(release_sigma_m=1.0, min_interval_s=0.2))
        >>> x, P = np.array([0.1, -3.0, 1.3, 0.0, 6.0, 2.0]), np.diag([1e-4] * 3 + [1e-2] * 3)
        >>> pl.update(0.0, x, P).send, pl.update(0.05, x + [0.05, 0.0, 0.0, 0.0, 0.0, 0.0], P).send  # 5 cm moved
        (True, False)
        >>> pl.due(0.1) is None, pl.due(0.2).send, pl.due(0.3) is None       # due once the interval has passed
        (True, True, True)
        """
        o, r = self.options, self.released
        if r is None or not self.history:
            return None
        last = self.history[-1]
        if last is r or not last.reachable or last.sigma_m > o.release_sigma_m or last.t_cross <= t:
            return None
        tol = max(o.refine_tol_m, o.refine_sigma_factor * last.sigma_m, float(tol_m))
        if not (np.linalg.norm(last.p_base - r.p_base) > tol and t - r.t >= o.min_interval_s):
            return None
        it = replace(last, send=True)
        self.released = self.history[-1] = it
        return it
