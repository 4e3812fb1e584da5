"""The catching side of the demo: perception, intercept, compensated IK, commands through the joint layer.

The agent sees the world only through the wall camera's frames
(:class:`~tudorvision.lab.catch.scenario.CameraFrame`) and the calibrated
camera extrinsics, and acts on the arm only through the joint layer: the
:class:`~tudorvision.joint.adapter.JointAdapter` of a
:class:`~tudorvision.lab.lockstep.LockstepLayer` (setpoints, mode, payload)
and the layer's state message (joint angles, speeds, strains, flags). It
never reads the simulated arm or the true ball; it weighs the payload from
the strains the layer reports. In the lockstep lab, waiting means advancing
the layer's simulated clock (:func:`pause_and_weigh`).

Per frame::

    depth image -> BallDetector (background subtraction)  |  modelled detection
    -> camera frame -> base frame (T_base_cam) -> CatchPerception (EKF, intercept, release rule)
    -> net target -> compensated IK (deflection model, estimated payload) -> JointAdapter.send_setpoint
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...catch.intercept import inner_reach_m, net_target
from ...catch.payload import PayloadBelief, between_throws
from ...catch.perception import detection_to_base
from .profile import ReferenceMirror, elbow_frequency_factor, hedged_goal, net_modes, overshoot_lead_target
from .planes import CatchIK, choose_plane, plane_candidates

__all__ = ["CatchAgent", "ThrowLog", "WEIGH_REST_SPEED_RAD_S", "pause_and_weigh",
           "profile_limits", "demo_inner_reach_m", "PREDICTION_COLUMNS", "SETPOINT_COLUMNS"]

WEIGH_REST_SPEED_RAD_S = 0.02   # joints slower than this throughout the weighing window: the arm rests
WEIGH_WINDOW_S = 0.6            # the payload is weighed from the strains of the pause's last 0.6 s
READY_SETTLE_S = 0.1            # a shaped return to the ready pose ends this long before the weighing window
ARRIVED_TOL_RAD = float(np.deg2rad(1.0))
#: Profile accelerations (fractions of the demo's) a shaped return to the ready pose may take (``ready_shaping``).
READY_ACCELS = (1.0, 0.7, 0.5, 0.35)

#: Columns of the agent's prediction rows (``predictions.csv``): one per intercept estimate.
PREDICTION_COLUMNS = ["throw", "t_s", "status", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", "t_cross_s",
                      "x_cross_m", "y_cross_m", "z_cross_m", "sigma_m", "reachable", "send", "x_ballistic_m",
                      "y_ballistic_m", "z_ballistic_m"]
#: Columns of the agent's setpoint rows (``setpoints.csv``): one per intercept setpoint sent.
SETPOINT_COLUMNS = ["throw", "t_s", "theta1_rad", "theta2_rad", "theta3_rad", "x_target_m", "y_target_m",
                    "z_target_m"]


def profile_limits(options, params) -> tuple[float, float]:
    """Setpoint profile speed and acceleration of the demo, rad/s and rad/s^2.

    The speed is ``speed_fraction`` of the slowest joint's limit: at the
    limit itself the links' swing pushed the measured joint speed past the
    layer's fault threshold (105 %).

    Parameters
    ----------
    options : DemoOptions
        ``speed_fraction`` and ``accel_fraction``.
    params : RobotParams
        Joint speed and acceleration limits.

    Returns
    -------
    tuple of float
        ``(max_speed, max_accel)``.
    """
    return (options.speed_fraction * float(np.min(params.max_speed_rad_s)),
            options.accel_fraction * float(np.min(params.max_accel_rad_s2)))


def demo_inner_reach_m(options, params) -> float:
    """The demo's inner edge of the reach, m: joint 3 at its range less its setpoint margin (0 if not ``inner_pull``).

    Parameters
    ----------
    options : DemoOptions
        ``inner_pull`` and ``setpoint_margin_rad``.
    params : RobotParams
        Link lengths and joint ranges.

    Returns
    -------
    float
    """
    if not options.inner_pull:
        return 0.0
    margin = np.broadcast_to(np.asarray(options.setpoint_margin_rad, float), (3,))
    return inner_reach_m(params, float(margin[2]))


def pause_and_weigh(layer, t_now: float, duration: float, rate: float, weigh_s: float = WEIGH_WINDOW_S,
                    on_frame=None):
    """Advance the layer by ``duration`` s; strains sampled at ``rate`` over the last ``weigh_s`` s.

    Parameters
    ----------
    layer : LockstepLayer
        Anything with ``advance_to(t)`` and ``state()`` (strains, theta_dot).
    t_now : float
        Current time, s.
    duration : float
        Pause length, s.
    rate : float
        Sampling rate, Hz.
    weigh_s : float
        Length of the weighing window at the end of the pause, s.
    on_frame : callable, optional
        Called with the time (s) after every step (e.g. to clear a fault).

    Returns
    -------
    tuple
        The time at the end, s, and the strain samples (list of (4,) arrays),
        or an empty list when a joint still moved faster than
        :data:`WEIGH_REST_SPEED_RAD_S` during the weighing window (the arm
        had not reached the ready pose yet: its strains carry the motion, not the payload).
    """
    t_end = t_now + duration
    strains, moving = [], False
    while t_now < t_end - 1e-9:
        t_now = min(t_now + 1.0 / rate, t_end)
        layer.advance_to(t_now)
        if on_frame is not None:
            on_frame(t_now)
        if t_end - t_now < weigh_s:
            st = layer.state()
            strains.append(np.asarray(st.strains))
            moving |= bool(np.max(np.abs(st.theta_dot)) > WEIGH_REST_SPEED_RAD_S)
    return t_now, ([] if moving else strains)


@dataclass
class ThrowLog:
    """What the agent saw and did during one throw (its own view, no ground truth).

    Attributes
    ----------
    detections : int
        Ball detections.
    last_intercept : Intercept or None
        The last intercept estimate.
    last_ballistic_base : ndarray, shape (3,), or None
        The ballistic peer's crossing at that estimate, metres, base frame.
    t_first_setpoint_s : float or None
        When the first intercept setpoint was sent, s.
    setpoint : ndarray, shape (3,), or None
        The last intercept setpoint, rad.
    setpoint_p_base : ndarray, shape (3,), or None
        The intercept estimate that setpoint went to, m, base frame.
    t_arrived_s : float or None
        When the joints came within 1 deg of it, s.
    payload_est_kg : float
        The payload estimate used during the throw, kg.
    deferred : int
        Frames a refinement waited because sending it would have made a joint pass its goal.
    kept_branch : int
        IK solutions replaced by the nearest point of the arm's own elbow branch (the other branch's would have
        arrived too late); up to two per setpoint: its target and the target moved back by the overshoot lead.
    passed : int
        Intercept setpoints sent as pass-through goals (``DemoOptions.pass_through``).
    hedged : int
        Joints of the first setpoint sent short of the estimate's goal (``DemoOptions.first_hedge_sigma``).
    yaw_rad : float
        The throw's working plane turned from the fixed one by joint 1, rad (``DemoOptions.yaw_max_rad``).
    """

    detections: int = 0
    last_intercept: object = None
    last_ballistic_base: np.ndarray | None = None
    t_first_setpoint_s: float | None = None
    setpoint: np.ndarray | None = None
    setpoint_p_base: np.ndarray | None = None
    t_arrived_s: float | None = None
    payload_est_kg: float = 0.0
    deferred: int = 0
    kept_branch: int = 0
    passed: int = 0
    hedged: int = 0
    yaw_rad: float = 0.0


class CatchAgent:
    """Catches balls with the arm behind a joint layer, from wall-camera frames.

    Parameters
    ----------
    layer : LockstepLayer
        The joint layer: its ``adapter`` (commands) and ``state()`` (feedback).
    ik : CatchIK
        Net inverse kinematics.
    strain_model : StrainModel
        Payload estimator from settled strains (:class:`~tudorvision.catch.kinematics.StrainModel`).
    perception : CatchPerception
        Ball filter, intercept planner and ballistic peer.
    detector : BallDetector
        Ball detector on depth images (rendered mode).
    T_base_cam : ndarray, shape (4, 4)
        The wall camera's calibrated extrinsics.
    options : DemoOptions
        The demo's options (damping, profile, margins, ready point).
    params : RobotParams
        The robot's parameters (limits, mount mass).
    payload_range_kg : tuple of float
        Range the payload estimate is clipped to (the kinematics' trained range), kg.
    depth_correction : tudorvision.rgbd.depth_pattern.DepthPatternCorrection, optional
        The wall camera's calibrated depth pattern, removed from every detection
        (:meth:`~tudorvision.rgbd.depth_pattern.DepthPatternCorrection.correct_points`); None: left in.
    intrinsics : tudorvision.rgbd.frames.Intrinsics, optional
        The wall camera's intrinsics (needed with ``depth_correction``).

    Attributes
    ----------
    payload_est_kg : float
        Current payload estimate on top of the mount, kg.
    faults : list of float
        Times of the layer faults cleared, s.
    refused : int
        Setpoints the layer did not acknowledge.
    latencies_s : list of float
        Per detection: detector (rendered mode) + filter + intercept, s (the peer's time excluded).
    predictions : list of list
        Rows of ``predictions.csv`` (:data:`PREDICTION_COLUMNS`).
    setpoints : list of list
        Rows of ``setpoints.csv`` (:data:`SETPOINT_COLUMNS`).
    """

    def __init__(self, layer, ik: CatchIK, strain_model, perception, detector, T_base_cam, *, options, params,
                 payload_range_kg: tuple[float, float], depth_correction=None, intrinsics=None):
        from ...joint import Damping, Mode

        self.layer, self.adapter = layer, layer.adapter
        self.ik, self.strain_model, self.perception, self.detector = ik, strain_model, perception, detector
        self.theta1_rad = float(getattr(ik, "theta1_rad", 0.0))     # the fixed working plane
        self.T_base_cam = np.asarray(T_base_cam, float)
        if depth_correction is not None and intrinsics is None:
            raise ValueError("CatchAgent: depth_correction needs the camera's intrinsics")
        self.depth_correction, self.intrinsics = depth_correction, intrinsics
        self.options, self.params = options, params
        self.inner_reach_m = demo_inner_reach_m(options, params)
        self.payload_range_kg = payload_range_kg
        self.mount_kg = float(params.end_effector_mount_mass_kg)
        self.max_speed, self.max_accel = profile_limits(options, params)
        self.late_speed = float(options.late_speed_fraction) * float(np.min(params.max_speed_rad_s))
        self.lims = np.asarray(params.joint_limits_rad, float)
        self.ready_point_base = np.asarray(options.ready_point_base, float)
        self.damping = {"off": Damping.OFF, "proportional": Damping.PROPORTIONAL, "integral": Damping.INTEGRAL,
                        "half_integrator": Damping.HALF_INTEGRATOR}[options.damping]
        self._mode = Mode.SETPOINT
        self.adapter.set_mode(self._mode, damping=self.damping)
        self.payload_est_kg, self.payload_belief = 0.0, PayloadBelief()
        self.faults: list[float] = []
        self.refused = 0
        self.latencies_s: list[float] = []
        self.predictions: list[list] = []
        self.setpoints: list[list] = []
        self._last_sent = None
        self._throw = -1
        self._pending = False
        self.mirror = ReferenceMirror(self.max_speed, self.max_accel, replan=options.replan)
        self._speed, self._accel = self.max_speed, self.max_accel
        self._ready_goal, self._ready_deadline = None, 0.0
        self.log = ThrowLog()

    # ------------------------------------------------------------------ commands
    def _setpoint(self, theta):
        return self.adapter.send_setpoint(theta, max_speed=self._speed, max_accel=self._accel, timeout=5.0)

    def _clear_fault_and_resend(self, theta, t: float):
        # the layer stopped the arm (speed or range fault): log it, clear it (a FaultReset: since protocol v2 a
        # mode switch no longer clears FAULT), restore the mode and send again
        self.faults.append(float(t))
        self.adapter.reset_fault()
        self.adapter.set_mode(self._mode, damping=self.damping)
        self.mirror.reset(self.layer.state().theta, t)      # the stop left the reference where the arm is
        reply = self._setpoint(theta)
        self.mirror.sent(theta, t, v_max=self._speed, a_max=self._accel)
        return reply

    def send(self, theta, t: float, speed: float | None = None, accel: float | None = None) -> bool:
        """Send a joint setpoint (rad, (3,)) at time ``t`` (s); a fault stop is cleared and the setpoint resent.

        ``speed``: the profile speed, rad/s (default the demo's, :func:`profile_limits`), at most the
        faster of the demo's and the late-move speed (``DemoOptions.late_speed_fraction``); ``accel``: the
        profile acceleration, rad/s^2 (default and at most the demo's).

        Returns
        -------
        bool
            Whether the layer acknowledged it.
        """
        from ...joint import Ack, Reason, Refusal

        self._last_sent = np.asarray(theta, float)
        self._speed = self.max_speed if speed is None else float(min(speed, max(self.max_speed, self.late_speed)))
        self._accel = self.max_accel if accel is None else float(min(accel, self.max_accel))
        reply = self._setpoint(theta)
        self.mirror.sent(theta, t, theta_now=self.layer.state().theta, v_max=self._speed, a_max=self._accel)
        if isinstance(reply, Refusal) and reply.code == Reason.FAULT:
            reply = self._clear_fault_and_resend(theta, t)
        ok = isinstance(reply, Ack)
        self.refused += not ok
        return ok

    def recover(self, t: float) -> None:
        """Clear a fault stop at once and send the last setpoint again (checked every frame), at ``t`` (s)."""
        from ...joint import StateFlags

        if self._last_sent is not None and self.layer.state().flags & StateFlags.FAULT:
            self._clear_fault_and_resend(self._last_sent, t)

    # ------------------------------------------------------------------ one throw
    def learn_background(self, depth_mm) -> None:
        """Feed an empty-scene depth frame (uint16 mm) to the detector's background model."""
        self.detector.update(depth_mm.astype(np.float32) / 1000.0)

    def begin_throw(self, index: int) -> None:
        """Start a new throw's log (the filter notices a new throw by itself)."""
        self._throw = index
        self._fixed_plane()
        self._pending = False
        self.log = ThrowLog(payload_est_kg=self.payload_est_kg)

    def step(self, t: float, frame, *, t_exposure: float | None = None):
        """A camera frame delivered at ``t`` (s): check the layer, perceive, send an intercept setpoint when released.

        The ball filter runs at the frame's exposure time (``frame.t``); the layer is checked and commanded at
        ``t``, when the frame arrives (``DemoOptions.camera_latency_s`` later).

        Parameters
        ----------
        t : float
            Time now, when the frame is delivered, s.
        frame : CameraFrame or None
            The wall camera's frame, stamped with its exposure time (None: nothing delivered).
        t_exposure : float, optional
            Exposure time of the frame slot when ``frame`` is None (default ``t``): a refinement held back by the
            interval goes out on frames without a detection too (``DemoOptions.refine_without_detection_m``).

        Returns
        -------
        tuple or None
            ``(p_base, record)`` for a detection: its base-frame centre (3,) and the perception record
            (:meth:`~tudorvision.catch.perception.CatchPerception.step`); None without one.
        """
        log = self.log
        self.recover(t)
        self._send_ready(t)
        st = self.layer.state()
        if log.setpoint is not None and log.t_arrived_s is None and \
                np.max(np.abs(st.theta - log.setpoint)) < ARRIVED_TOL_RAD:
            log.t_arrived_s = t
        if frame is None:
            self._refine_without_detection(t, t if t_exposure is None else t_exposure, st)
            return None
        t0 = time.perf_counter()
        if frame.depth_mm is not None:
            d = self.detector.update(frame.depth_mm.astype(np.float32) / 1000.0)
            if d is None:
                self._refine_without_detection(t, frame.t, st)
                return None
            p_cam, cov_cam = d.p_cam, d.cov_cam
        else:
            p_cam, cov_cam = frame.detection_cam
        if self.depth_correction is not None:
            p_cam = self.depth_correction.correct_points(p_cam, self.intrinsics)
        log.detections += 1
        p_b, C_b = detection_to_base(p_cam, cov_cam, self.T_base_cam)
        rec = self.perception.step(frame.t, p_b, C_b)
        self.latencies_s.append(time.perf_counter() - t0 - rec["peer_s"])
        it = rec["intercept"]
        if it is not None:
            log.last_intercept = it
            bal = rec["ballistic"][1]
            log.last_ballistic_base = bal
            self.predictions.append([self._throw, frame.t, rec["status"], *rec["x"], it.t_cross, *it.p_base, it.sigma_m,
                                     int(it.reachable), int(it.send), *(bal if bal is not None else [np.nan] * 3)])
            if (it.send or self._pending) and it.t_cross > t:
                # the planner releases only for a crossing still ahead (its own estimate); a refinement that
                # waited goes out with the latest estimate
                self._intercept(t, it, np.asarray(st.theta))
        return p_b, rec

    def _refine_without_detection(self, t: float, t_frame: float, st) -> None:
        """A frame (exposed at ``t_frame``, here at ``t``, s) without a detection: a refinement due goes out.

        The ball leaves the top of the image on high throws for up to 0.4 s; a refinement the minimum interval
        held back, or one waiting for a joint to brake, went out only when it came back. Now it goes out with
        the filter's latest estimate once due (:meth:`~tudorvision.catch.perception.CatchPerception.due`).
        """
        tol = self.options.refine_without_detection_m
        if not tol > 0 or self.log.setpoint is None:
            return
        it = self.perception.due(t_frame, tol_m=tol)
        if it is None and self._pending:
            it = self.log.last_intercept
        if it is not None and it.t_cross > t:
            self.log.last_intercept = it
            self._intercept(t, it, np.asarray(st.theta))

    def _bounds(self):
        """Joint bounds of the setpoints (rad, two (3,) arrays): the ranges less ``setpoint_margin_rad``."""
        # the joints overshoot (joint 2 by up to 8 deg) on fast moves: a setpoint near the edge of a range
        # tripped the layer's range fault (1 deg tolerance); margins per joint
        margin = np.asarray(self.options.setpoint_margin_rad, float)
        return self.lims[:, 0] + margin, self.lims[:, 1] - margin

    def _goal(self, p_base, theta_now, t: float | None = None, deadline: float | None = None):
        """Joint setpoint (rad, (3,)) for the net at ``p_base`` (m) inside the setpoint margins; None: unreachable.

        With ``t`` and ``deadline`` (s) and ``keep_elbow_branch``: a solution on the other elbow branch than
        the arm's (joint 3 swung through the stretched arm) is taken only if its move ends by the deadline;
        else the nearest point the arm's own branch reaches within the margins.
        """
        lo, hi = self._bounds()
        try:
            th = np.clip(self.ik(p_base, self.payload_est_kg, near=theta_now), lo, hi)
        except ValueError:
            return None
        up_now = bool(theta_now[2] > 0)
        if t is None or not self.options.keep_elbow_branch or bool(th[2] > 0) == up_now:
            return th
        if t + self._plan(th, t, theta_now).duration_s <= deadline:
            return th
        self.log.kept_branch += 1
        return self.ik.nearest_on_branch(p_base, self.payload_est_kg, elbow="up" if up_now else "down",
                                         lower_rad=lo, upper_rad=hi)[0]

    def _plan(self, th, t: float, theta_now):
        """The layer's motion to ``th`` (rad, (3,)) sent at ``t`` (s) at the fastest profile speed the agent uses."""
        from ...joint.planner import plan_motion

        speed = max(self.max_speed, self.late_speed)
        if self.mirror.motion is None:
            return plan_motion(theta_now, th, v_max=speed, a_max=self.max_accel, t0=t)
        return self.mirror.plan(th, t, speed)

    def _modes(self, goal):
        """The net's modes for the profile to goal ``goal`` (rad, (3,)): ``((f_hz, weight), ...)``; 0.0: none.

        :func:`~tudorvision.lab.catch.profile.net_modes` of the estimated payload (swinging in the bag when
        ``DemoOptions.mode_swing_hz`` > 0); 0.0 without a mode (``mode_f0_hz`` = 0: the full speed).
        """
        o = self.options
        if not o.mode_f0_hz > 0:
            return 0.0
        # with the elbow map, the arm's mode at the goal, where the residual swing rings
        f0 = o.mode_f0_hz * (elbow_frequency_factor(goal[2]) if o.mode_elbow_map else 1.0)
        return net_modes(self.payload_est_kg, f0, o.mode_mass_kg, o.mode_swing_hz)

    def _profile(self, th, t: float, deadline: float, f, t_cross: float | None = None):
        """Profile speed and acceleration for setpoint ``th`` sent at ``t`` (rad/s, rad/s^2; None: the defaults).

        The least residual swing of the modes ``f`` (:meth:`_modes`) by the deadline over the speeds and the
        accelerations ``DemoOptions.accel_candidates``; a move that cannot end in time at any of them takes the late
        speed at the full acceleration.
        """
        if self.mirror.motion is None:
            return None, None
        v, a = self.mirror.choose_profile(th, t, deadline, f, accels=self.options.accel_candidates,
                                          decay_per_s=self.options.settle_decay_per_s, t_cross_s=t_cross)
        if t + self.mirror.plan(th, t, v, a).duration_s <= deadline:
            return v, a
        return self.mirror.late_speed(th, t, deadline, self.max_speed, self.late_speed), self.max_accel

    def _intercept(self, t: float, it, theta_now) -> None:
        o = self.options
        if self.log.setpoint is None and o.yaw_max_rad > 0 and self.log.yaw_rad == 0.0:   # chosen once a throw
            it = self._choose_plane(t, it, theta_now)
        target = net_target(it.p_base, self.ik.theta1_rad, self.params, reach_margin_m=o.reach_margin_m,
                            inner_reach_m=self.inner_reach_m)
        deadline = it.t_cross - o.arrive_before_s
        th = self._goal(target, theta_now, t, deadline)
        if th is None:
            return
        passing = self._pass_goal(th, t, it.t_cross)
        if passing is not None:
            th = passing
        elif o.overshoot_lead_m > 0 and self.mirror.motion is not None:
            # when the planned profile would end, hence how far the net will still be carried past its goal
            speed, accel = self._profile(th, t, deadline, self._modes(th), it.t_cross)
            t_end = self.mirror.plan(th, t, speed, accel).duration_s + t
            th = self._goal(overshoot_lead_target(target, self.ready_point_base, o.overshoot_lead_m,
                                                  it.t_cross - t_end, fade_s=o.overshoot_fade_s,
                                                  full_move_m=o.overshoot_full_move_m), theta_now, t, deadline)
            if th is None:
                return
        if self.log.setpoint is None and o.first_hedge_sigma > 0:
            hedged = hedged_goal(th, self._plausible_goals(it, th, theta_now), theta_now, o.first_hedge_min_rad)
            self.log.hedged += int(np.sum(hedged != th))
            th = hedged
        if self.log.setpoint is not None:
            if np.max(np.abs(th - self.log.setpoint)) < o.refine_min_joint_rad:
                self._pending = False         # nothing worth a new profile
                return
            if np.max(self.mirror.overshoot_rad(th, t)) > o.overshoot_tol_rad and not self._stale(it):
                self._pending = True          # a joint brakes: wait for a frame where the new plan stops in time
                self.log.deferred += 1
                return
        self._pending = False
        self._ready_goal = None                # the intercept supersedes a ready move still waiting
        if passing is not None:
            self.log.passed += 1
            self.send(th, t, max(self.max_speed, self.late_speed), self.max_accel)
        else:
            self.send(th, t, *self._profile(th, t, deadline, self._modes(th), it.t_cross))
        self.log.setpoint, self.log.setpoint_p_base, self.log.t_arrived_s = th, np.asarray(it.p_base, float), None
        self.setpoints.append([self._throw, t, *th, *it.p_base])
        if self.log.t_first_setpoint_s is None:
            self.log.t_first_setpoint_s = t

    def _choose_plane(self, t: float, it, theta_now):
        """The throw's working plane (``DemoOptions.yaw_max_rad``): ``it`` on the chosen plane, taken for the throw."""
        o, per = self.options, self.perception
        found = {self.theta1_rad: it}

        def slack(th1: float):
            est = it if th1 == self.theta1_rad else per.on_plane(it.t, th1)
            if est is None or not est.reachable:
                return None
            self.ik.theta1_rad = th1
            th = self._goal(net_target(est.p_base, th1, self.params, reach_margin_m=o.reach_margin_m,
                                       inner_reach_m=self.inner_reach_m), theta_now)
            if th is None:
                return None
            found[th1] = est
            return est.t_cross - o.arrive_before_s - t - self._plan(th, t, theta_now).duration_s

        choice = choose_plane(self.theta1_rad + plane_candidates(o.yaw_max_rad, o.yaw_step_rad), slack,
                              o.yaw_margin_s, o.yaw_min_gain_s)
        th1 = self.theta1_rad if choice is None else choice[0]
        self.ik.theta1_rad, self.log.yaw_rad = th1, th1 - self.theta1_rad
        if th1 != self.theta1_rad:
            per.use_plane(th1, found[th1])
        return found[th1]

    def _fixed_plane(self) -> None:
        """Back to the fixed working plane after a throw that turned it (:meth:`_choose_plane`)."""
        if self.log.yaw_rad != 0.0:
            self.ik.theta1_rad = self.theta1_rad

    def _plausible_goals(self, it, th, theta_now):
        """Goals (rad, (K, 3)) on ``th``'s elbow branch for ``it`` moved by ``first_hedge_sigma`` std along its axes."""
        o = self.options
        w, v = np.linalg.eigh(np.asarray(it.cov_base, float))      # in the plane: the two largest
        steps = [s * o.first_hedge_sigma * np.sqrt(max(w[k], 0.0)) * v[:, k] for k in (1, 2) for s in (-1, 1)]
        goals = [self._goal(net_target(np.asarray(it.p_base, float) + d, self.ik.theta1_rad, self.params,
                                       reach_margin_m=o.reach_margin_m, inner_reach_m=self.inner_reach_m), theta_now)
                 for d in steps]
        return np.reshape([g for g in goals if g is not None and (g[2] > 0) == (th[2] > 0)], (-1, 3))

    def _pass_goal(self, th, t: float, t_cross: float):
        """Goals (rad, (3,)) passing ``th`` at the crossing ``t_cross`` (s) for a move that cannot stop in time.

        None unless ``DemoOptions.pass_through`` and the move to ``th`` sent at ``t`` (s) at the late speed ends
        after ``t_cross - pass_margin_s`` (:meth:`~tudorvision.lab.catch.profile.ReferenceMirror.pass_through_goal`).
        """
        o = self.options
        if not o.pass_through or self.mirror.motion is None:
            return None
        if t + self._plan(th, t, None).duration_s <= t_cross - o.pass_margin_s:
            return None
        lo, hi = self._bounds()
        goals, _ = self.mirror.pass_through_goal(th, t, t_cross - o.pass_lead_s, lo, hi,
                                                 v_max=max(self.max_speed, self.late_speed), a_max=self.max_accel)
        return goals if np.any(goals != np.asarray(th, float)) else None    # None: no goal beyond gets there sooner

    def _stale(self, it) -> bool:
        """Whether the net went to an estimate over ``refine_force_m`` from ``it`` (a refinement waits no more)."""
        sent = self.log.setpoint_p_base
        if sent is None:
            return False
        return bool(np.linalg.norm(np.asarray(it.p_base, float) - sent) > self.options.refine_force_m)

    # ------------------------------------------------------------------ between throws
    def return_to_ready(self, t: float) -> None:
        """Send the arm back to the ready pose (the nearest IK solution), at ``t`` (s), once it is safe.

        A joint still moving away from the ready pose (a fast intercept move braking at the end of its
        range) would, re-planned at once, brake later and pass its range limit: the layer's range
        fault then stopped the arm five or six times over and it reached the ready pose only after
        the next release. The ready setpoint waits (checked every frame, :meth:`wait` and
        :meth:`step`) until its re-plan stays ``setpoint_margin_rad`` inside the ranges or the
        current motion has ended.

        With ``DemoOptions.ready_shaping`` the move takes the profile (speed and acceleration) that leaves
        the least swing of the arm's first mode from everything it did since it last rested (the intercept
        move and this one) among those that end before the pause's weighing window
        (:meth:`~tudorvision.lab.catch.profile.ReferenceMirror.choose_profile`); else the demo's profile.
        """
        self._fixed_plane()
        self._ready_goal = self.ik(self.ready_point_base, self.payload_est_kg,
                                   near=np.asarray(self.layer.state().theta))
        self._ready_deadline = t + self.options.gap_s - WEIGH_WINDOW_S - READY_SETTLE_S
        self._send_ready(t)

    def _send_ready(self, t: float) -> None:
        goal = self._ready_goal
        if goal is None:
            return
        m = self.mirror.motion
        if m is not None and t < m.t0 + m.duration_s:
            lo, hi = self.mirror.path_range_rad(goal, t)
            margin = np.asarray(self.options.setpoint_margin_rad, float)
            if np.any(lo < self.lims[:, 0] + margin - 1e-9) or np.any(hi > self.lims[:, 1] - margin + 1e-9):
                return
        self._ready_goal = None
        if self.options.ready_shaping and self.mirror.motion is not None:
            v, a = self.mirror.choose_profile(goal, t, self._ready_deadline, self._modes(goal),
                                              accels=READY_ACCELS)
            self.send(goal, t, v, a)
            return
        self.send(goal, t)

    def wait(self, t_now: float, duration: float, rate: float):
        """Wait ``duration`` s (advancing the lockstep layer); strains of the last 0.6 s at rest.

        Every frame it clears a fault stop and sends a ready move that was waiting (:meth:`return_to_ready`).

        Returns
        -------
        tuple
            ``(t, strains)`` as :func:`pause_and_weigh`.
        """
        def on_frame(t: float) -> None:
            self.recover(t)
            self._send_ready(t)

        return pause_and_weigh(self.layer, t_now, duration, rate, on_frame=on_frame)

    def weigh(self, strains, *, emptied: bool = False) -> None:
        """Weigh the payload from strains at rest (their mean) and tell the layer (it schedules its damping on it).

        Clipped to ``payload_range_kg`` (the kinematics' range); nothing happens without samples, unless
        ``DemoOptions.payload_catch_prior`` > 0: then it is the mean of a belief the throw raised by a ball (if
        tried), ``emptied`` reset and the weighing updated (:func:`~tudorvision.catch.payload.between_throws`)."""
        o, z = self.options, None
        if len(strains):
            st = self.layer.state()
            z = float(self.strain_model.payload(np.asarray(st.theta)[None, 1:], np.mean(strains, axis=0)[None])[0])
        if o.payload_catch_prior > 0:
            p = o.payload_catch_prior if self.log.setpoint is not None else 0.0
            self.payload_belief = between_throws(self.payload_belief, z, ball_kg=self.params.ball_mass_kg,
                                                 p_catch=p, emptied=emptied, sigma_kg=o.payload_weigh_sigma_kg)
            z = self.payload_belief.mean_kg
        if z is not None:
            self.payload_est_kg = float(np.clip(z, *self.payload_range_kg))
            self.adapter.set_payload(self.mount_kg + self.payload_est_kg)
