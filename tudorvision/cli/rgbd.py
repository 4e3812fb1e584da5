"""``tudorvision rgbd cloud`` and ``tudorvision detect ball``.

Thin shells over :mod:`tudorvision.rgbd.cloud` and :mod:`tudorvision.rgbd.ball`;
sequences are read with :mod:`tudorvision.io`.
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._checks import TudorVisionError
from ..sensors import KINECT_DEPTH_NOISE, DepthNoiseModel
from .seq import add_sequence_options, partial_flags, problem_lines, sequence_options

if TYPE_CHECKING:
    from ..rgbd.frames import Intrinsics

__all__ = ["register", "intrinsics_for", "noise_model_from_calibration", "BALL_CSV_COLUMNS", "depth_pattern_arg"]

BALL_CSV_COLUMNS = ("frame", "t", "u", "v", "x", "y", "z", "valid")


def camera_from_file(path):
    """A CameraModel and its Calibration from a calibration in any format (``--calib``; see calib_convert)."""
    from .calib_convert import load_calibration_arg

    cal = load_calibration_arg(path)
    return pick_camera(cal, path), cal


def pick_camera(cal, where):
    cams = dict(cal.cameras)
    if "rgbd" in cams:
        return cams["rgbd"]
    if len(cams) == 1:
        return next(iter(cams.values()))
    raise TudorVisionError(f"{where}: no camera named 'rgbd' (have {sorted(cams)})")


def intrinsics_for(seq, calib=None) -> tuple[Intrinsics, object]:
    """Intrinsics of an RGB-D sequence: from ``calib`` (project YAML or ROS camera_info) or the sequence.

    Returns
    -------
    intrinsics : Intrinsics
    calibration : tudorvision.io.Calibration or None
        The calibration the camera came from (for the depth model), if any.

    Raises
    ------
    TudorVisionError
        No intrinsics anywhere (the message suggests ``--calib``).
    """
    if calib is not None:
        cam, cal = camera_from_file(calib)
    else:
        cal = seq.calibration
        if cal is None or not cal.cameras:
            raise TudorVisionError(f"{seq.path}: the sequence has no camera intrinsics; pass --calib FILE "
                                   "(project calibration or ROS camera_info YAML)")
        cam = pick_camera(cal, seq.path)
    from ..rgbd.frames import Intrinsics
    return Intrinsics.from_matrix(cam.K, cam.width, cam.height), cal


def noise_model_from_calibration(cal) -> DepthNoiseModel:
    """:class:`DepthNoiseModel` from a calibration's ``depth_model`` (any units); the seed's fit if absent."""
    dm = getattr(cal, "depth_model", None) if cal is not None else None
    if dm is None:
        return KINECT_DEPTH_NOISE
    return dm.noise_model()


def _open(path, args=None, *, strict: bool = True):
    from ..io import open_sequence
    return open_sequence(path, strict=strict, **sequence_options(args))


def _cmd_cloud(args) -> int:
    import cv2

    from ..rgbd.cloud import cloud_from_rgbd, points_colors_from_cloud, write_ply

    seq = _open(args.seq, args)
    if seq.kind != "rgbd":
        raise TudorVisionError(f"{args.seq}: expected an RGB-D sequence, got kind {seq.kind!r}")
    if not 0 <= args.frame < len(seq):
        raise TudorVisionError(f"--frame: {args.frame} is outside 0..{len(seq) - 1}")
    K, _ = intrinsics_for(seq, args.calib)
    frame = seq[args.frame]
    if frame.depth_raw.shape != K.shape:
        raise TudorVisionError(f"{args.seq}: frame size {frame.depth_raw.shape[::-1]} differs from the "
                               f"intrinsics' {K.width}x{K.height}")
    color = None if args.no_color else cv2.cvtColor(frame.bgr, cv2.COLOR_BGR2RGB)
    raw = frame.depth_raw
    pattern = depth_pattern_arg(args.depth_pattern, K)
    if pattern is not None:                 # the camera's fixed pattern removed, back in the file's depth units
        z = pattern.apply(raw.astype(np.float64) / seq.depth_scale)
        raw = np.where(raw > 0, np.clip(np.rint(z * seq.depth_scale), 1, 65535), 0).astype(np.uint16)
    pcd = cloud_from_rgbd(color, raw, K, depth_scale=seq.depth_scale, depth_trunc=args.depth_trunc)
    pts, cols = points_colors_from_cloud(pcd)
    out = write_ply(args.out, pts, cols)
    z = pts[:, 2]
    print(f"wrote {len(pts)} points (z {z.min():.2f}-{z.max():.2f} m, camera frame) to {out}")
    return 0


def depth_pattern_arg(path, K):
    """``--depth-pattern FILE``: the correction (:func:`tudorvision.rgbd.depth_pattern.read_depth_pattern`),
    checked against the camera's image size; None without the option.

    Parameters
    ----------
    path : str or None
        The option's value.
    K : Intrinsics
        The camera's intrinsics (its ``width`` and ``height``).

    Returns
    -------
    DepthPatternCorrection or None

    Raises
    ------
    TudorVisionError
        An unreadable file, or one made for another image size.
    """
    if path is None:
        return None
    from ..rgbd.depth_pattern import read_depth_pattern

    corr = read_depth_pattern(path)
    if tuple(int(v) for v in corr.image_size) != (int(K.width), int(K.height)):
        raise TudorVisionError(f"--depth-pattern {path}: made for {corr.image_size[0]}x{corr.image_size[1]} px "
                               f"images, the sequence's are {K.width}x{K.height}")
    return corr


def _ball_rows(seq, args, rows: list) -> None:
    """Detect the ball frame by frame, appending one row per readable frame to ``rows``."""
    from .._progress import progress
    from ..io.sequence import Problem
    from ..rgbd.ball import BallDetector, BallDetectorOptions, ColorBallDetector, ColorBallOptions

    if seq.kind == "rgbd":
        K, cal = intrinsics_for(seq, args.calib)
        opts = BallDetectorOptions(ball_radius_m=args.ball_diameter / 2.0, max_range_m=args.max_range,
                                   depth_model=noise_model_from_calibration(cal))
        det = BallDetector(K, opts, n_background=args.background)
        pattern = depth_pattern_arg(args.depth_pattern, K)
    elif seq.kind == "mono":
        det = ColorBallDetector(ColorBallOptions(n_background=args.background))
    else:
        raise TudorVisionError(f"{args.seq}: ball detection needs an RGB-D sequence or a video, got kind {seq.kind!r}")
    for f in progress(seq, total=len(seq), desc="detect ball"):   # defective frames are skipped and reported
        if seq.kind == "rgbd":
            if f.depth_m.shape != K.shape:
                seq.record_problem(Problem(f"frame {f.index}", f"depth is {f.depth_m.shape[1]}x{f.depth_m.shape[0]}, "
                                                            f"the intrinsics {K.width}x{K.height}", f.index))
                continue
            d = det.update(f.depth_m)
            if d is None:
                p = (np.nan,) * 3
            else:
                p = tuple(d.p_cam if pattern is None else pattern.correct_points(d.p_cam, K))
        else:
            d = det.update(f.image)
            p = (np.nan,) * 3
        rows.append([f.index, f.t, *([np.nan] * 2 if d is None else d.uv), *p, 0 if d is None else 1])


def _cmd_detect_ball(args) -> int:
    from ..io.atomic import atomic_write

    seq = _open(args.seq, args, strict=False)
    rows: list = []
    interrupted = None
    try:
        _ball_rows(seq, args, rows)
    except KeyboardInterrupt:
        interrupted = "interrupted (Ctrl-C)"
    except (TudorVisionError, ValueError, OSError, ArithmeticError) as exc:
        if not rows:
            raise
        interrupted = f"stopped by an error ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
    finally:
        seq.close()
    flags = partial_flags(len(rows), interrupted, problem_lines(seq))
    out = Path(args.out)
    with atomic_write(out, "w", newline="") as fh:
        for line in flags:
            fh.write(f"# {line}\n")
        w = csv.writer(fh)
        w.writerow(BALL_CSV_COLUMNS)
        for r in rows:
            w.writerow([int(r[0]), f"{r[1]:.6f}"] + ["" if not np.isfinite(x) else f"{x:.6f}" for x in r[2:7]]
                       + [int(r[7])])
    n = sum(r[7] for r in rows)
    mode = "3D (RGB-D)" if seq.kind == "rgbd" else "pixels only (colour video)"
    print(f"ball found in {n} of {len(rows)} frames, {mode}; wrote {out}"
          + (" (partial: see the # lines)" if flags else ""))
    if interrupted:
        return 130 if "Ctrl-C" in interrupted else 2
    return 0


def register(subparsers) -> None:
    """Add ``rgbd cloud`` and ``detect ball``."""
    p = subparsers.add_parser("rgbd", help="RGB-D frames: point clouds",
                              description="RGB-D frame tools.")
    sub = p.add_subparsers(dest="rgbd_command", metavar="ACTION")
    c = sub.add_parser("cloud", help="export one frame as a PLY point cloud (camera frame, metres)",
                       description="Back-project one RGB-D frame with Open3D (create_from_rgbd_image) and "
                                   "write a coloured PLY point cloud in the camera optical frame.")
    c.add_argument("seq", metavar="SEQ", help="RGB-D sequence (project layout, TUM, Kinect folders)")
    c.add_argument("--frame", type=int, default=0, help="0-based frame index (default 0)")
    c.add_argument("--out", required=True, help="output .ply file")
    c.add_argument("--calib", help="intrinsics file when the sequence has none (project calibration or "
                                   "ROS camera_info YAML)")
    c.add_argument("--depth-trunc", type=float, default=6.0, help="drop points farther than this, metres "
                                                                  "(default 6)")
    c.add_argument("--no-color", action="store_true", help="write points without colours")
    c.add_argument("--depth-pattern", metavar="FILE",
                   help="the camera's fixed depth pattern ('calib rgbd-pattern'), removed before the points are made")
    add_sequence_options(c)
    c.set_defaults(func=_cmd_cloud)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])

    d = subparsers.add_parser("detect", help="object detection in recordings (ball)",
                              description="Detectors over whole sequences.")
    dsub = d.add_subparsers(dest="detect_command", metavar="OBJECT")
    b = dsub.add_parser("ball", help="ball detection by background subtraction -> CSV",
                        description="Detect the thrown ball by background subtraction. RGB-D sequences give "
                                    "3D centres in the camera frame (metres); colour videos give pixel "
                                    "positions. CSV columns: frame, t, u, v, x, y, z, valid.")
    b.add_argument("seq", metavar="SEQ", help="RGB-D sequence or video file")
    b.add_argument("--out", required=True, help="output CSV")
    b.add_argument("--calib", help="intrinsics file when the sequence has none")
    b.add_argument("--depth-pattern", metavar="FILE",
                   help="the camera's fixed depth pattern ('calib rgbd-pattern'), removed from every ball position")
    b.add_argument("--background", type=int, default=10, help="initial frames for the background (default 10)")
    b.add_argument("--max-range", type=float, default=4.5, help="search range from the sensor, metres "
                                                                "(default 4.5)")
    b.add_argument("--ball-diameter", type=float, default=0.09, help="ball diameter, metres (default 0.09)")
    add_sequence_options(b)
    b.set_defaults(func=_cmd_detect_ball)
    d.set_defaults(func=lambda args: (d.print_help(), 2)[1])
