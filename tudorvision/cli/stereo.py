"""``tudorvision colormodel``, ``tudorvision track stereo`` and ``tudorvision track mono``.

Thin shells over :mod:`tudorvision.stereo.colormodel` and
:mod:`tudorvision.stereo.pipeline`. Sequences are opened leniently: corrupt
frames are skipped, counted and listed, and the partial result is written.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._viewer import add_viewer_arguments, open_viewer
from .seq import add_sequence_options, partial_flags, problem_lines, sequence_options

__all__ = ["register"]

#: Exit code of a tracking run that finished but has no valid frame (the trajectory is still written).
NO_VALID_EXIT = 3


def register(subparsers) -> None:
    """Add ``colormodel`` and ``track`` (``stereo``, ``mono``) to the top-level command."""
    c = subparsers.add_parser(
        "colormodel", help="fit sphere colour models from picked pixels on one frame",
        description="Fit one colour model (a Gaussian per channel of R, G, B, H, S, V) per camera and sphere "
                    "from a picked centre pixel and edge pixel on one frame. Without --pick, --save-frame "
                    "writes the frame as a PNG to pick the pixels on.")
    c.add_argument("seq", help="sequence directory, or a video file (camera 'mono')")
    c.add_argument("--frame", type=int, default=0, metavar="I", help="0-based frame index to pick on (default 0)")
    c.add_argument("--pick", action="append", default=[], metavar="CAMERA:SPHERE:CU,CV:EU,EV",
                   help="camera (left, right or mono), sphere name, centre pixel and edge pixel (u right, "
                        "v down); repeat for every camera and sphere, e.g. left:red:320,240:331,240")
    c.add_argument("--out", help="colour model file to write (.yaml or .json)")
    add_centre_argument(c)
    c.add_argument("--save-frame", metavar="PNG",
                   help="write the pick frame (stereo: left | right side by side, right starting at u = width)")
    c.set_defaults(func=run_colormodel)

    t = subparsers.add_parser("track", help="track the end effector (stereo) or one sphere (mono)",
                              description="Track the coloured spheres in recorded sequences.")
    tsub = t.add_subparsers(dest="track_command", metavar="KIND")
    t.set_defaults(func=lambda args: (t.print_help(), 2)[1])

    s = tsub.add_parser(
        "stereo", help="end-effector trajectory from a stereo sequence -> CSV",
        description="Track both spheres in both cameras, triangulate, and write the end-effector trajectory "
                    "(t, x, y, z, vx, vy, vz, ax, ay, az, valid; SI units). The frame is the robot base frame "
                    "when T_base_left is known (--base-calib, or in --calib), else the left camera optical "
                    "frame. Frames where a sphere is missing in either camera are written with valid = 0.")
    s.add_argument("seq", help="stereo sequence directory")
    s.add_argument("--calib", help="stereo calibration (default: the sequence's): tudorvision YAML, ROS "
                                   "left.yaml,right.yaml, OpenCV intrinsics.yml,extrinsics.yml, a folder holding a "
                                   "pair, or Kalibr camchain.yaml (docs/calibration_formats.md)")
    s.add_argument("--colormodel", required=True, help="colour model file (from 'tudorvision colormodel')")
    s.add_argument("--out", required=True, help="trajectory CSV to write")
    s.add_argument("--base-calib", metavar="FILE",
                   help="calibration file holding T_base_left (from 'tudorvision calib base-stereo'); "
                        "default: T_base_left of --calib when present")
    s.add_argument("--no-base", action="store_true", help="ignore T_base_left: write the left camera frame")
    s.add_argument("--plot", metavar="PNG", help="draw trajectory, speed and acceleration")
    add_viewer_arguments(s, file_help="write a rerun recording of images, detections and the 3D track")
    s.add_argument("--rerun-image-every", type=int, default=1, metavar="N",
                   help="log the images of every N-th frame only (default 1)")
    s.add_argument("--live", action="store_true",
                   help="pace playback at the recorded rate, drop frames when behind, report latency")
    s.add_argument("--speed", type=float, default=1.0, help="live playback speed factor (default 1)")
    s.add_argument("--full-frame", action="store_true", help="search every full frame (no tracking windows)")
    s.add_argument("--no-rolling-shutter", action="store_true",
                   help="do not compensate the rolling shutter even if the calibration has line_time_s")
    s.add_argument("--no-epipolar-centres", action="store_true",
                   help="keep each view's own sphere centre instead of moving the pair onto one epipolar plane")
    s.add_argument("--method", choices=("normalized", "rectified"), default="normalized",
                   help="triangulation route (default normalized)")
    s.add_argument("--sphere-separation", type=float, default=None, metavar="M",
                   help="known sphere distance in metres; frames whose triangulated distance is off by more "
                        "than 3 cm are flagged invalid (default: from the robot parameters; 0 disables)")
    s.add_argument("--sphere-radius-mm", type=float, default=None, metavar="MM",
                   help="known radius of the spheres in mm: a sphere whose two views imply another size (by "
                        "more than 16 %% and 1.5 px) is flagged missing in that frame (default: no check)")
    s.add_argument("--strict", action="store_true", help="stop at the first corrupt frame instead of skipping it")
    add_sequence_options(s)
    add_luma_edge_argument(s)
    add_centre_argument(s)
    s.set_defaults(func=run_track_stereo)

    m = tsub.add_parser(
        "mono", help="pixel track of one sphere in a video or image sequence -> CSV",
        description="Track one sphere in a single camera and write frame, t, u, v, valid (frame is the "
                    "0-based decode index; u right, v down, pixels).")
    m.add_argument("video", help="video file or mono sequence directory")
    m.add_argument("--colormodel", required=True, help="colour model file")
    m.add_argument("--sphere", required=True, help="sphere name in the colour model file")
    m.add_argument("--camera", default="mono", help="camera of the model to use (default mono)")
    m.add_argument("--out", required=True, help="pixel track CSV to write")
    m.add_argument("--full-frame", action="store_true", help="search every full frame (no tracking windows)")
    m.add_argument("--strict", action="store_true", help="stop at the first undecodable frame")
    add_viewer_arguments(m, file_help="write a rerun recording of the pixel track")
    add_sequence_options(m)
    add_luma_edge_argument(m)
    add_centre_argument(m)
    m.set_defaults(func=run_track_mono)


# ----------------------------------------------------------------------------- helpers
    from .batch import register_track_batch   # after stereo and mono in 'track --help'
    register_track_batch(tsub)


def add_luma_edge_argument(parser, help_text: str = "locate the sphere rims on the luma edge (robust to the "
                           "colour smear of JPEG and video; about halves the tracking speed): auto = on for JPEG "
                           "frames and video files (default auto)") -> None:
    """The ``--luma-edge auto|on|off`` option of the commands that track spheres (see :func:`luma_edge_params`)."""
    parser.add_argument("--luma-edge", choices=("auto", "on", "off"), default="auto", help=help_text)


def add_centre_argument(parser) -> None:
    """The ``--centre circle|centroid`` option: how a sphere's image centre is measured.

    ``circle`` (default) fits a robust circle to the region's rim, so a
    highlight or a shadowed side does not pull the centre; ``centroid`` is the
    seed's first moment, kept for comparison.
    """
    parser.add_argument("--centre", choices=("circle", "centroid"), default="circle",
                        help="sphere image centre: circle = robust circle fit to the rim (default), "
                             "centroid = first moment of the coloured region (the seed's method)")


def centroid_mode(centre: str) -> str:
    """``SegmentParams.centroid`` for a ``--centre`` choice.

    Examples
    --------
    >>> centroid_mode("centroid")
    'moment'
    """
    return {"circle": "shape", "centroid": "moment"}[centre]


def luma_edge_params(choice: str, source, centre: str = "circle"):
    """``TrackerParams`` for ``--luma-edge`` (auto: on for JPEG frames and video) and a line saying which.

    Examples
    --------
    >>> luma_edge_params("auto", "ball.mp4")[1]
    'luma edge: on (ball.mp4 is JPEG frames or a video)'
    """
    from ..stereo.rim_edge import chroma_subsampled_source
    from ..stereo.segment import SegmentParams
    from ..stereo.tracker2d import TrackerParams

    if choice == "auto":
        on = chroma_subsampled_source(source)
        why = f"{Path(source).name} is {'' if on else 'not '}JPEG frames or a video"
    else:
        on, why = choice == "on", "--luma-edge"
    seg = SegmentParams(edge_refine=on, centroid=centroid_mode(centre))
    return TrackerParams(segment=seg), f"luma edge: {'on' if on else 'off'} ({why})"

def _open(path, *, strict: bool = False, args=None):
    from ..io import open_sequence

    # open_sequence checks existence itself and also takes live sources (/dev/videoN, rtsp://, http://, a,b)
    return open_sequence(str(path), strict=strict, **sequence_options(args))


def _exit_code(interrupted: str | None) -> int:
    """130 after Ctrl-C, 2 after an error that stopped the run, else 0."""
    if not interrupted:
        return 0
    return 130 if "Ctrl-C" in interrupted else 2


def _load_models(path):
    from ..stereo.colormodel import load_color_models

    if not Path(path).is_file():
        raise TudorVisionError(f"{path}: colour model file not found")
    return load_color_models(path)


# ----------------------------------------------------------------------------- colormodel
def run_colormodel(args) -> int:
    import cv2

    from ..stereo.colormodel import fit_color_model_set, save_color_models

    if not args.pick and not args.save_frame:
        raise TudorVisionError("give at least one --pick CAMERA:SPHERE:CU,CV:EU,EV (or --save-frame PNG)")
    if args.pick and not args.out:
        raise TudorVisionError("--out: needed to write the colour models")
    seq = _open(args.seq, strict=True, args=args)
    try:
        n = len(seq)
        if not 0 <= args.frame < n:
            raise TudorVisionError(f"--frame: {args.frame} is outside the sequence (0..{n - 1})")
        f = seq[args.frame]
        if seq.kind == "stereo":
            frames = {"left": f.left, "right": f.right}
        elif seq.kind == "mono":
            frames = {"mono": f.image}
        else:
            raise TudorVisionError(f"{args.seq}: colour models need a stereo or mono sequence, got {seq.kind}")
    finally:
        seq.close()
    for cam, img in frames.items():
        if img.ndim != 3:
            raise TudorVisionError(f"{args.seq}: frame {args.frame} ({cam}) is a grey image; colour models "
                                   "need colour frames")
    if args.save_frame:
        img = np.hstack(list(frames.values())) if len(frames) > 1 else next(iter(frames.values()))
        from ..io.atomic import write_bytes_atomic
        ok, buf = cv2.imencode(Path(args.save_frame).suffix or ".png", img)
        if not ok:
            raise TudorVisionError(f"{args.save_frame}: cannot encode the image")
        write_bytes_atomic(args.save_frame, buf.tobytes())
        print(f"wrote {args.save_frame} (frame {args.frame}, cameras {' | '.join(frames)})")
    if not args.pick:
        return 0
    from ..stereo.detection import SegmentParams

    verify = SegmentParams(centroid=centroid_mode(getattr(args, "centre", "circle")))
    models = fit_color_model_set(frames, args.pick, verify_params=verify)
    for cam in models.cameras:
        for name in models.spheres(cam):
            mdl = models.get(cam, name)
            r, g, b = (round(x) for x in mdl.mean[:3])
            print(f"{cam}/{name}: centre ({mdl.center_uv[0]:.1f}, {mdl.center_uv[1]:.1f}), radius "
                  f"{mdl.radius_px:.1f} px, {mdl.n_pixels} pixels, mean RGB ({r}, {g}, {b}), hue "
                  f"{mdl.mean[3]:.1f}{'' if mdl.use_hue else ' (unused: unsaturated)'}")
            if mdl.is_local:
                print(f"warning: {cam}/{name}: local colour model: the frame holds this colour elsewhere, so it is "
                      f"searched only within {mdl.local_radius_px:.0f} px of its last position (pick on the frame "
                      f"tracking starts from)")
    for line in models.colour_mismatches():
        print(f"warning: {line}")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    save_color_models(models, args.out)
    print(f"wrote {args.out}")
    return 0


# ----------------------------------------------------------------------------- track stereo
def _calibrations(args, seq):
    from .calib_convert import load_calibration_arg

    size = (seq.size or {})
    if args.calib:
        left_size = tuple(size["left"]) if "left" in size else None
        cal = load_calibration_arg(args.calib, size=left_size)
        cal_name = args.calib
    else:
        cal = seq.calibration
        cal_name = "the sequence's calibration"
        if cal is None:
            raise TudorVisionError(f"{args.seq}: no calibration in the sequence; give --calib FILE")
    if cal.stereo is None:
        raise TudorVisionError(f"{cal_name}: has no stereo extrinsics (run 'tudorvision calib stereo')")
    T, source = None, None
    if args.base_calib:
        base = load_calibration_arg(args.base_calib, option="--base-calib")
        if "T_base_left" not in base.transforms:
            raise TudorVisionError(f"{args.base_calib}: has no transforms.T_base_left "
                                   "(run 'tudorvision calib base-stereo')")
        T, source = base.transforms["T_base_left"], args.base_calib
    elif "T_base_left" in cal.transforms:
        T, source = cal.transforms["T_base_left"], cal_name
    if args.no_base:
        T, source = None, None
    # image size check against the recording's declared size, before any frame is decoded
    for cam in ("left", "right"):
        cm = cal.camera(getattr(cal.stereo, cam))
        if cam in size and tuple(size[cam]) != (cm.width, cm.height):
            w, h = size[cam]
            raise TudorVisionError(f"{cal_name}: the {cam} camera is calibrated for {cm.width}x{cm.height}, "
                                   f"but the sequence's images are {w}x{h}")
    return cal, cal_name, T, source


def _sphere_separation(models):
    """Distance between the two modelled spheres from the robot parameters, or None."""
    from ..robot import load_robot_params

    names = [n for n in models.spheres("left") if n in models.spheres("right")]
    offsets = load_robot_params().sphere_offsets_ee_m
    if len(names) != 2 or not all(n in offsets for n in names):
        return None
    return float(np.linalg.norm(np.subtract(offsets[names[0]], offsets[names[1]])))


class ValidityDiagnosis:
    """Counts, per processed frame, where the spheres were lost, to explain a run with no valid frame.

    Called as ``on_result(result, frame)`` of :func:`tudorvision.stereo.tracking.track_stereo`;
    :meth:`cause` then names the likely cause in one line.
    """

    _GEOMETRY = ("stereo-inconsistent", "sphere separation")

    def __init__(self):
        self.frames = 0
        self.geometry = 0
        self.found = {"left": 0, "right": 0}

    def __call__(self, res, frame=None) -> None:
        self.frames += 1
        dets = res.detections
        seen = {cam: all(d.valid or any(g in (d.reason or "") for g in self._GEOMETRY) for d in dets[cam].values())
                for cam in ("left", "right")}
        for cam in seen:
            self.found[cam] += int(seen[cam])
        if not res.valid and seen["left"] and seen["right"]:
            self.geometry += 1

    def cause(self, cal) -> str:
        """The likely cause of 0 % valid frames, one line."""
        from ..io.calib_formats import swapped_stereo_reason

        n = self.frames
        swapped = swapped_stereo_reason(cal)
        if swapped:
            return f"the calibration's {swapped}"
        if self.geometry * 2 >= n:
            return (f"both spheres were found in both images in {self.geometry} of {n} frames but do not fit the "
                    "calibration's epipolar geometry: the calibration is likely not this rig's, or the left and "
                    "right images are exchanged (check --calib and the sequence's left/right streams)")
        missing = [f"{cam} {self.found[cam]} of {n}" for cam in ("left", "right")]
        return (f"the spheres were found in too few frames (all spheres seen: {', '.join(missing)} frames): check "
                "the colour models (tudorvision colormodel --save-frame, then --pick) for that camera")


def run_track_stereo(args) -> int:
    from ..stereo.pipeline import PipelineOptions
    from ..stereo.tracking import track_stereo
    from ..stereo.trajectory import plot_trajectory, write_trajectory_csv

    if not args.speed > 0:
        raise TudorVisionError(f"--speed: must be positive, got {args.speed}")
    seq = _open(args.seq, strict=args.strict, args=args)
    if seq.kind != "stereo":
        raise TudorVisionError(f"{args.seq}: expected a stereo sequence, got kind {seq.kind!r}")
    models = _load_models(args.colormodel)
    cal, cal_name, T_base_left, base_source = _calibrations(args, seq)
    sep = _sphere_separation(models) if args.sphere_separation is None else args.sphere_separation
    if sep is not None and sep < 0:
        raise TudorVisionError(f"--sphere-separation: must be a non-negative distance in metres, got {sep}")
    radius_mm = args.sphere_radius_mm
    if radius_mm is not None and not (math.isfinite(radius_mm) and radius_mm > 0):
        raise TudorVisionError(f"--sphere-radius-mm: must be a positive radius in mm, got {radius_mm}")
    tracker, edge_note = luma_edge_params(args.luma_edge, args.seq, getattr(args, "centre", "circle"))
    print(edge_note)
    options = PipelineOptions(tracking=not args.full_frame, method=args.method, tracker=tracker,
                              rolling_shutter=not args.no_rolling_shutter,
                              epipolar_centres=not args.no_epipolar_centres, sphere_separation_m=sep or None,
                              sphere_radius_m=None if radius_mm is None else radius_mm / 1000.0)
    log = None
    viewer = open_viewer(args, "tudorvision_stereo")
    if viewer is not None:
        from ..stereo.rerun_log import RerunStereoLog
        log = RerunStereoLog(recording=viewer.rec, image_every=args.rerun_image_every)
    diag = ValidityDiagnosis()

    def on_result(r, frame):
        diag(r, frame)
        if log is not None:
            log.log_frame(r, frame)

    try:
        res = track_stereo(seq, cal, models, T_base_left=T_base_left, options=options, live=args.live,
                           speed=args.speed, show_progress=None if not args.live else False,
                           on_result=on_result, keep_partial=True)
    except BaseException:
        if viewer is not None:
            viewer.close(hold=False)
        raise
    finally:
        seq.close()
    traj = res.trajectory
    comment = [f"sequence: {args.seq}", f"calibration: {cal_name}",
               f"colour models: {args.colormodel}",
               f"mode: {'full frame' if args.full_frame else 'tracking'}; triangulation {args.method}; "
               f"rolling shutter {'compensated' if res.rolling_shutter else 'not compensated'}"]
    if base_source:
        comment.append(f"T_base_left: {base_source}")
    if res.stats.skipped:
        comment.append(f"{res.stats.skipped} corrupt frame(s) skipped")
    if res.stats.dropped:
        comment.append(f"{res.stats.dropped} frame(s) dropped by live playback")
    comment = partial_flags(len(traj.t), res.stats.interrupted, problem_lines(seq)) + comment
    out = write_trajectory_csv(args.out, traj, comment="\n".join(comment))
    frame_desc = "robot base frame" if traj.frame == "base" else "left camera optical frame"
    print(f"wrote {out} ({len(traj.t)} rows, {frame_desc})")
    if args.plot:
        print(f"wrote {plot_trajectory(traj, args.plot, title=f'end effector: {Path(args.seq).name}')}")
    if log is not None:
        log.log_trajectory(traj, res.index)
        log.close()
        viewer.close()
    speed = traj.speed
    if np.isfinite(speed).any():
        print(f"peak speed {np.nanmax(speed):.2f} m/s, peak acceleration {np.nanmax(traj.accel_norm):.1f} m/s^2")
    print(res.stats.summary())
    if res.stats.processed and res.stats.valid == 0:
        print(f"warning: 0 % valid: no frame has both spheres in both cameras: {diag.cause(cal)}", file=sys.stderr)
        return _exit_code(res.stats.interrupted) or NO_VALID_EXIT
    return _exit_code(res.stats.interrupted)


# ----------------------------------------------------------------------------- track mono
def run_track_mono(args) -> int:
    from ..stereo.tracking import track_mono, write_mono_track_csv

    seq = _open(args.video, strict=args.strict, args=args)
    models = _load_models(args.colormodel)
    model = models.get(args.camera, args.sphere)
    viewer = None
    try:
        tracker, edge_note = luma_edge_params(args.luma_edge, args.video, getattr(args, "centre", "circle"))
        print(edge_note)
        viewer = open_viewer(args, "tudorvision_track_mono")
        res = track_mono(seq, model, tracking=not args.full_frame, params=tracker, show_progress=None,
                         keep_partial=True)
    except BaseException:
        if viewer is not None:
            viewer.close(hold=False)
        raise
    finally:
        seq.close()
    flags = partial_flags(len(res.t), res.stats.interrupted, problem_lines(seq))
    out = write_mono_track_csv(args.out, res, comment="\n".join(
        flags + [f"video: {args.video}", f"sphere: {args.sphere} ({args.camera}) from {args.colormodel}"]))
    print(f"wrote {out} ({len(res.t)} rows)")
    if viewer is not None:
        from ..stereo.rerun_log import log_mono_track
        try:
            log_mono_track(viewer.rec, res, sphere=args.sphere, camera=args.camera)
        finally:
            viewer.close()
    print(res.stats.summary())
    if len(res.t) and not np.any(res.valid):
        print(f"warning: 0 % valid: sphere {args.sphere!r} found in no frame: the colour model likely does not "
              f"fit this video (camera {args.camera!r}; re-pick with tudorvision colormodel --pick "
              f"{args.camera}:...)", file=sys.stderr)
        return _exit_code(res.stats.interrupted) or NO_VALID_EXIT
    return _exit_code(res.stats.interrupted)
