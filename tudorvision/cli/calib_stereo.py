"""``tudorvision calib stereo`` and ``tudorvision calib base-stereo``.

Thin shells over :mod:`tudorvision.stereo.calibrate` and
:mod:`tudorvision.stereo.base_frame`; files are written with
:mod:`tudorvision.io.calibration` and :mod:`tudorvision.io.formats`.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from .robot_args import add_robot_option, robot_from_args

__all__ = ["register"]

_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".ppm", ".pgm"}


def register(calib_sub) -> None:
    """Add the stereo calibration subcommands to the ``calib`` group."""
    from .stereo import add_luma_edge_argument

    p = calib_sub.add_parser(
        "stereo", help="stereo intrinsics/extrinsics from checkerboard image pairs",
        description="Calibrate a stereo pair from checkerboard image pairs: intrinsics, distortion, "
                    "extrinsics, rectification, per-view and overall RMS reprojection error. Pairs "
                    "where the board is not found in both images are skipped and counted.")
    p.add_argument("--left", help="comma-separated left images")
    p.add_argument("--right", help="comma-separated right images (same order as --left)")
    p.add_argument("--dir", help="directory with left/ and right/ image folders (a stereo recording such as "
                                 "sample_data/stereo-checkerboard), left*/right* image folders, or left*/right* "
                                 "images side by side; paired in natural sort order")
    p.add_argument("--board", default="9x6", help="inner corners COLSxROWS (default 9x6)")
    p.add_argument("--square", type=float, default=0.025, help="square edge length in metres (default 0.025)")
    p.add_argument("--out", help="calibration file to write (project YAML format)")
    p.add_argument("--plot", help="PNG of the per-view reprojection errors")
    p.add_argument("--export-ros", metavar="DIR", help="write DIR/left.yaml and DIR/right.yaml (ROS camera_info)")
    p.add_argument("--export-opencv", metavar="DIR",
                   help="write DIR/intrinsics.yml and DIR/extrinsics.yml like OpenCV's stereo_calib sample "
                        "(T in metres)")
    p.add_argument("--mode", choices=("default", "opencv-sample"), default="default",
                   help="'default': calibrateCamera per camera then a joint stereoCalibrate; "
                        "'opencv-sample': the flags of OpenCV's stereo_calib sample (default: default)")
    p.add_argument("--fix-intrinsic", action="store_true",
                   help="keep the per-camera intrinsics fixed in the stereo step")
    p.add_argument("--alpha", type=float, default=1.0, help="stereoRectify free scaling (default 1, like the sample)")
    p.add_argument("--line-time", type=float, default=None, metavar="S",
                   help="rolling-shutter row time in seconds, stored with both cameras")
    p.add_argument("--min-views", type=int, default=3, help="fewest usable pairs (default 3)")
    p.add_argument("--allow-swapped", action="store_true",
                   help="exit 0 even when left and right look swapped (T_x > 0); the warning is still printed")
    p.set_defaults(func=run_stereo)

    b = calib_sub.add_parser(
        "base-stereo", help="robot base frame from a theta1 sweep tracked by the stereo cameras",
        description="Robot base frame in the left camera frame from a theta1 sweep (theta2 = theta3 = 0): "
                    "circle fit of the end-effector trajectory, z = circle normal (up), x toward "
                    "theta1 = 0, gravity sag removed with the vertical posture [0, 90, 0] deg. Input is a "
                    "trajectory CSV in the left camera frame (--traj, from 'tudorvision track stereo' without "
                    "a base calibration), or the sequence SEQ itself, tracked here with --calib and "
                    "--colormodel; and the joint log.")
    b.add_argument("seq", nargs="?", help="sequence directory (its joints.txt is used unless --joints)")
    b.add_argument("--traj", help="trajectory CSV in the left camera frame (default: track SEQ)")
    b.add_argument("--calib", help="stereo calibration to track SEQ with (default: the sequence's), in any format "
                                   "of docs/calibration_formats.md")
    b.add_argument("--colormodel", help="colour model file to track SEQ with (needed without --traj)")
    b.add_argument("--joints", help="joints.txt: 'timestamp theta1 theta2 theta3' per line")
    b.add_argument("--joints-deg", action="store_true", help="joint angles in the file are degrees")
    b.add_argument("--vertical-frame", type=int, default=None, metavar="I",
                   help="0-based trajectory row in the vertical posture (default: rows whose joints are "
                        "[0, 90, 0] deg within --tol-deg)")
    b.add_argument("--tol-deg", type=float, default=1.0, help="joint tolerance for sweep/vertical rows (default 1)")
    add_robot_option(b, "link lengths and joint ranges of the theta1 sweep", legacy_alias="--robot-params")
    add_luma_edge_argument(b, "when tracking SEQ: locate the sphere rims on the luma edge (auto = on for JPEG "
                              "frames and video; see 'track stereo --help')")
    b.add_argument("--out", required=True,
                   help="calibration file; T_base_left and circle_rmse_m are added (kept content otherwise)")
    b.set_defaults(func=run_base_stereo)


# ----------------------------------------------------------------------------- calib stereo
def _natural_key(p: Path):
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", p.name)]


def _images_in(d: Path) -> list[Path]:
    return sorted((f for f in d.iterdir() if f.is_file() and f.suffix.lower() in _IMAGE_SUFFIXES), key=_natural_key)


def _side_folders(d: Path, side: str) -> list[Path]:
    return [f for f in d.iterdir() if f.is_dir() and f.name.lower().startswith(side) and _images_in(f)]


def _dir_lists(d: Path) -> tuple[list[Path], list[Path]]:
    """Left and right images of ``--dir``: ``left/`` + ``right/`` (or one ``left*`` + one ``right*``) folders,
    else ``left*`` / ``right*`` files side by side."""
    if not d.is_dir():
        raise TudorVisionError(f"{d}: not a directory")
    lf, rf = _side_folders(d, "left"), _side_folders(d, "right")
    if lf or rf:
        exact = [d / "left", d / "right"]
        if all(f.is_dir() for f in exact):
            lf, rf = [exact[0]], [exact[1]]
        if len(lf) != 1 or len(rf) != 1:
            raise TudorVisionError(f"{d}: expected one left* and one right* image folder, found "
                                   f"{', '.join(f.name for f in lf + rf) or 'one side only'}")
        left, right = _images_in(lf[0]), _images_in(rf[0])
        where = f"{lf[0].name}/ and {rf[0].name}/"
    else:
        files = _images_in(d)
        left = [f for f in files if f.name.lower().startswith("left")]
        right = [f for f in files if f.name.lower().startswith("right")]
        where = "left* and right* files"
    if not left or len(left) != len(right):
        raise TudorVisionError(f"{d}: found {len(left)} left and {len(right)} right images ({where}); "
                               "need the same nonzero number")
    return left, right


def _image_lists(args) -> tuple[list[Path], list[Path]]:
    if args.dir:
        if args.left or args.right:
            raise TudorVisionError("give either --dir or --left/--right, not both")
        return _dir_lists(Path(args.dir))
    if not (args.left and args.right):
        raise TudorVisionError("give --dir DIR or both --left and --right image lists")
    left = [Path(s.strip()) for s in args.left.split(",") if s.strip()]
    right = [Path(s.strip()) for s in args.right.split(",") if s.strip()]
    if len(left) != len(right):
        raise TudorVisionError(f"--right: expected {len(left)} images like --left, got {len(right)}")
    for f in left + right:
        if not f.is_file():
            raise TudorVisionError(f"{f}: image not found")
    return left, right


def run_stereo(args) -> int:
    from ..io.calib_formats import swapped_stereo_reason
    from ..io.calibration import save_calibration
    from ..io.formats import save_opencv_stereo, save_ros_camera_info
    from ..stereo.calibrate import calibrate_stereo_from_images, parse_board, plot_view_errors

    board = parse_board(args.board)
    if not args.square > 0:
        raise TudorVisionError(f"--square: must be positive metres, got {args.square}")
    left, right = _image_lists(args)
    res = calibrate_stereo_from_images(left, right, board, args.square, mode=args.mode,
                                       fix_intrinsic=args.fix_intrinsic, alpha=args.alpha,
                                       line_time_s=args.line_time, min_views=args.min_views)
    for name, reason in res.skipped:
        print(f"skipped {name}: {reason}")
    print(f"board {board[0]}x{board[1]} inner corners, square {args.square} m")
    print(res.summary())
    cal = res.calibration
    swapped = swapped_stereo_reason(cal)
    header = f"stereo calibration from {len(res.views)} checkerboard pairs"
    if swapped:
        print(f"warning: {swapped}" + (" (accepted: --allow-swapped)" if args.allow_swapped else ""),
              file=sys.stderr)
        header += f"\nWARNING: {swapped}"
    if args.out:
        print(f"wrote {save_calibration(cal, args.out, header=header)}")
    if args.plot:
        print(f"wrote {plot_view_errors(res, args.plot)}")
    st = cal.stereo
    if args.export_ros:
        d = Path(args.export_ros)
        for name, R, P in (("left", st.R1, st.P1), ("right", st.R2, st.P2)):
            print(f"wrote {save_ros_camera_info(d / f'{name}.yaml', cal.camera(name), name=name, R_rect=R, P=P)}")
    if args.export_opencv:
        d = Path(args.export_opencv)
        for f in save_opencv_stereo(cal, d / "intrinsics.yml", d / "extrinsics.yml"):
            print(f"wrote {f}")
    if not (args.out or args.export_ros or args.export_opencv):
        print("note: nothing written (use --out, --export-ros or --export-opencv)")
    return 3 if swapped and not args.allow_swapped else 0


# ----------------------------------------------------------------------------- calib base-stereo
def _joint_log(args):
    """(t (M,), theta (M, 3) radians) from --joints or the sequence's joints.txt."""
    if args.joints:
        from ..io import load_joint_log
        path = Path(args.joints)
        if not path.is_file():
            raise TudorVisionError(f"{path}: joints file not found")
        log = load_joint_log(path)
        t, th = log.t, log.theta_rad
    elif args.seq:
        from ..io.sequence import open_sequence
        log = open_sequence(args.seq).joints()
        t, th = log.t, log.theta_rad
    else:
        raise TudorVisionError("need the joint log: give SEQ (with joints.txt) or --joints FILE")
    if len(t) < 2:
        raise TudorVisionError("joint log: fewer than 2 samples")
    if args.joints_deg:
        th = np.deg2rad(th)
    return t, th


def _track_sweep(args):
    """Track SEQ in the left camera frame: (Trajectory, Calibration used)."""
    from ..io.sequence import open_sequence
    from .calib_convert import load_calibration_arg
    from .stereo import ValidityDiagnosis, luma_edge_params
    from ..stereo.colormodel import load_color_models
    from ..stereo.pipeline import PipelineOptions
    from ..stereo.tracking import track_stereo

    if not args.seq:
        raise TudorVisionError("give SEQ (tracked with --calib and --colormodel) or --traj CSV")
    if not args.colormodel:
        raise TudorVisionError("--colormodel: needed to track SEQ (or give --traj CSV)")
    if not Path(args.colormodel).is_file():
        raise TudorVisionError(f"{args.colormodel}: colour model file not found")
    seq = open_sequence(args.seq, strict=False)
    try:
        if args.calib:
            cal = load_calibration_arg(args.calib, size=tuple((seq.size or {}).get("left", ())) or None)
        else:
            cal = seq.calibration
            if cal is None:
                raise TudorVisionError(f"{args.seq}: no calibration in the sequence; give --calib FILE")
        tracker, edge_note = luma_edge_params(args.luma_edge, args.seq)
        print(edge_note)
        diag = ValidityDiagnosis()
        res = track_stereo(seq, cal, load_color_models(args.colormodel), show_progress=None,
                           options=PipelineOptions(tracker=tracker), on_result=diag)
    finally:
        seq.close()
    print(f"tracked {args.seq}: {res.stats.summary()}")
    if res.stats.processed and res.stats.valid == 0:
        raise TudorVisionError(f"{args.seq}: 0 % valid frames when tracking the sweep: {diag.cause(cal)}")
    return res.trajectory, cal, diag


def run_base_stereo(args) -> int:
    from ..io.calibration import Calibration, load_calibration, save_calibration
    from ..stereo.base_frame import base_frame_from_theta1_sweep
    from ..stereo.trajectory import read_trajectory_csv

    tracked_cal, diag = None, None
    if args.traj:
        traj = read_trajectory_csv(args.traj)
    else:
        traj, tracked_cal, diag = _track_sweep(args)
    src = args.traj or args.seq
    if traj.frame not in ("left", "unknown"):
        raise TudorVisionError(f"{src}: trajectory is in frame {traj.frame!r}; base-stereo needs "
                               "the left camera frame (track without a base calibration)")
    t_j, th_j = _joint_log(args)
    params = robot_from_args(args)
    tol = np.deg2rad(args.tol_deg)
    inside = (traj.t >= t_j[0]) & (traj.t <= t_j[-1])
    theta = np.stack([np.interp(traj.t, t_j, th_j[:, k]) for k in range(3)], axis=1)
    ok = traj.valid & inside
    sweep = ok & (np.abs(theta[:, 1]) < tol) & (np.abs(theta[:, 2]) < tol)
    if sweep.sum() < 10:
        cause = f" (likely cause: {diag.cause(tracked_cal)})" if diag is not None else ""
        raise TudorVisionError(f"{src}: only {int(sweep.sum())} valid trajectory rows with "
                               f"theta2 = theta3 = 0 (within {args.tol_deg} deg); need at least 10{cause}")
    if args.vertical_frame is not None:
        i = args.vertical_frame
        if not 0 <= i < len(traj.t):
            raise TudorVisionError(f"--vertical-frame: {i} is outside the trajectory (0..{len(traj.t) - 1})")
        if not traj.valid[i]:
            raise TudorVisionError(f"--vertical-frame: trajectory row {i} has no valid 3D position")
        vertical = traj.p[i]
        n_vert = 1
    else:
        target = np.array([0.0, np.pi / 2, 0.0])
        vmask = ok & np.all(np.abs(theta - target) < tol, axis=1)
        n_vert = int(vmask.sum())
        if n_vert == 0:
            raise TudorVisionError(f"{src}: no valid rows in the vertical posture [0, 90, 0] deg "
                                   f"(within {args.tol_deg} deg); record it or give --vertical-frame I")
        vertical = np.median(traj.p[vmask], axis=0)
    T, rep = base_frame_from_theta1_sweep(traj.p[sweep], theta[sweep], vertical, params,
                                   sweep_tol_rad=tol)
    print(f"vertical posture from {n_vert} trajectory row(s)")
    print(rep.summary())
    out = Path(args.out)
    base = load_calibration(out) if out.is_file() else (tracked_cal or Calibration())
    cal = base.with_updates(transforms={"T_base_left": T}, circle_rmse_m=rep.circle_rmse_m,
                            metadata={"base_stereo": {"sweep_points": rep.n_points,
                                                      "inliers": rep.n_inliers,
                                                      "sag_m": float(rep.sag_m),
                                                      "radius_m": float(rep.radius_m),
                                                      "trajectory": str(args.traj or args.seq)}})
    print(f"wrote {save_calibration(cal, out)}")
    return 0
