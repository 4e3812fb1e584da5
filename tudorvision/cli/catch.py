"""``tudorvision catch``: the catching demo and open-loop prediction on recorded RGB-D throws."""
from __future__ import annotations

import csv
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._viewer import add_viewer_arguments, open_viewer, viewer_requested
from .batch import add_rerun_stale_argument, apply_rerun_stale
from .robot_args import add_robot_option, robot_from_args

__all__ = ["register", "run_open_loop"]


def _base_transform(cal, path_hint) -> np.ndarray:
    if cal is not None:
        for name in ("T_base_cam", "T_base_rgbd"):
            try:
                return np.asarray(cal.transform(name), float)
            except (KeyError, ValueError, TudorVisionError):
                continue
    raise TudorVisionError(f"{path_hint}: no T_base_cam (camera to robot base) in the calibration; run "
                           "'tudorvision calib rgbd-base' and pass --calib FILE")


def run_open_loop(seq_path, out_dir, *, calib=None, ready_point_base=(0.0, 0.0, 1.07), background: int = 10,
                  show_progress=None, recording=None, depth_every: int = 5, params=None, depth_pattern=None) -> dict:
    """Detection -> EKF -> intercept -> compensated IK on a recorded RGB-D sequence (no arm).

    Writes ``predictions.csv`` (per detection: filter status, state, intercept,
    the drag-free peer's intercept) and ``setpoints.csv`` (the joint setpoints
    that would be sent) in ``out_dir``.

    Parameters
    ----------
    seq_path : str or Path
        RGB-D sequence.
    out_dir : str or Path
        Output folder (created).
    calib : str, optional
        Calibration with the intrinsics and ``T_base_cam`` (default: the sequence's).
    ready_point_base : array_like, shape (3,)
        The net's ready point, m, base frame.
    background : int
        Frames for the detector's background model.
    show_progress : bool or None
        Progress bar on stderr.
    recording : rerun.RecordingStream, optional
        Log every ``depth_every``-th depth frame, the detections, intercepts
        and setpoints to it (:class:`~tudorvision.lab.catch.writers.RerunLog`).
    depth_every : int
        Depth frames logged to ``recording``: every n-th (0: none).
    params : RobotParams, optional
        The robot (``--robot``); default the packaged ``tudor.yaml``.
    depth_pattern : str or Path, optional
        The camera's fixed depth pattern (``calib rgbd-pattern``), removed from every detection.

    Returns
    -------
    dict
        Counts: frames, detections, throws, setpoints; ``why_no_setpoint``:
        a one-line reason when no setpoint was sent (else empty).
    """
    from .._progress import progress
    from ..io import open_sequence
    from ..rgbd.ball import BallDetector, BallDetectorOptions
    from .rgbd import depth_pattern_arg, intrinsics_for, noise_model_from_calibration
    from ..robot import load_robot_params
    from ..catch.perception import CatchPerception, detection_to_base
    from ..lab.catch_demo import DemoOptions, demo_kinematics

    seq = open_sequence(seq_path)
    if seq.kind != "rgbd":
        raise TudorVisionError(f"{seq_path}: expected an RGB-D sequence, got kind {seq.kind!r}")
    K, cal = intrinsics_for(seq, calib)
    pattern = depth_pattern_arg(depth_pattern, K)
    cal_T = cal if calib is not None else seq.calibration   # --calib read once, any format (intrinsics_for)
    T_base_cam = _base_transform(cal_T, calib or seq_path)
    params = params or load_robot_params()
    km, ikm = demo_kinematics(DemoOptions(), params)
    perception = CatchPerception(params=params)
    det = BallDetector(K, BallDetectorOptions(depth_model=noise_model_from_calibration(cal)), n_background=background)
    theta = ikm(np.asarray(ready_point_base, float), 0.0, 0.0, elbow="up")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    preds, sps = [], []
    n_det = n_cross = n_reach = 0
    last_cross, min_sigma = None, np.inf
    throws = set()
    rr_log = None
    if recording is not None:
        from ..lab.catch.writers import RerunLog
        rr_log = RerunLog(recording=recording, net_radius_m=0.05)
    for f in progress(seq, total=len(seq), desc="catch (open loop)", enabled=show_progress):
        if rr_log is not None and depth_every and f.index % depth_every == 0:
            rr_log.depth(f.t, f.depth_m)
        d = det.update(f.depth_m)
        if d is None:
            continue
        n_det += 1
        p_cam = d.p_cam if pattern is None else pattern.correct_points(d.p_cam, K)
        p_b, C_b = detection_to_base(p_cam, d.cov_cam, T_base_cam)
        rec = perception.step(f.t, p_b, C_b)
        if rr_log is not None:
            rr_log.frame(f.t, p_b, rec)
        if rec["throw"] >= 0:
            throws.add(rec["throw"])
        it = rec["intercept"]
        x = rec.get("x", np.full(6, np.nan))
        bal = rec["ballistic"][1] if rec["ballistic"][1] is not None else np.full(3, np.nan)
        if it is None:
            preds.append([f.index, f.t, rec["status"], rec["throw"], *p_b, *x, *([np.nan] * 5), 0, 0, *bal])
            continue
        preds.append([f.index, f.t, rec["status"], rec["throw"], *p_b, *x, it.t_cross, *it.p_base, it.sigma_m,
                      int(it.reachable), int(it.send), *bal])
        n_cross += 1
        last_cross = it.p_base
        if it.reachable:
            n_reach += 1
            min_sigma = min(min_sigma, float(it.sigma_m))
        if it.send:
            try:
                theta = ikm(it.p_base, 0.0, 0.0, near=theta)
            except ValueError:
                continue
            sps.append([f.index, f.t, rec["throw"], *theta, *it.p_base])
            if rr_log is not None:
                rr_log.setpoint(f.t, theta, it.p_base)
    cols = ["frame", "t_s", "status", "throw", "x_det_m", "y_det_m", "z_det_m", "x_m", "y_m", "z_m", "vx_m_s",
            "vy_m_s", "vz_m_s", "t_cross_s", "x_cross_m", "y_cross_m", "z_cross_m", "sigma_m", "reachable", "send",
            "x_ballistic_m", "y_ballistic_m", "z_ballistic_m"]
    _write(out / "predictions.csv", cols, preds)
    _write(out / "setpoints.csv", ["frame", "t_s", "throw", "theta1_rad", "theta2_rad", "theta3_rad",
                                   "x_target_m", "y_target_m", "z_target_m"], sps)
    why = ""
    if not sps:
        if n_det == 0:
            why = (f"no ball detected (the first {background} frames are the background model; "
                   "is the ball in view and in range?)")
        elif n_cross == 0:
            why = "the filter never predicted a crossing of the arm's working plane (too few detections per throw?)"
        elif n_reach == 0:
            c = ", ".join(f"{v:.2f}" for v in last_cross)
            why = (f"all {n_cross} predicted crossings lie outside the arm's reachable workspace (last at "
                   f"({c}) m in the base frame): the throw misses the arm, or the calibration's T_base_cam is off")
        else:
            why = (f"the reachable crossings never became certain enough to release (smallest sigma "
                   f"{100 * min_sigma:.1f} cm)")
    return {"frames": len(seq), "detections": n_det, "throws": len(throws), "setpoints": len(sps),
            "why_no_setpoint": why}


def _write(path, cols, rows):
    from ..io.atomic import atomic_write
    with atomic_write(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([v if isinstance(v, str) else (int(v) if isinstance(v, (int, np.integer)) else
                        ("" if not np.isfinite(v) else f"{float(v):.6g}")) for v in r])


def _cmd_catch(args) -> int:
    if args.target != "demo" and (args.scheduler or args.workers or args.session_throws or args.rerun_stale
                                  or args.calibrations is not None):
        raise TudorVisionError("--scheduler, --workers, --session-throws, --calibrations, --rerun-stale: only with "
                               "'catch demo'")
    if args.target != "demo" and (args.plant is not None or args.camera_distance_m is not None
                                  or args.ball_swing_length_m is not None or args.camera_latency_ms is not None
                                  or args.camera_latency_jitter_ms is not None
                                  or args.depth_pattern_px is not None or args.no_depth_pattern_correction
                                  or args.no_model_assist or args.yaw_max_deg is not None
                                  or args.payload_catch_prior is not None
                                  or args.calibration_frames is not None):
        raise TudorVisionError("--plant, --camera-distance-m, --camera-latency-ms, --camera-latency-jitter-ms, "
                               "--ball-swing-length-m, --depth-pattern-px, --no-depth-pattern-correction, "
                               "--no-model-assist, --yaw-max-deg, --payload-catch-prior, --calibration-frames: only "
                               "with 'catch demo'")
    if args.target == "demo" and args.depth_pattern:
        raise TudorVisionError("--depth-pattern: only with a recorded SEQ (the demo's agent calibrates its own "
                               "camera's pattern; --no-depth-pattern-correction turns that off)")
    if args.target == "demo":
        from ..lab.catch_demo import DemoOptions, run_demo

        more = {}
        if args.plant is not None:
            more["plant"] = args.plant
        # (argument, option, range and unit on the command line, to SI, what it is)
        for arg, name, lo, hi, unit, scale, why in (
                ("camera_distance_m", "camera_distance_m", 1.0, 7.8, "m", 1.0, "in front of the robot (the wall "
                 "camera's depth reaches 8 m, the arm must stay in range)"),
                ("ball_swing_length_m", "ball_swing_length_m", 0.0, 0.5, "m", 1.0, "(0: the balls as point masses "
                 "at the end effector)"),
                ("camera_latency_ms", "camera_latency_s", 0.0, 500.0, "ms", 1e-3, "from a frame's exposure to its "
                 "delivery"),
                ("camera_latency_jitter_ms", "camera_latency_jitter_s", 0.0, 500.0, "ms", 1e-3, "of extra delay at "
                 "most"),
                ("depth_pattern_px", "depth_pattern_px", 0.0, 2.0, "px", 1.0, "of disparity, RMS (0: none)"),
                ("yaw_max_deg", "yaw_max_rad", 0.0, 90.0, "deg", np.pi / 180.0, "of joint 1 from the fixed working "
                 "plane (0: the fixed plane)"),
                ("payload_catch_prior", "payload_catch_prior", 0.0, 1.0, "", 1.0, "(the probability that a throw "
                 "the arm tries adds a ball; 0: the last weighing at rest)")):
            value = getattr(args, arg)
            if value is None:
                continue
            if not (np.isfinite(value) and lo <= value <= hi):
                flag = "--" + arg.replace("_", "-")
                raise TudorVisionError(f"{flag}: expected {lo:g}-{hi:g} {unit + ' ' if unit else ''}{why}, "
                                       f"got {value:g}")
            more[name] = float(value) * scale
        if args.calibration_frames is not None:
            if not 1 <= args.calibration_frames <= 256:
                raise TudorVisionError(f"--calibration-frames: expected 1-256 depth frames per pose of the disc "
                                       f"sweep, got {args.calibration_frames}")
            more["calibration_frames_per_pose"] = int(args.calibration_frames)
        if args.no_depth_pattern_correction:
            more["depth_pattern_correction"] = False
        if args.no_model_assist:
            more["damping_model_assist"] = False
            more["damping_gains"] = None
        opts = DemoOptions(throws=args.throws, seed=args.seed, render=not args.no_render, damping=args.damping,
                           compensate=not args.rigid, rerun=not args.no_rerun,
                           params=robot_from_args(args) if args.robot else None, **more)
        out = Path(args.out or "out/catch/demo")
        on_runner = args.scheduler or args.workers or args.session_throws or args.calibrations is not None
        if args.rerun_stale and not on_runner:
            raise TudorVisionError("--rerun-stale: only on the runner (with --scheduler, --workers, "
                                   "--session-throws or --calibrations)")
        if on_runner:
            if viewer_requested(args):
                raise TudorVisionError("--rerun, --rerun-live, --rerun-web: not with --scheduler, --workers, "
                                       "--session-throws or --calibrations (sessions write no recording)")
            return _demo_sessions(args, opts, out)
        viewer = open_viewer(args, "tudorvision_catch", default_file=None if args.no_rerun else out / "catch.rrd")
        opts = replace(opts, rerun=viewer is not None)
        try:
            s = run_demo(out, opts, recording=None if viewer is None else viewer.rec)
        except BaseException:
            if viewer is not None:
                viewer.close(hold=False)
            raise
        rate = "n/a" if s["success_rate"] is None else f"{100 * s['success_rate']:.0f} %"
        print(f"{s['throws']} throws, {s['crossing_workspace']} cross the reachable workspace, "
              f"{s['caught_in_workspace']} of them caught (success rate {rate}); {s['caught']} caught in all")
        for r in s["per_throw"]:
            what = "caught" if r["caught"] else f"missed: {r['reason']}"
            miss = "" if not np.isfinite(r["miss_m"]) else f", net {100 * r['miss_m']:.1f} cm from the ball"
            err = "" if not np.isfinite(r["pred_error_m"]) else f", intercept error {100 * r['pred_error_m']:.1f} cm"
            print(f"  throw {r['throw']}: {what}{miss}{err}")
        print(f"wrote {out / 'summary.json'}, throws.csv, predictions.csv, setpoints.csv"
              + (", catch.png" if opts.plots else ""))
        if viewer is not None:
            viewer.close()
        return 0
    seq = Path(args.target)
    if not seq.exists():
        raise FileNotFoundError(2, "no such sequence", str(seq))
    out = Path(args.out or "out/catch/open_loop")
    viewer = open_viewer(args, "tudorvision_catch_open_loop")
    try:
        res = run_open_loop(seq, out, calib=args.calib, background=args.background, params=robot_from_args(args),
                            recording=None if viewer is None else viewer.rec, depth_pattern=args.depth_pattern)
    except BaseException:
        if viewer is not None:
            viewer.close(hold=False)
        raise
    print(f"{res['detections']} detections in {res['frames']} frames, {res['throws']} throw(s), "
          f"{res['setpoints']} setpoint(s); wrote {out / 'predictions.csv'} and {out / 'setpoints.csv'}")
    if res["why_no_setpoint"]:
        print(f"no setpoint: {res['why_no_setpoint']}")
    if viewer is not None:
        viewer.close()
    return 0


def _demo_sessions(args, opts, out) -> int:
    from ..lab.catch.sessions import run_sessions
    from ..lab.runner import parse_scheduler
    if args.workers is not None and args.workers < 1:
        raise TudorVisionError(f"--workers: expected >= 1, got {args.workers}")
    if args.calibrations is not None and args.calibrations < 1:
        raise TudorVisionError(f"--calibrations: expected >= 1, got {args.calibrations}")
    scheduler = parse_scheduler(args.scheduler or "local")
    apply_rerun_stale(args, out)
    s = run_sessions(out, opts, session_throws=args.session_throws or 30, calibrations=args.calibrations or 1,
                     scheduler=scheduler, workers=args.workers, show_progress=None)
    rate = "n/a" if s["success_rate"] is None else f"{100 * s['success_rate']:.0f} %"
    print(f"{s['throws_done']} of {s['throws']} throws in {s['sessions']} sessions, {s['crossing_workspace']} cross "
          f"the reachable workspace, {s['caught_in_workspace']} of them caught (success rate {rate}); "
          f"{s['caught']} caught in all")
    for f in s["failures"]:
        print(f"failed: session {f['params']['session']} (seed {f['seed']}): {f['error']}", file=sys.stderr)
    note = "" if s["complete"] else " (incomplete: run the same command again to finish)"
    print(f"wrote {out / 'summary.json'}, throws.csv, runner.json{note}")
    if s["interrupted"]:
        return 130
    return 0 if s["complete"] else 1


def register(subparsers) -> None:
    """Add ``catch demo`` and ``catch SEQ``."""
    p = subparsers.add_parser(
        "catch", help="ball catching: simulated demo, or open-loop prediction on recorded RGB-D throws",
        description="'tudorvision catch demo': a simulated thrower throws balls at the elastic arm; wall RGB-D "
                    "frames -> detection -> EKF -> intercept -> compensated inverse kinematics -> joint layer -> "
                    "simulated arm; writes summary.json, throws.csv, plots and a rerun recording. "
                    "'tudorvision catch SEQ': the same perception open loop on a recorded RGB-D sequence, writing "
                    "predictions and setpoints as CSV (needs T_base_cam in the calibration).")
    p.add_argument("target", metavar="demo|SEQ", help="'demo' or an RGB-D sequence")
    p.add_argument("--out", help="output folder (default out/catch/demo or out/catch/open_loop)")
    p.add_argument("--throws", type=int, default=5, help="demo: number of throws (default 5)")
    p.add_argument("--seed", type=int, default=0, help="demo: random seed (default 0)")
    p.add_argument("--no-render", action="store_true",
                   help="demo: detection-noise model instead of rendered frames (fast)")
    p.add_argument("--damping", default="proportional",
                   choices=["off", "proportional", "integral", "half_integrator"],
                   help="demo: damping law of the joint layer (default proportional)")
    p.add_argument("--rigid", action="store_true", help="demo: rigid inverse kinematics (no deflection compensation)")
    p.add_argument("--no-model-assist", action="store_true",
                   help="demo: the joint layer's damper with the seed's static strain filter alone, at its tuned "
                        "gains (default: the strain the arm's identified model expects from the planned motion "
                        "removed first, gains 0 / 400 / 400)")
    p.add_argument("--no-rerun", action="store_true", help="demo: do not write OUT/catch.rrd")
    p.add_argument("--plant", default=None, choices=["seed_measured", "stiff"],
                   help="demo: the simulated arm: seed_measured (default; hub springs, dampers, backlash) or "
                        "stiff (rigid clamping, the plant before issue 18)")
    p.add_argument("--camera-distance-m", type=float, default=None, metavar="M",
                   help="demo: the wall camera stands M metres in front of the robot, for the throws and its "
                        "disc-sweep calibration (default 6.8: behind the thrower, as in the seed; 1-7.8)")
    p.add_argument("--camera-latency-ms", type=float, default=None, metavar="MS",
                   help="demo: the wall camera's frames reach the catching agent MS milliseconds after their "
                        "exposure (stamped with it; default 33.3, one frame at 30 Hz; 0-500)")
    p.add_argument("--camera-latency-jitter-ms", type=float, default=None, metavar="MS",
                   help="demo: each frame is late by a further delay drawn uniformly from 0-MS milliseconds, "
                        "frames kept in order (default 0)")
    p.add_argument("--depth-pattern-px", type=float, default=None, metavar="PX",
                   help="demo: the wall camera's fixed depth pattern, disparity pixels RMS (default 0.068, the "
                        "real Kinect measured in benchmarks/bench_depth_pattern_real.py: about 8 cm RMS at the "
                        "arm; 0: none)")
    p.add_argument("--no-depth-pattern-correction", action="store_true",
                   help="demo: the agent does not calibrate the depth pattern from a flat wall first (it stays "
                        "in the calibration and in every detection)")
    p.add_argument("--ball-swing-length-m", type=float, default=None, metavar="M",
                   help="demo: caught balls hang M metres below the ring in the net's bag and swing (default 0.1); "
                        "0: point masses at the end effector (the lab before the twenty-third session)")
    p.add_argument("--yaw-max-deg", type=float, default=None, metavar="DEG",
                   help="demo: a throw whose intercept the arm cannot reach in time in the fixed working plane is "
                        "caught in a plane joint 1 turns by up to DEG degrees, where the arm meets the ball sooner "
                        "and higher (default 0: the fixed plane, as in the seed; 0-90)")
    p.add_argument("--payload-catch-prior", type=float, default=None, metavar="P",
                   help="demo: between weighings at rest the agent believes each throw it tried added a ball with "
                        "probability P (a Kalman filter over the payload, tudorvision.catch.payload; default 0.9); 0: "
                        "the last weighing at rest stays, which in the demo's short pauses is often balls behind (0-1)")
    p.add_argument("--calibration-frames", type=int, default=None, metavar="N",
                   help="demo: depth frames per pose of the simulated disc sweep that calibrates the wall camera "
                        "(default 32; a placement no calibration is shipped or cached for renders 75 x N frames: "
                        "fewer are quicker and less accurate, 8 catch about 2 points fewer; 1-256)")
    add_viewer_arguments(p, file_help="rerun recording (.rrd) of detections, intercepts, net and setpoints "
                                      "(demo default: OUT/catch.rrd; SEQ: none)")
    p.add_argument("--scheduler", default=None, metavar="serial|local|ADDRESS",
                   help="demo: run the throws as independent sessions (fresh arm, seed S*1000+session) on the "
                        "experiment runner: 'serial', 'local' (a Dask cluster of --workers processes) or a "
                        "running Dask scheduler's address (tcp://host:8786); resumable; writes throws.csv, "
                        "summary.json and runner.json, no plots or recording")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="demo with --scheduler local: worker processes (default: the machine's cores)")
    add_rerun_stale_argument(p)
    p.add_argument("--session-throws", type=int, default=None, metavar="K",
                   help="demo on the runner: throws per session (default 30)")
    p.add_argument("--calibrations", type=int, default=None, metavar="K",
                   help="demo on the runner: wall-camera calibrations the sessions take in turn (each its own "
                        "simulated disc sweep; default 1, one for all)")
    p.add_argument("--calib", help="SEQ: calibration with intrinsics and T_base_cam")
    p.add_argument("--depth-pattern", metavar="FILE",
                   help="SEQ: the camera's fixed depth pattern ('calib rgbd-pattern'), removed from every detection")
    p.add_argument("--background", type=int, default=10, help="SEQ: frames for the background (default 10)")
    add_robot_option(p, "the arm, its kinematics and joint limits (demo: also the simulated arm)")
    p.set_defaults(func=_cmd_catch)
