"""Collision detection, isolation and reaction from link strains (sections 10.2, 11.1, 11.2).

The strain-referred dynamics it runs on are :mod:`tudorvision.joint.strain_dynamics`.

Generalised momentum residual (11.1.6, de Luca's observer)
----------------------------------------------------------
``p = I_eps(theta) dtheta`` and, with ``n = C_eps dtheta + g_eps - dI_eps/dt dtheta``
(the seed writes ``-C_eps^T dtheta`` using skew symmetry; here ``dI/dt`` is
evaluated exactly because the identified rows need not be symmetric)::

    r = K_I [ int (eps - n - r) dt - (p - p(0)) ]    =>    dr/dt = K_I (eps_c - r)

so ``r`` is the collision strain ``eps_c`` through a first-order low-pass
(11.1.8), positive for tension on the top surface. (The seed's sign is the
opposite; the ``+ r`` feedback that gives 11.1.7 is written out here.) A
collision is flagged when ``|r_i|`` exceeds 6 sigma of collision-free
residuals; the isolated link is the last link over its threshold, the
direction the sign of its residual.

Isolation and the inertial transient (:class:`CollisionMonitor`): the root
strain of link 3 is a load-side torque of joint 3, so a contact on link 2
adds no *static* collision strain there. But the model is driven by the
encoder angles, which do not see the link-2 deflection: an impact on link 2
jerks the base of link 3 (the link-2 tip) and the inertia of link 3 and the
payload answers with a short strain transient at the link-3 root that
changes sign within a few milliseconds (on the simulated arm: over the
link-3 threshold for ~8 ms, then the opposite sign). A contact on link 3
loads its root with one sign for as long as the contact lasts. The monitor
therefore flags the collision (and reacts) at the first threshold violation
and confirms link 3 only if the link-3 residual, from its first violation,
stays over its threshold with that sign for ``isolation_window_s`` (default
15 ms); if it falls back or reverses earlier, or does not cross within the
window after detection, the contact is isolated to link 2. (A link-3
contact shorter than the window is then isolated to link 2.)

With the damping gains that make the detection fast, the link-3 residual of
a link-2 impact stays over its threshold for more than 20 ms (the reaction
brakes the arm and both roots answer in the ratio of the arm's first
bending mode). The collision-free residuals of the two roots are almost
collinear (correlation 0.99), so the monitor can isolate on the decoupled
residual ``r3 - c(m) r2`` (:class:`ResidualCoupling`, fitted on the
collision-free data of the thresholds): a load on link 3 itself shows in it
with one sign, a link-2 impact only for ~10 ms.

Reaction (11.2.1)
-----------------
``theta_dot_r = G_r(s) tau_c`` with ``G_r = k_or / (m_r s + f_r + k_r / s)`` and
the equivalent collision torque ``tau_c = -(E I / y_b) r`` on the joint (4.2.3;
a downward push gives tension on top, i.e. a negative joint torque). On
detection the velocity reference ``theta_dot_r`` replaces the PD output;
the damping law keeps acting. Strategies: ``stop`` (theta_dot_r = 0),
``reflex`` (small m_r, f_r, k_r = 0, k_or > 1) and ``interaction``
(k_or = 1, k_r = 0).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_array, check_mass
from .collision_transient import TransientAllowance
from .strain_dynamics import StrainDynamicsModel

__all__ = ["STRATEGIES", "MomentumObserver", "thresholds_from_residuals", "isolate",
           "ReactionConfig", "reaction_config", "Admittance", "CollisionMonitor", "root_torque_per_strain",
           "STRATEGY_OF_CODE", "ResidualCoupling", "fit_residual_coupling", "DEFAULT_K_I"]
STRATEGIES = ("none", "stop", "reflex", "interaction")
#: Strategy name per protocol code (:class:`tudorvision.joint.protocol.CollisionStrategy`).
STRATEGY_OF_CODE = dict(enumerate(STRATEGIES))
#: Default observer gain K_I (1/s; residual cut-off 32 Hz). The seed leaves K_I to tuning (11.1:
#: reactivity against noise sensitivity). On the simulated arm (bench_collision, 6-sigma thresholds
#: recomputed per gain): 100 /s misses the 400 g link-2 impact (its residual stays below the 400 g
#: threshold), 200 /s detects every contact in 5-11.5 ms without false positives (also on held-out
#: seeds); thresholds computed with one K_I only hold for monitors with the same K_I.
DEFAULT_K_I = 200.0
#: gauge channels of the root strains of links 2 and 3
ROOT_GAUGES = (0, 2)


# ----------------------------------------------------------------- residual and isolation
class MomentumObserver:
    """Strain-based generalised momentum residual (11.1.6) for joints 2 and 3.

    State: the integral ``int (eps - n - r) dt`` (2,), ``p(0)`` (2,), residual (2,).

    Parameters
    ----------
    model : StrainDynamicsModel
        Identified strain-referred dynamics (10.2.8).
    payload_kg : float
        Payload mass, kg.
    k_i : float or array_like, shape (2,), optional
        Observer gains ``K_I``, 1/s (cut-off of the residual low-pass); default
        :data:`DEFAULT_K_I`.
    dt : float
        Sample time, seconds.
    input_lag_s : float, optional
        Time constant of the first-order filter applied to the angle and
        strain inputs, seconds (match the velocity filter); 0: raw inputs.

    Raises
    ------
    ValueError
        If ``dt`` or a gain is not positive, or ``input_lag_s`` is negative.
    """

    def __init__(self, model: StrainDynamicsModel, payload_kg: float, *, k_i=None, dt: float,
                 input_lag_s: float = 0.0):
        if not dt > 0:
            raise ValueError(f"dt: expected > 0, got {dt}")
        if not input_lag_s >= 0:
            raise ValueError(f"input_lag_s: expected >= 0, got {input_lag_s}")
        # the same first-order filter 1/(t s + 1) on angles and strains as on the velocity input
        self._alpha = float(dt) / (float(input_lag_s) + float(dt))
        k_i = DEFAULT_K_I if k_i is None else k_i
        k = np.broadcast_to(np.asarray(k_i, dtype=np.float64), (2,))
        if np.any(k <= 0):
            raise ValueError(f"k_i: expected > 0, got {k_i}")
        self.model = model
        self.dt = float(dt)
        self.k_i = [float(x) for x in k]
        self.set_payload(payload_kg)
        self.r = [0.0, 0.0]
        self._started = False

    def set_payload(self, payload_kg: float) -> None:
        """Use a new payload mass in the model terms.

        Parameters
        ----------
        payload_kg : float
            Payload mass, kg.
        """
        self.payload_kg = float(payload_kg)
        self._chi = self.model.at_payload(payload_kg)

    def reset(self) -> None:
        """Restart the observer: zero residual, ``p(0)`` taken at the next sample."""
        self._started = False
        self.r = [0.0, 0.0]

    def step(self, theta, dtheta, eps2) -> list:
        """One sample; ``eps2`` are the two root strains (m/m). Returns the residual (2 floats).

        With ``input_lag_s > 0`` the angles and strains first pass the same
        first-order filter as the (filtered encoder) velocity ``dtheta``, so
        that all inputs of the model carry the same lag.

        Parameters
        ----------
        theta : sequence of 3 floats
            Encoder joint angles, rad.
        dtheta : sequence of 3 floats
            Joint velocities (filtered encoder), rad/s.
        eps2 : sequence of 2 floats
            Root strains of links 2 and 3, m/m (positive: tension on top).

        Returns
        -------
        r : list of 2 floats
            Momentum residuals of joints 2 and 3, m/m (0 at the first sample).
        """
        a = self._alpha
        if a < 1.0:
            if not self._started:
                self._thf = [float(theta[1]), float(theta[2])]
                self._ef = [float(eps2[0]), float(eps2[1])]
            thf, ef = self._thf, self._ef
            thf[0] += a * (theta[1] - thf[0])
            thf[1] += a * (theta[2] - thf[1])
            ef[0] += a * (eps2[0] - ef[0])
            ef[1] += a * (eps2[1] - ef[1])
            theta = (0.0, thf[0], thf[1])
            eps2 = ef
        I, dI, cor, g = StrainDynamicsModel.terms(self._chi, theta[2], theta[1], dtheta[1], dtheta[2])
        self.inertia = I            # I_eps at this sample (the monitor's transient allowance)
        d2, d3 = dtheta[1], dtheta[2]
        p = [I[0, 0] * d2 + I[0, 1] * d3, I[1, 0] * d2 + I[1, 1] * d3]
        f = [eps2[i] - cor[i] - g[i] + (dI[i, 0] * d2 + dI[i, 1] * d3) * d3 for i in range(2)]
        if not self._started:
            self._p0 = p
            self._S = [0.0, 0.0]
            self._f = f
            self._started = True
            return list(self.r)
        r = self.r
        for i in range(2):
            # trapezoidal rule on the model part, the residual feedback from the last sample
            self._S[i] += self.dt * (0.5 * (f[i] + self._f[i]) - r[i])
            r[i] = self.k_i[i] * (self._S[i] - (p[i] - self._p0[i]))
        self._f = f
        return list(r)


def thresholds_from_residuals(residuals, *, n_sigma: float = 6.0) -> np.ndarray:
    """Detection thresholds ``n_sigma * std`` per column of collision-free residuals.

    Examples
    --------
    >>> r = np.random.default_rng(0).normal(0.0, [1e-6, 2e-6], size=(20000, 2))
    >>> np.round(thresholds_from_residuals(r) * 1e6, 1).tolist()
    [6.0, 12.0]
    """
    r = check_array(residuals, "residuals", (None, None))
    return n_sigma * r.std(axis=0)


def isolate(residual, thresholds):
    """Collision flag, isolated link and direction (11.1).

    Parameters
    ----------
    residual, thresholds : array_like, shape (2,)
        Residuals of the link-2 and link-3 root strains and their thresholds.

    Returns
    -------
    link : int or None
        2 or 3: the last link in the chain over its threshold; ``None``: no collision.
    direction : int
        Sign of that link's residual (+1: tension on top, a push toward
        decreasing joint angle), 0 without collision.

    Examples
    --------
    >>> isolate([5e-6, -9e-6], [4e-6, 4e-6])
    (3, -1)
    >>> isolate([1e-6, 1e-6], [4e-6, 4e-6])
    (None, 0)
    """
    for i in (1, 0):
        if abs(residual[i]) > thresholds[i]:
            return i + 2, (1 if residual[i] > 0 else -1)
    return None, 0


# ----------------------------------------------------------------- reaction
@dataclass(frozen=True, kw_only=True)
class ReactionConfig:
    """Reaction admittance ``G_r = k_or / (m_r s + f_r + k_r / s)`` (11.2.1) and strategy.

    Attributes
    ----------
    strategy : {"none", "stop", "reflex", "interaction"}
        ``none`` detects and reports only.
    m_r : float
        Inertial part, N m s^2/rad (> 0).
    f_r : float
        Resistive part, N m s/rad (>= 0).
    k_r : float
        Capacitive part, N m/rad (>= 0).
    k_or : float
        Over-reaction gain.
    torque_per_strain : tuple of 2 floats
        ``E I / y_b`` of the root sections of links 2 and 3, N m per (m/m) (4.2.3).
    v_max : float
        Clamp of the reaction velocity, rad/s.
    """

    strategy: str = "stop"
    m_r: float = 0.05
    f_r: float = 0.2
    k_r: float = 0.0
    k_or: float = 1.0
    torque_per_strain: tuple = (8000.0, 8000.0)
    v_max: float = 1.0

    def __post_init__(self):
        if self.strategy not in STRATEGIES:
            raise ValueError(f"strategy: expected one of {STRATEGIES}, got {self.strategy!r}")
        if not self.m_r > 0 or self.f_r < 0 or self.k_r < 0:
            raise ValueError(f"m_r, f_r, k_r: expected m_r > 0, f_r >= 0, k_r >= 0, got "
                             f"{self.m_r}, {self.f_r}, {self.k_r}")


def root_torque_per_strain(params) -> tuple:
    """``E I / y_b`` of the root sections of links 2 and 3 (4.2.3), N m per (m/m).

    Parameters
    ----------
    params : RobotParams

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> k2, k3 = root_torque_per_strain(load_robot_params())
    >>> bool(k2 > 0 and k3 > 0)
    True
    """
    out = []
    for link in (params.link2, params.link3):
        area_moment = link.width_m * link.height_m ** 3 / 12.0
        out.append(float(link.youngs_modulus_Pa * area_moment / (0.5 * link.height_m)))
    return tuple(out)


def reaction_config(strategy: str, *, torque_per_strain=(8000.0, 8000.0)) -> ReactionConfig:
    """Default parameters per strategy (reflex: light, low friction, k_or = 2; interaction: k_or = 1).

    Parameters
    ----------
    strategy : {"none", "stop", "reflex", "interaction"}
        Reaction strategy.
    torque_per_strain : sequence of 2 floats, optional
        ``E I / y_b`` of the root sections of links 2 and 3, N m per (m/m)
        (:func:`root_torque_per_strain`).

    Returns
    -------
    ReactionConfig
        The strategy's admittance parameters.

    Raises
    ------
    ValueError
        If ``strategy`` is not one of :data:`STRATEGIES`.

    Examples
    --------
    >>> reaction_config("reflex").k_or
    2.0
    """
    tps = tuple(float(x) for x in torque_per_strain)
    if strategy == "reflex":
        return ReactionConfig(strategy="reflex", m_r=0.02, f_r=0.05, k_r=0.0, k_or=2.0, torque_per_strain=tps)
    if strategy == "interaction":
        return ReactionConfig(strategy="interaction", m_r=0.05, f_r=0.5, k_r=0.0, k_or=1.0,
                              torque_per_strain=tps)
    return ReactionConfig(strategy=strategy, torque_per_strain=tps)


class Admittance:
    """Discrete ``G_r(s)`` (semi-implicit Euler), state ``[theta_dot_r, int theta_dot_r]``.

    Examples
    --------
    >>> a = Admittance(ReactionConfig(strategy="reflex", m_r=1.0, f_r=1.0, k_or=1.0), 1e-3)
    >>> v = [a.step(1.0) for _ in range(20000)][-1]   # steady state k_or tau / f_r
    >>> round(v, 3)
    1.0
    """

    def __init__(self, config: ReactionConfig, dt: float):
        self.c = config
        self.dt = float(dt)
        self.v, self.x = 0.0, 0.0

    def reset(self) -> None:
        self.v, self.x = 0.0, 0.0

    def step(self, tau: float) -> float:
        c, dt = self.c, self.dt
        # m dv/dt = k_or tau - f v - k x  (implicit in the damping term)
        self.v = (c.m_r * self.v + dt * (c.k_or * tau - c.k_r * self.x)) / (c.m_r + dt * c.f_r)
        self.v = max(-c.v_max, min(c.v_max, self.v))
        self.x += dt * self.v
        return self.v


class CollisionMonitor:
    """Residual observer, detection, isolation and reaction, stepped at the control rate.

    Use as ``ControlledArm.reaction``: :meth:`step` returns ``None`` (no
    reaction: cascade inputs unchanged) or the replaced inputs
    ``(theta_ref, dtheta_ref, extra)`` with the PD output removed
    (``theta_ref`` = measured angles) and the reaction velocity as the new
    velocity reference (damping ``extra`` kept).

    Parameters
    ----------
    model : StrainDynamicsModel
        Identified strain-referred dynamics (10.2.8) the observer runs on.
    thresholds : array_like, shape (2,)
        Residual thresholds of the link-2 and link-3 root strains, m/m.
    payload_kg : float
        Payload mass, kg.
    dt : float
        Control sample time, seconds.
    config : ReactionConfig
        Reaction strategy and admittance.
    k_i : float, optional
        Observer gain, 1/s (default :data:`DEFAULT_K_I`; use the gain the
        thresholds were computed with).
    isolation_window_s : float
        How long the link-3 residual must stay over its threshold with one
        sign to isolate link 3 (module docstring); 0 applies the plain rule
        of :func:`isolate` at the first violation.
    armed_after_s : float
        No detection during this time after construction (the observer runs):
        e.g. while the cascade takes up the gravity load after power-up.
    input_lag_s : float
        Lag of the first-order filter applied to the observer's angle and
        strain inputs (match the cascade's velocity filter ``t_d``); 0: raw.
    detect_highpass_hz : float
        Corner of a first-order high-pass on the residual used for detection
        and isolation (not for the reaction torque); 0: off (the seed's
        rule on the residual itself). It removes the slow part of the
        residual, i.e. the unmodelled link oscillation below the corner
        (first mode 1.5-3 Hz with payload), and keeps the contact onset; a
        sustained contact fades from the detection residual after detection
        (the latch holds).
    isolation_coupling : ResidualCoupling or (c0, c1, threshold), optional
        Isolation on the decoupled link-3 residual ``r3 - c(m) r2`` (see
        :class:`ResidualCoupling`) with its own threshold instead of ``r3``;
        ``None``: ``r3`` and its threshold (the seed's residual).
    detect_decoupled : bool
        Also flag a collision when the decoupled residual exceeds its
        threshold (needs ``isolation_coupling``); isolation as above.
    transient_gain : float
        Detection thresholds widened by this multiple of the inertial transient due after a change
        of planned acceleration (:class:`~tudorvision.joint.collision_transient.TransientAllowance`);
        0: fixed thresholds (the seed's rule).

    Attributes
    ----------
    residual : list of 3 floats
        Per joint (joint 1: 0); the detection residual (high-passed when
        ``detect_highpass_hz > 0``).
    collision : bool
        Latched after the first detection until :meth:`reset`.
    detected_at : float or None
        Sample count times dt at the first threshold violation, s.
    link, direction :
        Isolated link (2 or 3) and the sign of its residual; provisional
        (the plain rule at detection) until ``isolated``.
    isolated : bool
        The isolation is final.
    """

    def __init__(self, model: StrainDynamicsModel, thresholds, payload_kg: float, dt: float,
                 config: ReactionConfig = ReactionConfig(), *, k_i: float | None = None,
                 isolation_window_s: float = 0.015, armed_after_s: float = 0.0, input_lag_s: float = 0.0,
                 detect_highpass_hz: float = 0.0, isolation_coupling=None, detect_decoupled: bool = False,
                 transient_gain: float = 0.0):
        if not isolation_window_s >= 0 or not armed_after_s >= 0 or not detect_highpass_hz >= 0:
            raise ValueError(f"isolation_window_s, armed_after_s, detect_highpass_hz: expected >= 0, got "
                             f"{isolation_window_s}, {armed_after_s}, {detect_highpass_hz}")
        if isolation_coupling is not None and not isinstance(isolation_coupling, ResidualCoupling):
            isolation_coupling = ResidualCoupling(*isolation_coupling)
        self.isolation_coupling = isolation_coupling
        if detect_decoupled and self.isolation_coupling is None:
            raise ValueError("detect_decoupled: needs isolation_coupling")
        self.detect_decoupled = bool(detect_decoupled)
        w = 2.0 * math.pi * float(detect_highpass_hz) * float(dt)
        self._hp_a = w / (1.0 + w)          # backward-Euler low-pass; high-pass = r - low-pass
        self._lp = None
        self._armed_k = int(round(float(armed_after_s) / float(dt)))
        self.isolation_window_s = float(isolation_window_s)
        self._window_k = int(round(self.isolation_window_s / float(dt)))
        self.observer = MomentumObserver(model, payload_kg, k_i=k_i, dt=dt, input_lag_s=input_lag_s)
        self.transient = TransientAllowance(dt, gain=transient_gain) if transient_gain > 0 else None
        self.thresholds = [float(x) for x in check_array(thresholds, "thresholds", (2,), finite=False)]
        self.config = config
        self.dt = float(dt)
        self._adm = [Admittance(config, dt), Admittance(config, dt)]
        self.residual = [0.0, 0.0, 0.0]
        self.reset()

    def set_payload(self, payload_kg: float, *, quiet_s: float = 0.05) -> None:
        """Use a new payload mass (kg) in the observer and the isolation coupling.

        The model's inertia and gravity terms change at once, which steps the
        residual while the arm moves; detection pauses for ``quiet_s`` seconds
        (ten observer time constants at ``K_I = 200 /s``) while it settles.

        Parameters
        ----------
        payload_kg : float
            New payload mass, kg.
        quiet_s : float, optional
            Detection pause after the change, seconds.

        Raises
        ------
        ValueError
            If ``payload_kg`` is not a finite mass in the allowed range.
        """
        self.observer.set_payload(check_mass(payload_kg))
        self._armed_k = max(self._armed_k, self._k + int(round(float(quiet_s) / self.dt)))

    def reset(self) -> None:
        """Clear the latched collision (the observer keeps running)."""
        self.collision = False
        self.detected_at = None
        self.link, self.direction = None, 0
        self.isolated = False
        self._k = getattr(self, "_k", 0)
        self._k_det = 0
        self._l3_since = None       # sample of the first link-3 violation after detection
        self._l3_sign = 0
        self._l2_sign = 0           # sign of the first link-2 violation since detection
        self._r2_last = 0.0
        for a in self._adm:
            a.reset()

    def step(self, theta, dtheta, strain, theta_ref, dtheta_ref, extra):
        """One control sample; see the class docstring for the return value.

        Parameters
        ----------
        theta : sequence of 3 floats
            Encoder joint angles, rad.
        dtheta : sequence of 3 floats
            Joint velocities (filtered encoder), rad/s.
        strain : sequence of floats
            Strain gauge readings, m/m; channels 0 and 2 are the roots of
            links 2 and 3.
        theta_ref : sequence of 3 floats
            Position references of the cascade, rad.
        dtheta_ref : sequence of 3 floats
            Velocity feed-forward of the cascade, rad/s.
        extra : sequence of 3 floats
            Extra velocity input (damping law), rad/s.

        Returns
        -------
        tuple of 3 lists or None
            None while no reaction is active (cascade inputs unchanged), else
            the replaced ``(theta_ref, dtheta_ref, extra)``: the measured
            angles (rad), zero feed-forward and the reaction velocity plus
            ``extra`` (rad/s).
        """
        r_full = self.observer.step(theta, dtheta, (strain[ROOT_GAUGES[0]], strain[ROOT_GAUGES[1]]))
        r = r_full
        if self._hp_a > 0.0:
            if self._lp is None:
                self._lp = list(r_full)
            lp, a = self._lp, self._hp_a
            lp[0] += a * (r_full[0] - lp[0])
            lp[1] += a * (r_full[1] - lp[1])
            r = [r_full[0] - lp[0], r_full[1] - lp[1]]
        self.residual = [0.0, r[0], r[1]]
        self._k += 1
        thr = self.thresholds
        if self.transient is not None:
            extra_thr = self.transient.step(self.observer.inertia, dtheta_ref)
            thr = [thr[0] + extra_thr[0], thr[1] + extra_thr[1]]
        if not self.collision and self._k > self._armed_k:
            link, direction = isolate(r, thr)
            if link is None and self.detect_decoupled:
                cp = self.isolation_coupling
                r3d = r[1] - cp.at_payload(self.observer.payload_kg) * r[0]
                if abs(r3d) > cp.threshold:
                    link, direction = 3, (1 if r3d > 0 else -1)
            if link is not None:
                self.collision = True
                self.detected_at = self._k * self.dt
                self._k_det = self._k
                self.link, self.direction = link, direction
                self.isolated = self.isolation_window_s == 0.0
        if self.collision and not self.isolated:
            self._isolate_step(r)
        if not self.collision or self.config.strategy == "none":
            return None
        c = self.config
        v = [0.0, 0.0, 0.0]
        if c.strategy != "stop":
            for i in range(2):
                tau = -c.torque_per_strain[i] * r_full[i]
                v[i + 1] = self._adm[i].step(tau)
        return list(theta), [0.0, 0.0, 0.0], [v[j] + extra[j] for j in range(3)]

    def _isolate_step(self, r) -> None:
        """Follow the first link-3 violation; finalise ``link`` when confirmed, refuted or at the window end."""
        thr = self.thresholds
        cp = self.isolation_coupling
        if cp is None:
            r3, thr3 = r[1], thr[1]
        else:                               # the link-3 residual less its share of the arm mode (r2)
            r3, thr3 = r[1] - cp.at_payload(self.observer.payload_kg) * r[0], cp.threshold
        s3 = (1 if r3 > 0 else -1) if abs(r3) > thr3 else 0
        if abs(r[0]) > thr[0] and not self._l2_sign:
            self._l2_sign = 1 if r[0] > 0 else -1
        self._r2_last = r[0]
        window = self._window_k
        if self._l3_since is None and s3:
            self._l3_since, self._l3_sign = self._k, s3
        if self._l3_since is not None:
            if s3 != self._l3_sign:          # the link-3 load ended or reversed: an inertial transient
                self._final(2)
            elif self._k - self._l3_since + 1 >= window:
                self.link, self.direction, self.isolated = 3, self._l3_sign, True
        elif self._k - self._k_det + 1 >= window:
            self._final(2)

    def _final(self, link: int) -> None:
        # direction: sign of the first link-2 violation, else of the link-2 residual now
        self.link, self.direction, self.isolated = link, self._l2_sign or (1 if self._r2_last > 0 else -1), True


@dataclass(frozen=True)
class ResidualCoupling:
    """Share of the link-2 residual in the link-3 residual, ``c(m) = c0 + m c1``, for isolation.

    On the simulated arm the collision-free residuals of the two root strains
    are almost collinear (correlation 0.99: both are the unmodelled first
    bending mode of the whole arm, which loads both roots in a fixed ratio),
    and so is the inertial answer of link 3 to an impact on link 2. The
    decoupled residual ``r3 - c(m) r2`` removes that common part; a load on
    link 3 itself shows in it, a load on link 2 only transiently.

    Attributes
    ----------
    c0, c1 : float
        Regression coefficient of ``r3`` on ``r2`` at zero payload and its
        slope per kg (least squares on collision-free residuals).
    threshold : float
        Threshold of the decoupled residual (6 sigma of the collision-free
        data), m/m.
    """

    c0: float
    c1: float
    threshold: float

    def at_payload(self, payload_kg: float) -> float:
        return self.c0 + float(payload_kg) * self.c1


def fit_residual_coupling(residuals, payload_kg, *, n_sigma: float = 6.0) -> ResidualCoupling:
    """Least squares ``r3 ~ (c0 + c1 m) r2`` on collision-free residuals and 6 sigma of what is left.

    Parameters
    ----------
    residuals : array_like, shape (N, 2)
        Collision-free residuals ``(r2, r3)``, m/m.
    payload_kg : array_like, shape (N,) or float

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> r2 = rng.normal(0, 1e-4, 20000); m = np.repeat([0.0, 0.4], 10000)
    >>> r = np.stack([r2, (0.3 + 0.2 * m) * r2 + rng.normal(0, 1e-6, 20000)], axis=1)
    >>> c = fit_residual_coupling(r, m)
    >>> round(c.c0, 2), round(c.c1, 2), round(c.threshold * 1e6, 1)
    (0.3, 0.2, 6.0)
    """
    r = check_array(residuals, "residuals", (None, 2))
    m = np.broadcast_to(np.asarray(payload_kg, dtype=np.float64), (r.shape[0],))
    A = np.stack([r[:, 0], m * r[:, 0]], axis=1)
    (c0, c1), *_ = np.linalg.lstsq(A, r[:, 1], rcond=None)
    left = r[:, 1] - A @ np.array([c0, c1])
    return ResidualCoupling(float(c0), float(c1), float(n_sigma * left.std()))
