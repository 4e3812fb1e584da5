"""Flight model of a thrown ball: gravity and quadratic drag, RK4 propagation with its exact Jacobian.

State layout (base frame, SI units)::

    x = [x, y, z, vx, vy, vz]      metres, metres per second

Process model (continuous time), ``g = [0, 0, -9.81]`` m/s^2 and the drag
coefficient ``k`` in 1/m (the lab's soft 9 cm ball: ``k = 0.012``)::

    dp/dt = v
    dv/dt = g - k |v| v

It is integrated with RK4 over ``dt`` (sub-stepped at ``max_step_s``), and the
state-transition Jacobian ``F = d x(t+dt) / d x(t)`` is integrated alongside
(variational equation), so ``F`` is exact for the discretised model.

The filter built on it is :mod:`tudorvision.catch.ekf`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_array

__all__ = ["DEFAULT_DRAG_K_PER_M", "BallModel", "check_ball_state", "ball_dynamics", "dynamics_jacobian",
           "propagate", "propagate_state"]

#: Drag coefficient of the lab's soft 9 cm ball in ``a = g - k |v| v``, 1/m.
DEFAULT_DRAG_K_PER_M = 0.012


@dataclass(frozen=True, kw_only=True)
class BallModel:
    """Flight model: gravity and quadratic drag ``a = g - k |v| v``.

    Attributes
    ----------
    drag_k_per_m : float
        Drag coefficient ``k``, 1/m (0: drag-free parabola).
    gravity_m_s2 : float
        Gravity magnitude along ``-z`` of the filter frame (base z up).
    max_step_s : float
        Largest RK4 sub-step.
    """

    drag_k_per_m: float = DEFAULT_DRAG_K_PER_M
    gravity_m_s2: float = 9.81
    max_step_s: float = 0.025

    def __post_init__(self):
        if not self.drag_k_per_m >= 0:
            raise ValueError(f"drag_k_per_m: expected >= 0, got {self.drag_k_per_m}")
        if not self.max_step_s > 0:
            raise ValueError(f"max_step_s: expected > 0, got {self.max_step_s}")


def check_ball_state(x) -> np.ndarray:
    return check_array(x, "x", (6,))


def ball_dynamics(x, model: BallModel = BallModel()) -> np.ndarray:
    """Time derivative of the state, ``[v, g - k |v| v]``.

    Parameters
    ----------
    x : array_like, shape (6,)
        ``[x, y, z, vx, vy, vz]``, metres and m/s.

    Returns
    -------
    dx : ndarray, shape (6,)

    Examples
    --------
    >>> (ball_dynamics([0, 0, 1, 0, 0, 0]) + 0.0).tolist()
    [0.0, 0.0, 0.0, 0.0, 0.0, -9.81]
    """
    x = check_ball_state(x)
    return _f(x, model.drag_k_per_m, model.gravity_m_s2)


def _f(x, k, g):
    v = x[3:]
    a = -k * np.sqrt(v @ v) * v
    a[2] -= g
    return np.concatenate([v, a])


def _A(x, k):
    v = x[3:]
    s = np.sqrt(v @ v)
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    if s > 0:
        A[3:6, 3:6] = -k * (s * np.eye(3) + np.outer(v, v) / s)
    return A


def dynamics_jacobian(x, model: BallModel = BallModel()) -> np.ndarray:
    """Jacobian ``d f / d x`` of :func:`ball_dynamics`, shape (6, 6).

    The velocity block is ``-k (|v| I + v v^T / |v|)``.

    Examples
    --------
    >>> A = dynamics_jacobian([0, 0, 0, 3.0, 0, 0], BallModel(drag_k_per_m=0.01))
    >>> round(float(A[3, 3]), 3)
    -0.06
    """
    return _A(check_ball_state(x), model.drag_k_per_m)


def propagate(x, dt: float, model: BallModel = BallModel(), *, jacobian: bool = True):
    """Integrate the flight over ``dt`` seconds (RK4, sub-stepped); optionally with ``F``.

    Parameters
    ----------
    x : array_like, shape (6,)
        State ``[x, y, z, vx, vy, vz]``, metres and m/s, filter frame.
    dt : float
        Seconds (may be negative: backwards in time).
    model : BallModel, optional
        Gravity, drag coefficient and integration step.
    jacobian : bool, optional
        Also integrate the state-transition Jacobian ``F``.

    Returns
    -------
    x_new : ndarray, shape (6,)
    F : ndarray, shape (6, 6)
        ``d x_new / d x`` (only when ``jacobian``).

    Examples
    --------
    >>> x1, F = propagate([0, 0, 0, 1.0, 0, 0], 1.0, BallModel(drag_k_per_m=0.0))
    >>> np.round(x1, 4).tolist()
    [1.0, 0.0, -4.905, 1.0, 0.0, -9.81]
    """
    x = check_ball_state(x)
    if jacobian:
        n, h = _substeps(float(dt), model)
        return _propagate_floats_jac(x, n, h, model.drag_k_per_m, model.gravity_m_s2)
    return propagate_state(x, float(dt), model)


def _substeps(dt: float, model: BallModel):
    """RK4 sub-steps for ``dt``: their number and length (at most ``model.max_step_s`` each)."""
    n = max(1, int(math.ceil(abs(dt) / model.max_step_s)))
    return n, dt / n


def propagate_state(x, dt: float, model: BallModel) -> np.ndarray:
    """:func:`propagate` without Jacobian and without the argument check (for inner loops).

    Parameters
    ----------
    x : ndarray, shape (6,)
        State ``[x, y, z, vx, vy, vz]`` (m, m/s), already checked.
    dt : float
        Prediction horizon, s.
    model : BallModel

    Returns
    -------
    ndarray, shape (6,)
        The state after ``dt``.
    """
    n, h = _substeps(dt, model)
    return _propagate_floats(x, n, h, model.drag_k_per_m, model.gravity_m_s2)


def _propagate_reference(x, dt, model):
    # RK4 on the augmented system (x, Phi) with dPhi/dt = A(x) Phi on 6x6 numpy arrays: the
    # plain form of _propagate_floats_jac, kept as its test oracle
    x = check_ball_state(x).copy()
    k, g = model.drag_k_per_m, model.gravity_m_s2
    n, h = _substeps(float(dt), model)
    F = np.eye(6)
    for _ in range(n):
        k1 = _f(x, k, g); K1 = _A(x, k) @ F
        x2 = x + h / 2 * k1; k2 = _f(x2, k, g); K2 = _A(x2, k) @ (F + h / 2 * K1)
        x3 = x + h / 2 * k2; k3 = _f(x3, k, g); K3 = _A(x3, k) @ (F + h / 2 * K2)
        x4 = x + h * k3; k4 = _f(x4, k, g); K4 = _A(x4, k) @ (F + h * K3)
        F = F + h / 6 * (K1 + 2 * K2 + 2 * K3 + K4)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x, F


def _propagate_floats_jac(x, n, h, k, g):
    # The same RK4 as _propagate_reference, on Python floats. The flight does not depend on the
    # position, so F = [[I, Pp], [0, Pv]] and only the two 3x3 blocks Pp = dp/dv0, Pv = dv/dv0
    # are integrated: dPp/dt = Pv, dPv/dt = Av(v) Pv with Av = -k (s I + v v^T / s), s = |v|.
    px, py, pz, vx, vy, vz = (float(a) for a in x)
    sqrt = math.sqrt
    Pv = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]      # row-major 3x3
    Pp = [0.0] * 9

    def acc(ux, uy, uz):
        s = k * sqrt(ux * ux + uy * uy + uz * uz)
        return -s * ux, -s * uy, -s * uz - g

    def av_times(ux, uy, uz, M):
        s = sqrt(ux * ux + uy * uy + uz * uz)
        if s == 0.0 or k == 0.0:
            return [0.0] * 9
        w0 = ux * M[0] + uy * M[3] + uz * M[6]
        w1 = ux * M[1] + uy * M[4] + uz * M[7]
        w2 = ux * M[2] + uy * M[5] + uz * M[8]
        c, d = -k * s, -k / s
        return [c * M[0] + d * ux * w0, c * M[1] + d * ux * w1, c * M[2] + d * ux * w2,
                c * M[3] + d * uy * w0, c * M[4] + d * uy * w1, c * M[5] + d * uy * w2,
                c * M[6] + d * uz * w0, c * M[7] + d * uz * w1, c * M[8] + d * uz * w2]

    h2, h6 = h / 2, h / 6
    for _ in range(n):
        a1 = acc(vx, vy, vz); K1 = av_times(vx, vy, vz, Pv)
        b = (vx + h2 * a1[0], vy + h2 * a1[1], vz + h2 * a1[2])
        M2 = [m + h2 * q for m, q in zip(Pv, K1)]
        a2 = acc(*b); K2 = av_times(*b, M2)
        c = (vx + h2 * a2[0], vy + h2 * a2[1], vz + h2 * a2[2])
        M3 = [m + h2 * q for m, q in zip(Pv, K2)]
        a3 = acc(*c); K3 = av_times(*c, M3)
        d = (vx + h * a3[0], vy + h * a3[1], vz + h * a3[2])
        M4 = [m + h * q for m, q in zip(Pv, K3)]
        a4 = acc(*d); K4 = av_times(*d, M4)
        px += h6 * (vx + 2 * b[0] + 2 * c[0] + d[0])
        py += h6 * (vy + 2 * b[1] + 2 * c[1] + d[1])
        pz += h6 * (vz + 2 * b[2] + 2 * c[2] + d[2])
        vx += h6 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0])
        vy += h6 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1])
        vz += h6 * (a1[2] + 2 * a2[2] + 2 * a3[2] + a4[2])
        Pp = [pp + h6 * (m1 + 2 * m2 + 2 * m3 + m4) for pp, m1, m2, m3, m4 in zip(Pp, Pv, M2, M3, M4)]
        Pv = [m + h6 * (q1 + 2 * q2 + 2 * q3 + q4) for m, q1, q2, q3, q4 in zip(Pv, K1, K2, K3, K4)]
    F = np.eye(6)
    F[0:3, 3:6] = np.reshape(Pp, (3, 3))
    F[3:6, 3:6] = np.reshape(Pv, (3, 3))
    return np.array([px, py, pz, vx, vy, vz]), F


def _propagate_floats(x, n, h, k, g):
    # the same RK4 on Python floats (no Jacobian): about ten times faster for 6 states
    px, py, pz, vx, vy, vz = (float(a) for a in x)
    sqrt = math.sqrt

    def acc(ux, uy, uz):
        s = k * sqrt(ux * ux + uy * uy + uz * uz)
        return -s * ux, -s * uy, -s * uz - g

    h2, h6 = h / 2, h / 6
    for _ in range(n):
        a1 = acc(vx, vy, vz)
        b = (vx + h2 * a1[0], vy + h2 * a1[1], vz + h2 * a1[2]); a2 = acc(*b)
        c = (vx + h2 * a2[0], vy + h2 * a2[1], vz + h2 * a2[2]); a3 = acc(*c)
        d = (vx + h * a3[0], vy + h * a3[1], vz + h * a3[2]); a4 = acc(*d)
        px += h6 * (vx + 2 * b[0] + 2 * c[0] + d[0])
        py += h6 * (vy + 2 * b[1] + 2 * c[1] + d[1])
        pz += h6 * (vz + 2 * b[2] + 2 * c[2] + d[2])
        vx += h6 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0])
        vy += h6 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1])
        vz += h6 * (a1[2] + 2 * a2[2] + 2 * a3[2] + a4[2])
    return np.array([px, py, pz, vx, vy, vz])
