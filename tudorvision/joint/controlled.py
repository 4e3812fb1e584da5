"""The joint controller around any arm: cascade, planner, damping, collision handling, settling.

* :class:`ControlledArm`: a :class:`~tudorvision.joint.plant.Plant` with its
  joint cascade and online planner stepped at the plant's sample time, driven
  by setpoints or velocity commands, with the layer's hooks (strain damper,
  collision monitor);
* :class:`CascadeCore`: the controlled arm as the core of the joint-layer
  server (:class:`tudorvision.joint.server.JointCore`): mode switches install
  the damping law and the collision monitor, the payload the layer is told
  schedules their gains, and the state reports whether the arm has settled.

Nothing here knows whether the plant is simulated: the virtual lab wraps
:class:`CascadeCore` around :class:`tudorvision.sim.arm.ElasticArm`
(``tudorvision.lab.SimCore``).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from .._checks import check_mass, check_vector
from .cascade import JointCascade, design_cascade
from .collision import STRATEGY_OF_CODE, CollisionMonitor, reaction_config, root_torque_per_strain
from .damping import LAWS, StrainDamper, default_damping_config
from .damping_gains import gain_set_of, gain_table, hold_loop_of, scheduled_gains
from .plant import Plant
from .planner import REPLAN_MODES, OnlinePlanner, blend_replan, plan_motion
from .cores import MAX_PAYLOAD_KG, CoreState

__all__ = ["ControlledArm", "CascadeCore"]


class ControlledArm:
    """The simulated arm with its joint cascade, driven by setpoints or velocity commands.

    This is the joint-control layer's view of the plant at 2 kHz: a
    point-to-point setpoint starts a B.6 motion (re-planned from the current
    reference when a new one arrives in motion); a velocity command is
    followed with the acceleration limits and integrated into the position
    reference; :meth:`stop` brakes at the acceleration limits and holds.

    Parameters
    ----------
    arm : Plant
        The arm (advanced in place), e.g. :class:`tudorvision.sim.arm.ElasticArm`.
    gains : CascadeGains, optional
        Default: designed from the zero-configuration inertia (section 3.2).
    v_max, a_max : array_like, shape (3,), optional
        Default limits for setpoints and velocity commands (rad/s, rad/s^2);
        default the chapter-8 values capped by the hardware limits.
    damping : callable, optional
        ``f(arm) -> 3 floats`` added at the velocity-loop input every sample
        (e.g. ``-k_eps * eps_tilde``, eq. 5.2.1).
    friction : tudorvision.joint.cascade.FrictionCompensation, optional
        Coulomb feed-forward of the velocity loop (default none, the bare PI loop).
    saturate_speed : bool
        Saturate the velocity-loop reference at the rated joint speeds
        (default True: a damping input on top of a fast profile cannot
        drive a joint past its rated speed).
    replan : {"restart", "blend"}
        How a setpoint re-plans a motion in flight: the acceleration restarts from zero (the seed's
        B.6, default) or the current one fades out continuously
        (:func:`tudorvision.joint.planner.blend_replan`).

    Examples
    --------
    >>> from tudorvision.sim.arm import ElasticArm
    >>> ca = ControlledArm(ElasticArm([0.0, 0.5, 0.0]))
    >>> ca.set_velocity([0.0, 0.2, 0.0])
    >>> ca.run(0.5)
    >>> round(ca.arm.dtheta[1], 2)
    0.2
    """

    def __init__(self, arm: Plant, *, gains=None, v_max=None, a_max=None, damping=None, friction=None,
                 saturate_speed: bool = True, replan: str = "restart"):
        if replan not in REPLAN_MODES:
            raise ValueError(f"replan: expected one of {REPLAN_MODES}, got {replan!r}")
        self.replan = replan
        self.arm = arm
        p = arm.params
        self.v_max = np.minimum(p.experiment_speed_rad_s, p.max_speed_rad_s) if v_max is None \
            else check_vector(np.broadcast_to(np.asarray(v_max, float), (3,)), "v_max", 3)
        self.a_max = np.minimum(p.experiment_accel_rad_s2, p.max_accel_rad_s2) if a_max is None \
            else check_vector(np.broadcast_to(np.asarray(a_max, float), (3,)), "a_max", 3)
        self.controller = JointCascade(gains or design_cascade(p, arm.design_inertia_kg_m2(), **hold_loop_of(arm)),
                                       arm.dt, arm.measured_theta(), friction=friction,
                                       max_speed_rad_s=p.max_speed_rad_s if saturate_speed else None)
        self.damping = damping
        # -- joint-layer hooks (tudorvision.joint.damping / .collision) --------------------
        self.damper = None          # StrainDamper: strain feedback (velocity and position level)
        self.reaction = None        # CollisionMonitor: residual observer and reaction admittance
        # ----------------------------------------------------------------------------------
        self._planner = OnlinePlanner(arm.theta, v_max=self.v_max, a_max=self.a_max, t0=arm.t)
        self.mode = "setpoint"
        self.theta_ref = list(arm.theta)
        self.dtheta_ref = [0.0, 0.0, 0.0]
        self.ddtheta_ref = [0.0, 0.0, 0.0]
        self._v_cmd = [0.0, 0.0, 0.0]
        self._lo = [float(x) for x in p.joint_limits_rad[:, 0]]
        self._hi = [float(x) for x in p.joint_limits_rad[:, 1]]

    def set_goal(self, theta_goal, *, v_max=None, a_max=None) -> None:
        """Start (or re-plan) a point-to-point motion to ``theta_goal`` (rad).

        Raises
        ------
        ValueError
            If the goal lies outside the joint ranges or a limit exceeds the hardware limits.
        """
        goal = check_vector(theta_goal, "theta_goal", 3)
        p = self.arm.params
        if np.any(goal < p.joint_limits_rad[:, 0]) or np.any(goal > p.joint_limits_rad[:, 1]):
            raise ValueError(f"theta_goal: {np.round(np.rad2deg(goal), 2).tolist()} deg "
                             "is outside the joint ranges")
        vmax = self.v_max if v_max is None else np.broadcast_to(np.asarray(v_max, float), (3,))
        amax = self.a_max if a_max is None else np.broadcast_to(np.asarray(a_max, float), (3,))
        if np.any(vmax > p.max_speed_rad_s + 1e-9) or np.any(amax > p.max_accel_rad_s2 + 1e-9):
            raise ValueError("v_max, a_max: exceed the joint speed or acceleration limits")
        if self.replan == "blend" and self.mode == "setpoint":
            th, dth, ddth = self._planner.motion.sample_scalar(self.arm.t)
            self._planner.motion = blend_replan(th, dth, ddth, goal, v_max=vmax, a_max=amax, t0=self.arm.t)
        else:
            self._planner.motion = plan_motion(self.theta_ref, goal, v_max=vmax, a_max=amax,
                                               dtheta_start=self.dtheta_ref, t0=self.arm.t)
        self.mode = "setpoint"

    def set_velocity(self, dtheta_cmd) -> None:
        """Follow a joint velocity command (rad/s), clipped to ``v_max``, ramped at ``a_max``."""
        v = check_vector(dtheta_cmd, "dtheta_cmd", 3)
        self._v_cmd = [float(x) for x in np.clip(v, -self.v_max, self.v_max)]
        self.mode = "velocity"

    def stop(self) -> None:
        """Brake at the acceleration limits and hold where the arm comes to rest."""
        self.set_velocity([0.0, 0.0, 0.0])

    def _reference(self, t: float):
        """Reference ``(theta, dtheta, ddtheta)`` of the cascade at time ``t``."""
        if self.mode == "setpoint":
            return self._planner.sample_scalar(t)
        dt = self.arm.dt
        th, dth = self.theta_ref, self.dtheta_ref
        out_th, out_dth = [0.0] * 3, [0.0] * 3
        for j in range(3):
            dv_max = float(self.a_max[j]) * dt
            v = dth[j] + max(-dv_max, min(dv_max, self._v_cmd[j] - dth[j]))
            # brake so that the joint stops inside its range
            a = float(self.a_max[j])
            room_hi, room_lo = self._hi[j] - th[j], th[j] - self._lo[j]
            if v > 0 and v * v / a > 2 * max(room_hi, 0.0):
                v = max(dth[j] - dv_max, 0.0)
            elif v < 0 and v * v / a > 2 * max(room_lo, 0.0):
                v = min(dth[j] + dv_max, 0.0)
            out_dth[j] = v
            out_th[j] = min(self._hi[j], max(self._lo[j], th[j] + v * dt))
        return out_th, out_dth, [(out_dth[j] - dth[j]) / dt for j in range(3)]

    def step(self) -> None:
        """Advance one control sample (``arm.dt``)."""
        arm = self.arm
        th_ref, dth_ref, self.ddtheta_ref = self._reference(arm.t)
        self.theta_ref, self.dtheta_ref = th_ref, dth_ref
        extra = self.damping(arm) if self.damping is not None else (0.0, 0.0, 0.0)
        th_meas = arm.measured_theta()
        if self.damper is not None or self.reaction is not None:
            th_ref, dth_ref, extra = self._joint_layer(th_meas, th_ref, dth_ref, extra)
        arm.step(self.controller.step(th_meas, th_ref, dth_ref, extra))

    # -- joint-layer hooks ----------------------------------------------------------------------
    def set_damper(self, damper) -> None:
        """Use a :class:`tudorvision.joint.damping.StrainDamper` (``None``: bare cascade).

        The damper's ``pd_scale`` multiplies the PD position gain while it is set
        (0.5 for the integral law of section 6.5).
        """
        self.damper = damper
        scale = 1.0 if damper is None else float(damper.pd_scale)
        self.controller.set_pd_scale(scale)

    def _joint_layer(self, th_meas, th_ref, dth_ref, extra):
        """Apply the damping law and the collision reaction to the cascade inputs."""
        arm = self.arm
        if self.damper is not None:
            dv, dth = self.damper.step(arm.measured_strain(), (th_ref, dth_ref, self.ddtheta_ref))
            extra = [extra[j] + dv[j] for j in range(3)]
            th_ref = [th_ref[j] + dth[j] for j in range(3)]
        if self.reaction is not None:
            out = self.reaction.step(th_meas, self.controller.velocity, arm.measured_strain(),
                                     th_ref, dth_ref, extra)
            if out is not None:      # the reaction replaces the PD output (section 11.2)
                th_ref, dth_ref, extra = out
                self.theta_ref, self.dtheta_ref = list(th_ref), [0.0, 0.0, 0.0]
                self.mode, self._v_cmd = "velocity", [0.0, 0.0, 0.0]   # hold after the release
        return th_ref, dth_ref, extra

    @property
    def velocity_command(self) -> list:
        """The joint velocity command being followed in velocity mode, rad/s (zeros after :meth:`stop`)."""
        return list(self._v_cmd)

    def run(self, duration_s: float, *, on_step=None) -> None:
        """Advance ``duration_s`` seconds (rounded to whole samples).

        Parameters
        ----------
        duration_s : float
            Seconds.
        on_step : callable, optional
            ``f(controlled_arm)`` called after every sample (e.g. a recorder).
        """
        for _ in range(int(round(duration_s / self.arm.dt))):
            self.step()
            if on_step is not None:
                on_step(self)
class CascadeCore:
    """An arm under its cascade as a core of the joint-layer server (:class:`tudorvision.joint.server.JointCore`).

    Wraps :class:`ControlledArm` around any :class:`~tudorvision.joint.plant.Plant`;
    :meth:`step` sub-steps at the plant's sample time. The virtual lab's
    ``SimCore`` (:mod:`tudorvision.lab.sim_core`) is this core around the
    simulated elastic arm.

    :meth:`set_modes` (called by the server on a mode switch) installs the
    joint layer's damping and collision handling on the cascade: a
    :class:`tudorvision.joint.damping.StrainDamper` with the tuned gains of
    the law (one-way or two-way plant) and, when a strain-dynamics model is
    given, a :class:`tudorvision.joint.collision.CollisionMonitor` with the
    strategy (``NONE`` detects and reports only). The residuals and the
    latched collision flag appear in :meth:`state`; a detected collision
    stays latched (the reaction keeps replacing the PD output) until the
    next :meth:`set_modes` call. The selected codes are kept in
    ``self.damping`` and ``self.collision``.

    Parameters
    ----------
    arm : Plant
        The arm, at rest where the core takes over.
    settle_band : float
        Strain settling band, m/m (15 um/m in the seed).
    collision_model : StrainDynamicsModel, optional
        Identified strain-referred dynamics (10.2.8) for the momentum
        residual; without it collision modes are recorded but nothing is
        detected (a warning is issued when a reaction strategy is selected).
    collision_thresholds : array_like, shape (2,), optional
        Residual thresholds of the link-2 and link-3 root strains, m/m
        (required with ``collision_model``).
    collision_coupling : ResidualCoupling, optional
        Share of the link-2 residual in the link-3 residual (fitted on the
        same collision-free data as the thresholds); isolation then runs on
        the decoupled residual ``r3 - c(m) r2`` with a 20 ms window
        (:class:`tudorvision.joint.collision.CollisionMonitor`).
    collision_transient_gain : float
        Thresholds widened after changes of planned acceleration by this multiple of the inertial
        transient due (:class:`~tudorvision.joint.collision_transient.TransientAllowance`); 0: fixed.
    damping_model : StrainDynamicsModel, optional
        Identified strain-referred dynamics for the model-assisted static
        strain cancellation of the installed damper (``StrainDamper(...,
        strain_model=...)``, proportional gains ``ASSISTED_GAINS``); default
        none (the seed's double moving average alone).
    replan : {"restart", "blend"}
        How a setpoint re-plans a motion in flight (:class:`ControlledArm`); default the seed's restart.
    damping_gains : tuple of 3 floats or array_like, shape (M, 4), optional
        ``k_eps`` of every law the mode switch installs instead of the tuned gains (rad/s per m/m for the
        proportional law); default the tuned ones (:func:`~tudorvision.joint.damping.default_damping_config`).
        Or a table of rows ``(payload_kg, k1, k2, k3)``: the gains follow the payload the layer is told
        (:func:`~tudorvision.joint.damping_gains.scheduled_gains`).

    Examples
    --------
    >>> from tudorvision.sim.arm import ElasticArm
    >>> core = CascadeCore(ElasticArm(np.deg2rad([0.0, 90.0, 0.0])))
    >>> core.apply_setpoint(np.deg2rad([0.0, 80.0, 0.0]), max_speed_rad_s=np.full(3, 1.0),
    ...                     max_accel_rad_s2=np.full(3, 3.0))
    >>> core.step(1.5)
    >>> round(float(np.rad2deg(core.state().theta[1])), 1)
    80.0
    """

    def __init__(self, arm: Plant, *, settle_band: float = 15e-6,
                 collision_model=None, collision_thresholds=None, collision_coupling=None, damping_model=None,
                 collision_transient_gain: float = 0.0, replan: str = "restart", damping_gains=None):
        self.damping_model = damping_model
        self._gain_table = None if damping_gains is None else gain_table(damping_gains)    # checks both forms
        self.damping_gains = None if damping_gains is None or self._gain_table is not None else \
            tuple(float(k) for k in np.asarray(damping_gains, float))
        if not collision_transient_gain >= 0:
            raise ValueError(f"collision_transient_gain: expected >= 0, got {collision_transient_gain!r}")
        self.collision_transient_gain = float(collision_transient_gain)
        if collision_coupling is not None and collision_model is None:
            raise ValueError("collision_coupling: needs collision_model and collision_thresholds")
        self.collision_coupling = collision_coupling
        if (collision_model is None) != (collision_thresholds is None):
            raise ValueError("collision_model, collision_thresholds: give both or neither")
        self.collision_model = collision_model
        self.collision_thresholds = None if collision_thresholds is None else \
            [float(x) for x in check_vector(collision_thresholds, "collision_thresholds", 2)]
        p = arm.params
        self.controlled = ControlledArm(arm, v_max=p.max_speed_rad_s, a_max=p.max_accel_rad_s2, replan=replan)
        self.damping, self.collision = 0, 0
        #: payload mass the layer knows (kg): the lab's payload at start, then what
        #: :meth:`set_payload` says (the layer never reads the plant's payload afterwards)
        self.payload_kg = float(arm.payload_kg)
        self._band = float(settle_band)
        self._mean = list(arm.strain)              # static strain estimate (two cascaded EMAs)
        self._mean1 = list(arm.strain)
        self._env = [0.0, 0.0, 0.0, 0.0]          # decaying peak of |strain - mean|
        self._goal = None

    @property
    def arm(self) -> Plant:
        return self.controlled.arm

    def apply_velocity(self, theta_dot) -> None:
        self._goal = None
        self.controlled.set_velocity(theta_dot)

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2) -> None:
        p = self.arm.params
        self.controlled.set_goal(theta, v_max=np.minimum(max_speed_rad_s, p.max_speed_rad_s),
                                 a_max=np.minimum(max_accel_rad_s2, p.max_accel_rad_s2))
        self._goal = check_vector(theta, "theta", 3)

    def stop(self) -> None:
        self._goal = None
        self.controlled.stop()

    def set_modes(self, *, damping, collision) -> None:
        """Install the damping law and the collision monitor of the given codes.

        Parameters
        ----------
        damping : int or Damping
            0 off, 1 proportional, 2 integral, 3 half-integrator.
        collision : int or CollisionStrategy
            0 none (detect and report only), 1 stop, 2 reflex, 3 interaction.

        Raises
        ------
        ValueError
            On an unknown code.
        """
        d, c = int(damping), int(collision)
        if not 0 <= d < len(LAWS) or c not in STRATEGY_OF_CODE:
            raise ValueError(f"damping, collision: unknown codes {damping!r}, {collision!r}")
        ca, arm = self.controlled, self.arm
        if ca.damper is None or ca.damper.config.law != LAWS[d]:
            ca.set_damper(None if d == 0 else StrainDamper(
                self._damping_config(LAWS[d]), arm.measured_strain(), arm.dt,
                strain_model=self.damping_model, payload_kg=self.payload_kg))
        strategy = STRATEGY_OF_CODE[c]
        if self.collision_model is None:
            ca.reaction = None
            if strategy != "none":
                warnings.warn(f"CascadeCore: collision strategy {strategy!r} selected without a collision_model; "
                              "nothing is detected", RuntimeWarning, stacklevel=2)
        else:                   # a fresh monitor: the latch is cleared, the observer restarts at rest state
            ca.reaction = CollisionMonitor(self.collision_model, self.collision_thresholds, self.payload_kg,
                                           arm.dt, reaction_config(
                                               strategy, torque_per_strain=root_torque_per_strain(arm.params)),
                                           armed_after_s=0.1 if arm.t < 0.1 else 0.0,   # start-up sag
                                           isolation_coupling=self.collision_coupling,
                                           isolation_window_s=0.015 if self.collision_coupling is None else 0.02,
                                           transient_gain=self.collision_transient_gain)
        self.damping, self.collision = damping, collision

    def _damping_config(self, law: str):
        gains = self.damping_gains if self._gain_table is None else scheduled_gains(self._gain_table, self.payload_kg)
        over = {} if gains is None else {"k_eps": gains}
        return default_damping_config(law, plant=gain_set_of(self.arm), assisted=self.damping_model is not None,
                                      payload_kg=self.payload_kg, **over)

    def set_payload(self, payload_kg: float) -> None:
        """Tell the layer the payload mass (kg, end effector total: mount, plates, balls).

        The installed damper's gains follow the payload schedule
        (:data:`tudorvision.joint.damping_gains.PAYLOAD_SCHEDULES`), its strain model and
        the collision monitor's momentum observer use the new mass. The plant's
        payload is not touched (that is the lab's :meth:`ElasticArm.set_payload`).

        Raises
        ------
        ValueError
            If ``payload_kg`` is not a finite mass in [0, 5] kg.
        """
        self.payload_kg = m = check_mass(payload_kg, max_kg=MAX_PAYLOAD_KG)
        ca = self.controlled
        if ca.damper is not None:
            ca.damper.set_gains(self._damping_config(ca.damper.config.law).k_eps)
            ca.damper.set_payload(m)
        if ca.reaction is not None:
            ca.reaction.set_payload(m)

    def step(self, dt: float) -> None:
        arm = self.arm
        n = max(1, int(round(float(dt) / arm.dt)))
        a = arm.dt / 0.5                    # second-order smoothing (section 2.2), 0.5 s
        decay = math.exp(-arm.dt / 0.5)     # peak envelope forgets within ~0.5 s
        for _ in range(n):
            self.controlled.step()
            s = arm.strain
            for k in range(4):
                self._mean1[k] += a * (s[k] - self._mean1[k])
                self._mean[k] += a * (self._mean1[k] - self._mean[k])
                self._env[k] = max(abs(s[k] - self._mean[k]), self._env[k] * decay)

    def state(self):
        arm = self.arm
        strain = np.asarray(arm.measured_strain())
        calm = max(self._env) < self._band
        at_rest = bool(np.all(np.abs(np.asarray(arm.dtheta)) < 1e-3))
        reached = self._goal is None or bool(np.all(np.abs(np.asarray(arm.theta) - self._goal) < 1e-3))
        settled = calm and at_rest and reached and self.controlled.mode == "setpoint" \
            or (calm and at_rest and self.controlled.mode == "velocity"
                and not any(self.controlled.velocity_command))
        mon = self.controlled.reaction
        residuals = np.zeros(3) if mon is None else np.asarray(mon.residual, float)
        return CoreState(t=arm.t, theta=np.asarray(arm.theta, float), theta_dot=np.asarray(arm.dtheta, float),
                         strains=strain, residuals=residuals, collision=bool(mon is not None and mon.collision),
                         settled=bool(settled))
