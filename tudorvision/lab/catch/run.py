"""The catching demo's run loop: the scenario's clock, the agent, the scorer and the writers.

Loop per wall-camera frame (30 Hz)::

    scenario: render RGB-D frame (or the detection-noise model)
    agent:    BallDetector -> T_base_cam (calibrated) -> CatchPerception (EKF, intercept) -> compensated IK
              -> JointAdapter.send_setpoint -> joint-control layer (JointLayerServer) -> simulated elastic arm
    scorer:   at the true crossing, the net against the ball (ground truth)

Simulation time: the joint-control layer (:class:`~tudorvision.joint.server.JointLayerServer`
with its safety checks and faults) runs in lockstep with the demo
(:class:`~tudorvision.lab.lockstep.LockstepLayer`, ``tick`` at ``layer_rate_hz``);
commands still travel through the adapter, and runs are deterministic for a
seed whatever the machine's load.

Caught balls add 30 g of payload each and swing with the arm. Between throws
the arm returns to the ready pose and the agent weighs the payload from the
strains the layer reports at rest; the estimate is clipped to the range the
kinematics were trained on (``collection.payloads_kg``, on top of the mount:
:func:`~tudorvision.lab.catch.options.trained_payload_range_kg`).

Before the throws, the wall camera is calibrated from a simulated disc sweep
with the camera where it stands for the throws
(:func:`~tudorvision.lab.catch.calibration.calibrate_wall_camera`, the
perception of ``calib rgbd-base``); ``DemoOptions.true_calibration`` gives the
agent the true transform instead, for comparison.

The frames after the ball has left the sensor's detection range (4.5 m) are
not rendered (nothing can be detected in them); between throws no frames
are rendered.
"""
from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ...catch.ekf import BallModel, EKFOptions
from ...catch.intercept import InterceptOptions
from ...catch.perception import CatchPerception
from .agent import CatchAgent, demo_inner_reach_m, profile_limits
from .planes import CatchIK
from .calibration import calibrate_wall_camera, wall_camera_position_world, wall_depth_pattern
from .options import DemoOptions, layer_damping, trained_payload_range_kg
from .scenario import FRAME_RATE_HZ, CatchScenario
from .score import score_throw, summarize_throws
from . import writers

__all__ = ["demo_intercept_options", "demo_kinematics", "run_demo", "wall_camera_transform"]

N_BACKGROUND_FRAMES = 10
AFTER_CROSSING_S = 0.1      # frames go on this long after the true crossing


def demo_intercept_options(options: DemoOptions, params) -> InterceptOptions:
    """The intercept planner's release and refinement policy for the demo's options.

    Parameters
    ----------
    options : DemoOptions
        The demo's options (release threshold, refinement rules, ball, net and reach margins).
    params : RobotParams
        Robot parameters (the inner edge of the reach).

    Returns
    -------
    InterceptOptions
    """
    o = options
    # a crossing estimated a little beyond full stretch is released too: the net, pulled in by the reach margin,
    # still takes the ball there (the estimate of a crossing at the edge of the reach flickers across it)
    reach_tol = max(0.0, o.net_radius_m - o.ball_radius_m - o.reach_margin_m)
    return InterceptOptions(release_sigma_m=o.release_sigma_m, refine_sigma_factor=o.refine_sigma_factor,
                            refine_tol_m=o.refine_tol_m, min_interval_s=o.refine_interval_s,
                            refine_sharper=o.refine_sharper,
                            reach_tol_m=reach_tol, inner_reach_m=demo_inner_reach_m(o, params),
                            inner_reach_tol_m=(o.net_radius_m - o.ball_radius_m if o.inner_reach_tol_m is None
                                               else o.inner_reach_tol_m))


def demo_kinematics(options: DemoOptions, params):
    """The data-based kinematics of the demo, learnt from its settled-pose collection (cached).

    Parameters
    ----------
    options : DemoOptions
        ``collection`` (collected on the demo's ``plant``) and ``cache_dir``.
    params : RobotParams
        The robot's parameters.

    Returns
    -------
    tuple
        ``(models, inverse)``: the fitted :class:`~tudorvision.catch.kinematics.KinematicsModels`
        (test payload 100 g held out) and the compensated
        :class:`~tudorvision.catch.kinematics.InverseKinematics` (1 deg inside the joint ranges).
    """
    from dataclasses import replace

    from ...catch.kinematics import InverseKinematics, fit_kinematics
    from ..data_collection import load_or_collect

    data = load_or_collect(options.cache_dir, replace(options.collection, plant=options.plant), params)
    km = fit_kinematics(data, test_payloads_kg=[0.1], params=params)
    return km, InverseKinematics(km.deflection, params, margin_rad=np.deg2rad(1.0))


def demo_damping_model(options: DemoOptions):
    """The joint layer's strain model for the model-assisted cancellation, or None.

    With ``damping_model_assist``, for the proportional law on the seed-measured plant (where the cancellation
    was measured; :func:`~tudorvision.lab.catch.options.layer_damping`): identified once on the demo's plant
    (:func:`~tudorvision.lab.ch10.identified_strain_model`; shipped for the default plant, else cached in
    ``options.cache_dir``), as a user identifies their arm before switching the cancellation on.
    """
    if not layer_damping(options)[0]:
        return None
    from ..ch10 import identified_strain_model
    from ..data_collection import plant_config

    return identified_strain_model(plant_config(options.plant), params=options.params, cache_dir=options.cache_dir)


def _net_at_cross(layer, world, t_cross_s):
    """True net centre (m), its velocity (m/s, finite difference over the last control period) and joint 1's
    angle (rad) at the crossing."""
    layer.advance_to(t_cross_s - layer.period)
    t0, p0 = layer.t, world.net_position()
    layer.advance_to(t_cross_s)
    t1, p1 = layer.t, world.net_position()
    return p1, ((p1 - p0) / (t1 - t0) if t1 > t0 else None), float(world.sim.arm.theta[0])


def _pattern_at_arm(world, pattern) -> list:
    """Lab side: the wall camera's fixed depth pattern at the arm's distance, RMS over the image, as the sensor
    has it and as the agent's correction leaves it, metres (``[before, after]``; after is before without one)."""
    from ...sim.depth_sensor import pattern_field

    K = world.intrinsics
    c = pattern_field(world.depth_sensor, K.height, K.width)
    z = float(np.linalg.norm(world.T_base_cam[:3, 3]))
    seen = 1.0 / (1.0 / z + c)
    after = seen if pattern is None else pattern.apply(seen)
    return [float(np.sqrt(np.mean((seen - z) ** 2))), float(np.sqrt(np.mean((after - z) ** 2)))]


def wall_camera_transform(options: DemoOptions, params, T_base_cam_true, *, verbose: bool = True,
                          deflection=None):
    """The ``T_base_cam`` the agent gets: calibrated from the disc sweep, or the truth if asked for.

    Parameters
    ----------
    options : DemoOptions
        ``true_calibration``, the camera placement and ``calibration_seed``.
    params : RobotParams
        The robot's parameters.
    T_base_cam_true : array_like, shape (4, 4)
        The wall camera's true pose in the base frame (lab side: the calibration's error).
    verbose : bool
        Print the calibration's error against the truth (one line).
    deflection : callable, optional
        The agent's learnt deflection model, for a ``options.calibration_method`` that names ``deflection``
        (default: learnt here, :func:`demo_kinematics`).

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        Camera to base transform for the agent.
    report : dict
        ``source`` (``"disc sweep"`` or ``"true"``), and for the sweep the report of
        :func:`~tudorvision.lab.catch.calibration.calibrate_wall_camera` (``position_error_m``,
        ``rotation_error_deg``, ...).
    """
    if options.true_calibration:
        return np.asarray(T_base_cam_true, float), {"source": "true"}
    if deflection is None and "deflection" in options.calibration_method.split("+"):
        deflection = demo_kinematics(options, params)[0].deflection
    T, rep = calibrate_wall_camera(options, params, T_base_cam_true, deflection=deflection)
    rep = {"source": "disc sweep", **rep}
    if verbose:
        print(f"wall camera calibrated from the disc sweep ({rep['frames']} frames, circle RMSE "
              f"{rep['circle_rmse_m'] * 1e3:.1f} mm{', cached' if rep['cached'] else ''}): error against the "
              f"truth {rep['position_error_m'] * 100:.2f} cm, {rep['rotation_error_deg']:.3f} deg (camera pose), "
              f"{rep['error_at_arm_m'] * 100:.2f} cm at the arm")
    return T, rep


def run_demo(out, options: DemoOptions = DemoOptions(), *, recording=None) -> dict:
    """Run the catching demo and write ``summary.json``, ``throws.csv``, ``predictions.csv``, plots, ``catch.rrd``.

    Parameters
    ----------
    out : str or Path
        Output directory (created).
    options : DemoOptions
        The demo's options.
    recording : rerun.RecordingStream, optional
        With ``options.rerun``: log to this stream (the CLI's live or web
        viewer, its sinks chosen by the caller) instead of ``out/catch.rrd``.

    Returns
    -------
    dict
        The summary (also written to ``out/summary.json``), with ``per_throw`` (one
        :meth:`ThrowResult.as_dict <tudorvision.lab.catch.score.ThrowResult.as_dict>` per throw, as in
        ``throws.csv``), ``predictions`` (the rows of ``predictions.csv``) and ``latencies_s``
        (per detection: detector in rendered mode + filter + intercept, s).
    """
    from ..._progress import progress
    from ...rgbd.ball import BallDetector
    from ...robot import load_robot_params

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    o = options
    params = o.params or load_robot_params()
    wall0 = time.perf_counter()
    km, inverse = demo_kinematics(o, params)
    ekf_opts = EKFOptions(**{**asdict(o.ekf), "model": BallModel(drag_k_per_m=o.drag_k_per_m)})
    iopts = demo_intercept_options(o, params)
    ik = CatchIK(inverse, params, compensate=o.compensate, theta1_rad=iopts.theta1_rad)

    world = CatchScenario(o, params, ik(np.asarray(o.ready_point_base, float), 0.0, elbow="up"),
                          damping_model=demo_damping_model(o))
    layer = world.layer
    T_base_cam, calib = wall_camera_transform(o, params, world.T_base_cam, verbose=o.show_progress is not False,
                                              deflection=km.deflection)
    detector = BallDetector(world.intrinsics, world.detector_options, n_background=N_BACKGROUND_FRAMES)
    K = world.intrinsics
    pattern = wall_depth_pattern(o, world.camera.K, K.width, K.height)
    agent = CatchAgent(layer, ik, km.strain, CatchPerception(ekf_opts, iopts, params), detector, T_base_cam,
                       options=o, params=params, payload_range_kg=trained_payload_range_kg(o.collection),
                       depth_correction=pattern, intrinsics=K)
    max_speed, max_accel = profile_limits(o, params)
    rate = FRAME_RATE_HZ
    t_now = 0.0
    if o.render:
        for _ in range(N_BACKGROUND_FRAMES):
            agent.learn_background(world.render_depth(t_now))
            t_now += 1.0 / rate
        layer.advance_to(t_now)

    rr_log = (writers.RerunLog(out / "catch.rrd", net_radius_m=o.net_radius_m, recording=recording)
              if o.rerun else None)
    results = []
    rng_delay = np.random.default_rng([o.seed, 6])         # the frames' extra delays, a stream of their own
    t_delivered = -np.inf
    for i in progress(range(o.throws), desc="throws", enabled=o.show_progress):
        throw = world.throw(i, t_now)
        theta_release = np.asarray(layer.state().theta)
        payload_true = world.payload_added_kg
        agent.begin_throw(i)
        net, net_vel, theta1_cross = None, None, None
        k = int(np.ceil(t_now * rate - 1e-9))
        while (t_exposed := k / rate) <= throw.t_cross_s + AFTER_CROSSING_S:
            t = t_exposed + o.camera_latency_s            # the frame reaches the agent, in order
            if o.camera_latency_jitter_s > 0:
                t = t_delivered = max(t + rng_delay.uniform(0.0, o.camera_latency_jitter_s), t_delivered)
            if t > t_now:
                # plant to this frame's delivery, evaluating the net at the true crossing on the way
                if throw.crosses and net is None and t_now < throw.t_cross_s <= t:
                    net, net_vel, theta1_cross = _net_at_cross(layer, world, throw.t_cross_s)
                layer.advance_to(t)
                t_now = t
            seen = agent.step(t, world.observe(t_exposed), t_exposure=t_exposed)
            if seen is not None and rr_log is not None:
                rr_log.frame(t, seen[0], seen[1], world.net_position())
            k += 1
        if throw.crosses and net is None:
            net, net_vel, theta1_cross = _net_at_cross(layer, world, throw.t_cross_s)
        result = score_throw(throw, agent.log, net_at_cross=net, net_velocity_at_cross=net_vel,
                             ring_theta1_rad=theta1_cross, theta_at_release=theta_release,
                             payload_true_kg=payload_true, options=o, params=params, theta1_rad=iopts.theta1_rad,
                             max_speed=max_speed, max_accel=max_accel, frame_rate_hz=rate,
                             latency_s=o.camera_latency_s + 0.5 * o.camera_latency_jitter_s)
        results.append(result)
        if result.caught:
            world.catch_ball()
        world.end_throw()
        # back to the ready pose; weigh the payload at the end of the pause (strain model, 9.2)
        agent.return_to_ready(t_now)
        t_now, strains = agent.wait(t_now, o.gap_s, rate)
        emptied = world.net_full
        if emptied:
            # the operator empties the net once the arm rests at the ready pose and tells the layer (and the
            # agent); the payload is weighed again after a short settling pause
            world.empty_net()
            t_now, strains = agent.wait(t_now, o.empty_pause_s, rate)
        agent.weigh(strains, emptied=emptied)
    world.close()

    lat = np.array(agent.latencies_s) if agent.latencies_s else np.array([np.nan])
    score = summarize_throws(results)
    summary = {
        "throws": int(o.throws), "crossing_workspace": score["crossing_workspace"], "caught": score["caught"],
        "caught_in_workspace": score["caught_in_workspace"], "success_rate": score["success_rate"],
        # secondary: the crossing throws the arm could reach in time at all (lower bound on the move time)
        "crossing_in_time": score["crossing_in_time"], "caught_in_time": score["caught_in_time"],
        "success_rate_in_time": score["success_rate_in_time"],
        # the earlier criterion (ball centre within the ring's radius) and balls that touched the rim
        "success_rate_centre": score["success_rate_centre"],
        "caught_centre_in_workspace": score["caught_centre_in_workspace"],
        "rim_contacts_in_workspace": score["rim_contacts_in_workspace"],
        "calibration": calib, "camera_position_world_m": [float(x) for x in wall_camera_position_world(o)],
        "camera_max_depth_m": o.camera_max_depth_m, "camera_latency_s": o.camera_latency_s,
        "camera_latency_jitter_s": o.camera_latency_jitter_s, "plant": o.plant,
        "depth_pattern_px": o.depth_pattern_px, "depth_pattern_correction": o.depth_pattern_correction,
        "depth_pattern_rms_at_arm_m": _pattern_at_arm(world, pattern),
        "ball_swing_length_m": o.ball_swing_length_m,
        "yaw_max_rad": o.yaw_max_rad, "throws_on_a_turned_plane": int(sum(r.yaw_deg != 0.0 for r in results)),
        "seed": o.seed, "render": o.render, "damping": o.damping, "compensate": o.compensate,
        "net_radius_m": o.net_radius_m, "balls_in_net": world.balls, "net_emptied": world.emptied,
        "median_pred_error_m": score["median_pred_error_m"],
        "median_ballistic_error_m": score["median_ballistic_error_m"],
        "perception_latency_ms_median": float(np.nanmedian(lat) * 1e3),
        "setpoints_not_acknowledged": agent.refused,
        "layer_faults_cleared": len(agent.faults),
        "kinematics": km.report, "wall_time_s": time.perf_counter() - wall0,
        "misses": score["misses"],
    }
    writers.write_throws_csv(out / "throws.csv", results)
    writers.write_predictions_csv(out / "predictions.csv", agent.predictions)
    writers.write_setpoints_csv(out / "setpoints.csv", agent.setpoints)
    if o.plots:
        fig = writers.plot_catch(results, agent.predictions, net_radius_m=o.net_radius_m, params=params)
        fig.savefig(out / "catch.png", dpi=110)
    if rr_log is not None:
        rr_log.close()
    summary["wall_time_s"] = time.perf_counter() - wall0
    writers.write_summary_json(out / "summary.json", summary)
    summary["per_throw"] = [r.as_dict() for r in results]
    summary["predictions"] = agent.predictions          # as in predictions.csv
    summary["latencies_s"] = agent.latencies_s          # per detection: detector (rendered mode) + filter + intercept
    return summary
