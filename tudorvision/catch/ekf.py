"""Extended Kalman filter for a thrown ball with gravity and quadratic drag (section 9.3).

State layout (base frame, SI units)::

    x = [x, y, z, vx, vy, vz]      metres, metres per second

Process model (continuous time), ``g = [0, 0, -9.81]`` m/s^2 and the drag
coefficient ``k`` in 1/m (the lab's soft 9 cm ball: ``k = 0.012``)::

    dp/dt = v
    dv/dt = g - k |v| v

It is integrated with RK4 over ``dt`` (sub-stepped at ``max_step_s``), and the
state-transition Jacobian ``F = d x(t+dt) / d x(t)`` is integrated alongside
(variational equation), so ``F`` is exact for the discretised model.

Process noise: white acceleration noise of spectral density
``q_m2_s3`` (m^2/s^3) on each axis, the standard ``[[dt^3/3, dt^2/2],
[dt^2/2, dt]] q`` blocks; it covers drag-coefficient error and spin.

Measurements are ball centres ``z = p + noise`` in the same frame with the
detector's covariance (``sigma_z(z)`` along the viewing ray, rotated into the
filter frame by the caller). Innovations whose Mahalanobis distance squared
(NIS) exceeds ``gate_nis`` are rejected (outliers).

The flight model and its propagation are :mod:`tudorvision.catch.ball_model`.
The pure functions :func:`predict` and :func:`update` are the core; :class:`BallEKF` holds one filter between
frames on top of :class:`filterpy.kalman.ExtendedKalmanFilter`, with
least-squares initialisation from the first detections and reset on a new
throw. Always call ``predict(dt)`` then ``update(z, R)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array
from .ball_model import BallModel, check_ball_state, propagate

__all__ = ["EKFOptions", "process_noise", "predict", "update", "init_from_detections", "BallEKF"]

@dataclass(frozen=True, kw_only=True)
class EKFOptions:
    """Tuning of :class:`BallEKF`.

    Attributes
    ----------
    model : BallModel
    q_m2_s3 : float
        White acceleration noise spectral density per axis, m^2/s^3.
    gate_nis : float
        Mahalanobis gate on the innovation (chi-square, 3 dof; 16.27 = 99.9 %).
    n_init : int
        Detections used for the least-squares initialisation (>= 2).
    init_velocity_sigma_m_s : float
        Floor of the initial velocity standard deviation.
    max_gap_s : float
        A detection later than this after the last accepted one starts a new throw, unless it
        fits the flight predicted over the gap (below).
    max_coast_s : float
        A detection after a longer gap than ``max_gap_s`` but at most this long continues the
        throw when it passes the gate against the flight predicted over the gap (the ball left
        the image or the sensor's range for a while, e.g. a high lob above the image's top edge);
        at most ``max_gap_s`` (e.g. 0): every longer gap starts a new throw (the behaviour before), seconds.
    max_rejections : int
        Consecutive gated detections after which the filter restarts (new throw).
    """

    model: BallModel = BallModel()
    q_m2_s3: float = 0.001
    gate_nis: float = 16.27
    n_init: int = 3
    init_velocity_sigma_m_s: float = 0.05
    max_gap_s: float = 0.25
    max_coast_s: float = 0.6
    max_rejections: int = 3

    def __post_init__(self):
        if int(self.n_init) != self.n_init or self.n_init < 2:
            raise ValueError(f"n_init: expected an integer >= 2, got {self.n_init}")
        if not self.gate_nis > 0 or not self.q_m2_s3 >= 0:
            raise ValueError("gate_nis, q_m2_s3: expected > 0 and >= 0")
        if not self.max_gap_s > 0 or not self.max_coast_s >= 0:
            raise ValueError(f"max_gap_s, max_coast_s: expected > 0 and >= 0, got {self.max_gap_s}, {self.max_coast_s}")


def _nis(p_pred, P_pred, z, R) -> float:
    """Normalised innovation squared of a position measurement ``z`` (R) against ``p_pred`` (P's first 3 rows)."""
    y = np.asarray(z, float) - p_pred
    return float(y @ np.linalg.solve(P_pred[:3, :3] + R, y))


def process_noise(dt: float, q_m2_s3: float) -> np.ndarray:
    """Discrete white-acceleration process noise, shape (6, 6).

    Examples
    --------
    >>> Q = process_noise(0.1, 1.0)
    >>> round(float(Q[0, 0]), 6), round(float(Q[0, 3]), 4), round(float(Q[3, 3]), 2)
    (0.000333, 0.005, 0.1)
    """
    dt = abs(float(dt))
    Q = np.zeros((6, 6))
    for i in range(3):
        Q[i, i] = dt ** 3 / 3
        Q[i, i + 3] = Q[i + 3, i] = dt ** 2 / 2
        Q[i + 3, i + 3] = dt
    return Q * float(q_m2_s3)


def predict(x, P, dt: float, model: BallModel = BallModel(), q_m2_s3: float = 0.001):
    """EKF prediction over ``dt`` seconds: ``x <- f(x)``, ``P <- F P F^T + Q``.

    Parameters
    ----------
    x : array_like, shape (6,)
        State ``[x, y, z, vx, vy, vz]``, metres and m/s, filter frame.
    P : array_like, shape (6, 6)
        State covariance.
    dt : float
        Prediction horizon, seconds.
    model : BallModel, optional
        Gravity, drag coefficient and integration step.
    q_m2_s3 : float, optional
        White-acceleration process-noise spectral density, m^2/s^3.

    Returns
    -------
    x : ndarray, shape (6,)
    P : ndarray, shape (6, 6)

    Examples
    --------
    >>> x, P = predict(np.zeros(6), np.eye(6), 0.1, BallModel(drag_k_per_m=0.0), 0.0)
    >>> round(float(P[0, 0]), 2), round(float(x[5]), 3)
    (1.01, -0.981)
    """
    P = check_array(P, "P", (6, 6))
    x1, F = propagate(x, dt, model)
    P1 = F @ P @ F.T + process_noise(dt, q_m2_s3)
    return x1, 0.5 * (P1 + P1.T)


_H = np.hstack([np.eye(3), np.zeros((3, 3))])


def update(x, P, z, R):
    """EKF update with a position measurement ``z = p + noise``, ``noise ~ N(0, R)``.

    Parameters
    ----------
    x : array_like, shape (6,)
        State ``[x, y, z, vx, vy, vz]``, metres and m/s, filter frame.
    P : array_like, shape (6, 6)
        State covariance (m^2, m^2/s, m^2/s^2 blocks).
    z : array_like, shape (3,)
        Measured ball centre, metres, filter frame.
    R : array_like, shape (3, 3)
        Its covariance, m^2.

    Returns
    -------
    x, P : ndarray, shapes (6,), (6, 6)
        Posterior (Joseph form).
    nis : float
        Normalised innovation squared (Mahalanobis distance squared), before the update.

    Examples
    --------
    >>> x, P, nis = update(np.zeros(6), np.eye(6), [1.0, 0, 0], np.eye(3))
    >>> round(float(x[0]), 2), round(float(nis), 2)
    (0.5, 0.5)
    """
    x = check_ball_state(x)
    P = check_array(P, "P", (6, 6))
    z = check_array(z, "z", (3,))
    R = check_array(R, "R", (3, 3))
    y = z - x[:3]
    S = P[:3, :3] + R
    Si = np.linalg.inv(S)
    nis = float(y @ Si @ y)
    K = P[:, :3] @ Si
    IKH = np.eye(6) - K @ _H
    P1 = IKH @ P @ IKH.T + K @ R @ K.T
    return x + K @ y, 0.5 * (P1 + P1.T), nis


def init_from_detections(t, p, R, model: BallModel = BallModel(), *, velocity_sigma_floor_m_s: float = 0.05):
    """Initial state at the last detection by weighted least squares on the first detections.

    Fits ``p(t) = p_L + v_L (t - t_L) + c(t)`` where ``c`` is the flight
    model's curvature about the two-point guess (gravity and drag, evaluated
    by integrating backwards from the linear fit), i.e. a Gauss-Newton step on
    the flight model. With two detections this is the two-point
    initialisation.

    Parameters
    ----------
    t : array_like, shape (N,)
        Detection times, seconds, N >= 2, increasing.
    p : array_like, shape (N, 3)
        Ball centres, metres, filter frame.
    R : array_like, shape (N, 3, 3)
        Their covariances, m^2.
    model : BallModel, optional
        Flight model (gravity, drag) used for the curvature term.
    velocity_sigma_floor_m_s : float, optional
        Lower bound on the initial velocity standard deviation, m/s.

    Returns
    -------
    x : ndarray, shape (6,)
        State at ``t[-1]``.
    P : ndarray, shape (6, 6)
        Its covariance from the least-squares normal equations.

    Raises
    ------
    ValueError
        For fewer than two detections or non-increasing times.

    Examples
    --------
    >>> t = np.array([0.0, 0.1, 0.2])
    >>> p = np.array([[0.0, 0.0, 1.0 - 0.5 * 9.81 * s ** 2] for s in t]); p[:, 1] = 5 * t
    >>> x, P = init_from_detections(t, p, np.tile(1e-6 * np.eye(3), (3, 1, 1)), BallModel(drag_k_per_m=0.0))
    >>> np.round(x, 3).tolist()
    [0.0, 1.0, 0.804, 0.0, 5.0, -1.962]
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    p = check_array(p, "p", (len(t), 3))
    R = check_array(R, "R", (len(t), 3, 3))
    if len(t) < 2:
        raise ValueError(f"t: expected at least 2 detections, got {len(t)}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t: expected strictly increasing times")
    tL = t[-1]
    # linear guess from the first and last points, then Gauss-Newton steps on the flight model
    v0 = (p[-1] - p[0]) / (t[-1] - t[0])
    x = np.concatenate([p[-1], v0 + np.array([0, 0, model.gravity_m_s2]) * (t[-1] - t[0]) / 2 * -1])
    W = [np.linalg.inv(Ri) for Ri in R]
    for _ in range(3):
        N = np.zeros((6, 6)); b = np.zeros(6)
        for ti, pi, Wi in zip(t, p, W):
            xi, Fi = propagate(x, ti - tL, model)
            Hi = Fi[:3]
            r = pi - xi[:3]
            N += Hi.T @ Wi @ Hi
            b += Hi.T @ Wi @ r
        if len(t) == 2:     # two points: position and velocity exactly determined only in the limit
            N += np.diag([0, 0, 0, 1e-9, 1e-9, 1e-9])
        dx = np.linalg.solve(N, b)
        x = x + dx
        if np.max(np.abs(dx)) < 1e-9:
            break
    P = np.linalg.inv(N)
    P[3:, 3:] += np.eye(3) * velocity_sigma_floor_m_s ** 2
    return x, 0.5 * (P + P.T)


class BallEKF:
    """Stateful ball tracker: initialisation, gating, reset on a new throw.

    Wraps :class:`filterpy.kalman.ExtendedKalmanFilter` (``x`` as a column,
    ``F`` and ``Q`` set per step from :func:`propagate` and
    :func:`process_noise`). Feed detections in time order with
    :meth:`step`, or call :meth:`predict` then :meth:`update` yourself.

    Parameters
    ----------
    options : EKFOptions, optional
        Flight model, process noise, gating, initialisation and restart settings.

    Attributes
    ----------
    t : float or None
        Time of the current estimate, seconds.
    initialised : bool
    throw_id : int
        Counts (re)starts: increments on every new throw.
    last_nis : float or None
        NIS of the last offered detection.

    Examples
    --------
    >>> ekf = BallEKF(EKFOptions(model=BallModel(drag_k_per_m=0.0)))
    >>> R = 1e-6 * np.eye(3)
    >>> for t in (0.0, 1 / 30, 2 / 30, 3 / 30):
    ...     _ = ekf.step(t, [0.0, 6.0 * t, 1.5 - 4.905 * t * t], R)
    >>> np.round(ekf.x[3:], 2).tolist()
    [0.0, 6.0, -0.98]
    """

    def __init__(self, options: EKFOptions = EKFOptions()):
        from filterpy.kalman import ExtendedKalmanFilter

        self.options = options
        self._kf = ExtendedKalmanFilter(dim_x=6, dim_z=3)
        self._kf.predict_x = self._predict_x
        self._buffer: list = []
        self.t: float | None = None
        self.initialised = False
        self.throw_id = -1
        self.last_nis: float | None = None
        self._rejections = 0
        self._dt = 0.0

    # ------------------------------------------------------------------ state
    @property
    def x(self) -> np.ndarray:
        """State ``[x, y, z, vx, vy, vz]``, shape (6,)."""
        return self._kf.x[:, 0].copy()

    @property
    def P(self) -> np.ndarray:
        """State covariance, shape (6, 6)."""
        return self._kf.P.copy()

    def reset(self) -> None:
        """Forget the current throw (the next detections initialise a new one)."""
        self._buffer = []
        self.initialised = False
        self.t = None
        self._rejections = 0

    def _predict_x(self, u=0):
        self._kf.x = self._x_pred[:, None]      # computed with F in predict()

    # ------------------------------------------------------------- filtering
    def predict(self, dt: float) -> None:
        """Propagate the estimate by ``dt`` seconds (filterpy ``predict`` with F, Q set).

        Parameters
        ----------
        dt : float
            Seconds.

        Raises
        ------
        RuntimeError
            If the filter is not initialised.
        """
        if not self.initialised:
            raise RuntimeError("predict: the filter is not initialised")
        o = self.options
        self._x_pred, F = propagate(self._kf.x[:, 0], dt, o.model)
        self._dt = float(dt)
        self._kf.F = F
        self._kf.Q = process_noise(dt, o.q_m2_s3)
        self._kf.predict()
        self.t += float(dt)

    def update(self, z, R) -> bool:
        """Gate and fuse one detection at the current time; returns whether it was accepted.

        Parameters
        ----------
        z : array_like, shape (3,)
            Measured ball centre, metres, filter frame.
        R : array_like, shape (3, 3)
            Its covariance, m^2.

        Returns
        -------
        bool
            True if the detection passed the NIS gate and was fused.
        """
        z = check_array(z, "z", (3,))
        R = check_array(R, "R", (3, 3))
        self.last_nis = _nis(self._kf.x[:3, 0], self._kf.P, z, R)
        if self.last_nis > self.options.gate_nis:
            self._rejections += 1
            return False
        self._rejections = 0
        self._kf.update(z[:, None], lambda x: _H, lambda x: x[:3], R=R)
        self._kf.P = 0.5 * (self._kf.P + self._kf.P.T)
        return True

    def step(self, t: float, z, R) -> str:
        """Offer the detection at time ``t`` (seconds); handles init, gating and new throws.

        Parameters
        ----------
        t : float
            Detection time, seconds.
        z : array_like, shape (3,)
            Measured ball centre, metres, filter frame.
        R : array_like, shape (3, 3)
            Its covariance, m^2.

        Returns
        -------
        str
            ``"buffered"`` (collecting for the initialisation), ``"initialised"``,
            ``"accepted"``, ``"rejected"`` (gated outlier) or ``"restarted"``
            (new throw: the filter was reset and this detection starts it).
        """
        t = float(t)
        o = self.options
        z = check_array(z, "z", (3,))
        R = check_array(R, "R", (3, 3))
        restarted = False
        if self.initialised and (self._rejections >= o.max_rejections or not self._continues(t, z, R)):
            self.reset()
            restarted = True
        if not self.initialised:
            if self._buffer and t - self._buffer[-1][0] > o.max_gap_s:
                self._buffer = []
            self._buffer.append((t, z, R))
            if len(self._buffer) < o.n_init:
                return "restarted" if restarted else "buffered"
            tt = np.array([b[0] for b in self._buffer])
            x, P = init_from_detections(tt, np.array([b[1] for b in self._buffer]),
                                        np.array([b[2] for b in self._buffer]), o.model,
                                        velocity_sigma_floor_m_s=o.init_velocity_sigma_m_s)
            self._kf.x = x[:, None].copy()
            self._kf.P = P
            self.t = t
            self.initialised = True
            self.throw_id += 1
            self._buffer = []
            return "initialised"
        self.predict(t - self.t)
        if self.update(z, R):
            return "accepted"
        if self._rejections >= o.max_rejections:
            # the detections no longer fit this flight: a new throw starts with them
            self.reset()
            self._buffer.append((t, z, R))
            return "restarted"
        return "rejected"

    def _continues(self, t: float, z, R) -> bool:
        """Whether a detection at ``t`` belongs to the current throw as far as the gap goes."""
        o = self.options
        gap = t - self.t
        if gap <= o.max_gap_s:
            return True
        if gap > o.max_coast_s:
            return False
        x, P = self.predict_at(t)
        return _nis(x[:3], P, z, R) <= o.gate_nis

    def predict_at(self, t: float):
        """Predicted ``(x, P)`` at time ``t`` without changing the filter.

        Parameters
        ----------
        t : float
            Time, seconds (same clock as :meth:`step`).

        Returns
        -------
        x : ndarray, shape (6,)
            Predicted state ``[x, y, z, vx, vy, vz]``.
        P : ndarray, shape (6, 6)
            Its covariance.

        Raises
        ------
        RuntimeError
            If the filter is not initialised.
        """
        if not self.initialised:
            raise RuntimeError("predict_at: the filter is not initialised")
        return predict(self._kf.x[:, 0], self._kf.P, t - self.t, self.options.model, self.options.q_m2_s3)
