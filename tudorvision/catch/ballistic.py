"""Drag-free ballistic least-squares predictor: the peer baseline of the EKF.

All detections of a throw are fitted with ``p(t) = p0 + v0 (t - t_ref) +
g (t - t_ref)^2 / 2`` (gravity known, no drag) by weighted least squares; the
crossing with the working plane ``n . p = 0`` is solved in closed form (a
vertical plane: ``n . g = 0``, so it is linear in time).
"""
from __future__ import annotations

import numpy as np

from .._checks import check_array

__all__ = ["fit_ballistic", "ballistic_crossing", "BallisticPredictor"]


def fit_ballistic(t, p, *, t_ref: float | None = None, sigma_m=None, gravity_m_s2: float = 9.81):
    """Least-squares release state of a drag-free flight.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, seconds (N >= 2).
    p : array_like, shape (N, 3)
        Ball centres, metres (z up).
    t_ref : float, optional
        Time of the returned state (default the last time).
    sigma_m : array_like, shape (N,), optional
        Per-detection standard deviations, metres (weights ``1 / sigma_m``);
        default equal weights.
    gravity_m_s2 : float, optional
        Gravitational acceleration along ``-z``, m/s^2.

    Returns
    -------
    p0, v0 : ndarray, shape (3,)
        Position and velocity at ``t_ref``.

    Raises
    ------
    ValueError
        For fewer than two points.

    Examples
    --------
    >>> t = np.linspace(0, 0.3, 10)
    >>> p = np.stack([t, 5 * t, 1 + 2 * t - 4.905 * t ** 2], axis=1)
    >>> p0, v0 = fit_ballistic(t, p, t_ref=0.0)
    >>> np.round(p0, 6).tolist(), np.round(v0, 6).tolist()
    ([0.0, 0.0, 1.0], [1.0, 5.0, 2.0])
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    p = check_array(p, "p", (len(t), 3))
    if len(t) < 2:
        raise ValueError(f"t: expected at least 2 points, got {len(t)}")
    tr = t[-1] if t_ref is None else float(t_ref)
    s = t - tr
    y = p.copy()
    y[:, 2] += 0.5 * gravity_m_s2 * s ** 2
    A = np.stack([np.ones_like(s), s], axis=1)
    w = np.ones_like(s) if sigma_m is None else 1.0 / np.asarray(sigma_m, float).ravel()
    coef, *_ = np.linalg.lstsq(A * w[:, None], y * w[:, None], rcond=None)
    return coef[0], coef[1]


def ballistic_crossing(p0, v0, normal, *, point=(0.0, 0.0, 0.0), gravity_m_s2: float = 9.81):
    """Time and point where the drag-free flight from ``(p0, v0)`` crosses a vertical plane.

    Parameters
    ----------
    p0 : array_like, shape (3,)
        Ball position at the state time, metres, base frame (z up).
    v0 : array_like, shape (3,)
        Ball velocity at the state time, m/s, base frame.
    normal : array_like, shape (3,)
        Normal of the vertical plane, base frame (``normal . g = 0``).
    point : array_like, shape (3,), optional
        A point on the plane, metres, base frame (default the origin).
    gravity_m_s2 : float, optional
        Gravitational acceleration along ``-z``, m/s^2.

    Returns
    -------
    dt_s : float or None
        Time from the state to the crossing, seconds (None if moving away or parallel).
    p_base : ndarray, shape (3,) or None
        Crossing point, metres, base frame (None when ``dt_s`` is None).

    Raises
    ------
    ValueError
        If an argument does not have shape (3,).

    Examples
    --------
    >>> dt, p = ballistic_crossing([0, -2.0, 1.0], [0, 4.0, 0], [0, 1, 0])
    >>> dt, np.round(p, 3).tolist()
    (0.5, [0.0, 0.0, -0.226])
    """
    p0 = check_array(p0, "p0", (3,))
    v0 = check_array(v0, "v0", (3,))
    n = check_array(normal, "normal", (3,))
    c = check_array(point, "point", (3,))
    vn = float(n @ v0)
    if vn == 0.0:
        return None, None
    dt = -float(n @ (p0 - c)) / vn
    if dt < 0:
        return None, None
    p = p0 + v0 * dt + 0.5 * np.array([0.0, 0.0, -gravity_m_s2]) * dt ** 2
    return dt, p


class BallisticPredictor:
    """Accumulates the detections of one throw and predicts the plane crossing without drag.

    Parameters
    ----------
    normal : array_like, shape (3,)
        Normal of the vertical working plane through the base origin, base frame.
    gravity_m_s2 : float, optional
        Gravitational acceleration along ``-z``, m/s^2.

    Raises
    ------
    ValueError
        If ``normal`` does not have shape (3,).

    Examples
    --------
    >>> bp = BallisticPredictor([0, 1, 0])
    >>> for t in (0.0, 0.1, 0.2):
    ...     bp.add(t, [0.0, -2.0 + 4 * t, 1.0 - 4.905 * t * t])
    >>> t_cross, p = bp.predict()
    >>> round(t_cross, 6)
    0.5
    """

    def __init__(self, normal, *, gravity_m_s2: float = 9.81):
        self.normal = check_array(normal, "normal", (3,))
        self.gravity_m_s2 = float(gravity_m_s2)
        self.reset()

    def reset(self) -> None:
        """Forget all detections (start a new throw)."""
        self._t: list = []
        self._p: list = []

    def add(self, t: float, p_base) -> None:
        """Add one detection.

        Parameters
        ----------
        t : float
            Detection time, seconds.
        p_base : array_like, shape (3,)
            Ball centre, metres, base frame (z up).

        Raises
        ------
        ValueError
            If ``p_base`` does not have shape (3,).
        """
        self._t.append(float(t))
        self._p.append(check_array(p_base, "p_base", (3,)))

    def __len__(self) -> int:
        return len(self._t)

    def predict(self):
        """Fit the detections so far and predict the crossing of the working plane.

        Returns
        -------
        t_cross : float or None
            Absolute crossing time, seconds (None with fewer than two
            detections or when the ball does not reach the plane).
        p_base : ndarray, shape (3,) or None
            Crossing point, metres, base frame.
        """
        if len(self._t) < 2:
            return None, None
        p0, v0 = fit_ballistic(self._t, np.array(self._p), gravity_m_s2=self.gravity_m_s2)
        dt, p = ballistic_crossing(p0, v0, self.normal, gravity_m_s2=self.gravity_m_s2)
        if dt is None:
            return None, None
        return self._t[-1] + dt, p
