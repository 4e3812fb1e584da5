"""Oscillation damping of the joint-control layer (sections 2.2, 5.2, 6.5, 7.5).

Static strain cancellation (section 2.2)
-----------------------------------------
The static (gravity) part of a strain signal is estimated by a moving-average
FIR ``M(z) = (1/N) sum_{i<N} z^-i`` applied twice with trend correction
(double moving average, "second order smoothing" of figure 2.2)::

    mu_hat = (2 M - M^2) eps,        eps_tilde = eps - mu_hat = (1 - M)^2 eps

so the high-pass ``(1 - M)^2`` has a double zero at DC: a constant *and* a
ramp in the static strain are removed after the transient (40 dB/decade edge,
as in figure 2.3). The seed uses ``N = 50`` at 100 Hz (a 0.5 s window). Here
the filter runs at the 2 kHz control rate with the equivalent window
``N = 1000`` by default; ``decimation = 20`` with ``N = 50`` reproduces the
100 Hz filter exactly (new input every 20th sample, output held).

Damping laws (per joint, joint 2 fed by the link-2 root gauge, joint 3 by the
link-3 root gauge; joint 1 has no gauge in the bending plane: gain 0)
----------------------------------------------------------------------------
* proportional (5.2.1), at the velocity-loop input: ``theta_dot_e = -k eps_tilde``;
* integral (6.5.3), at the position-loop input with the PD gain halved:
  ``theta_e = -(k / s) eps_tilde``;
* half-integrator (7.4.14), at the position-loop input:
  ``theta_e = -k P55(s) eps_tilde`` with the shifted Padé approximant of
  ``1 / sqrt(s)`` (7.5.1), discretised by the bilinear (Tustin) transform.

The tuned gains per plant, their payload schedules and the position-loop scale a
law needs on a plant (``PD_SCALES``: the proportional law on the soft plant runs
with ``k_PD`` scaled by 0.01, see there) are in
:mod:`tudorvision.joint.damping_gains` (re-exported here).

Signs follow the plant's strain convention (top surface, tension positive;
deflection toward increasing joint angle): positive gains damp. Units: ``k``
in rad/s per (m/m) for the proportional and integral laws, rad s^-1/2 per
(m/m) for the half-integrator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from .._checks import check_array, check_mass

from .iir_filter import ExponentialStrainFilter
from .damping_gains import (ASSISTED_GAINS, DEFAULT_GAINS, GAIN_SETS, LAWS, ONE_WAY_GAINS, PAYLOAD_SCHEDULE,
                            PAYLOAD_SCHEDULES, PD_SCALES, SOFT_GAINS, TWO_WAY_GAINS, payload_gain_factor,
                            pd_scale_of)

__all__ = ["LAWS", "moving_average_fir", "static_strain_fir", "highpass_response", "StaticStrainFilter",
           "proportional_feedback", "pade_p55", "half_integrator_sos", "SosFilter", "DampingConfig",
           "StrainDamper", "default_damping_config", "GAUGE_OF_JOINT", "ONE_WAY_GAINS", "TWO_WAY_GAINS",
           "SOFT_GAINS", "GAIN_SETS", "DEFAULT_GAINS", "ASSISTED_GAINS", "PAYLOAD_SCHEDULE", "PAYLOAD_SCHEDULES",
           "PD_SCALES", "payload_gain_factor", "pd_scale_of"]

#: Strain channel feeding each joint's damping law (None: no gauge in the bending plane).
GAUGE_OF_JOINT = (None, 0, 2)


# ----------------------------------------------------------------- static strain cancellation
def moving_average_fir(n_window: int) -> np.ndarray:
    """Coefficients of the equally weighted moving average (2.2.2).

    Parameters
    ----------
    n_window : int
        Number of averaged samples ``N >= 1``.

    Returns
    -------
    b : ndarray, shape (N,)

    Raises
    ------
    ValueError
        If ``n_window < 1``.

    Examples
    --------
    >>> moving_average_fir(4).tolist()
    [0.25, 0.25, 0.25, 0.25]
    """
    n = int(n_window)
    if n < 1:
        raise ValueError(f"n_window: expected >= 1, got {n_window}")
    return np.full(n, 1.0 / n)


def static_strain_fir(n_window: int) -> np.ndarray:
    """FIR of the static strain estimate ``mu_hat = (2 M - M^2) eps``.

    Returns
    -------
    b : ndarray, shape (2 N - 1,)
        Coefficients; they sum to 1 (unit DC gain) and their first moment is
        0 (no lag on a ramp).

    Examples
    --------
    >>> b = static_strain_fir(50)
    >>> round(float(b.sum()), 12), round(float(np.arange(b.size) @ b), 9)
    (1.0, 0.0)
    """
    m = moving_average_fir(n_window)
    b = -np.convolve(m, m)
    b[:m.size] += 2.0 * m
    return b


def highpass_response(freq_hz, n_window: int, fs_hz: float) -> np.ndarray:
    """Analytic frequency response of ``eps_tilde / eps = (1 - M)^2``.

    Parameters
    ----------
    freq_hz : array_like, shape (K,)
        Frequencies, Hz (below Nyquist).
    n_window : int
    fs_hz : float
        Sampling rate of the filter, Hz.

    Returns
    -------
    H : ndarray of complex, shape (K,)

    Examples
    --------
    >>> H = highpass_response([0.0, 2.0], 50, 100.0)
    >>> float(round(abs(H[0]), 12)), float(round(abs(H[1]), 12))   # 2 Hz: one period fills the window
    (0.0, 1.0)
    """
    f = np.atleast_1d(np.asarray(freq_hz, dtype=np.float64))
    n = int(n_window)
    w = 2.0 * np.pi * f / float(fs_hz)
    z1 = np.exp(-1j * w)
    with np.errstate(invalid="ignore", divide="ignore"):
        M = np.where(np.abs(w) < 1e-12, 1.0 + 0j, (1.0 - z1**n) / (n * (1.0 - z1)))
    return (1.0 - M) ** 2


class StaticStrainFilter:
    """Running static strain estimate and mean-liberated strain (section 2.2).

    State: two ring buffers of length ``N`` per channel (the input of each
    moving average) and their running sums.

    Parameters
    ----------
    eps0 : array_like, shape (C,)
        Initial strain (the buffers start filled with it: a static start).
    n_window : int
        ``N``, samples per moving average (1000 = 0.5 s at 2 kHz).
    decimation : int
        The filter takes a new input every ``decimation`` calls and holds its
        estimate in between (``N = 50, decimation = 20`` at 2 kHz is the
        seed's 100 Hz filter).

    Examples
    --------
    >>> f = StaticStrainFilter([1e-4], n_window=10)
    >>> mu, et = f.step([1e-4])
    >>> float(et[0])
    0.0
    """

    def __init__(self, eps0, *, n_window: int = 1000, decimation: int = 1):
        e0 = check_array(np.atleast_1d(eps0), "eps0", (None,))
        if int(n_window) < 1 or int(decimation) < 1:
            raise ValueError(f"n_window, decimation: expected >= 1, got {n_window}, {decimation}")
        self.n = int(n_window)
        self.decimation = int(decimation)
        self.channels = e0.size
        self.reset(e0)

    def reset(self, eps0) -> None:
        """Fill both averages with ``eps0`` (static state)."""
        e0 = [float(x) for x in np.atleast_1d(eps0)]
        n = self.n
        self._buf1 = [[x] * n for x in e0]
        self._buf2 = [[x] * n for x in e0]
        self._sum1 = [x * n for x in e0]
        self._sum2 = [x * n for x in e0]
        self._i = 0
        self._count = 0
        self.mu = list(e0)

    def step(self, eps):
        """Take one strain sample; return ``(mu_hat, eps_tilde)`` as lists of C floats."""
        if self._count % self.decimation == 0:
            n, i = self.n, self._i
            for c in range(self.channels):
                x = float(eps[c])
                b1, b2 = self._buf1[c], self._buf2[c]
                s1 = self._sum1[c] + x - b1[i]
                b1[i] = x
                m1 = s1 / n
                s2 = self._sum2[c] + m1 - b2[i]
                b2[i] = m1
                self._sum1[c], self._sum2[c] = s1, s2
                self.mu[c] = 2.0 * m1 - s2 / n
            self._i = i + 1 if i + 1 < n else 0
            if self._i == 0:              # refresh the running sums (no float drift)
                self._sum1 = [math.fsum(b) for b in self._buf1]
                self._sum2 = [math.fsum(b) for b in self._buf2]
        self._count += 1
        mu = list(self.mu)
        return mu, [float(eps[c]) - mu[c] for c in range(self.channels)]


# ----------------------------------------------------------------- damping laws
def proportional_feedback(eps_tilde, k_eps) -> np.ndarray:
    """Proportional strain feedback at the velocity-loop input (5.2.1).

    Parameters
    ----------
    eps_tilde : array_like, shape (J,)
        Mean-liberated strain of the gauge assigned to each joint, m/m.
    k_eps : array_like, shape (J,)
        Gains, rad/s per (m/m).

    Returns
    -------
    theta_dot_e : ndarray, shape (J,)
        Extra velocity reference, rad/s: ``-k_eps * eps_tilde``.

    Examples
    --------
    >>> proportional_feedback([1e-4, -2e-4], [500.0, 500.0]).tolist()
    [-0.05, 0.1]
    """
    e = np.asarray(eps_tilde, dtype=np.float64)
    return -np.asarray(k_eps, dtype=np.float64) * e


def pade_p55(shift_rad_s: float):
    """Shifted Padé approximant ``P_5,5(s) ~ 1 / sqrt(s)`` (7.5.1).

    Parameters
    ----------
    shift_rad_s : float
        Frequency shift ``Delta_s > 0``, rad/s; the approximation is best
        around ``|s| = Delta_s`` (about two decades either side).

    Returns
    -------
    num, den : ndarray, shape (6,)
        Polynomial coefficients in ``s`` (highest power first).

    Raises
    ------
    ValueError
        If the shift is not positive.

    Examples
    --------
    >>> num, den = pade_p55(1.0)
    >>> H = np.polyval(num, 1j) / np.polyval(den, 1j)
    >>> float(round(abs(H), 4)), round(float(np.degrees(np.angle(H))), 1)
    (1.0, -45.0)
    """
    ds = float(shift_rad_s)
    if not ds > 0:
        raise ValueError(f"shift_rad_s: expected > 0, got {shift_rad_s}")
    a = np.array([1.0, 55.0, 330.0, 462.0, 165.0, 11.0])
    b = np.array([11.0, 165.0, 462.0, 330.0, 55.0, 1.0])
    powers = ds ** -np.arange(5, -1, -1.0)       # s_hat^k = s^k / ds^k
    return a * powers / math.sqrt(ds), b * powers


def half_integrator_sos(shift_rad_s: float, dt: float) -> np.ndarray:
    """Tustin discretisation of :func:`pade_p55` as second-order sections.

    Returns
    -------
    sos : ndarray, shape (3, 6)
        For :class:`SosFilter` or ``scipy.signal.sosfilt``.

    Examples
    --------
    >>> half_integrator_sos(2 * np.pi * 3, 5e-4).shape
    (3, 6)
    """
    if not dt > 0:
        raise ValueError(f"dt: expected > 0, got {dt}")
    num, den = pade_p55(shift_rad_s)
    z, p, k = signal.tf2zpk(num, den)
    zd, pd, kd = signal.bilinear_zpk(z, p, k, 1.0 / dt)
    return signal.zpk2sos(zd, pd, kd)


class SosFilter:
    """Per-sample cascade of second-order sections (transposed direct form II).

    State layout: two delay values per section.

    Examples
    --------
    >>> f = SosFilter(np.array([[1.0, 0, 0, 1.0, -0.5, 0]]))
    >>> [f.step(1.0), f.step(0.0)]
    [1.0, 0.5]
    """

    def __init__(self, sos):
        s = check_array(sos, "sos", (None, 6))
        if np.any(np.abs(s[:, 3] - 1.0) > 1e-12):
            raise ValueError("sos: expected a0 = 1 in every section")
        self._sec = [tuple(float(v) for v in row) for row in s]
        self.reset()

    def reset(self) -> None:
        self._z = [[0.0, 0.0] for _ in self._sec]

    def step(self, x: float) -> float:
        for (b0, b1, b2, _, a1, a2), z in zip(self._sec, self._z):
            y = b0 * x + z[0]
            z[0] = b1 * x - a1 * y + z[1]
            z[1] = b2 * x - a2 * y
            x = y
        return x


# ----------------------------------------------------------------- the damper of the layer
@dataclass(frozen=True, kw_only=True)
class DampingConfig:
    """Damping law and its parameters.

    Attributes
    ----------
    law : {"off", "proportional", "integral", "half_integrator"}
    k_eps : tuple of 3 floats
        Gain per joint (units in the module docstring); joint 1 has no gauge.
    n_window : int
        Moving-average length at the filter rate (1000 = 0.5 s at 2 kHz).
    decimation : int
        Filter input every ``decimation`` control samples.
    pade_shift_rad_s : float
        ``Delta_s`` of the half-integrator (7.5.1).
    pd_gain_scale : float or None
        Factor on the position-loop gain ``k_PD`` while the law is active;
        ``None``: 0.5 for the integral law (6.5), 1 otherwise.
    iir_alpha : float or None
        If given, the IIR variant of the static strain cancellation (2.2.3,
        :class:`~tudorvision.joint.iir_filter.ExponentialStrainFilter`) with this
        discount factor replaces the moving averages (``n_window`` unused).
    gauge_of_joint : tuple
        Strain channel per joint (``None`` for none).
    """

    law: str = "proportional"
    k_eps: tuple = (0.0, 0.0, 0.0)
    n_window: int = 1000
    decimation: int = 1
    pade_shift_rad_s: float = 2.0 * math.pi * 3.0
    pd_gain_scale: float | None = None
    gauge_of_joint: tuple = field(default=GAUGE_OF_JOINT)
    iir_alpha: float | None = None

    def __post_init__(self):
        if self.law not in LAWS:
            raise ValueError(f"law: expected one of {LAWS}, got {self.law!r}")
        k = check_array(self.k_eps, "k_eps", (3,))
        object.__setattr__(self, "k_eps", tuple(float(x) for x in k))
        if len(self.gauge_of_joint) != 3:
            raise ValueError(f"gauge_of_joint: expected 3 entries, got {self.gauge_of_joint!r}")

    @property
    def pd_scale(self) -> float:
        if self.pd_gain_scale is not None:
            return float(self.pd_gain_scale)
        return 0.5 if self.law == "integral" else 1.0


def default_damping_config(law: str, *, plant: str | None = None, two_way: bool | None = None,
                           assisted: bool = False, payload_kg: float | None = None, **overrides) -> DampingConfig:
    """:class:`DampingConfig` with the tuned gains of ``law`` for a plant.

    ``assisted=True`` selects ``ASSISTED_GAINS`` for the proportional law (the gains for a
    damper with a ``strain_model``); the other laws keep their gains. With ``payload_kg``
    (the known payload mass) the tuned link-3 gain follows the plant's payload schedule
    (:data:`PAYLOAD_SCHEDULES`; not for the assisted gains or given ``k_eps``).
    The plant's position-loop scale for the law (:data:`PD_SCALES`, e.g. 0.01 for the
    proportional law on the soft plant) is set unless ``pd_gain_scale`` is given, also
    with given ``k_eps``.

    Parameters
    ----------
    law : {"off", "proportional", "integral", "half_integrator"}
        Damping law.
    plant : {"soft", "one-way", "two-way"}, optional
        Gain set (:data:`GAIN_SETS`); default ``"soft"`` (the lab's default plant) unless
        ``two_way`` is given.
    two_way : bool, optional
        The stiff plant's sets: ``True`` ``"two-way"``, ``False`` ``"one-way"`` (when ``plant`` is not given).
    assisted : bool, optional
        Proportional law with a model-assisted static strain cancellation
        (``ASSISTED_GAINS``).
    payload_kg : float, optional
        Known payload mass, kg, for the one-way plant's link-3 gain schedule.
    **overrides
        Further :class:`DampingConfig` fields (``k_eps`` given here replaces the
        tuned gains).

    Returns
    -------
    DampingConfig
        The configuration with the tuned gains.

    Raises
    ------
    ValueError
        If ``law`` is not one of ``LAWS`` (or an override is invalid).

    Examples
    --------
    >>> default_damping_config("proportional", two_way=False).k_eps
    (0.0, 1600.0, 300.0)
    >>> default_damping_config("proportional", plant="one-way", assisted=True).k_eps
    (0.0, 1600.0, 100.0)
    >>> default_damping_config("proportional", plant="one-way", payload_kg=0.05).k_eps
    (0.0, 1600.0, 200.0)
    >>> default_damping_config("proportional").pd_scale, default_damping_config("proportional", two_way=False).pd_scale
    (0.01, 1.0)
    """
    if law not in LAWS:
        raise ValueError(f"law: expected one of {LAWS}, got {law!r}")
    if plant is None:
        plant = "soft" if two_way is None else ("two-way" if two_way else "one-way")
    if plant not in GAIN_SETS:
        raise ValueError(f"plant: expected one of {tuple(GAIN_SETS)}, got {plant!r}")
    table = dict(GAIN_SETS[plant])
    if "pd_gain_scale" not in overrides:
        overrides["pd_gain_scale"] = pd_scale_of(law, plant)
    if assisted:
        table["proportional"] = ASSISTED_GAINS[plant]
    if "k_eps" in overrides:
        k = overrides.pop("k_eps")
    else:
        k = tuple(table.get(law, (0.0, 0.0, 0.0)))
        if payload_kg is not None and not (assisted and law == "proportional"):
            k = (k[0], k[1], k[2] * payload_gain_factor(law, payload_kg, plant))
    return DampingConfig(law=law, k_eps=k, **overrides)


class StrainDamper:
    """Static strain cancellation plus one damping law, stepped at the control rate.

    Parameters
    ----------
    config : DampingConfig
        Damping law, gains, filter length and gauge channels.
    eps0 : array_like, shape (C,)
        Strain at start (the arm at rest).
    dt : float
        Control sample time, seconds.

    strain_model : object, optional
        Model-assisted static strain cancellation (off by default): an
        identified strain-referred dynamics model (chapter 10, e.g.
        :class:`tudorvision.joint.collision.StrainDynamicsModel`) with
        ``predict(theta, dtheta, ddtheta, payload_kg) -> (N, 2)`` (link-2 and
        link-3 root strains). When :meth:`step` gets the cascade's reference
        ``(theta, dtheta, ddtheta)``, the model's expected change of the root
        strains since the start is subtracted before the double moving
        average, so ``eps_tilde`` is the oscillation about the moving
        quasi-static equilibrium (gravity and inertial strain of the planned
        motion) instead of about the filter's lagging mean. The filter still
        removes whatever the model misses (offsets, drift). The channels are
        those of ``config.gauge_of_joint`` for joints 2 and 3.
    payload_kg : float
        Payload mass for the model (the layer's known or estimated payload), kg.

    Raises
    ------
    ValueError
        If ``dt`` is not positive or ``payload_kg`` is not a valid mass.
    TypeError
        If ``strain_model`` has no ``predict`` method.

    Attributes
    ----------
    eps_tilde : list of C floats
        Last mean-liberated strains.
    mu : list of C floats
        Last static strain estimates (of the model-corrected strain when a
        ``strain_model`` acts).

    Examples
    --------
    >>> d = StrainDamper(DampingConfig(law="proportional", k_eps=(0, 500, 500)), [0.0] * 4, 5e-4)
    >>> dv, dth = d.step([0.0, 0.0, 0.0, 0.0])
    >>> [x + 0.0 for x in dv], [x + 0.0 for x in dth]
    ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    """

    def __init__(self, config: DampingConfig, eps0, dt: float, *, strain_model=None, payload_kg: float = 0.0):
        if not dt > 0:
            raise ValueError(f"dt: expected > 0, got {dt}")
        if strain_model is not None and not callable(getattr(strain_model, "predict", None)):
            raise TypeError("strain_model: expected an object with predict(theta, dtheta, ddtheta, payload_kg), "
                            f"got {type(strain_model).__name__}")
        self.strain_model = strain_model
        # the identified model's one-sample path (same numbers as predict, a fifth of its cost)
        self._predict_one = getattr(strain_model, "predict_one", None)
        self.payload_kg = check_mass(payload_kg)
        self._model_ch = list(config.gauge_of_joint[1:3])
        self._model0 = None         # model strains at the first referenced step
        self.config = config
        self.dt = float(dt)
        self.filter = StaticStrainFilter(eps0, n_window=config.n_window, decimation=config.decimation) \
            if config.iir_alpha is None else ExponentialStrainFilter(eps0, alpha=config.iir_alpha,
                                                                     decimation=config.decimation)
        self.eps_tilde = [0.0] * self.filter.channels
        self.mu = list(self.filter.mu)
        self._k = list(config.k_eps)
        self._g = list(config.gauge_of_joint)
        self._integ = [0.0, 0.0, 0.0]
        self._half = [SosFilter(half_integrator_sos(config.pade_shift_rad_s, dt)) for _ in range(3)] \
            if config.law == "half_integrator" else None

    @property
    def pd_scale(self) -> float:
        """Factor on the PD position gain while this law acts."""
        return self.config.pd_scale

    @property
    def k_eps(self) -> tuple:
        """Gains in use, one per joint (``config.k_eps`` until :meth:`set_gains`)."""
        return tuple(self._k)

    def set_gains(self, k_eps) -> None:
        """Change the gains while running (e.g. scheduled on a new payload).

        The integral law's state is rescaled so that its output ``-k * integral``
        does not jump (bumpless); the filter state is kept.

        Parameters
        ----------
        k_eps : array_like, shape (3,)
            New gain per joint (units of :class:`DampingConfig`'s ``k_eps``).

        Raises
        ------
        ValueError
            If ``k_eps`` does not have shape (3,).
        """
        k = [float(x) for x in check_array(k_eps, "k_eps", (3,))]
        if self.config.law == "integral":
            self._integ = [i * (ko / kn) if kn != 0.0 else 0.0 for i, ko, kn in zip(self._integ, self._k, k)]
        self._k = k

    def set_payload(self, payload_kg: float) -> None:
        """Payload mass given to the ``strain_model`` from now on (kg).

        Parameters
        ----------
        payload_kg : float
            Payload mass, kg.

        Raises
        ------
        ValueError
            If ``payload_kg`` is not a finite mass in the allowed range.
        """
        m = check_mass(payload_kg)
        # the layer learns of a payload change after it happened: re-anchor the model at the next
        # referenced step instead of stepping its prediction by the payload's static strain now
        self._model0 = None
        self.payload_kg = m

    def step(self, strain, reference=None):
        """One control sample.

        Parameters
        ----------
        strain : sequence of C floats
            Measured strains, m/m.
        reference : tuple of 3 sequences of 3 floats, optional
            The cascade's reference ``(theta, dtheta, ddtheta)`` (rad, rad/s,
            rad/s^2) for the model-assisted cancellation; ignored without a
            ``strain_model``.

        Returns
        -------
        dtheta_extra : list of 3 floats
            Added at the velocity-loop input, rad/s (proportional law).
        theta_extra : list of 3 floats
            Added to the position reference, rad (integral, half-integrator).
        """
        if self.strain_model is not None and reference is not None:
            strain = self._model_corrected(strain, reference)
        self.mu, self.eps_tilde = self.filter.step(strain)
        law = self.config.law
        dv, dth = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        if law == "off":
            return dv, dth
        for j in range(3):
            g = self._g[j]
            if g is None or self._k[j] == 0.0:
                continue
            e = self.eps_tilde[g]
            if law == "proportional":
                dv[j] = -self._k[j] * e
            elif law == "integral":
                self._integ[j] += e * self.dt
                dth[j] = -self._k[j] * self._integ[j]
            else:
                dth[j] = -self._k[j] * self._half[j].step(e)
        return dv, dth

    def _model_corrected(self, strain, reference):
        """``strain`` minus the model's expected change of the root strains since the first call."""
        if self._predict_one is not None:
            m = self._predict_one(*reference, self.payload_kg)
        else:
            th, dth, ddth = (np.asarray(x, dtype=np.float64).reshape(1, 3) for x in reference)
            m = np.asarray(self.strain_model.predict(th, dth, ddth, self.payload_kg), dtype=np.float64).reshape(-1)
        if self._model0 is None:
            self._model0 = m.copy()
        out = [float(x) for x in strain]
        for i, c in enumerate(self._model_ch):
            if c is not None:
                out[c] -= float(m[i] - self._model0[i])
        return out
