"""Strain-referred damped dynamics of the elastic arm and its identification (sections 10.2.7, 10.2.8).

Strain-referred damped dynamics (10.2.7, 10.2.8)
-------------------------------------------------
The root strains ``eps = [eps_21, eps_31]`` of links 2 and 3 (gauge channels
0 and 2) behave like load-side joint torques (10.2.6), so with joint 1 at
rest they follow the rigid-arm structure::

    eps = I_eps(theta) ddtheta + C_eps(theta, dtheta) dtheta + g_eps(theta)

over ``q = (theta2, theta3)``. Each output row ``i`` has its own parameters on
the regressor (:func:`regressor`)::

    phi = [dd2, dd3, c3 dd2, c3 dd3, s3 d2^2, s3 d2 d3, s3 d3^2, c2, s2, c23, s23, 1,
           c2 s23, c23 s23, c2 s2, c23 s2]

(``c3 = cos theta3`` etc.): row ``i`` of ``I_eps`` is
``[chi0 + chi2 c3, chi1 + chi3 c3]``, the velocity terms are the Coriolis and
centrifugal part and the rest is ``g_eps`` with a gauge offset; the last four
products are first-order corrections of gravity for the static deflection
(the link-2 tip slope and sag move link 3 and the payload, both proportional
to the gravity loads). Rigid-body
parameters are affine in the payload mass, so the identified model is
``chi(m) = chi_0 + m chi_1`` (regressor ``[phi, m phi]``), fitted by linear
least squares on APRBS stimuli with several payloads; the payload mass is
known to the layer when the residual runs (e.g. from the estimator of 9.2).

The collision monitor (:mod:`tudorvision.joint.collision`) and the model-assisted damper
(:mod:`tudorvision.joint.damping`) evaluate this model along the measured motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_array

__all__ = ["N_PARAMS", "regressor", "regressor_payload", "StrainDynamicsModel", "fit_strain_dynamics",
           "FitReport", "fit_report", "derivatives", "aprbs"]

N_PARAMS = 16


def regressor(theta, dtheta, ddtheta) -> np.ndarray:
    """Per-row regressor ``phi(theta, dtheta, ddtheta)`` of the strain dynamics.

    Parameters
    ----------
    theta, dtheta, ddtheta : array_like, shape (N, 3)
        Joint angles (rad), velocities (rad/s), accelerations (rad/s^2);
        joint 1 is ignored (held at rest).

    Returns
    -------
    Phi : ndarray, shape (N, 16)

    Examples
    --------
    >>> regressor(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)))[0].tolist()[:12]
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0]
    """
    th = check_array(theta, "theta", (None, 3))
    d = check_array(dtheta, "dtheta", (th.shape[0], 3))
    a = check_array(ddtheta, "ddtheta", (th.shape[0], 3))
    t2, t3 = th[:, 1], th[:, 2]
    c3, s3 = np.cos(t3), np.sin(t3)
    d2, d3 = d[:, 1], d[:, 2]
    c2, s2, c23, s23 = np.cos(t2), np.sin(t2), np.cos(t2 + t3), np.sin(t2 + t3)
    return np.stack([a[:, 1], a[:, 2], c3 * a[:, 1], c3 * a[:, 2], s3 * d2 * d2, s3 * d2 * d3, s3 * d3 * d3,
                     c2, s2, c23, s23, np.ones_like(t2), c2 * s23, c23 * s23, c2 * s2, c23 * s2], axis=1)


def regressor_payload(theta, dtheta, ddtheta, payload_kg) -> np.ndarray:
    """Payload-affine regressor ``[phi, m phi]``, shape (N, 32).

    ``payload_kg`` is a float or an array of shape (N,).
    """
    phi = regressor(theta, dtheta, ddtheta)
    m = np.broadcast_to(np.asarray(payload_kg, dtype=np.float64), (phi.shape[0],))
    return np.hstack([phi, m[:, None] * phi])


@dataclass(frozen=True, kw_only=True)
class StrainDynamicsModel:
    """Identified strain-referred dynamics (payload-affine).

    Attributes
    ----------
    chi : ndarray, shape (2, 32)
        Parameters per output (link-2 root, link-3 root strain) on
        :func:`regressor_payload`.
    """

    chi: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "chi", check_array(self.chi, "chi", (2, 2 * N_PARAMS)))

    def at_payload(self, payload_kg: float) -> np.ndarray:
        """Parameters at one payload mass, shape (2, 16).

        Parameters
        ----------
        payload_kg : float
            Payload mass, kg.

        Returns
        -------
        chi_m : ndarray, shape (2, 16)
            Parameters per output on :func:`regressor` (link-2, link-3 root strain).
        """
        return self.chi[:, :N_PARAMS] + float(payload_kg) * self.chi[:, N_PARAMS:]

    def predict(self, theta, dtheta, ddtheta, payload_kg) -> np.ndarray:
        """Predicted root strains, shape (N, 2), m/m.

        Parameters
        ----------
        theta : array_like, shape (N, 3)
            Joint angles, rad.
        dtheta : array_like, shape (N, 3)
            Joint velocities, rad/s.
        ddtheta : array_like, shape (N, 3)
            Joint accelerations, rad/s^2.
        payload_kg : float or array_like, shape (N,)
            Payload mass, kg.

        Returns
        -------
        eps : ndarray, shape (N, 2)
            Predicted link-2 and link-3 root strains, m/m.

        Raises
        ------
        ValueError
            If the shapes do not match.
        """
        return regressor_payload(theta, dtheta, ddtheta, payload_kg) @ self.chi.T

    def predict_one(self, theta, dtheta, ddtheta, payload_kg: float) -> np.ndarray:
        """:meth:`predict` for one sample, bit for bit, without its checks (the layer's 2 kHz path).

        Parameters
        ----------
        theta, dtheta, ddtheta : sequence of 3 floats
            Joint angles (rad), velocities (rad/s), accelerations (rad/s^2); joint 1 is ignored.
        payload_kg : float
            Payload mass, kg.

        Returns
        -------
        eps : ndarray, shape (2,)
            Predicted link-2 and link-3 root strains, m/m.

        Raises
        ------
        ValueError
            If an angle, velocity or acceleration of joints 2, 3 is not finite (as :meth:`predict`).
        """
        t2, t3 = float(theta[1]), float(theta[2])
        if not math.isfinite(t2 + t3 + float(dtheta[1]) + float(dtheta[2]) + float(ddtheta[1]) + float(ddtheta[2])):
            raise ValueError("theta, dtheta, ddtheta: contain NaN or infinite values")
        angles = np.array([t3, t2, t2 + t3])
        c3, c2, c23 = np.cos(angles)
        s3, s2, s23 = np.sin(angles)
        d2, d3 = np.float64(dtheta[1]), np.float64(dtheta[2])
        a2, a3 = np.float64(ddtheta[1]), np.float64(ddtheta[2])
        phi = np.array([a2, a3, c3 * a2, c3 * a3, s3 * d2 * d2, s3 * d2 * d3, s3 * d3 * d3,
                        c2, s2, c23, s23, 1.0, c2 * s23, c23 * s23, c2 * s2, c23 * s2])
        row = np.concatenate([phi, np.float64(payload_kg) * phi]).reshape(1, 2 * N_PARAMS)
        return (row @ self.chi.T).reshape(2)

    @staticmethod
    def terms(chi_m: np.ndarray, theta3: float, theta2: float, d2: float, d3: float):
        """``I_eps`` (2x2), ``dI_eps/dtheta3`` (2x2), Coriolis ``C_eps dtheta`` (2,), ``g_eps`` (2,).

        Parameters
        ----------
        chi_m : ndarray, shape (2, 16)
            Parameters at one payload (:meth:`at_payload`).
        theta3, theta2 : float
            Joint 3 and joint 2 angles, rad.
        d2, d3 : float
            Joint 2 and joint 3 velocities, rad/s.

        Returns
        -------
        I : ndarray, shape (2, 2)
            Strain-referred inertia ``I_eps``, m/m per rad/s^2.
        dI : ndarray, shape (2, 2)
            Its derivative with respect to ``theta3``.
        cor : ndarray, shape (2,)
            Coriolis and centrifugal term ``C_eps dtheta``, m/m.
        g : ndarray, shape (2,)
            Gravity term ``g_eps``, m/m.
        """
        c3, s3 = math.cos(theta3), math.sin(theta3)
        I = np.empty((2, 2))
        dI = np.empty((2, 2))
        cor = np.empty(2)
        g = np.empty(2)
        c2, s2 = math.cos(theta2), math.sin(theta2)
        c23, s23 = math.cos(theta2 + theta3), math.sin(theta2 + theta3)
        for i in range(2):
            x = chi_m[i]
            I[i, 0], I[i, 1] = x[0] + x[2] * c3, x[1] + x[3] * c3
            dI[i, 0], dI[i, 1] = -x[2] * s3, -x[3] * s3
            cor[i] = s3 * (x[4] * d2 * d2 + x[5] * d2 * d3 + x[6] * d3 * d3)
            g[i] = (x[7] * c2 + x[8] * s2 + x[9] * c23 + x[10] * s23 + x[11] + x[12] * c2 * s23
                    + x[13] * c23 * s23 + x[14] * c2 * s2 + x[15] * c23 * s2)
        return I, dI, cor, g


def fit_strain_dynamics(theta, dtheta, ddtheta, eps, payload_kg) -> StrainDynamicsModel:
    """Linear least squares of (10.2.8) on stacked data from several payloads.

    Parameters
    ----------
    theta : array_like, shape (N, 3)
        Joint angles, rad.
    dtheta : array_like, shape (N, 3)
        Joint velocities, rad/s.
    ddtheta : array_like, shape (N, 3)
        Joint accelerations, rad/s^2.
    eps : array_like, shape (N, 2)
        Root strains of links 2 and 3, m/m.
    payload_kg : array_like, shape (N,) or float
        Payload mass per sample, kg.

    Returns
    -------
    StrainDynamicsModel
        The fitted payload-affine model.

    Raises
    ------
    ValueError
        On shape mismatch or too few samples.
    """
    Y = regressor_payload(theta, dtheta, ddtheta, payload_kg)
    e = check_array(eps, "eps", (Y.shape[0], 2))
    if Y.shape[0] < Y.shape[1]:
        raise ValueError(f"theta: expected at least {Y.shape[1]} samples, got {Y.shape[0]}")
    # column scaling for conditioning; minimum-norm solution if a payload level is missing
    s = np.linalg.norm(Y, axis=0)
    s[s == 0] = 1.0
    chi, *_ = np.linalg.lstsq(Y / s, e, rcond=None)
    return StrainDynamicsModel(chi=(chi / s[:, None]).T)


@dataclass(frozen=True, kw_only=True)
class FitReport:
    """Goodness of fit (B.4.2) per output, RMSE and error std (m/m)."""

    fit_pct: tuple
    rmse: tuple
    sigma: tuple
    n_samples: int


def fit_report(model: StrainDynamicsModel, theta, dtheta, ddtheta, eps, payload_kg) -> FitReport:
    """Validation metrics of a model on data (table 10.1 style)."""
    from .metrics import goodness_of_fit
    e = np.asarray(eps, dtype=np.float64)
    pred = model.predict(theta, dtheta, ddtheta, payload_kg)
    err = e - pred
    return FitReport(fit_pct=tuple(goodness_of_fit(pred[:, i], e[:, i]) for i in range(2)),
                     rmse=tuple(float(np.sqrt(np.mean(err[:, i] ** 2))) for i in range(2)),
                     sigma=tuple(float(np.std(err[:, i])) for i in range(2)), n_samples=int(e.shape[0]))


def derivatives(t, theta, *, window_s: float = 0.02, polyorder: int = 3):
    """Velocities and accelerations from sampled angles (Savitzky–Golay, zero phase).

    Parameters
    ----------
    t : array_like, shape (N,)
        Uniform sample times, seconds.
    theta : array_like, shape (N, J)

    Returns
    -------
    dtheta, ddtheta : ndarray, shape (N, J)
    """
    from scipy.signal import savgol_filter
    t = check_array(t, "t", (None,))
    th = check_array(theta, "theta", (t.size, None))
    dt = float(t[1] - t[0])
    w = max(polyorder + 2, int(round(window_s / dt)) | 1)
    d = savgol_filter(th, w, polyorder, deriv=1, delta=dt, axis=0)
    dd = savgol_filter(th, w, polyorder, deriv=2, delta=dt, axis=0)
    return d, dd




def aprbs(rng: np.random.Generator, duration_s: float, lo, hi, *, hold_s=(0.6, 2.5)):
    """Amplitude-modulated pseudo-random binary sequence of setpoints (Isermann, p. 174).

    Parameters
    ----------
    rng : numpy.random.Generator
    duration_s : float
    lo, hi : array_like, shape (J,)
        Amplitude range per channel.
    hold_s : (float, float)
        Range of the random hold times, seconds.

    Returns
    -------
    times : ndarray, shape (K,)
        Switching instants from 0.
    levels : ndarray, shape (K, J)
        Setpoint held from each instant.

    Examples
    --------
    >>> t, lv = aprbs(np.random.default_rng(0), 10.0, [0.0], [1.0])
    >>> bool(t[0] == 0.0 and np.all(np.diff(t) > 0) and lv.shape == (t.size, 1))
    True
    """
    lo = np.atleast_1d(np.asarray(lo, float))
    hi = np.atleast_1d(np.asarray(hi, float))
    times, t = [], 0.0
    while t < duration_s:
        times.append(t)
        t += rng.uniform(*hold_s)
    times = np.asarray(times)
    levels = rng.uniform(lo, hi, size=(times.size, lo.size))
    return times, levels
