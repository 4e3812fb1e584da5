"""The simulated TUDOR under the joint layer's controller: simulation runs and the ``sim`` core.

* :func:`simulate`, :func:`simulate_ptp`: the plant (:class:`tudorvision.sim.arm.ElasticArm`)
  and the joint cascade run together, recorded as a :class:`tudorvision.sim.arm.SimLog`;
* :func:`run_recorded`: advance a :class:`tudorvision.joint.controlled.ControlledArm`
  around the simulated arm and record every sample;
* :class:`SimCore`: the joint layer's :class:`~tudorvision.joint.controlled.CascadeCore`
  around a freshly built elastic arm; registered as the server core ``"sim"``
  when :mod:`tudorvision.lab` is imported.
"""
from __future__ import annotations

import numpy as np

from .._checks import check_vector
from ..joint.cascade import JointCascade, design_cascade
from ..joint.controlled import CascadeCore, ControlledArm
from ..joint.damping_gains import hold_loop_of
from ..joint.planner import plan_motion
from ..robot.params import RobotParams, load_robot_params
from ..sim.arm import ElasticArm, Payload, PlantConfig, SimLog, zero_config_inertia

__all__ = ["simulate", "simulate_ptp", "run_recorded", "SimCore"]


def simulate(arm: ElasticArm, controller: JointCascade, reference, duration_s: float, *,
             dtheta_extra=None) -> SimLog:
    """Run the plant and the joint cascade together for ``duration_s``.

    Parameters
    ----------
    arm : ElasticArm
        Plant, advanced in place.
    controller : JointCascade
        Joint controller, advanced in place (same ``dt`` as the plant).
    reference : object with ``sample(t) -> (theta, dtheta, ddtheta)``
        E.g. a :class:`tudorvision.joint.planner.JointMotion`; sampled at all
        step times up front.
    duration_s : float
        Simulated time, seconds.
    dtheta_extra : callable, optional
        ``f(arm) -> 3 floats`` added at the velocity-loop input each step (damping hook).

    Returns
    -------
    SimLog
    """
    dt = arm.config.dt
    if abs(controller.dt - dt) > 1e-12:
        raise ValueError(f"controller.dt: expected the plant step {dt}, got {controller.dt}")
    n = int(round(duration_s / dt))
    if n < 1:
        raise ValueError(f"duration_s: expected at least one step of {dt} s, got {duration_s}")
    times = arm.t + dt * np.arange(n)          # reference at the sample instant
    ref_th, ref_dth, _ = reference.sample(times)
    ref_th, ref_dth = ref_th.tolist(), ref_dth.tolist()
    rec = _Recorder()
    zero = (0.0, 0.0, 0.0)
    for k in range(n):
        extra = dtheta_extra(arm) if dtheta_extra is not None else zero
        v = controller.step(arm.measured_theta(), ref_th[k], ref_dth[k], extra)
        arm.step(v)
        rec.add(arm, ref_th[k], ref_dth[k])
    return rec.log(arm.params)


class _Recorder:
    """Collects the per-step state of an :class:`ElasticArm` into a :class:`SimLog`."""

    _KEYS = ("t", "theta", "dtheta", "ddtheta", "ref", "dref", "tau", "strain", "tip2", "tip3", "fc")

    def __init__(self):
        self.cols = {k: [] for k in self._KEYS}

    def add(self, arm: "ElasticArm", theta_ref, dtheta_ref) -> None:
        c = self.cols
        c["t"].append(arm.t)
        c["theta"].append(list(arm.theta))
        c["dtheta"].append(list(arm.dtheta))
        c["ddtheta"].append(list(arm.ddtheta))
        c["ref"].append(theta_ref)
        c["dref"].append(dtheta_ref)
        c["tau"].append(arm.tau)
        c["strain"].append(arm.strain)
        c["tip2"].append(arm.tip2)
        c["tip3"].append(arm.tip3)
        c["fc"].append(arm.contact_force)

    def log(self, params: RobotParams) -> SimLog:
        c = {k: np.asarray(v, dtype=np.float64) for k, v in self.cols.items()}
        return SimLog(t=c["t"], theta=c["theta"], dtheta=c["dtheta"], ddtheta=c["ddtheta"],
                      theta_ref=c["ref"], dtheta_ref=c["dref"], tau=c["tau"], strain=c["strain"],
                      tip2=c["tip2"], tip3=c["tip3"], contact_force=c["fc"], params=params)


def simulate_ptp(theta_start, theta_goal, duration_s: float, *, payload: Payload | None = None,
                 v_max=None, a_max=None, t_move: float = 0.0, params: RobotParams | None = None,
                 config: PlantConfig = PlantConfig(), obstacles=()) -> SimLog:
    """Simulate a point-to-point motion with the planner, cascade and elastic plant.

    Parameters
    ----------
    theta_start, theta_goal : array_like, shape (3,)
        Radians. The arm starts at rest in static equilibrium at ``theta_start``.
    duration_s : float
        Total simulated time, seconds.
    payload : Payload, optional
        End-effector payload; default the mount with the camera rig
        (``Payload.from_parts(params, camera=True)``).
    v_max, a_max : float or array_like, optional
        Planner limits, rad/s and rad/s^2; default the experiment values of chapter 8 (60 deg/s,
        200 deg/s^2) capped by each joint's maximum speed and acceleration.
    t_move : float
        When the motion starts, seconds.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    config : PlantConfig, optional
        Options of the simulated arm (step, bending modes, gravity, encoder).
    obstacles : sequence of SpringDamperObstacle, optional
        Contact obstacles in the base frame.

    Returns
    -------
    SimLog
        Every control sample of the run (angles, strains, references).

    Raises
    ------
    ValueError
        If a goal lies outside the joint ranges or a limit exceeds the hardware limits.

    Examples
    --------
    >>> log = simulate_ptp([0, 0.5, 0], [0, 0.6, 0], 0.05)
    >>> log.strain.shape
    (100, 4)
    """
    p = params or load_robot_params()
    goal = check_vector(theta_goal, "theta_goal", 3)
    start = check_vector(theta_start, "theta_start", 3)
    lo, hi = p.joint_limits_rad[:, 0], p.joint_limits_rad[:, 1]
    for name, th in (("theta_start", start), ("theta_goal", goal)):
        if np.any(th < lo - 1e-9) or np.any(th > hi + 1e-9):
            raise ValueError(f"{name}: {np.round(np.rad2deg(th), 2).tolist()} deg "
                             "is outside the joint ranges")
    vmax = np.minimum(p.experiment_speed_rad_s, p.max_speed_rad_s) if v_max is None \
        else np.broadcast_to(np.asarray(v_max, float), (3,))
    amax = np.minimum(p.experiment_accel_rad_s2, p.max_accel_rad_s2) if a_max is None \
        else np.broadcast_to(np.asarray(a_max, float), (3,))
    if np.any(vmax > p.max_speed_rad_s + 1e-9) or np.any(amax > p.max_accel_rad_s2 + 1e-9):
        raise ValueError("v_max, a_max: exceed the joint speed or acceleration limits of the parameter file")
    arm = ElasticArm(start, payload=payload, params=p, config=config, obstacles=obstacles)
    gains = design_cascade(p, zero_config_inertia(arm), **hold_loop_of(arm))
    ctrl = JointCascade(gains, config.dt, arm.measured_theta())
    motion = plan_motion(start, goal, v_max=vmax, a_max=amax, t0=t_move)
    return simulate(arm, ctrl, motion, duration_s)


def run_recorded(controlled: ControlledArm, duration_s: float) -> SimLog:
    """Advance a controlled simulated arm ``duration_s`` seconds and record every sample.

    Parameters
    ----------
    controlled : ControlledArm
        Around an :class:`~tudorvision.sim.arm.ElasticArm` (advanced in place).
    duration_s : float
        Seconds, rounded to whole samples.

    Returns
    -------
    SimLog
        The states after every sample, with the cascade's references (e.g. to
        change goals between calls and concatenate).
    """
    rec = _Recorder()
    controlled.run(duration_s, on_step=lambda ca: rec.add(ca.arm, ca.theta_ref, ca.dtheta_ref))
    return rec.log(controlled.arm.params)


class SimCore(CascadeCore):
    """The simulated elastic TUDOR as the joint layer's core (server core ``"sim"``).

    A :class:`~tudorvision.joint.controlled.CascadeCore` around a new
    :class:`~tudorvision.sim.arm.ElasticArm`; see there for the modes, the
    payload schedule and settling.

    Parameters
    ----------
    theta0 : array_like, shape (3,), optional
        Initial angles (rad); default the vertical posture [0, 90 deg, 0].
    payload : Payload, optional
        End-effector payload; default the mount with the camera rig
        (``Payload.from_parts(params, camera=True)``).
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    config : PlantConfig, optional
        Options of the simulated arm (step, bending modes, gravity, encoder).
    obstacles : sequence of SpringDamperObstacle, optional
        Contact obstacles in the base frame.
    **options
        ``settle_band``, ``collision_model``, ``collision_thresholds``,
        ``collision_coupling``, ``damping_model``, ``damping_gains``, ``replan`` of :class:`CascadeCore`.

    Raises
    ------
    ValueError
        On a malformed ``theta0`` or inconsistent collision options.

    Examples
    --------
    >>> core = SimCore()
    >>> core.apply_setpoint(np.deg2rad([0.0, 80.0, 0.0]), max_speed_rad_s=np.full(3, 1.0),
    ...                     max_accel_rad_s2=np.full(3, 3.0))
    >>> core.step(1.5)
    >>> round(float(np.rad2deg(core.state().theta[1])), 1)
    80.0
    """

    def __init__(self, theta0=None, *, payload: Payload | None = None, params: RobotParams | None = None,
                 config: PlantConfig = PlantConfig(), obstacles=(), **options):
        th = np.array([0.0, np.pi / 2, 0.0]) if theta0 is None else check_vector(theta0, "theta0", 3)
        super().__init__(ElasticArm(th, payload=payload, params=params, config=config, obstacles=obstacles),
                         **options)
