"""Actuator model and cascaded joint controller (sections 3.1, 3.2).

Actuator (per joint, referred to the gear output)
-------------------------------------------------
The amplifier with its current loop is fast (833 Hz) compared to the
mechanics and is merged into one gain (3.1.2)::

    tau_E = n_M k_tau k_amp v_M = k_M v_M

Friction follows Zeng's direction-dependent model (3.1.3). The seed lists the
Coulomb coefficients as magnitudes; here they always oppose the motion::

    tau_F = k_v+ dtheta + k_c+      (dtheta > 0)
    tau_F = k_v- dtheta - k_c-      (dtheta < 0)

with the motor-side coefficients of appendix A.3 reflected through the gear:
viscous ``n_M^2 k_v``, Coulomb ``n_M k_c``, inertia ``n_M^2 I_M``. The design
model is the linear ``G_M = k_M / (s (I s + k_v))`` (3.1.7).

Controller (per joint, 2 kHz)
-----------------------------
velocity loop: PI ``k_PI (t_PI s + 1) / s`` on the error between the velocity
reference and the encoder velocity (backward difference, first-order filter
``1 / (t_d s + 1)``); ``t_PI`` cancels the mechanical time constant
``I / k_v`` and ``k_PI = k_v / (2 k_M t_d)`` gives the closed velocity loop a
damping of ``1 / sqrt(2)``.

position loop: PD with first-order lag ``k_PD (t_PD s + 1) / (t_l s + 1)``;
``t_PD = 2 t_d`` cancels the first-order approximation of the closed velocity
loop and ``k_PD = 1 / (4 t_l)`` makes the remaining position loop
``k_PD / (s (t_l s + 1))`` critically damped, so steps do not overshoot
(section 3.3: "There is no overshoot").

The velocity reference is ``PD output + feed-forward + extra``, where the
feed-forward is the planned velocity and ``extra`` is the damping input of
the oscillation controllers (e.g. ``-k_eps * eps_tilde``, eq. 5.2.1). The
output voltage saturates at the intermittent torque limit; the integrator
stops integrating while saturated (anti-windup).

Friction feed-forward (optional, :class:`FrictionCompensation`): the
controller's own identified Coulomb terms of (3.1.3) (appendix A.3, reflected
through the gear) are added to the PI output as a voltage
``(k_c+ s+(w) - k_c- s-(w)) / k_M`` with the switching functions of (3.1.5)
smoothed into ramps over ``|w| < w_band``, by default on the velocity
reference ``w`` of the PI loop (``source="reference"``; the measured velocity,
``"measured"``, chatters on the encoder quantisation at rest). The PI integrator then only carries gravity and
model error, so small velocity commands (e.g. the damping input of 5.2.1 at
small strain amplitude) move the joint at once instead of waiting until the
integrator has built up the break-away torque (section 3.2: the velocity
loop compensates the joint friction).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_array
from ..robot.actuators import motor_gain, reflected_viscous
from ..robot.params import RobotParams

__all__ = ["CascadeGains", "design_cascade", "FrictionCompensation", "friction_compensation",
           "JointCascade"]


@dataclass(frozen=True, kw_only=True)
class CascadeGains:
    """Gains of the joint cascade, each an array of shape (3,).

    Attributes
    ----------
    k_pi : V / (rad/s) / s   (PI gain of ``k_PI (t_PI s + 1) / s``)
    t_pi : s
    t_d : s   (velocity measurement filter)
    k_pd : 1/s   (``k_PD (t_PD s + 1) / (t_l s + 1)``)
    t_pd : s
    t_l : s
    v_limit : V   (amplifier input limit, intermittent torque over k_M)
    """

    k_pi: np.ndarray
    t_pi: np.ndarray
    t_d: np.ndarray
    k_pd: np.ndarray
    t_pd: np.ndarray
    t_l: np.ndarray
    v_limit: np.ndarray


def design_cascade(params: RobotParams, effective_inertia_kg_m2, *, t_d: float = 0.003,
                   t_l: float = 0.01) -> CascadeGains:
    """Tune the PI velocity and PD position loops from the actuator model (section 3.2).

    Parameters
    ----------
    params : RobotParams
        Robot parameters (actuator gains and viscous friction of appendix A.3).
    effective_inertia_kg_m2 : array_like, shape (3,)
        Inertia seen by each joint at the gear output (rotor reflected plus the
        attached bodies, e.g. in the zero configuration as in the seed).
    t_d : float
        Velocity filter time constant, seconds (> 0).
    t_l : float
        Position-loop lag time constant, seconds (> 0).

    Returns
    -------
    CascadeGains
        The per-joint gains.

    Raises
    ------
    ValueError
        If an inertia or time constant is not positive.

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> g = design_cascade(load_robot_params(), [0.3, 0.8, 0.15])
    >>> np.round(g.k_pd, 1).tolist()
    [25.0, 25.0, 25.0]
    """
    inertia = check_array(effective_inertia_kg_m2, "effective_inertia_kg_m2", (3,))
    if np.any(inertia <= 0) or t_d <= 0 or t_l <= 0:
        raise ValueError("effective_inertia_kg_m2, t_d, t_l: expected positive values, got "
                         f"{inertia.tolist()}, {t_d}, {t_l}")
    kM = motor_gain(params)
    kv = reflected_viscous(params)
    ones = np.ones(3)
    return CascadeGains(
        k_pi=kv / (2.0 * kM * t_d),
        t_pi=inertia / kv,
        t_d=t_d * ones,
        k_pd=ones / (4.0 * t_l),
        t_pd=2.0 * t_d * ones,
        t_l=t_l * ones,
        v_limit=np.asarray(params.max_intermittent_torque_Nm, float) / kM,
    )


FRICTION_SOURCES = ("reference", "measured", "command")


@dataclass(frozen=True, kw_only=True)
class FrictionCompensation:
    """Coulomb friction feed-forward of the velocity loop (model 3.1.3).

    Attributes
    ----------
    coulomb_pos, coulomb_neg : ndarray, shape (3,)
        Coulomb magnitudes at the gear output for positive / negative motion, N m (>= 0).
    motor_gain : ndarray, shape (3,)
        ``k_M`` (N m per volt) to turn the torque into an amplifier voltage.
    w_band : float
        Half-width of the linear ramp replacing the sign switch around zero
        velocity reference, rad/s (> 0).
    source : str
        Signal the switching functions follow: ``"reference"`` (the PI loop's
        velocity reference), ``"measured"`` (filtered encoder velocity) or
        ``"command"`` (planned velocity + damping input).
    """

    coulomb_pos: np.ndarray
    coulomb_neg: np.ndarray
    motor_gain: np.ndarray
    w_band: float = 0.002
    source: str = "reference"

    def __post_init__(self):
        if self.source not in FRICTION_SOURCES:
            raise ValueError(f"source: expected one of {FRICTION_SOURCES}, got {self.source!r}")

    def voltage(self, w_ref) -> np.ndarray:
        """Feed-forward voltages for velocity references ``w_ref`` (shape (3,) or (N, 3)), volts.

        Examples
        --------
        >>> from tudorvision.robot import load_robot_params
        >>> fc = friction_compensation(load_robot_params())
        >>> v = fc.voltage([0.1, -0.1, 0.0])
        >>> bool(v[0] > 0 and v[1] < 0 and v[2] == 0)
        True
        """
        w = np.asarray(w_ref, dtype=np.float64)
        s = np.clip(w / self.w_band, -1.0, 1.0)
        tau = np.where(s > 0, self.coulomb_pos * s, self.coulomb_neg * s)
        return tau / self.motor_gain


def friction_compensation(params: RobotParams, *, scale: float = 1.0,
                          w_band: float = 0.002) -> FrictionCompensation:
    """Coulomb feed-forward from the identified friction model of appendix A.3.

    Parameters
    ----------
    params : RobotParams
    scale : float
        Fraction of the identified Coulomb torque to compensate (0..1.5);
        below 1 leaves a margin for friction that dropped since identification.
    w_band : float
        Ramp half-width around zero velocity reference, rad/s (> 0).

    Raises
    ------
    ValueError
        On a negative or too large ``scale`` or a non-positive ``w_band``.

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> fc = friction_compensation(load_robot_params())
    >>> np.round(fc.coulomb_pos, 3).tolist()
    [0.072, 0.768, 0.367]
    """
    if not 0.0 <= scale <= 1.5 or not w_band > 0:
        raise ValueError(f"scale, w_band: expected 0 <= scale <= 1.5 and w_band > 0, got {scale}, {w_band}")
    n = np.asarray(params.gear_ratio, float)
    return FrictionCompensation(coulomb_pos=scale * n * np.asarray(params.coulomb_pos_Nm, float),
                                coulomb_neg=scale * n * np.asarray(params.coulomb_neg_Nm, float),
                                motor_gain=motor_gain(params), w_band=float(w_band))


class JointCascade:
    """Discrete cascaded controller for the three joints (state between samples).

    Parameters
    ----------
    gains : CascadeGains
        Loop gains, e.g. from :func:`design_cascade`.
    dt : float
        Sample time, seconds (0.0005 at 2 kHz).
    theta0 : array_like, shape (3,)
        Initial encoder reading, radians.
    friction : FrictionCompensation, optional
        Coulomb feed-forward on the velocity reference (default none: the PI
        integrator alone overcomes friction).
    max_speed_rad_s : array_like, shape (3,), optional
        Saturation of the velocity reference (PD output + planned velocity +
        damping input) per joint, rad/s; default none. With the rated joint
        speeds, a damping input on top of a fast profile cannot ask the
        velocity loop for more than the actuator's rated speed.

    Raises
    ------
    ValueError
        If ``dt`` is not positive, ``theta0`` or ``max_speed_rad_s`` does not
        have shape (3,), or a speed limit is not positive.

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> c = JointCascade(design_cascade(load_robot_params(), [0.3, 0.8, 0.15]), 0.0005, [0, 0, 0])
    >>> v = c.step([0.0, 0.0, 0.0], [0.01, 0.0, 0.0])
    >>> v[0] > 0 and v[1] == 0.0
    True
    """

    def __init__(self, gains: CascadeGains, dt: float, theta0, *, friction: FrictionCompensation | None = None,
                 max_speed_rad_s=None):
        if not dt > 0:
            raise ValueError(f"dt: expected > 0, got {dt}")
        self.gains = gains
        self.dt = float(dt)
        th = check_array(theta0, "theta0", (3,))
        g = gains
        # per-joint scalar constants (lists of floats keep the 2 kHz loop fast)
        self._kp_vel = [float(g.k_pi[j] * g.t_pi[j]) for j in range(3)]
        self._ki_vel = [float(g.k_pi[j]) for j in range(3)]
        self._alpha_d = [self.dt / (float(g.t_d[j]) + self.dt) for j in range(3)]
        self._kpd = [float(g.k_pd[j]) for j in range(3)]
        self._tpd = [float(g.t_pd[j]) for j in range(3)]
        self._tl = [float(g.t_l[j]) for j in range(3)]
        self._vlim = [float(g.v_limit[j]) for j in range(3)]
        if max_speed_rad_s is None:
            self._wmax = [math.inf] * 3
        else:
            wmax = check_array(max_speed_rad_s, "max_speed_rad_s", (3,))
            if np.any(wmax <= 0):
                raise ValueError(f"max_speed_rad_s: expected positive speeds, got {wmax.tolist()}")
            self._wmax = [float(x) for x in wmax]
        self.friction = friction
        self._fc = None if friction is None else (
            [float(friction.coulomb_pos[j] / friction.motor_gain[j]) for j in range(3)],
            [float(friction.coulomb_neg[j] / friction.motor_gain[j]) for j in range(3)],
            1.0 / float(friction.w_band), FRICTION_SOURCES.index(friction.source))
        self.reset(th)

    def set_pd_scale(self, scale: float) -> None:
        """Multiply the designed PD position gains by ``scale`` (e.g. 0.5 for the integral law, 6.5).

        Parameters
        ----------
        scale : float
            Positive factor on ``gains.k_pd``; 1 restores the design.

        Raises
        ------
        ValueError
            If ``scale`` is not a positive finite number.
        """
        s = float(scale)
        if not (math.isfinite(s) and s > 0):
            raise ValueError(f"scale: expected a positive finite factor, got {scale!r}")
        self._kpd = [float(self.gains.k_pd[j]) * s for j in range(3)]

    def reset(self, theta) -> None:
        """Zero the controller state at encoder reading ``theta``.

        Parameters
        ----------
        theta : array_like, shape (3,)
            Encoder joint angles, rad.

        Raises
        ------
        ValueError
            If ``theta`` does not have shape (3,).
        """
        th = check_array(theta, "theta", (3,))
        self._th_prev = [float(x) for x in th]
        self._vel = [0.0, 0.0, 0.0]
        self._integ = [0.0, 0.0, 0.0]
        self._e_prev = [0.0, 0.0, 0.0]
        self._pd = [0.0, 0.0, 0.0]
        self.velocity = [0.0, 0.0, 0.0]        # filtered encoder velocity, rad/s
        self.velocity_ref = [0.0, 0.0, 0.0]    # input of the PI loop, rad/s

    def step(self, theta_meas, theta_ref, dtheta_ff=(0.0, 0.0, 0.0),
             dtheta_extra=(0.0, 0.0, 0.0)) -> list:
        """One control sample.

        Parameters
        ----------
        theta_meas : sequence of 3 floats
            Encoder angles, radians.
        theta_ref : sequence of 3 floats
            Position setpoints, radians.
        dtheta_ff : sequence of 3 floats
            Velocity feed-forward (planned velocity), rad/s.
        dtheta_extra : sequence of 3 floats
            Extra velocity-loop input (oscillation damping, eq. 5.2.1), rad/s.

        Returns
        -------
        list of 3 floats
            Amplifier input voltages ``v_M``, volts (``tau_E = k_M v_M``).
        """
        dt = self.dt
        fc = self._fc
        out = [0.0, 0.0, 0.0]
        for j in range(3):
            th = theta_meas[j]
            raw = (th - self._th_prev[j]) / dt
            self._th_prev[j] = th
            vel = self._vel[j] + self._alpha_d[j] * (raw - self._vel[j])
            self._vel[j] = vel
            # PD with first-order lag, backward Euler
            e = theta_ref[j] - th
            tl = self._tl[j]
            pd = (tl * self._pd[j] + self._kpd[j] * (self._tpd[j] * (e - self._e_prev[j]) + dt * e)) \
                / (tl + dt)
            self._pd[j] = pd
            self._e_prev[j] = e
            wref = pd + dtheta_ff[j] + dtheta_extra[j]
            wmax = self._wmax[j]
            if wref > wmax:
                wref = wmax
            elif wref < -wmax:
                wref = -wmax
            ew = wref - vel
            integ = self._integ[j] + self._ki_vel[j] * ew * dt
            u = self._kp_vel[j] * ew + integ
            if fc is not None:          # Coulomb feed-forward on the velocity reference
                src = fc[3]
                s = (wref if src == 0 else (vel if src == 1 else dtheta_ff[j] + dtheta_extra[j])) * fc[2]
                s = 1.0 if s > 1.0 else (-1.0 if s < -1.0 else s)
                u += (fc[0][j] if s > 0 else fc[1][j]) * s
            lim = self._vlim[j]
            if u > lim:
                u = lim
                if ew < 0:
                    self._integ[j] = integ
            elif u < -lim:
                u = -lim
                if ew > 0:
                    self._integ[j] = integ
            else:
                self._integ[j] = integ
            out[j] = u
            self.velocity[j] = vel
            self.velocity_ref[j] = wref
        return out
