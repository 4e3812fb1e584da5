"""Motor-current model of the damped arm and its identification (section 10.1).

The motor torque balance (3.1.1) with Zeng's friction model (3.1.3) and the
rigid-arm load torque (10.1.1) is linear in its parameters, so the winding
currents ``i_M = [i_M2, i_M3]`` of joints 2 and 3 (joint 1 at rest) follow the
linear regression (10.1.2)::

    i_M = Y_i(theta, dtheta, ddtheta) chi_i

Each output row ``j`` (joint 2, joint 3) has its own parameters on::

    [phi, m phi, f_j]

where ``phi`` is the 16-column regressor of the strain model
(:func:`tudorvision.joint.strain_dynamics.regressor`: the same mathematical
structure, seed section 10.2), ``m`` the payload mass (the rigid-body
parameters are affine in it) and ``f_j`` the friction columns of joint ``j``
(:func:`friction_regressor`)::

    f = [max(v, 0), min(v, 0), sign(v)]

whose coefficients are, in amperes, the viscous ``k_v+``, ``k_v-`` and the mean
Coulomb magnitude ``k_c = (k_c+ + k_c-) / 2`` of (3.1.3) referred to the
winding current (Coulomb friction opposes the motion). The asymmetric part
``(k_c+ - k_c-) / 2`` is a constant current while the joint moves and is not
separable from the constant column of ``phi`` (with both one-sided steps as
columns the regressor is rank deficient: ``1[v > 0] + 1[v < 0] = 1``); the
seed resolves the same dependency by its numerical base-parameter reduction
(section 10.1). The rotor and gear inertia add to the constant inertia
columns of ``phi``. Friction does not depend on the payload.

At rest ``v`` is the differentiated encoder signal, whose sign flips with
the quantisation noise: the Coulomb column then switches between ``+k_c``
and ``-k_c``, the chattering of the analytical current model the seed
describes (section 10.5, figure 10.4).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array
from .strain_dynamics import N_PARAMS, regressor_payload

__all__ = ["N_FRICTION", "N_CURRENT_PARAMS", "friction_regressor", "current_regressor", "MotorCurrentModel",
           "fit_motor_current", "CurrentFitReport", "current_fit_report"]

#: Friction columns per joint (viscous +, viscous -, Coulomb).
N_FRICTION = 3
#: Parameters per output row: payload-affine rigid part plus the joint's friction.
N_CURRENT_PARAMS = 2 * N_PARAMS + N_FRICTION


def friction_regressor(dtheta_j) -> np.ndarray:
    """Friction columns of Zeng's model (3.1.3) for one joint.

    Parameters
    ----------
    dtheta_j : array_like, shape (N,)
        Joint velocity, rad/s.

    Returns
    -------
    F : ndarray, shape (N, 3)
        ``[max(v, 0), min(v, 0), sign(v)]``: the coefficients are ``k_v+``, ``k_v-``
        and the mean Coulomb magnitude ``k_c`` (opposing the motion).

    Examples
    --------
    >>> friction_regressor([0.5, -0.2, 0.0]).tolist()
    [[0.5, 0.0, 1.0], [0.0, -0.2, -1.0], [0.0, 0.0, 0.0]]
    """
    v = check_array(dtheta_j, "dtheta_j", (None,))
    return np.stack([np.maximum(v, 0.0), np.minimum(v, 0.0), np.sign(v)], axis=1)


def current_regressor(theta, dtheta, ddtheta, payload_kg) -> np.ndarray:
    """Per-row regressor ``Y_i`` of (10.1.2) for joints 2 and 3.

    Parameters
    ----------
    theta, dtheta, ddtheta : array_like, shape (N, 3)
        Joint angles (rad), velocities (rad/s), accelerations (rad/s^2); joint 1 is ignored.
    payload_kg : float or array_like, shape (N,)
        Payload mass, kg.

    Returns
    -------
    Y : ndarray, shape (2, N, 35)
        ``Y[0]`` for the joint-2 current, ``Y[1]`` for joint 3: ``[phi, m phi, f_j]``.
    """
    Yp = regressor_payload(theta, dtheta, ddtheta, payload_kg)
    d = np.asarray(dtheta, dtype=np.float64)
    return np.stack([np.hstack([Yp, friction_regressor(d[:, j])]) for j in (1, 2)])


@dataclass(frozen=True, kw_only=True)
class MotorCurrentModel:
    """Identified motor-current model (10.1.2) of joints 2 and 3 (payload-affine, with friction).

    Attributes
    ----------
    chi : ndarray, shape (2, 35)
        Parameters per output (joint-2, joint-3 current) on :func:`current_regressor`;
        columns 32-34 are the friction coefficients ``k_v+, k_v-`` (A s/rad) and
        ``k_c`` (A) referred to the winding current.
    """

    chi: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "chi", check_array(self.chi, "chi", (2, N_CURRENT_PARAMS)))

    def predict(self, theta, dtheta, ddtheta, payload_kg) -> np.ndarray:
        """Predicted winding currents of joints 2 and 3.

        Parameters
        ----------
        theta, dtheta, ddtheta : array_like, shape (N, 3)
            Joint angles (rad), velocities (rad/s), accelerations (rad/s^2).
        payload_kg : float or array_like, shape (N,)
            Payload mass, kg.

        Returns
        -------
        i_M : ndarray, shape (N, 2)
            Currents, A.
        """
        Y = current_regressor(theta, dtheta, ddtheta, payload_kg)
        return np.stack([Y[j] @ self.chi[j] for j in range(2)], axis=1)

    def friction(self) -> np.ndarray:
        """Friction coefficients per joint: ``k_v+, k_v-`` (A s/rad), ``k_c`` (A).

        Returns
        -------
        ndarray, shape (2, 3)
            Rows joint 2, joint 3.
        """
        return self.chi[:, 2 * N_PARAMS:].copy()


def fit_motor_current(theta, dtheta, ddtheta, i_M, payload_kg) -> MotorCurrentModel:
    """Linear least squares of (10.1.2), one row per joint, on stacked data from several payloads.

    The columns are scaled to unit norm; the minimum-norm solution covers
    columns without excitation (a missing payload level, the base-parameter
    reduction of the seed's numerical approach).

    Parameters
    ----------
    theta, dtheta, ddtheta : array_like, shape (N, 3)
        Joint angles (rad), velocities (rad/s), accelerations (rad/s^2).
    i_M : array_like, shape (N, 2)
        Measured currents of joints 2 and 3, A.
    payload_kg : float or array_like, shape (N,)
        Payload mass per sample, kg.

    Returns
    -------
    MotorCurrentModel

    Raises
    ------
    ValueError
        On shape mismatch or fewer samples than parameters.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> th = np.c_[np.zeros(400), rng.uniform(0, 3, (400, 2))]
    >>> d, dd = rng.normal(0, 1, (400, 3)), rng.normal(0, 3, (400, 3))
    >>> m = np.repeat([0.0, 0.4], 200)
    >>> true = MotorCurrentModel(chi=rng.normal(0, 0.1, (2, 35)))
    >>> fit = fit_motor_current(th, d, dd, true.predict(th, d, dd, m), m)
    >>> bool(np.allclose(fit.chi, true.chi))
    True
    """
    Y = current_regressor(theta, dtheta, ddtheta, payload_kg)
    n = Y.shape[1]
    cur = check_array(i_M, "i_M", (n, 2))
    if n < N_CURRENT_PARAMS:
        raise ValueError(f"theta: expected at least {N_CURRENT_PARAMS} samples, got {n}")
    chi = np.empty((2, N_CURRENT_PARAMS))
    for j in range(2):
        s = np.linalg.norm(Y[j], axis=0)
        s[s == 0] = 1.0
        sol, *_ = np.linalg.lstsq(Y[j] / s, cur[:, j], rcond=None)
        chi[j] = sol / s
    return MotorCurrentModel(chi=chi)


@dataclass(frozen=True, kw_only=True)
class CurrentFitReport:
    """Goodness of fit (B.4.2, %), RMSE and error std (A) per joint (2, 3)."""

    fit_pct: tuple
    rmse: tuple
    sigma: tuple
    n_samples: int


def current_fit_report(model: MotorCurrentModel, theta, dtheta, ddtheta, i_M, payload_kg) -> CurrentFitReport:
    """Table 10.1 metrics of a current model on data.

    Parameters
    ----------
    model : MotorCurrentModel
    theta, dtheta, ddtheta : array_like, shape (N, 3)
        Joint angles (rad), velocities (rad/s), accelerations (rad/s^2).
    i_M : array_like, shape (N, 2)
        Measured currents, A.
    payload_kg : float or array_like, shape (N,)
        Payload mass, kg.

    Returns
    -------
    CurrentFitReport
    """
    from .metrics import goodness_of_fit
    cur = np.asarray(i_M, dtype=np.float64)
    pred = model.predict(theta, dtheta, ddtheta, payload_kg)
    err = cur - pred
    return CurrentFitReport(fit_pct=tuple(goodness_of_fit(pred[:, j], cur[:, j]) for j in range(2)),
                            rmse=tuple(float(np.sqrt(np.mean(err[:, j] ** 2))) for j in range(2)),
                            sigma=tuple(float(np.std(err[:, j])) for j in range(2)), n_samples=int(cur.shape[0]))
