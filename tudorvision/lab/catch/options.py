"""Options of the catching demo (:func:`~tudorvision.lab.catch.run.run_demo`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...catch.ekf import EKFOptions
from ...robot import RobotParams
from ...sim.depth_sensor import KINECT_PATTERN_DISPARITY_PX
from ..data_collection import DEMO_COLLECTION, PLANTS, CollectionOptions, plant_config
from .calibration import CALIBRATION_METHODS

__all__ = ["DemoOptions", "DAMPING_LAWS", "PLANTS", "plant_config", "trained_payload_range_kg", "layer_damping"]

DAMPING_LAWS = ("off", "proportional", "integral", "half_integrator")


@dataclass(frozen=True, kw_only=True)
class DemoOptions:
    """Options of :func:`~tudorvision.lab.catch.run.run_demo` (SI units).

    Attributes
    ----------
    throws : int
        Number of throws.
    seed : int
        Seed of every random stream of the run (throws, rendering, detection noise, scene).
    render : bool
        Render the wall RGB-D frames and detect the ball in them; ``False``:
        the detection-noise model (:func:`~tudorvision.lab.catch.scenario.simulated_detection`,
        for long benchmarks).
    noise_scale : float
        Factor on the detection-noise model's standard deviations.
    damping : str
        Damping law of the joint layer (``"off"``, ``"proportional"``, ``"integral"``,
        ``"half_integrator"``).
    damping_model_assist : bool
        The joint layer's damper subtracts the strain its identified model expects from the planned motion before
        the seed's static strain filter (model-assisted static strain cancellation, ``docs/joint_layer.md``; the
        model identified on the demo's plant by :func:`~tudorvision.lab.ch10.identified_strain_model`, shipped for
        the default plant, else cached in ``cache_dir``); default since the thirty-second session (the filter's
        echo of each move's inertial strain, 0.5-1 s after it, pushed the net about as the ball arrived); with
        the proportional law on the seed-measured plant only (:func:`layer_damping`); ``False``: the seed's filter
        alone.
    damping_gains : tuple of 3 floats, or rows (payload_kg, k1, k2, k3), optional
        The proportional law's ``k_eps`` instead of the joint layer's tuned gains (rad/s per m/m) on the
        seed-measured plant; default (0, 400, 400), chosen with the model on the net's swing after the demo's
        moves (``docs/catch.md``); None: the layer's tuned gains (the other laws and plants keep theirs). Or a
        table of rows ``(payload_kg, k1, k2, k3)``, flattened or not: the gains follow the payload the agent tells
        the layer (:func:`~tudorvision.joint.damping_gains.scheduled_gains`).
    compensate : bool
        Data-based deflection compensation in the inverse kinematics (else rigid IK).
    gap_s : float
        Pause between a crossing and the next release (the arm returns to the ready pose), s.
    ready_point_base : tuple of float
        Net position waited at between throws, metres, base frame.
    target_height_m : tuple of float
        Range of the thrower's aim height at the robot (the simulator's
        ``random_throw``: release 1.4-1.9 m high about 6 m away, aim within
        +-0.45 m sideways, flight 0.8-1.1 s, drag).
    net_radius_m : float
        Radius of the net's ring, m: a ball is caught when it passes wholly inside, its centre within
        ``net_radius_m - ball_radius_m`` of the ring centre and never touching the rim
        (:func:`~tudorvision.lab.catch.score.ring_passage`); the earlier criterion, the centre within
        ``net_radius_m``, is reported beside it (``success_rate_centre``).
    ball_radius_m : float
        Radius of the ball, a sphere, m (rendering, the detector and the catch criterion).
    release_sigma_m : float
        Intercept release threshold (largest in-plane standard deviation), m. 0.5 m: in practice the
        first reachable estimate of the two-detection filter (0.1-0.2 m sigma), a frame (33 ms) before
        the 0.1 m of earlier versions; the refinements correct it (docs/catch.md, twentieth session).
    refine_sigma_factor : float
        A refinement is sent only if the intercept moved more than this many of its current
        standard deviations (and more than 2 cm); 0 (default since the camera stands behind the
        thrower): the 2 cm rule alone. The 2-sigma rule held back refinements that the better-seen
        flights made worth sending (the net went to an older estimate, 1-2.5 cm worse than the last).
    refine_tol_m : float
        A refinement is sent only if the intercept moved more than this since the last setpoint, m
        (:class:`~tudorvision.catch.intercept.InterceptOptions`).
    refine_interval_s : float
        ... and at least this long after the previous setpoint, s ...
    refine_sharper : float
        ... unless the new estimate's standard deviation is at most this fraction of the last sent
        one's (an early, rough release corrected at once; 0: the interval always applies).
    refine_without_detection_m : float
        A refinement the minimum interval (or a braking joint) held back goes out on the first frame it is due,
        with or without a detection, when the estimate moved by more than this, m
        (:meth:`~tudorvision.catch.intercept.InterceptPlanner.due`; high throws leave the top of the image for up
        to 0.4 s); 0: only on a frame with a detection.
    refine_min_joint_rad : float
        A refinement whose joint setpoint differs from the last one by less than this in every joint is
        not sent (a new setpoint re-plans the layer's profile, which costs more than it corrects), rad.
    overshoot_tol_rad : float
        A refinement that would make a joint pass its goal by more than this (the layer's planner
        restarts the acceleration from zero: sent while a joint brakes, it brakes too late;
        :class:`~tudorvision.lab.catch.agent.ReferenceMirror`) waits for a later frame, rad;
        ``inf``: refinements go out at once (the behaviour before).
    refine_force_m : float
        A refinement waiting for ``overshoot_tol_rad`` goes out anyway once the estimate is more than this
        from the one the net was sent to (a joint passing its goal costs less than a net several
        centimetres off), m; ``inf``: it always waits (the behaviour before the twenty-sixth session,
        when such waits lasted until the crossing).
    keep_elbow_branch : bool
        An intercept setpoint whose IK solution lies on the other elbow branch than the arm's (the arm's
        branch cannot reach it within the setpoint margins: a crossing low on the right with the elbow up)
        goes there only if that move (joint 3 swung through the stretched arm) ends by the deadline; else the
        net goes to the nearest point its own branch reaches
        (:meth:`~tudorvision.lab.catch.planes.CatchIK.nearest_on_branch`).
        False: the swing is always made (the behaviour before the twenty-seventh session: 0.9-1.5 s of
        motion, late for this throw and often the next).
    first_hedge_sigma, first_hedge_min_rad : float
        The first intercept setpoint of a throw moves a joint whose goals over the estimate moved by
        ``first_hedge_sigma`` standard deviations along the crossing covariance's principal directions spread
        by more than ``2 first_hedge_min_rad`` (rad) only to the near edge of that range
        (:func:`~tudorvision.lab.catch.profile.hedged_goal`); 0: the first setpoint goes to the estimate.
    payload_catch_prior, payload_weigh_sigma_kg : float
        The payload between weighings (:mod:`tudorvision.catch.payload`): 0 keeps the last weighing at rest
        (the default before the thirty-eighth session); > 0 (0-1; default 0.9) a belief that each throw the
        agent tried to catch adds a ball with this probability, that the operator's emptying resets and that
        each weighing at rest, of standard deviation ``payload_weigh_sigma_kg`` (kg; 12 g measured in the
        demo's pauses), updates. In the demo the arm rests for only a third of the pauses between throws (its
        damper still works on the swing), so the last weighing is often balls behind.
    yaw_max_rad, yaw_step_rad, yaw_margin_s, yaw_min_gain_s : float
        The working plane per throw: when the first intercept setpoint's move (the layer's plan, at the
        fastest profile speed) would end later than ``yaw_margin_s`` (s) before its deadline (negative: after
        it; the deadline is ``arrive_before_s`` before the crossing), joint 1 turns the plane (up to
        ``yaw_max_rad``, in steps of ``yaw_step_rad``) to the smallest angle where the arm meets the ball
        elsewhere on its flight with that margin, or, failing that, where the move ends soonest against its
        deadline if that gains ``yaw_min_gain_s`` (:func:`~tudorvision.lab.catch.planes.choose_plane`);
        the throw is then estimated, refined and caught on that plane, and the arm turns back with the ready
        move. ``yaw_max_rad`` 0: the fixed plane (``intercept.theta1_rad``), as in the seed.
    replan : {"restart", "blend"}
        How the joint layer re-plans a motion when a refinement arrives in flight (the simulated layer's
        ``SimCore(replan=...)`` and the agent's mirror of it): the acceleration restarts from zero (the
        seed's B.6 planner) or fades out continuously (:func:`tudorvision.joint.planner.blend_replan`).
    mode_f0_hz, mode_mass_kg : float
        The arm's first bending mode for the intercept profile
        (:func:`~tudorvision.lab.catch.profile.mode_frequency_hz`:
        ``mode_f0_hz`` with the bare net, Hz, falling with the estimated payload over ``mode_mass_kg``, kg):
        each intercept setpoint gets the profile speed whose accelerations excite it least and still
        arrive ``arrive_before_s`` before the predicted crossing
        (:meth:`~tudorvision.lab.catch.profile.ReferenceMirror.choose_speed`); ``mode_f0_hz=0``: always the
        full profile speed (the behaviour before).
    mode_swing_hz : float
        The agent's model of the caught balls: they hang in the net's bag as a pendulum of this frequency, Hz
        (what a user measures by swinging the loaded net with the arm held still), coupled to the arm's mode
        (:func:`~tudorvision.lab.catch.profile.net_modes`: two modes, the profile choice weighs both); 0: the
        payload as a rigid mass at the end effector, one mode (the behaviour before).
    mode_elbow_map : bool
        Scale that frequency by the goal's elbow angle (:func:`~tudorvision.lab.catch.profile.elbow_frequency_factor`:
        a folded elbow rings up to 18 % faster than the ready pose, a stretched arm 10 % slower); False: one
        frequency for every pose.
    overshoot_lead_m, overshoot_fade_s, overshoot_full_move_m : float
        The net target moved back along its move from the ready point by the overshoot expected at the
        crossing (:func:`~tudorvision.lab.catch.profile.overshoot_lead_target`): ``overshoot_lead_m`` (m)
        for a move of ``overshoot_full_move_m`` (m) or more whose planned profile ends at the predicted
        crossing, falling to zero for one that ends ``overshoot_fade_s`` (s) before it; 0: no lead. Default
        12 mm, 0.25 s, 0.2 m (2026-11-27, twenty-second session): seed 0 caught 755 of 840 crossing throws against
        734 without it, held-out seeds 100 / 200 / 300 / 400 184 / 196 / 200 / 185 against 183 / 185 / 191 / 174.
        6 mm (thirty-third session, on the model-assisted layer, where the net stops 0.6 cm short along its move on
        average): 379 against 373 of seeds 0 / 1's 410, but 399 against 408 of held-out seeds 100 / 200's 429.
    ball_swing_length_m : float
        The caught balls hang in the net's bag this far below the ring and swing
        (:class:`~tudorvision.sim.net_balls.SwingingBalls`: at 1.55 Hz for 0.1 m, the fabric damping the swing
        at 0.1 of critical), as the seed's do; 0: point masses fixed at the end effector (the lab before
        2026-11-27, twenty-third session).
    accel_candidates : tuple of float
        Profile accelerations the speed choice may also take for an intercept setpoint, fractions of
        ``accel_fraction``'s (:meth:`~tudorvision.lab.catch.profile.ReferenceMirror.choose_profile`): a
        refinement of a few centimetres never reaches the profile speed, so at the full acceleration it is a
        pulse of 0.1-0.2 s, near half a period of the arm's first mode; a lower acceleration stretches it.
        ``(1.0,)``: the full acceleration only (the behaviour before the twenty-seventh session).
    settle_decay_per_s : float
        The speed choice weighs each profile's residual swing by ``exp(-settle_decay_per_s x (crossing - end))``,
        what the arm's damping leaves of it at the predicted crossing, 1/s: an earlier arrival has longer to
        settle (the net's error falls from 2.5 cm RMS when the arm arrives less than 0.1 s before the crossing
        to 1.0 cm after 0.3 s); 0: the swing at the end of the motion (the behaviour before).
    ready_shaping : bool
        The return to the ready pose after a crossing takes the speed and acceleration that leave the arm's
        first mode least excited by everything since it last rested, ending before the pause's weighing window
        (:meth:`~tudorvision.lab.catch.agent.CatchAgent.return_to_ready`); the net was still moving by
        1.4 cm (median, 3.4 cm p90) in the half second before the next release. False (default): the demo's
        profile; the shaped return caught 187 / 189 of 201 / 209 crossing throws on seeds 0 / 1 (480 throws), as
        many as without it (twenty-eighth session).
    arrive_before_s : float
        The profile must end this long before the crossing the agent predicts, s (0.1 since
        2026-11-26: the net has a little longer to settle; 0.05 caught 9 fewer of 211 development throws).
    pass_through : bool
        A setpoint whose motion (at the late speed) would not end ``pass_margin_s`` before the predicted crossing
        sends each late joint to a goal beyond its intercept angle, chosen so that its reference passes the
        intercept angle ``pass_lead_s`` before the crossing still moving
        (:meth:`~tudorvision.lab.catch.profile.ReferenceMirror.pass_through_goal`) instead of braking to a stop
        after it; the overshoot lead is not applied to it. False (default): every intercept move stops at its goal.
        Measured (thirty-fourth session, 480 throws, eight calibrations): 375 of 410 crossing throws on seeds 0 / 1
        against 373, **389 of 429 held out (seeds 100 / 200) against 408**, nearly all the loss on the rim.
    pass_lead_s, pass_margin_s : float
        See ``pass_through``, s.
    speed_fraction : float
        Setpoint profile speed as a fraction of the slowest joint's limit (at
        the limit, the links' swing trips the layer's over-speed fault).
    late_speed_fraction : float
        A setpoint whose profile at ``speed_fraction`` would end after the deadline may use up to this
        fraction of the slowest joint's limit instead (0 or anything at or below ``speed_fraction``: never).
        Default 0.9: seed 0 caught 682 of 840 crossing throws against 678 without it (layer faults 56
        against 66), held-out seeds 100 and 200 166 / 173 against 163 / 173; 1.0 gave the same.
    accel_fraction : float
        Setpoint profile acceleration as a fraction of the joints' limit (400 deg/s^2).
    layer_rate_hz : float
        Control rate of the lockstep joint layer (its over-speed and range checks run every period).
    reach_margin_m : float
        Net targets are kept this far inside full stretch (:func:`~tudorvision.catch.intercept.net_target`).
        Default 2 cm since the twenty-seventh session (5 cm until 2026-11-26, then 3 cm): at 5 cm a ball
        crossing within 2 cm of full stretch met the ring's rim (59 of the 136 rim misses of seed 0's 840
        crossing throws lay beyond 0.79 m); 3 cm caught 662 of them against 633, 2 cm 660; on the soft plant,
        with the setpoints kept on the arm's elbow branch, 2 cm caught 187 / 189 / 196 of 480 throws on seeds
        0 / 1 / 100 against 183 / 189 / 189 at 3 cm (crossings beyond 0.81 m: 65-79 % -> 83-89 %), 1 cm 186 on
        seed 0. The planner's release tolerance beyond full stretch follows it (net radius - ball radius - margin).
    inner_pull : bool
        Crossings nearer the shoulder than the elbow can fold (joint 3 at its range less its setpoint
        margin: 0.546 m) get the net at that distance, and estimates up to the reach tolerance nearer are
        released (:func:`~tudorvision.catch.intercept.inner_reach_m`); False: the compensated IK then
        finds only the other elbow branch there, a swing of joint 3 through most of its range (the
        behaviour before 2026-11-26, seventh session).
    inner_reach_tol_m : float or None
        How far nearer the shoulder than that circle an estimate is still released and refined, m; None:
        net radius - ball radius (4.5 cm; the net sits on the circle itself, no reach margin there), which
        replaced the outer edge's 1.5 cm in the twenty-sixth session (estimates inside it got no
        refinement and the net stayed at the first one, up to 6 cm off).
    setpoint_margin_rad : float or tuple of 3 floats
        Setpoints are clipped this far inside the joint ranges, one value or one per joint, rad
        (joint 2 overshot by up to 8 deg on fast moves, and the layer faults 1 deg outside a
        range). Default 10, 10, 3 deg: joint 3's 10 deg cut every crossing nearer than 0.58 m to
        the shoulder (the elbow folded to 92 of its 102 deg), leaving the net 3-5 cm too far out.
    empty_pause_s : float
        Extra pause after the net is emptied, before the payload is weighed again, s.
    net_capacity_balls : int
        The net is emptied (by the operator, during the pause) once it holds this
        many balls; keeps the payload within the kinematics' trained range (400 g).
        Emptying happens at the end of the pause, the arm at rest, and adds
        ``empty_pause_s`` of pause before the payload is weighed again.
    drag_k_per_m : float
        Quadratic drag coefficient of the ball, 1/m (the throws and the EKF's model).
    cache_dir : str
        Where the kinematics data collection is cached (the default collection is shipped
        with the package and found there first).
    collection : CollectionOptions
        The data collection the kinematics are learnt from (default: the seed's grid
        measured through the stereo tracker, :data:`~tudorvision.lab.data_collection.DEMO_COLLECTION`).
        Its ``payloads_kg`` bound the payload estimate (:func:`trained_payload_range_kg`).
    rerun : bool
        Write a rerun recording (``catch.rrd``).
    plots : bool
        Write the PNG plot (``catch.png``).
    show_progress : bool or None
        Progress bar over the throws; ``None``: only on a terminal.
    ekf : EKFOptions
        Ball filter options (its ball model is replaced by one with ``drag_k_per_m``). The demo starts
        the filter on two detections (``n_init=2``; the library's default is 3): the camera behind the
        thrower sees the first part of the flight from 1-2 m, where two positions one frame apart give
        the velocity well enough, and every frame earlier is worth 2-3 % of the throws (the oracle bound
        in docs/catch.md); 3 caught 173 of 211 development throws, 2 caught 186.
    camera_distance_m : float
        The wall camera stands this far in front of the robot base (base -y), m, for the throws and
        for its calibration sweep alike. Default 6.8 m: on the wall behind the thrower, as in the seed
        (the thrower releases 5.7-6.3 m in front of the base); nearer than about 6 m the thrower
        releases behind the camera and the first part of the flight is not seen.
    camera_latency_s : float
        Time from a depth frame's exposure to its delivery to the agent, s: the sensor's on-board depth
        computation, the USB transfer and the image-processing PC's soft real-time loop (the seed, section
        2.2: "services running besides the image processing program contribute to the variance of the
        delay"). The agent gets each frame with its exposure time stamp, filters at that time and acts
        when the frame arrives (:meth:`~tudorvision.lab.catch.agent.CatchAgent.step`). Default one frame
        period of the 30 Hz camera (33.3 ms), the least a frame can be late once it is read out; a real
        Kinect's pipeline adds more (set the latency you measure). 0: the frame is seen the instant it is
        exposed (the lab before the thirtieth session: 375 against 368 of 410 crossing throws on seeds 0 / 1;
        two frames, 67 ms, 350).
    camera_latency_jitter_s : float
        On top of ``camera_latency_s``, each frame is late by a further delay drawn uniformly from
        ``[0, camera_latency_jitter_s]`` s (the seed's "variance of the delay" of a soft real-time
        image-processing loop), frames still delivered in order (a frame never overtakes the one before);
        its own random stream of ``seed``. 0 (default): every frame equally late.
    camera_height_m : float
        Height of the wall camera above the floor, m (it looks at the point 1 m above the base).
    camera_max_depth_m : float
        End of the wall camera's depth range, m (:func:`~tudorvision.lab.catch.calibration.wall_depth_sensor`;
        the sensor reports depth up to here, with the seed's cubic sigma_z(z) extrapolated beyond its 6 m
        fit, 96 mm at 6.8 m). Must exceed the disc's distance for the calibration sweep. The package's
        :data:`~tudorvision.sensors.KINECT_RANGE_M` (0.6-6 m, the fit's range) is unchanged.
    calibration_frames_per_pose : int
        Depth frames per pose of the calibration sweep (theta2 10-170 deg every 10 deg,
        :data:`~tudorvision.lab.catch.calibration.SWEEP_THETA2_DEG`; the vertical posture gets six times as
        many): at 6.8 m one disc centre has about 1.2 cm of depth noise, the frames per pose average it.
        Default 32 since the twenty-eighth session (2400 frames, 80 s of a 30 Hz camera; 8 before): the
        calibration's tilt towards the camera, which the catch follows, fell from 0.128 deg RMS over eight
        calibration seeds (8 frames) to 0.094 (16) and 0.056 (32), and seed 0's 1980 throws over those eight
        calibrations caught 757 -> 757 -> 776 of 840.
    calibration_method : str
        ``"seed+mirror+yaw"`` (default): ``"seed+mirror"``, then the tilt towards the camera from a theta1
        sweep at theta2 = 45 deg (52 frames per ``calibration_frames_per_pose``, joint 1 turned through
        +-45 deg; :func:`~tudorvision.rgbd.yaw_sweep.refine_tilt_from_yaw`: at 6.8 m the theta2 sweep alone
        leaves 0.3-0.6 deg of it under the Kinect's correlated depth noise). ``"seed+mirror"``: the seed's
        sweep construction, then its in-plane angle and lateral
        origin from the sweep's mirror symmetry about the vertical (no model:
        :func:`~tudorvision.rgbd.base_calib.refine_sweep_mirror`; the arm's vertical posture leans
        0.45 deg, and the residual tilt of gravity moves the predicted crossing); ``"seed+deflection"``:
        in-plane angle and origin fitted to the agent's learnt deflection model
        (:func:`~tudorvision.rgbd.base_calib.refine_sweep_in_plane`); ``"seed+deflection+mirror"``: both,
        in that order; ``"seed"``: the seed's construction alone.
    true_calibration : bool
        Give the agent the true camera-to-base transform instead of the one calibrated from the
        simulated disc sweep (:func:`~tudorvision.lab.catch.calibration.calibrate_wall_camera`); for
        comparison only.
    calibration_seed : int
        Seed of the calibration sweep's rendering and depth noise (one calibration per camera
        placement, shared by all throws and sessions; cached); also which depth camera unit the wall camera
        is (its fixed depth pattern, ``depth_pattern_px``): another calibration seed, another lab.
    depth_pattern_px : float
        The wall camera's fixed depth pattern, disparity pixels RMS
        (:class:`~tudorvision.sim.depth_sensor.DepthSensorModel` ``pattern_disparity_px``; default the measured
        Kinect's :data:`~tudorvision.sim.depth_sensor.KINECT_PATTERN_DISPARITY_PX`, 0.068 px: about 8 cm RMS
        at the arm, 7.1 m away). 0: none (the lab before 2026-12-06).
    depth_pattern_correction : bool
        The agent calibrates the wall camera's depth pattern from 30 frames of a flat wall first
        (:func:`~tudorvision.lab.catch.calibration.wall_depth_pattern`,
        :func:`~tudorvision.rgbd.depth_pattern.calibrate_depth_pattern`) and removes it from the calibration
        sweep's frames and from every ball detection (default True). False: the pattern is left in.
    params : RobotParams or None
        The robot (``--robot``: arm, kinematics, limits); None: the packaged ``tudor.yaml``.
    plant : str
        The simulated arm (:data:`PLANTS`): ``"seed_measured"`` (default, the softer plant identified
        on the seed's measured modes) or ``"stiff"`` (rigid link clamping); passed explicitly to every
        elastic arm the demo builds (:func:`plant_config`), and the kinematics are learnt on the same plant.

    Raises
    ------
    ValueError
        On a non-positive number of throws, an unknown damping law, a
        non-positive net radius, a ball that does not fit through the net or a negative gap.

    Examples
    --------
    >>> DemoOptions(throws=3, render=False).net_radius_m
    0.09
    """

    throws: int = 5
    seed: int = 0
    render: bool = True
    noise_scale: float = 1.0
    damping: str = "proportional"
    damping_model_assist: bool = True
    damping_gains: tuple | None = (0.0, 400.0, 400.0)
    compensate: bool = True
    gap_s: float = 1.2
    ready_point_base: tuple = (0.0, 0.0, 1.07)
    target_height_m: tuple = (0.45, 1.2)
    net_radius_m: float = 0.09
    ball_radius_m: float = 0.045
    release_sigma_m: float = 0.5
    refine_sigma_factor: float = 0.0
    refine_tol_m: float = 0.02
    refine_interval_s: float = 0.2
    refine_sharper: float = 0.0
    refine_without_detection_m: float = 0.0
    refine_min_joint_rad: float = float(np.deg2rad(0.5))
    overshoot_tol_rad: float = float(np.deg2rad(0.5))
    refine_force_m: float = 0.04
    keep_elbow_branch: bool = True
    mode_f0_hz: float = 2.6
    mode_mass_kg: float = 0.26
    mode_swing_hz: float = 0.0
    mode_elbow_map: bool = False
    overshoot_lead_m: float = 0.012
    overshoot_fade_s: float = 0.25
    overshoot_full_move_m: float = 0.2
    ball_swing_length_m: float = 0.1
    accel_candidates: tuple = (1.0,)
    settle_decay_per_s: float = 0.0
    ready_shaping: bool = False
    arrive_before_s: float = 0.1
    replan: str = "restart"
    first_hedge_sigma: float = 0.0
    first_hedge_min_rad: float = float(np.deg2rad(5.0))
    yaw_max_rad: float = 0.0
    yaw_step_rad: float = float(np.deg2rad(2.0))
    yaw_margin_s: float = -0.15
    yaw_min_gain_s: float = 0.05
    payload_catch_prior: float = 0.9
    payload_weigh_sigma_kg: float = 0.012
    pass_through: bool = False
    pass_lead_s: float = 0.0
    pass_margin_s: float = 0.0
    speed_fraction: float = 0.75
    late_speed_fraction: float = 0.9
    accel_fraction: float = 1.0
    layer_rate_hz: float = 500.0
    reach_margin_m: float = 0.02
    inner_pull: bool = True
    inner_reach_tol_m: float | None = None
    setpoint_margin_rad: float | tuple = tuple(float(x) for x in np.deg2rad([10.0, 10.0, 3.0]))
    empty_pause_s: float = 1.0
    net_capacity_balls: int = 8
    drag_k_per_m: float = 0.012
    cache_dir: str = "out/catch/cache"
    collection: CollectionOptions = DEMO_COLLECTION
    rerun: bool = True
    plots: bool = True
    show_progress: bool | None = None
    ekf: EKFOptions = field(default_factory=lambda: EKFOptions(n_init=2))
    params: RobotParams | None = None
    camera_distance_m: float = 6.8
    camera_height_m: float = 2.0
    camera_latency_s: float = 1.0 / 30.0
    camera_latency_jitter_s: float = 0.0
    camera_max_depth_m: float = 8.0
    calibration_frames_per_pose: int = 32
    calibration_method: str = "seed+mirror+yaw"
    true_calibration: bool = False
    calibration_seed: int = 0
    depth_pattern_px: float = KINECT_PATTERN_DISPARITY_PX
    depth_pattern_correction: bool = True
    plant: str = "seed_measured"

    def __post_init__(self):
        if int(self.throws) != self.throws or self.throws < 1:
            raise ValueError(f"throws: expected a positive integer, got {self.throws}")
        if self.damping not in DAMPING_LAWS:
            raise ValueError(f"damping: expected off, proportional, integral or half_integrator, got {self.damping!r}")
        if self.damping_gains is not None:
            from ...joint.damping_gains import gain_table

            gain_table(self.damping_gains)          # a one-line ValueError naming damping_gains
        if self.plant not in PLANTS:
            raise ValueError(f"plant: expected one of {', '.join(PLANTS)}, got {self.plant!r}")
        if self.replan not in ("restart", "blend"):
            raise ValueError(f"replan: expected restart or blend, got {self.replan!r}")
        if not self.net_radius_m > 0 or not self.gap_s >= 0:
            raise ValueError("net_radius_m, gap_s: expected > 0 and >= 0")
        if not 0 < self.ball_radius_m < self.net_radius_m:
            raise ValueError(f"ball_radius_m: expected 0 < ball_radius_m < net_radius_m ({self.net_radius_m}), "
                             f"got {self.ball_radius_m}")
        if not 1.0 <= self.camera_distance_m <= 8.0 or not 0.5 <= self.camera_height_m <= 3.0:
            raise ValueError(f"camera_distance_m, camera_height_m: expected 1-8 m and 0.5-3 m, got "
                             f"{self.camera_distance_m}, {self.camera_height_m}")
        if not (np.isfinite(self.camera_latency_s) and 0.0 <= self.camera_latency_s <= 0.5):
            raise ValueError(f"camera_latency_s: expected 0-0.5 s, got {self.camera_latency_s}")
        if not (np.isfinite(self.camera_latency_jitter_s)
                and 0.0 <= self.camera_latency_jitter_s <= 0.5 - self.camera_latency_s):
            raise ValueError(f"camera_latency_jitter_s: expected 0 to 0.5 s less camera_latency_s, "
                             f"got {self.camera_latency_jitter_s}")
        if self.calibration_method not in CALIBRATION_METHODS:
            raise ValueError(f"calibration_method: expected one of {CALIBRATION_METHODS}, "
                             f"got {self.calibration_method!r}")
        if not (np.isfinite(self.depth_pattern_px) and 0.0 <= self.depth_pattern_px <= 2.0):
            raise ValueError(f"depth_pattern_px: expected 0-2 disparity px, got {self.depth_pattern_px}")
        if not 0.6 < self.camera_max_depth_m <= 10.0:
            raise ValueError(f"camera_max_depth_m: expected 0.6-10 m, got {self.camera_max_depth_m}")
        if not (0.0 < self.speed_fraction <= 1.0 and 0.0 <= self.late_speed_fraction <= 1.0):
            raise ValueError(f"speed_fraction, late_speed_fraction: expected (0, 1] and [0, 1] of the slowest "
                             f"joint's limit, got {self.speed_fraction}, {self.late_speed_fraction}")
        if not 0.0 <= self.ball_swing_length_m <= 0.5:
            raise ValueError(f"ball_swing_length_m: expected 0-0.5 m, got {self.ball_swing_length_m}")
        margin = np.asarray(self.setpoint_margin_rad, float)
        if margin.shape not in ((), (3,)) or not np.all(np.isfinite(margin)) or np.any(margin < 0):
            raise ValueError(f"setpoint_margin_rad: expected one or three angles >= 0, rad, "
                             f"got {self.setpoint_margin_rad!r}")
        if not (0.0 <= self.overshoot_lead_m <= 0.05 and self.overshoot_fade_s > 0
                and self.overshoot_full_move_m > 0):
            raise ValueError(f"overshoot_lead_m, overshoot_fade_s, overshoot_full_move_m: expected 0-0.05 m, > 0 s and "
                             f"> 0 m, got {self.overshoot_lead_m}, {self.overshoot_fade_s}, "
                             f"{self.overshoot_full_move_m}")
        if not (abs(self.pass_lead_s) <= 0.2 and abs(self.pass_margin_s) <= 0.5):
            raise ValueError(f"pass_lead_s, pass_margin_s: expected within +-0.2 s and +-0.5 s, "
                             f"got {self.pass_lead_s}, {self.pass_margin_s}")
        if not (0.0 <= self.payload_catch_prior <= 1.0 and 0.0 < self.payload_weigh_sigma_kg <= 1.0):
            raise ValueError(f"payload_catch_prior, payload_weigh_sigma_kg: expected 0-1 and (0, 1] kg, "
                             f"got {self.payload_catch_prior}, {self.payload_weigh_sigma_kg}")
        if not (0.0 <= self.first_hedge_sigma <= 3.0 and 0.0 <= self.first_hedge_min_rad < np.pi):
            raise ValueError(f"first_hedge_sigma, first_hedge_min_rad: expected 0-3 and [0, pi) rad, "
                             f"got {self.first_hedge_sigma}, {self.first_hedge_min_rad}")
        if not (0.0 <= self.yaw_max_rad <= np.pi / 2 and 0.0 < self.yaw_step_rad <= np.pi / 2
                and abs(self.yaw_margin_s) <= 1.0 and 0.0 <= self.yaw_min_gain_s <= 1.0):
            raise ValueError(f"yaw_max_rad, yaw_step_rad, yaw_margin_s, yaw_min_gain_s: expected [0, pi/2] rad, "
                             f"(0, pi/2] rad, within +-1 s and 0-1 s, got {self.yaw_max_rad}, {self.yaw_step_rad}, "
                             f"{self.yaw_margin_s}, {self.yaw_min_gain_s}")
        if not (np.isfinite(self.mode_swing_hz) and self.mode_swing_hz >= 0):
            raise ValueError(f"mode_swing_hz: expected >= 0 (Hz), got {self.mode_swing_hz}")
        if not (np.isfinite(self.settle_decay_per_s) and self.settle_decay_per_s >= 0):
            raise ValueError(f"settle_decay_per_s: expected >= 0 (1/s), got {self.settle_decay_per_s}")
        acc = np.asarray(self.accel_candidates, float)
        if acc.ndim != 1 or not len(acc) or not np.all((acc > 0) & (acc <= 1)):
            raise ValueError(f"accel_candidates: expected fractions in (0, 1], got {self.accel_candidates!r}")
        if not (np.isfinite(self.refine_without_detection_m) and self.refine_without_detection_m >= 0):
            raise ValueError(f"refine_without_detection_m: expected >= 0 (m), got {self.refine_without_detection_m}")
        if not 0.0 <= self.refine_sharper < 1.0:
            raise ValueError(f"refine_sharper: expected [0, 1), got {self.refine_sharper}")
        if int(self.calibration_frames_per_pose) != self.calibration_frames_per_pose \
                or self.calibration_frames_per_pose < 1:
            raise ValueError(f"calibration_frames_per_pose: expected a positive integer, "
                             f"got {self.calibration_frames_per_pose}")


def trained_payload_range_kg(collection: CollectionOptions) -> tuple[float, float]:
    """Range of added payload (on top of the end-effector mount) the kinematics were trained on, kg.

    The settled poses are collected with ``mount + m`` for each ``m`` in
    ``collection.payloads_kg``; the strain model's payload estimate is
    clipped to this range, so the payload told to the joint layer stays
    within ``mount + [0, max(payloads_kg)]``.

    Parameters
    ----------
    collection : CollectionOptions
        The collection the kinematics were fitted on.

    Returns
    -------
    tuple of float
        ``(0.0, max(payloads_kg))``, kg.

    Examples
    --------
    >>> trained_payload_range_kg(CollectionOptions(payloads_kg=(0.0, 0.2, 0.4)))
    (0.0, 0.4)
    """
    return 0.0, float(max(max(collection.payloads_kg), 0.0))


def layer_damping(options) -> tuple[bool, tuple | None]:
    """What the demo's joint layer damps with: ``(model_assist, proportional_gains)``.

    ``DemoOptions.damping_model_assist`` and ``damping_gains`` where they were measured: the proportional law on
    the seed-measured plant. Any other law or plant gets the seed's static strain filter at the layer's tuned
    gains, ``(False, None)``.

    Parameters
    ----------
    options : DemoOptions

    Returns
    -------
    tuple
        Whether the layer removes its identified strain model's expectation first, and the proportional law's
        ``k_eps`` (None: the tuned ones).

    Examples
    --------
    >>> layer_damping(DemoOptions(render=False))
    (True, (0.0, 400.0, 400.0))
    >>> layer_damping(DemoOptions(render=False, plant="stiff")), layer_damping(DemoOptions(damping="integral"))
    ((False, None), (False, None))
    """
    if options.damping != "proportional" or options.plant != "seed_measured":
        return False, None
    return bool(options.damping_model_assist), options.damping_gains
