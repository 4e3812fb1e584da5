"""``tudorvision servo``: visual servoing in the virtual lab, the repeatability experiment, open loop on a sequence.

* ``tudorvision servo --sim [--payload-g G] [--seed S] --out DIR``: one
  closed-loop run on the simulated elastic arm (static deflection, payload,
  damping on) from a start posture around the goal; the goal is taught as an
  image. Writes ``errors.csv``, ``servo.rrd`` (rerun) and ``errors.png``
  (workspace and image-space error, the seed's figure 9.3).
* ``tudorvision servo --sim --experiment repeatability --repetitions N --seed S --out DIR
  [--scheduler serial|local|tcp://host:8786] [--workers W]``: ``DIR/summary.json``, ``DIR/runs.csv``,
  ``DIR/runner.json`` and one record per run in ``DIR/runs/`` (resumable; see docs/experiments.md).
* ``tudorvision servo --sim --experiment tracking --out DIR``: steady error on a slowly moving square.
* ``tudorvision servo SEQ --goal IMAGE``: open loop on a recorded RGB-D
  sequence, one command line per frame.
"""
from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ..io.atomic import atomic_write, write_text_atomic
from ._viewer import add_viewer_arguments, open_viewer
from .robot_args import add_robot_option, robot_from_args

__all__ = ["register", "run_sim", "run_sequence", "plot_errors"]

_CSV_COLUMNS = ("t", "e_u_px", "e_v_px", "e_z_m", "error_est_m", "error_true_m", "image_error_px", "ok",
                "theta1", "theta2", "theta3", "x_cam_world", "y_cam_world", "z_cam_world")


def register(sub) -> None:
    p = sub.add_parser("servo", help="hybrid visual servoing with the eye-in-hand RGB-D camera (section 9.1)",
                       description="Visual servoing: closed loop in the virtual lab (--sim), the repeatability "
                                   "experiment, or open loop on a recorded RGB-D sequence (SEQ --goal IMAGE).")
    p.add_argument("seq", nargs="?", metavar="SEQ", help="recorded RGB-D sequence (open loop)")
    p.add_argument("--goal", metavar="IMAGE", help="goal colour image (open loop)")
    p.add_argument("--goal-depth", metavar="DEPTH", help="goal depth image (16-bit PNG in the sequence's depth "
                                                         "units); default: the sequence's depth of the same frame")
    p.add_argument("--calib", metavar="YAML", help="calibration with the rgbd camera and T_ee_cam "
                                                   "(default: the sequence's)")
    p.add_argument("--sim", action="store_true", help="closed loop in the virtual lab")
    p.add_argument("--experiment", choices=("repeatability", "tracking"), help="with --sim")
    p.add_argument("--repetitions", type=int, default=20, help="repeatability: runs per law, payload and pose")
    p.add_argument("--payload-g", type=int, default=200, help="payload in addition to the camera, multiple of "
                                                              "100 g (default 200)")
    p.add_argument("--start-pose", type=int, default=0, help="start pose 0..7 (0-3 near, 4-7 far) for --sim")
    p.add_argument("--law", choices=("hybrid", "ibvs"), default="hybrid")
    p.add_argument("--interaction", choices=("current", "desired", "mean"), default="current",
                   help="IBVS interaction matrix")
    p.add_argument("--no-damping", action="store_true", help="run the joint layer without strain damping")
    p.add_argument("--smoothing-frames", type=int, default=None,
                   help="moving average of the features over N frames (default 15 with --sim, 1 for SEQ)")
    p.add_argument("--supersample", type=int, default=1, metavar="K",
                   help="--sim: K x K colour samples per pixel around the square (pixel-area integration; "
                        "1 = the simulator's point sampling)")
    p.add_argument("--workers", type=int, default=None,
                   help="repeatability: local worker processes (default: the machine's cores; 1: serial)")
    p.add_argument("--scheduler", default=None, metavar="serial|local|ADDRESS",
                   help="repeatability: 'serial', 'local' (a Dask cluster of --workers processes; the default "
                        "unless --workers 1) or a running Dask scheduler's address, e.g. tcp://host:8786")
    p.add_argument("--compare-repetitions", type=int, default=None,
                   help="repeatability: runs per payload and pose for the compared law (default --repetitions)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", metavar="DIR", help="output directory (--sim)")
    add_viewer_arguments(p, file_help="rerun recording (.rrd) of images, features, errors and joint commands "
                                      "(default with --sim: OUT/servo.rrd; open loop: none)")
    add_robot_option(p, "the simulated arm (--sim) and the joint map (Jacobian) of the servo law")
    p.set_defaults(func=_main)


def _main(args) -> int:
    if args.sim:
        if args.seq is not None:
            raise TudorVisionError("SEQ: give either a sequence or --sim, not both")
        if not args.out:
            raise TudorVisionError("--out: required with --sim")
        if args.experiment == "repeatability":
            return _repeatability(args)
        if args.experiment == "tracking":
            return _tracking(args)
        return run_sim(args)
    if args.experiment:
        raise TudorVisionError("--experiment: needs --sim")
    if args.seq is None:
        raise TudorVisionError("SEQ: give a recorded RGB-D sequence (with --goal IMAGE) or --sim")
    if not args.goal:
        raise TudorVisionError("--goal: a goal image is required for SEQ")
    return run_sequence(args)


def _lab_config(args):
    from dataclasses import replace

    from ..lab.servo_lab import LabConfig
    cfg = LabConfig(params=robot_from_args(args) if args.robot else None)
    if args.no_damping:
        cfg = replace(cfg, damping=False)
    if args.supersample < 1:
        raise TudorVisionError(f"--supersample: expected a positive integer, got {args.supersample}")
    if args.supersample > 1:
        cfg = replace(cfg, supersample=args.supersample)
    return cfg


def _check_payload(g: int) -> int:
    if g < 0 or g % 100:
        raise TudorVisionError(f"--payload-g: expected a non-negative multiple of 100, got {g}")
    return g


def run_sim(args) -> int:
    """One closed-loop run with outputs (see the module notes)."""
    from ..lab.servo_experiments import start_poses
    from ..servo.laws import LawConfig
    from ..lab.servo_lab import ServoLab, run_closed_loop, teach_goal
    from ..servo.loop import DEFAULT_SMOOTHING_FRAMES, VisualServo
    g = _check_payload(args.payload_g)
    if not 0 <= args.start_pose <= 7:
        raise TudorVisionError(f"--start-pose: expected 0..7, got {args.start_pose}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = _lab_config(args)
    goal, p_goal, (goal_bgr, _) = teach_goal(cfg, np.random.default_rng([args.seed, 999]), scene_seed=args.seed)
    lab = ServoLab(cfg, cfg.theta_goal, plates=g // 100, rng=np.random.default_rng([args.seed, 1]),
                   scene_seed=args.seed)
    theta0 = start_poses(cfg, lab.square_center_world)[args.start_pose]
    lab = ServoLab(cfg, theta0, plates=g // 100, rng=np.random.default_rng([args.seed, 1]), scene_seed=args.seed)
    servo = VisualServo(goal, cfg.T_ee_cam, law=LawConfig(law=args.law, interaction=args.interaction), params=cfg.params,
                        smoothing_frames=args.smoothing_frames or DEFAULT_SMOOTHING_FRAMES)
    from ..servo.rerun_log import RerunServoLog
    viewer = open_viewer(args, "tudorvision_servo", default_file=out / "servo.rrd")
    log = RerunServoLog(viewer.rec, goal) if viewer is not None else None
    if log is not None:
        log.log_goal(goal_bgr)
    try:
        result = run_closed_loop(lab, servo, p_goal, on_frame=_with_status(None if log is None else log.log_frame,
                                                                            cfg.t_max_s))
    except BaseException:
        if viewer is not None:
            viewer.close(hold=False)
        raise
    if sys.stderr.isatty():
        sys.stderr.write("\n")                     # end the status line
    _write_csv(out / "errors.csv", result.history)
    plot_errors(result.history, out / "errors.png")
    summary = {"converged": result.converged, "settling_time_s": result.settling_time_s,
               "final_error_m": result.final_error_m, "final_offset_world_m": result.final_offset_world.tolist(),
               "payload_g": g, "start_pose": args.start_pose, "law": args.law, "seed": args.seed,
               "theta_start_rad": np.asarray(theta0).tolist()}
    write_text_atomic(out / "result.json", json.dumps(summary, indent=2))
    if viewer is not None:
        viewer.close()
    print(f"servo: {'converged' if result.converged else 'did not converge'}"
          + (f" in {result.settling_time_s:.2f} s" if result.converged else "")
          + f", final camera position error {result.final_error_m * 1e3:.1f} mm; wrote {out}")
    return 0 if result.converged else 1


def _with_status(on_frame, t_max_s: float, stream=None):
    """``on_frame`` plus a status line on stderr every simulated second (a terminal only: logs stay clean)."""
    import sys
    stream = stream or sys.stderr
    if not (hasattr(stream, "isatty") and stream.isatty()):
        return on_frame
    shown = [-1]

    def frame(t, bgr, depth, step):
        if on_frame is not None:
            on_frame(t, bgr, depth, step)
        if int(t) > shown[0]:
            shown[0] = int(t)
            c = step.command
            err = f"{c.error_m * 1e3:6.1f} mm" if c.ok and c.error_m is not None else "features lost"
            stream.write(f"\rservo: t {t:5.1f} / {t_max_s:.0f} s, estimated error {err}   ")
            stream.flush()
    return frame


def _write_csv(path: Path, h: dict) -> None:
    with atomic_write(path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(_CSV_COLUMNS)
        for i in range(len(h["t"])):
            wr.writerow([f"{h['t'][i]:.4f}", f"{h['e_u'][i]:.3f}", f"{h['e_v'][i]:.3f}", f"{h['e_z'][i]:.5f}",
                         f"{h['error_est_m'][i]:.5f}", f"{h['error_true_m'][i]:.5f}",
                         f"{h['image_error_px'][i]:.3f}", int(h["ok"][i]),
                         *[f"{x:.6f}" for x in h["theta"][i]], *[f"{x:.5f}" for x in h["p_cam_world"][i]]])


def plot_errors(h: dict, path) -> None:
    """Workspace error (a) and image-space error (b) over time, as the seed's figure 9.3."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(7, 6))
    a, b = fig.subplots(2, 1, sharex=True)
    t = h["t"]
    a.plot(t, 1e3 * h["error_true_m"], label="true camera position error")
    a.plot(t, 1e3 * h["error_est_m"], "--", label=r"estimated $\|L^{-1}e\|$")
    a.set_ylabel("workspace error [mm]")
    a.legend()
    a.grid(True, alpha=0.3)
    b.plot(t, h["e_u"], label="$e_u$")
    b.plot(t, h["e_v"], label="$e_v$")
    bz = b.twinx()
    bz.plot(t, 1e3 * h["e_z"], "g:", label="$e_z$")
    bz.set_ylabel("$e_z$ [mm]")
    b.set_ylabel("image error [px]")
    b.set_xlabel("time [s]")
    b.legend(loc="upper right")
    b.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(str(path), dpi=100)


def _repeatability(args) -> int:
    from ..lab.runner import parse_scheduler
    from ..lab.servo_experiments import repeatability
    if args.repetitions < 1:
        raise TudorVisionError(f"--repetitions: expected >= 1, got {args.repetitions}")
    if args.compare_repetitions is not None and args.compare_repetitions < 1:
        raise TudorVisionError(f"--compare-repetitions: expected >= 1, got {args.compare_repetitions}")
    if args.workers is not None and args.workers < 1:
        raise TudorVisionError(f"--workers: expected >= 1, got {args.workers}")
    scheduler = None if args.scheduler is None else parse_scheduler(args.scheduler)
    laws = ("hybrid", "ibvs") if args.law == "hybrid" else ("ibvs", "hybrid")
    s = repeatability(args.out, repetitions=args.repetitions, seed=args.seed, laws=laws,
                      interaction=args.interaction, cfg=_lab_config(args), workers=args.workers,
                      compare_repetitions=args.compare_repetitions, scheduler=scheduler, show_progress=None)
    for law, r in s["laws"].items():
        if r is None:
            print(f"{law:6s}: no run finished")
            continue
        print(f"{law:6s}: mean {r['mean_error_m'] * 1e3:.1f} mm, p90 {r['p90_error_m'] * 1e3:.1f} mm, "
              f"radius {r['radius_m'] * 1e3:.1f} mm, converged {100 * r['convergence_rate']:.0f} %, "
              f"settling {r['settling_time_s']:.2f} s ({r['n_runs']} runs)")
    for f in s["failures"]:
        print(f"failed: {f['params']} seed {f['seed']}: {f['error']}", file=sys.stderr)
    note = "" if s["complete"] else (f" (incomplete: {s['runs_done']} of {s['runs_planned']} runs; "
                                     "run the same command again to finish)")
    print(f"wrote {Path(args.out) / 'summary.json'} ({s['wall_s']:.0f} s){note}")
    if s["interrupted"]:
        return 130
    return 0 if s["complete"] else 1


def _tracking(args) -> int:
    from ..lab.servo_experiments import track_moving_square
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    r = track_moving_square(seed=args.seed, cfg=_lab_config(args), law=args.law)
    write_text_atomic(out / "tracking.json", json.dumps(r, indent=2))
    print(f"tracking {r['speed_m_s'] * 1e3:.0f} mm/s: steady error (square in the camera frame vs goal view) "
          f"mean {r['steady_error_mean_m'] * 1e3:.1f} mm, max {r['steady_error_max_m'] * 1e3:.1f} mm; camera "
          f"{r['world_offset_end_m'] * 1e3:.0f} mm from the goal pose carried along, tilted {r['tilt_end_deg']:.1f} deg")
    return 0


# ----------------------------------------------------------------------------- open loop
def _read_depth_image(path: Path, depth_scale: float):
    import cv2

    from ..sensors import depth_m_from_raw
    if not path.is_file():
        raise FileNotFoundError(2, "no such file", str(path))
    d = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if d is None or d.ndim != 2:
        raise TudorVisionError(f"{path}: not a single-channel depth image")
    return depth_m_from_raw(d, depth_scale)


def run_sequence(args) -> int:
    """Open loop on a recorded sequence: print one command line per frame."""
    import cv2

    from ..io import open_sequence
    from .calib_convert import load_calibration_arg
    from ..servo.laws import LawConfig
    from ..servo.loop import VisualServo, default_T_ee_cam
    goal_path = Path(args.goal)
    if not goal_path.is_file():
        raise FileNotFoundError(2, "no such file", str(goal_path))
    bgr = cv2.imread(str(goal_path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise TudorVisionError(f"{goal_path}: not a readable image")
    seq = open_sequence(args.seq)
    if seq.kind != "rgbd":
        raise TudorVisionError(f"{args.seq}: expected an RGB-D sequence, got {seq.kind}")
    scale = float(seq.depth_scale or 1000.0)
    if args.goal_depth:
        goal_depth = _read_depth_image(Path(args.goal_depth), scale)
    else:
        cand = goal_path.parent.parent / "depth" / (goal_path.stem + ".png")
        if not cand.is_file():
            raise TudorVisionError(f"--goal-depth: no depth image found for {goal_path} (looked for {cand})")
        goal_depth = _read_depth_image(cand, scale)
    if goal_depth.shape != bgr.shape[:2]:
        raise TudorVisionError(f"--goal-depth: size {goal_depth.shape[::-1]} differs from the goal image "
                               f"{bgr.shape[1::-1]}")
    cal = load_calibration_arg(args.calib) if args.calib else seq.calibration
    if cal is None:
        raise TudorVisionError(f"{args.seq}: no calibration; pass --calib")
    cams = dict(cal.cameras)
    cam = cams.get("rgbd") or (next(iter(cams.values())) if len(cams) == 1 else None)
    if cam is None:
        raise TudorVisionError(f"calibration: no camera named 'rgbd' (have {sorted(cams)})")
    try:
        T_ee_cam = cal.transform("T_ee_cam")
        have_he = True
    except (KeyError, TudorVisionError, ValueError):
        T_ee_cam, have_he = default_T_ee_cam(), False
    try:
        servo = VisualServo.from_goal_image(bgr, goal_depth, cam.K, T_ee_cam,
                                            law=LawConfig(law=args.law, interaction=args.interaction),
                                            smoothing_frames=args.smoothing_frames or 1,
                                            params=robot_from_args(args))
    except ValueError as exc:
        raise TudorVisionError(f"{goal_path}: {exc}") from None
    try:
        joints = seq.joints()
    except (TudorVisionError, OSError, AttributeError):
        joints = None
    print("# frame t ok e_u_px e_v_px e_z_m vx_cam vy_cam vz_cam theta_dot1 theta_dot2 theta_dot3 reason"
          + ("" if have_he and joints is not None else "  (theta_dot: no joints.txt or T_ee_cam; zero)"))
    from ..servo.rerun_log import RerunServoLog
    viewer = open_viewer(args, "tudorvision_servo")
    log = RerunServoLog(viewer.rec, servo.goal) if viewer is not None else None
    if log is not None:
        log.log_goal(bgr)
    try:
        _open_loop_lines(seq, servo, joints, have_he, log)
    finally:
        if viewer is not None:
            viewer.close()
    return 0


def _open_loop_lines(seq, servo, joints, have_he, log) -> None:
    for fr in seq:
        theta = joints.at(fr.t) if joints is not None else np.zeros(3)
        st = servo.step(fr.bgr, fr.depth_m, theta)
        if log is not None:
            log.log_frame(fr.t, fr.bgr, fr.depth_m, st)
        c = st.command
        td = st.theta_dot if (have_he and joints is not None) else np.zeros(3)
        e = c.error if c.error is not None else np.full(3, np.nan)
        reason = c.reason or (st.joint.reason if (have_he and joints is not None) else "")
        print(f"{fr.index} {fr.t:.4f} {int(c.ok)} {e[0]:.2f} {e[1]:.2f} {e[2]:.4f} "
              f"{c.v_cam[0]:.4f} {c.v_cam[1]:.4f} {c.v_cam[2]:.4f} {td[0]:.4f} {td[1]:.4f} {td[2]:.4f}"
              + (f" {reason}" if reason else ""))
