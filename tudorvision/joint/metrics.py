"""Performance metrics of appendix B.4 and the chapter-8 damping criteria.

All functions take uniformly sampled time series (SI units) and are pure.
Time ``t`` is measured from the start of the experiment (motion start), so the
time weighting of IATE/IATS and the settling times refer to it.
"""
from __future__ import annotations

import numpy as np

from .._checks import check_array

__all__ = ["STRAIN_BAND", "ANGLE_BAND_RAD", "nrmse", "goodness_of_fit", "iate", "iats", "settling_time",
           "max_abs", "spectral_amplitude", "damping_metrics", "normalise_metrics", "METRIC_NAMES"]

#: Strain settling band of B.4, m/m.
STRAIN_BAND = 15e-6
#: Joint angle settling band of B.4 (0.01 deg), rad.
ANGLE_BAND_RAD = float(np.deg2rad(0.01))

METRIC_NAMES = ("max_strain", "strain_settling_s", "spectral_amp", "iats", "joint_settling_s", "iate")


def _series(t, x, name):
    t = check_array(t, "t", (None,))
    x = check_array(x, name, (t.size,))
    if t.size < 2:
        raise ValueError(f"t: expected at least 2 samples, got {t.size}")
    return t, x


def nrmse(x, x_ref) -> float:
    """Normalised root mean squared error (B.4.1), percent.

    ``100 ||x - x_ref|| / ||x_ref - mean(x_ref)||`` (the seed's denominator,
    read as the deviation of the reference from its mean).

    Examples
    --------
    >>> nrmse([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    0.0
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    r = np.asarray(x_ref, dtype=np.float64).ravel()
    if x.shape != r.shape:
        raise ValueError(f"x, x_ref: expected equal shapes, got {x.shape}, {r.shape}")
    den = np.linalg.norm(r - r.mean())
    if den == 0:
        raise ValueError("x_ref: constant reference, NRMSE undefined")
    return float(100.0 * np.linalg.norm(x - r) / den)


def goodness_of_fit(x, x_ref) -> float:
    """Goodness of fit ``100 - NRMSE`` (B.4.2), percent (above 80 % counts as good).

    Examples
    --------
    >>> goodness_of_fit([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])
    100.0
    """
    return 100.0 - nrmse(x, x_ref)


def iate(t, x, x_ref=0.0) -> float:
    """Integral of absolute time-weighted error ``int t |x - x_ref| dt`` (B.4.3), trapezoidal.

    Examples
    --------
    >>> round(iate([0.0, 1.0, 2.0], [1.0, 1.0, 1.0]), 6)
    2.0
    """
    t, x = _series(t, x, "x")
    e = np.abs(x - np.asarray(x_ref, dtype=np.float64))
    y = t * e
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def iats(t, eps) -> float:
    """Integral absolute time-weighted strain surface ``int t |eps| dt`` (B.4.4), (m/m) s^2."""
    return iate(t, eps, 0.0)


def settling_time(t, x, x_ref=0.0, *, band: float, horizon_s: float | None = None) -> float:
    """Time until ``|x - x_ref|`` stays inside ``band`` (B.4), seconds from ``t[0]``.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times, seconds (N >= 2).
    x : array_like, shape (N,)
        Signal, SI units (m/m for strain, rad for joint angles).
    x_ref : float or array_like, shape (N,)
        Reference the signal settles to, same unit as ``x``.
    band : float
        Half-width of the band, same unit as ``x`` (15e-6 for strain,
        0.01 deg in rad for joint angles).
    horizon_s : float, optional
        Cap, seconds (the seed normalises strain settling to a 10 s horizon); default
        the end of the record. A signal that never settles returns the cap.

    Returns
    -------
    float
        Settling time, seconds from ``t[0]`` (0 when always inside the band).

    Raises
    ------
    ValueError
        If ``t`` has fewer than two samples, ``x`` does not match it, or
        ``band`` is not positive.

    Examples
    --------
    >>> settling_time([0, 1, 2, 3], [5.0, 2.0, 0.5, 0.1], band=1.0)
    2.0
    """
    t, x = _series(t, x, "x")
    if not band > 0:
        raise ValueError(f"band: expected > 0, got {band}")
    cap = float(t[-1] - t[0]) if horizon_s is None else float(horizon_s)
    out = np.nonzero(np.abs(x - np.asarray(x_ref, dtype=np.float64)) > band)[0]
    if out.size == 0:
        return 0.0
    k = out[-1]
    if k == t.size - 1:
        return cap
    return float(min(t[k + 1] - t[0], cap))


def max_abs(x) -> float:
    """``max |x|``."""
    return float(np.max(np.abs(np.asarray(x, dtype=np.float64))))


def spectral_amplitude(t, x, freq_hz: float) -> float:
    """Single-sided DFT amplitude of ``x`` at ``freq_hz`` (``|F(omega_1)|`` of chapter 8).

    Examples
    --------
    >>> t = np.arange(2000) * 1e-3
    >>> round(spectral_amplitude(t, 3.0 * np.sin(2 * np.pi * 5.0 * t), 5.0), 6)
    3.0
    """
    t, x = _series(t, x, "x")
    w = 2.0 * np.pi * float(freq_hz)
    return float(2.0 * np.abs(np.mean(x * np.exp(-1j * w * (t - t[0])))))


def damping_metrics(t, eps_tilde, theta, theta_ref, *, theta_goal: float, freq_hz: float,
                    strain_band: float = STRAIN_BAND, angle_band: float = ANGLE_BAND_RAD,
                    horizon_s: float = 10.0) -> dict:
    """The chapter-8 metrics of one run (one strain channel, one joint).

    Parameters
    ----------
    t : array_like, shape (N,)
        Seconds from motion start.
    eps_tilde : array_like, shape (N,)
        Oscillatory strain of the link-2 root gauge, m/m.
    theta, theta_ref : array_like, shape (N,)
        Joint-2 angle and its planned reference, rad.
    theta_goal : float
        Goal angle, rad (for the joint settling time).
    freq_hz : float
        Dominant frequency for the spectral amplitude, Hz.
    strain_band : float, optional
        Strain settling band, m/m (B.4: 15e-6).
    angle_band : float, optional
        Joint angle settling band, rad (B.4: 0.01 deg).
    horizon_s : float, optional
        Cap of the strain settling time, seconds.

    Returns
    -------
    dict
        ``max_strain`` (m/m), ``strain_settling_s``, ``spectral_amp`` (m/m),
        ``iats`` ((m/m) s^2), ``joint_settling_s``, ``iate`` (rad s^2) and
        ``final_joint_error_rad``.

    Raises
    ------
    ValueError
        If ``t`` has fewer than two samples or a series does not match it.
    """
    t, e = _series(t, eps_tilde, "eps_tilde")
    _, th = _series(t, theta, "theta")
    _, thr = _series(t, theta_ref, "theta_ref")
    return {
        "max_strain": max_abs(e),
        "strain_settling_s": settling_time(t, e, band=strain_band, horizon_s=horizon_s),
        "spectral_amp": spectral_amplitude(t, e, freq_hz),
        "iats": iats(t, e),
        "joint_settling_s": settling_time(t, th, theta_goal, band=angle_band),
        "iate": iate(t, th, thr),
        "final_joint_error_rad": float(th[-1] - theta_goal),
    }


def normalise_metrics(damped: dict, undamped: dict, *, horizon_s: float = 10.0) -> dict:
    """Metrics in percent of the undamped case (chapter 8).

    The strain settling time is normalised by the fixed horizon (the seed:
    undamped oscillations last minutes, so 10 s stands for 100 %); the
    others by the undamped value.

    Examples
    --------
    >>> u = dict(max_strain=2.0, strain_settling_s=10.0, spectral_amp=1.0, iats=4.0,
    ...          joint_settling_s=2.0, iate=1.0)
    >>> d = dict(max_strain=1.0, strain_settling_s=2.0, spectral_amp=0.1, iats=1.0,
    ...          joint_settling_s=2.0, iate=1.0)
    >>> normalise_metrics(d, u)["strain_settling_s"]
    20.0
    """
    out = {}
    for k in METRIC_NAMES:
        den = horizon_s if k == "strain_settling_s" else undamped[k]
        out[k] = float(100.0 * damped[k] / den) if den else float("nan")
    return out
