"""``tudorvision sim``: the virtual lab's commands (recordings and plant runs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._args import parse_floats
from .robot_args import add_robot_option, robot_from_args

__all__ = ["register"]


def _deg3(text: str, name: str) -> np.ndarray:
    return np.deg2rad(parse_floats(text, name, 3, example="0,45,-45"))


def _cmd_record(args) -> int:
    from ..lab.record import KINDS, RecordOptions, record
    if args.kind not in KINDS:
        raise TudorVisionError(f"KIND: unknown recording kind {args.kind!r}; choose from {', '.join(KINDS)}")
    if args.frames is not None and args.frames < 1:
        raise TudorVisionError(f"--frames: expected a positive count, got {args.frames}")
    opts = RecordOptions(seed=args.seed, small=args.small, frames=args.frames, rolling_shutter=args.rolling_shutter,
                         payload_plates=args.plates, jitter_rig=args.jitter_rig, image_ext=args.image_ext,
                         force=args.force, params=robot_from_args(args) if args.robot else None)
    out = record(args.kind, args.out, opts)
    print(f"wrote {args.kind} recording to {out}")
    return 0


def _deg_text(rad) -> str:
    return "[" + ", ".join(f"{x:.0f}" for x in np.rad2deg(rad)) + "]"


def _cmd_ptp(args) -> int:
    from ..sim.arm import Payload
    from ..lab.simulation import simulate_ptp
    p = robot_from_args(args)
    start, goal = _deg3(args.start, "--from"), _deg3(args.to, "--to")
    if args.plates < 0:
        raise TudorVisionError(f"--plates: expected >= 0, got {args.plates}")
    log = simulate_ptp(start, goal, args.duration, params=p,
                       payload=Payload.from_parts(p, plates=args.plates, camera=args.camera))
    ee = log.ee_position()
    from ..io.atomic import atomic_write
    out = Path(args.out)
    cols = np.column_stack([log.t, log.theta, log.strain * 1e6, ee])
    header = ("t_s,theta1_rad,theta2_rad,theta3_rad,strain2a_um_m,strain2b_um_m,strain3a_um_m,strain3b_um_m,"
              "ee_x_base_m,ee_y_base_m,ee_z_base_m")
    with atomic_write(out, "w") as fh:
        np.savetxt(fh, cols[::max(1, args.decimate)], delimiter=",", header=header, comments="# ", fmt="%.9g")
    print(f"wrote {len(cols[::max(1, args.decimate)])} samples to {out}")
    if args.plot:
        from matplotlib.figure import Figure
        fig = Figure(figsize=(8, 8))
        ax = fig.subplots(3, 1, sharex=True)
        ax[0].plot(log.t, np.rad2deg(log.theta)); ax[0].set_ylabel("joint angle [deg]")
        ax[0].legend(["θ1", "θ2", "θ3"])
        ax[1].plot(log.t, log.strain * 1e6); ax[1].set_ylabel("strain [µm/m]")
        ax[1].legend(["link 2 near", "link 2 far", "link 3 near", "link 3 far"])
        ax[2].plot(log.t, (ee - ee[-1]) * 1e3); ax[2].set_ylabel("EE − final [mm]"); ax[2].set_xlabel("t [s]")
        ax[2].legend(["x (base)", "y (base)", "z (base)"])
        for a in ax:
            a.grid(True, alpha=0.3)
        ax[0].set_title(f"point-to-point {_deg_text(start)} → {_deg_text(goal)} deg, {args.plates} plate(s)")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=100)
        print(f"wrote plot {args.plot}")
    return 0


def _cmd_modes(args) -> int:
    import json
    import math
    from ..io.atomic import write_text_atomic
    from ..lab.plant_modes import plant_modes
    from ..sim.arm import PlantConfig
    th = _deg3(args.at, "--at")
    params = robot_from_args(args)
    if not np.all(np.isfinite(th)):
        raise TudorVisionError(f"--at: expected finite degrees, got {args.at!r}")
    lim = np.asarray(params.joint_limits_rad, float)
    if np.any(th < lim[:, 0] - 1e-9) or np.any(th > lim[:, 1] + 1e-9):
        raise TudorVisionError(f"--at: {args.at} is outside the joint ranges "
                               f"{np.round(np.rad2deg(lim)).astype(int).tolist()} deg")
    if not (math.isfinite(args.payload_kg) and 0.0 <= args.payload_kg <= 2.0):
        raise TudorVisionError(f"--payload-kg: expected 0 .. 2 kg, got {args.payload_kg}")
    if not (math.isfinite(args.duration) and 2.0 <= args.duration <= 120.0):
        raise TudorVisionError(f"--duration: expected 2 .. 120 s, got {args.duration}")
    servo = None
    if args.servo_time_constants_s is not None:
        servo = parse_floats(args.servo_time_constants_s, "--servo-time-constants-s", 2, example="0.001,0.003")
        if not all(math.isfinite(x) and 1e-4 <= x <= 1.0 for x in servo):
            raise TudorVisionError("--servo-time-constants-s: expected T_D,T_L in seconds, each 0.0001 .. 1, "
                                   f"got {args.servo_time_constants_s!r}")
    cfg = PlantConfig.stiff() if args.stiff else PlantConfig()
    r = plant_modes(th, args.payload_kg, cfg, args.duration, params=params, servo_time_constants_s=servo)
    out = {"theta_deg": [float(x) for x in np.rad2deg(th)], "payload_kg": args.payload_kg,
           "plant": "stiff" if args.stiff else "seed_measured", **r}
    write_text_atomic(args.out, json.dumps(out, indent=2) + "\n")
    print(f"link 2: {r['link2_hz'][0]:.2f} / {r['link2_hz'][1]:.2f} Hz, link 3: {r['link3_hz'][0]:.2f} Hz, "
          f"ring-down {r['ringdown_hz']:.2f} Hz decaying at {r['decay_per_s']:.3f} 1/s; wrote {args.out}")
    return 0


def register(sub) -> None:
    p = sub.add_parser("sim", help="virtual lab: recordings with ground truth, plant runs",
                       description="The virtual TUDOR lab: a simulated elastic arm and rendered cameras.")
    s = p.add_subparsers(dest="sim_command", metavar="ACTION")
    r = s.add_parser("record", help="write a recording (sequence directory with ground truth)",
                     description="Regenerate a recording deterministically. KIND is one of: stereo-step, "
                                 "stereo-static, stereo-sweep, stereo-checkerboard, rgbd-plane, rgbd-disc, "
                                 "rgbd-throws, rgbd-wall, servo-views.")
    r.add_argument("kind", metavar="KIND")
    r.add_argument("--out", required=True, help="output directory (must be empty or absent unless --force)")
    r.add_argument("--force", action="store_true",
                   help="write into a non-empty folder, deleting only the files a recording writes (index "
                        "files, sequence.yaml, calibration.yaml, numbered frames, listed ground truth); "
                        "other files are kept")
    r.add_argument("--seed", type=int, default=0, help="scene and noise seed (default 0)")
    r.add_argument("--small", action="store_true", help="fewer frames (the sample_data sizes)")
    r.add_argument("--frames", type=int, default=None, help="override the number of frames/poses/throws")
    r.add_argument("--plates", type=int, default=0, help="100 g payload plates (default 0)")
    r.add_argument("--rolling-shutter", action="store_true", help="stereo cameras with a rolling shutter")
    r.add_argument("--jitter-rig", action="store_true", help="randomise the stereo rig pose per seed")
    r.add_argument("--image-ext", default=".jpg", choices=[".jpg", ".png"], help="colour image format")
    add_robot_option(r, "the simulated arm (link lengths, blades, limits) and its ground truth")
    r.set_defaults(func=_cmd_record)
    q = s.add_parser("ptp", help="simulate a point-to-point motion of the elastic arm",
                     description="Planner + cascade + elastic plant at 2 kHz; writes a CSV (and a PNG plot).")
    q.add_argument("--from", dest="start", default="0,45,-45", help="start, degrees (default 0,45,-45)")
    q.add_argument("--to", default="0,135,45", help="goal, degrees (default 0,135,45)")
    q.add_argument("--duration", type=float, default=4.0, help="simulated seconds (default 4)")
    q.add_argument("--plates", type=int, default=3, help="100 g plates (default 3)")
    q.add_argument("--camera", action="store_true", help="add the 450 g camera and spheres")
    q.add_argument("--decimate", type=int, default=4, help="write every n-th 2 kHz sample (default 4)")
    q.add_argument("--out", required=True, help="CSV output")
    q.add_argument("--plot", help="PNG plot output")
    add_robot_option(q, "the simulated arm: rigid chain, blades, motors, limits")
    q.set_defaults(func=_cmd_ptp)
    m = s.add_parser("modes", help="frequencies and decay of the link modes at a pose (seed 4.7, 4.8)",
                     description="Linearised modes (joints held) and a simulated hammer ring-down at one pose; "
                                 "writes a JSON with link2_hz [first, second], link3_hz [first], decay_per_s.")
    m.add_argument("--at", required=True, help="pose, degrees, like 0,45,-45")
    m.add_argument("--payload-kg", type=float, default=0.3, help="plate payload, kg (default 0.3)")
    m.add_argument("--duration", type=float, default=8.0, help="ring-down seconds (default 8)")
    m.add_argument("--stiff", action="store_true", help="the default rigid-hub plant instead of the seed-measured one")
    m.add_argument("--servo-time-constants-s", metavar="T_D,T_L",
                   help="velocity filter and position-loop lag of the holding joint cascade, s (default the "
                        "joint layer's loop for the plant: 0.001,0.003 identified on the seed's figure 4.8, "
                        "0.003,0.01 with --stiff; a stiffer hold decays slower)")
    m.add_argument("--out", required=True, help="JSON output")
    add_robot_option(m, "the simulated arm: blades, payload mount, joint ranges")
    m.set_defaults(func=_cmd_modes)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
