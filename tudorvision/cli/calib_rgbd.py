"""``tudorvision calib rgbd-depth``, ``tudorvision calib rgbd-pattern`` and ``tudorvision calib rgbd-base``.

Thin shells over :mod:`tudorvision.rgbd.depth_model`,
:mod:`tudorvision.rgbd.disc` and :mod:`tudorvision.rgbd.base_calib`;
sequences and calibration files go through :mod:`tudorvision.io`.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._args import parse_floats
from ._viewer import add_viewer_arguments, open_viewer
from .robot_args import add_robot_option, robot_from_args

__all__ = ["register", "observe_sweep", "check_sweep_fit"]


def _save(out, base_cal, camera, **updates):
    from ..io import Calibration, load_calibration, save_calibration

    out = Path(out)
    cal = load_calibration(out) if out.is_file() else (base_cal or Calibration())
    if camera is not None and "rgbd" not in cal.cameras:
        cal = cal.with_updates(cameras={"rgbd": camera})
    return save_calibration(cal.with_updates(**updates), out)


def camera_for_sweep(seq, calib):
    from .rgbd import camera_from_file, pick_camera
    if calib is not None:
        return camera_from_file(calib)
    cal = seq.calibration
    if cal is None or not cal.cameras:
        raise TudorVisionError(f"{seq.path}: the sequence has no camera intrinsics; pass --calib FILE")
    return pick_camera(cal, seq.path), cal


def _nominal_distance(seq):
    """Target distance from the sequence's ground truth or metadata, if recorded."""
    if "target" in getattr(seq, "groundtruth_names", []):
        gt = seq.groundtruth("target")
        if "distance_m" in gt:
            return float(np.median(gt["distance_m"]))
    meta = getattr(seq, "meta", None) or {}
    if "distance_m" in meta:
        return float(meta["distance_m"])
    return None


def _cmd_depth(args) -> int:
    from .._progress import progress
    from ..io import DepthModel, open_sequence
    from ..rgbd.depth_model import calibrate_depth_model, plot_depth_model, write_depth_table_csv
    from ..rgbd.frames import Intrinsics

    distances = None if args.distances is None else parse_floats(args.distances, "--distances", len(args.seq))
    roi = None if args.roi is None else tuple(int(v) for v in parse_floats(args.roi, "--roi", 4))
    stacks, nominal, cam, cal0 = [], [], None, None
    for i, path in enumerate(args.seq):
        seq = open_sequence(path)
        if seq.kind != "rgbd":
            raise TudorVisionError(f"{path}: expected an RGB-D sequence, got kind {seq.kind!r}")
        if cam is None:
            cam, cal0 = camera_for_sweep(seq, args.calib)
        stacks.append(np.stack([f.depth_m for f in progress(seq, total=len(seq), desc=Path(path).name)]))
        nominal.append(distances[i] if distances is not None else _nominal_distance(seq))
    K = Intrinsics.from_matrix(cam.K, cam.width, cam.height)
    if any(d is None for d in nominal):
        nominal = None          # bias needs every distance; plane depth gives the distance column
    model, table = calibrate_depth_model(stacks, K, nominal_distances_m=nominal,
                                         rois=None if roi is None else [roi] * len(stacks))
    for r in table:
        print(f"z {r.distance_m:6.3f} m  sigma {r.sigma_m * 1e3:7.2f} mm  bias {r.bias_m * 1e3:+7.2f} mm  "
              f"pixels {r.n_pixels}")
    print("sigma_z(z) [m] = " + " ".join(f"{c:+.5g}" for c in model.coeffs) + " (z in m, highest power first)")
    if args.out:
        dm = DepthModel(sigma_z_poly=list(model.coeffs), z_unit="m", sigma_unit="m",
                        valid_range_m=tuple(model.z_range_m))
        print(f"wrote {_save(args.out, cal0, cam, depth_model=dm)}")
    if args.report:
        print(f"wrote {write_depth_table_csv(args.report, table)}")
    if args.plot:
        print(f"wrote {plot_depth_model(args.plot, table, model)}")
    return 0


def _cmd_pattern(args) -> int:
    from .._progress import progress
    from ..io import open_sequence
    from ..rgbd.depth_pattern import calibrate_depth_pattern, write_depth_pattern

    if not args.step_px >= 1:
        raise TudorVisionError(f"--step-px: expected a positive integer, got {args.step_px}")
    if not 0.0 < args.min_plane_fraction <= 1.0:
        raise TudorVisionError(f"--min-plane-fraction: expected a fraction in (0, 1], got {args.min_plane_fraction}")
    frames = []
    for path in args.seq:
        seq = open_sequence(path)
        try:
            if seq.kind != "rgbd":
                raise TudorVisionError(f"{path}: expected an RGB-D sequence, got kind {seq.kind!r}")
            frames += [np.asarray(f.depth_m, np.float32) for f in progress(seq, total=len(seq),
                                                                            desc=Path(path).name)]
        finally:
            seq.close()
    corr = calibrate_depth_pattern(frames, step_px=args.step_px, min_plane_fraction=args.min_plane_fraction)
    c = corr.grid_inv_m
    print(f"depth pattern from {corr.n_frames} of {len(frames)} frames (a plane over at least "
          f"{args.min_plane_fraction:.0%} of the image): RMS {np.sqrt(np.mean(c ** 2)) * 1e3:.3f} x 1e-3 1/m "
          f"(moves a depth z by about z^2 times that: {np.sqrt(np.mean(c ** 2)) * 9e3:.1f} mm RMS at 3 m), "
          f"largest {np.abs(c).max() * 9e3:.1f} mm at 3 m")
    print(f"wrote {write_depth_pattern(args.out, corr)}")
    if args.plot:
        from ..rgbd.depth_pattern import plot_depth_pattern
        print(f"wrote {plot_depth_pattern(args.plot, corr)}")
    return 0


def _is_vertical(theta, tol):
    return abs(theta[0]) < tol and abs(theta[1] - np.pi / 2) < tol and abs(theta[2]) < tol


def _predict_uv(samples, thetas, th2, max_gap=np.radians(30.0)):
    """Pixel and depth of the disc at ``th2``, interpolated between the sweep samples around it."""
    keys = sorted(samples, key=lambda k: thetas[k, 1])
    t = np.array([thetas[k, 1] for k in keys])
    lo = [k for k, tk in zip(keys, t) if tk <= th2]
    hi = [k for k, tk in zip(keys, t) if tk >= th2]
    if lo and hi:
        a, b = lo[-1], hi[0]
        ta, tb = thetas[a, 1], thetas[b, 1]
        if tb - ta > max_gap:
            return None
        w = 0.0 if tb == ta else (th2 - ta) / (tb - ta)
        uv = (1 - w) * samples[a][1] + w * samples[b][1]
        z = (1 - w) * samples[a][0][2] + w * samples[b][0][2]
        return uv, float(z)
    k = lo[-1] if lo else hi[0]
    if abs(thetas[k, 1] - th2) > max_gap / 2:
        return None
    return samples[k][1], float(samples[k][0][2])


def observe_sweep(seq, K, seed_uv, options, *, vertical_frame: int | None = None, joint_tol_deg: float = 0.5,
                  on_frame=None, depth_pattern=None):
    """Track the disc through a recorded theta2 sweep and its vertical-posture frames.

    Parameters
    ----------
    seq : Sequence
        RGB-D sequence (``tudorvision.io.open_sequence``), with ``joints.txt``
        unless ``vertical_frame`` is given.
    K : Intrinsics
    seed_uv : array_like, shape (2,)
        Pixel on the disc in the first frame.
    options : DiscOptions or Disc3DOptions
        ``Disc3DOptions`` (the default of ``calib rgbd-base``): the disc found
        in 3D as a plane disc of known radius, tracked with a circle prediction
        from the joint angles (:mod:`tudorvision.rgbd.disc3d`); frames where it
        is not measurable are skipped and listed in ``lost``. ``DiscOptions``:
        the seed's uniform-depth region grown from the seed pixel.
    vertical_frame : int, optional
        Frame index of the vertical posture (default: from ``joints.txt``).
    joint_tol_deg : float
        Joint tolerance for sweep and vertical frames, degrees.
    on_frame : callable, optional
        ``on_frame(frame, centre_cam)`` for every sweep or vertical frame:
        the RGB-D frame and the disc centre (m, camera frame) or None when lost.
    depth_pattern : tudorvision.rgbd.depth_pattern.DepthPatternCorrection, optional
        The camera's fixed depth pattern (``calib rgbd-pattern``), removed from every frame first.

    Returns
    -------
    dict
        ``points_cam`` (N, 3) sweep centroids in sweep order (NaN when lost),
        ``frames`` (N,) their frame indices, ``theta2_rad`` (N,) or None,
        ``vertical_cam`` (M, 3), ``vertical_frames`` (M,), ``lost``
        (frame -> reason), ``yaw_depth`` (K, H, W) and ``yaw_theta_rad``
        (K, 3): the frames of a theta1 sweep (theta1 off zero, theta3 zero;
        K = 0 without joint angles or such frames), ``yaw_frames`` (K,).

    Raises
    ------
    TudorVisionError
        No way to find the vertical posture, or the disc lost in all its frames.
    """
    from .._progress import progress
    from ..rgbd.disc import DiscTracker
    from ..rgbd.disc3d import Disc3DOptions
    from ..rgbd.disc_track import DiscSweepTracker

    tol = np.radians(joint_tol_deg)
    thetas = None
    if seq.joints_path is not None:     # joints.txt wherever present, listed in streams or not
        thetas = seq.joints().at(seq.timestamps)
    if thetas is None and vertical_frame is None:
        raise TudorVisionError(f"{seq.path}: no joints.txt to find the vertical posture; pass --vertical-frame I")
    n = len(seq)
    vertical = np.zeros(n, bool)
    if vertical_frame is not None:
        if not 0 <= vertical_frame < n:
            raise TudorVisionError(f"--vertical-frame: {vertical_frame} is outside 0..{n - 1}")
        vertical[vertical_frame] = True
    else:
        vertical = np.array([_is_vertical(th, tol) for th in thetas])
        if not vertical.any():
            raise TudorVisionError(f"{seq.path}: joints.txt never reaches the vertical posture [0, 90, 0] deg "
                                   f"(within {joint_tol_deg} deg); pass --vertical-frame I")
    sweep = np.ones(n, bool)
    yaw = np.zeros(n, bool)
    if thetas is not None:
        sweep = (np.abs(thetas[:, 0]) < tol) & (np.abs(thetas[:, 2]) < tol)
        yaw = (np.abs(thetas[:, 0]) >= tol) & (np.abs(thetas[:, 2]) < tol) & ~vertical
    yaw_depth = []
    if isinstance(options, Disc3DOptions):
        tracker3d = DiscSweepTracker(K, seed_uv, options)
    else:
        tracker = DiscTracker(K, seed_uv, options, max_consecutive_lost=10 ** 9)
    samples = {}          # frame -> (centroid_cam, centroid_uv)
    lost = {}
    for f in progress(seq, total=n, desc="disc"):
        i = f.index
        if not (yaw[i] or sweep[i] or vertical[i]):
            continue
        depth = f.depth_m if depth_pattern is None else depth_pattern.apply(f.depth_m)
        if yaw[i]:
            yaw_depth.append(np.asarray(depth, np.float32))
            continue
        if isinstance(options, Disc3DOptions):
            m = tracker3d.update(depth, None if thetas is None else float(thetas[i, 1]))
            if m.valid:
                samples[i] = (m.centre_cam, None)
            else:
                lost[i] = m.reason
            if on_frame is not None:
                on_frame(f, samples[i][0] if i in samples else None)
            continue
        obs = tracker.update(depth)
        if not obs.valid and thetas is not None and samples:
            # the arm jumped (e.g. back to the vertical posture): re-seed where the sweep saw
            # the disc at this theta2 (interpolated between the nearest samples) and retry
            guess = _predict_uv(samples, thetas, thetas[i, 1])
            if guess is not None:
                tracker.reseed(guess[0], guess[1])
                obs = tracker.update(depth)
        if obs.valid:
            samples[i] = (obs.centroid_cam, obs.centroid_uv)
        else:
            lost[i] = obs.reason
        if on_frame is not None:
            on_frame(f, samples[i][0] if i in samples else None)
    vidx = [i for i in range(n) if vertical[i] and i in samples]
    if not vidx:
        raise TudorVisionError("disc lost in every vertical-posture frame")
    circle_idx = [i for i in range(n) if sweep[i] and (vertical_frame is None or not vertical[i])]
    pts = np.array([samples[i][0] if i in samples else [np.nan] * 3 for i in circle_idx]).reshape(-1, 3)
    return {"points_cam": pts, "frames": np.array(circle_idx, int),
            "theta2_rad": None if thetas is None else thetas[circle_idx, 1],
            "vertical_cam": np.array([samples[i][0] for i in vidx]), "vertical_frames": np.array(vidx, int),
            "lost": lost, "yaw_depth": np.array(yaw_depth).reshape(-1, K.height, K.width),
            "yaw_theta_rad": np.zeros((0, 3)) if thetas is None else thetas[yaw],
            "yaw_frames": np.nonzero(yaw)[0]}


def _fit_base(args, seq, K, seed, opts, prm, recording):
    """observe_sweep + base_frame_from_theta2_sweep, logging depth (every 5th frame), disc and base frame."""
    from .rgbd import depth_pattern_arg
    from ..rgbd.base_calib import base_frame_from_theta2_sweep
    from ..rgbd import rerun_log

    def on_frame(f, centre):
        if f.index % 5 == 0:
            rerun_log.log_depth_frame(recording, f.index, f.t, f.depth_m)
        rerun_log.log_disc(recording, f.index, f.t, centre)

    obs = observe_sweep(seq, K, seed, opts, vertical_frame=args.vertical_frame, joint_tol_deg=args.joint_tol_deg,
                        on_frame=None if recording is None else on_frame,
                        depth_pattern=depth_pattern_arg(args.depth_pattern, K))
    T_base_cam, rep = base_frame_from_theta2_sweep(obs["points_cam"], obs["vertical_cam"], theta2_rad=obs["theta2_rad"],
                                                   origin=args.origin, vertical=args.vertical,
                                                   link1_height_m=prm.link1_height_m)
    T_base_cam, rep["mirror"] = _mirror(args.mirror, T_base_cam, obs)
    rep["spread"] = _spread(args, T_base_cam, obs, rep, prm)
    T_base_cam, rep["yaw"] = _yaw(args.yaw, T_base_cam, obs, K, opts, prm)
    rep["T_base_cam"] = np.asarray(T_base_cam, float).tolist()
    if recording is not None:
        rerun_log.log_base_frame(recording, T_base_cam, obs["points_cam"])
    return T_base_cam, rep, obs


def _spread(args, T_base_cam, obs, rep, prm):
    """``--spread-refits``: how far the sweep's own scatter lets the frame be off (``rgbd.base_spread``)."""
    import sys
    from ..rgbd.base_spread import sweep_calibration_spread

    if args.spread_refits <= 0:
        return None
    mirrored = isinstance(rep.get("mirror"), dict) and "skipped" not in rep["mirror"]
    try:
        s = sweep_calibration_spread(T_base_cam, obs["points_cam"], obs["vertical_cam"], obs["theta2_rad"],
                                     mirror=mirrored, n_boot=args.spread_refits, origin=args.origin,
                                     vertical=args.vertical, link1_height_m=prm.link1_height_m)
    except (TudorVisionError, ValueError) as exc:
        print(f"warning: sweep spread not estimated: {exc}", file=sys.stderr)
        return {"skipped": str(exc)}
    print(f"sweep spread ({s['n_boot']} refits on resampled samples): origin within "
          f"{100 * s['translation_p95_m']:.2f} cm, axes within {s['rotation_p95_deg']:.2f} deg (95 %)")
    if s["translation_p95_m"] > args.max_spread_m or s["rotation_p95_deg"] > args.max_spread_deg:
        s["warning"] = (f"the sweep's own scatter lets the base frame be {100 * s['translation_p95_m']:.2f} cm / "
                        f"{s['rotation_p95_deg']:.2f} deg off (95 %): record more depth frames per pose, more poses "
                        f"or from closer" + ("" if args.depth_pattern else
                                             "; a structured-light camera (a Kinect): remove its fixed depth pattern "
                                             "first (calib rgbd-pattern, --depth-pattern)"))
        print(f"warning: {s['warning']}", file=sys.stderr)
    return s


def _mirror(mode: str, T_base_cam, obs):
    """``--mirror``: the in-plane angle from the sweep's mirror symmetry (needs the joint angles)."""
    from ..rgbd.base_calib import refine_sweep_mirror

    if mode == "off":
        return T_base_cam, None
    if obs["theta2_rad"] is None:
        if mode == "on":
            raise TudorVisionError("--mirror on: needs the sweep's joint angles (joints.txt)")
        return T_base_cam, {"skipped": "no joint angles"}
    t2 = np.asarray(obs["theta2_rad"], float)
    theta = np.stack([np.zeros_like(t2), t2, np.zeros_like(t2)], axis=1)
    try:
        T, info = refine_sweep_mirror(T_base_cam, obs["points_cam"], theta)
    except ValueError as exc:
        if mode == "on":
            raise TudorVisionError(f"--mirror on: {exc}") from None
        return T_base_cam, {"skipped": str(exc)}
    print(f"mirror symmetry: {info['pairs']} mirrored pose pairs turned the frame by "
          f"{info['mirror_rotation_deg']:+.3f} deg in the sweep plane (spread {info['mirror_tilt_sd_deg']:.3f} deg)")
    return T, info


def _yaw(mode: str, T_base_cam, obs, K, opts, prm):
    """``--yaw``: the tilt towards the camera from the frames of a theta1 sweep (:mod:`tudorvision.rgbd.yaw_sweep`)."""
    from ..rgbd.disc3d import Disc3DOptions
    from ..rgbd.yaw_sweep import measure_yaw_sweep, refine_tilt_from_yaw

    if mode == "off":
        return T_base_cam, None
    why = None
    if not isinstance(opts, Disc3DOptions):
        why = "the disc3d detector only"
    elif len(obs["yaw_frames"]) == 0:
        why = "no theta1 sweep in joints.txt (frames with theta1 off zero and theta3 zero)"
    if why is not None:
        if mode == "on":
            raise TudorVisionError(f"--yaw on: {why}")
        return T_base_cam, {"skipped": why}
    pts, skipped = measure_yaw_sweep(obs["yaw_depth"], K, T_base_cam, obs["yaw_theta_rad"], opts, robot=prm)
    sweep_mean = np.nanmean(obs["points_cam"], axis=0)
    lost = {int(obs["yaw_frames"][k]): r for k, r in skipped.items()}
    try:
        T, info = refine_tilt_from_yaw(T_base_cam, pts, pivot_cam=sweep_mean if np.all(np.isfinite(sweep_mean))
                                       else None, theta_rad=obs["yaw_theta_rad"], robot=prm)
    except TudorVisionError as exc:
        if mode == "on":
            raise TudorVisionError(f"--yaw on: {exc}") from None
        return T_base_cam, {"skipped": str(exc), "lost": lost}
    info["lost"] = lost
    print(f"theta1 sweep: {info['yaw_points_used']} of {len(pts)} frames turned the frame's tilt towards the camera by "
          f"{info['yaw_tilt_correction_deg']:+.3f} deg (standard error {info['yaw_tilt_std_deg']:.3f} deg)")
    return T, info


def _cmd_base(args) -> int:
    from ..io import open_sequence
    from .rgbd import noise_model_from_calibration
    from ..rgbd.disc import DiscOptions
    from ..rgbd.disc3d import Disc3DOptions
    from ..rgbd.frames import Intrinsics

    seed = parse_floats(args.seed, "--seed", 2)
    seq = open_sequence(args.seq)
    if seq.kind != "rgbd":
        raise TudorVisionError(f"{args.seq}: expected an RGB-D sequence, got kind {seq.kind!r}")
    cam, cal0 = camera_for_sweep(seq, args.calib)
    K = Intrinsics.from_matrix(cam.K, cam.width, cam.height)
    annulus = tuple(parse_floats(args.depth_annulus, "--depth-annulus", 2))
    if not args.disc_radius > 0:
        raise TudorVisionError(f"--disc-radius: expected a positive radius in metres, got {args.disc_radius}")
    prm = robot_from_args(args)            # the disc moves on a circle of link2 + link3 about joint 2
    if args.detector == "disc3d":
        opts = Disc3DOptions(disc_radius_m=args.disc_radius, depth_model=noise_model_from_calibration(cal0),
                             arm_radius_m=float(prm.link2_length_m + prm.link3_length_m))
    else:
        opts = DiscOptions(disc_radius_m=args.disc_radius, depth_model=noise_model_from_calibration(cal0),
                           depth_annulus=annulus, depth_window=args.depth_window)
    viewer = open_viewer(args, "tudorvision_calib_rgbd_base")
    try:
        T_base_cam, rep, obs = _fit_base(args, seq, K, seed, opts, prm, None if viewer is None else viewer.rec)
    finally:
        if viewer is not None:
            viewer.close()
    circle_idx, vidx, lost = obs["frames"], obs["vertical_frames"], obs["lost"]
    # report indices as sequence frame numbers
    rep["points_used"] = [int(circle_idx[k]) for k in rep["points_used"]]
    rep["rejected"] = [dict(r, frame=int(circle_idx[r.pop("index")])) for r in rep["rejected"]]
    for r in rep["rejected"]:
        if r["frame"] in lost:
            r["reason"] = "lost: " + lost[r["frame"]]
    rep["vertical_frames"] = [int(i) for i in vidx]
    rep["sequence"] = str(seq.path)
    rep["detector"] = args.detector
    rep["skipped_frames"] = {str(k): v for k, v in sorted(lost.items())}
    print(f"circle RMSE {rep['circle_rmse_m'] * 100:.2f} cm over {len(rep['points_used'])} samples "
          f"({len(rep['rejected'])} rejected), radius {rep['circle_radius_m']:.3f} m, "
          f"{len(vidx)} vertical frames; {len(lost)} frames skipped (disc not measurable)")
    print("T_base_cam =\n" + np.array2string(T_base_cam, precision=4, suppress_small=True))
    bad = check_sweep_fit(rep["circle_radius_m"], rep["circle_rmse_m"], params=prm, radius_tol_m=args.radius_tol,
                          max_rmse_m=args.max_rmse)
    rep["fit_warning"] = bad
    if bad:
        import sys
        print(f"warning: {bad}" + (" (accepted: --accept-bad-fit)" if args.accept_bad_fit else ""), file=sys.stderr)
    if args.out:
        written = _save(args.out, cal0, cam, transforms={"T_base_cam": T_base_cam}, circle_rmse_m=rep["circle_rmse_m"])
        print(f"wrote {written}")
    if args.report:
        from ..io.atomic import write_text_atomic
        write_text_atomic(args.report, json.dumps(rep, indent=2))
        print(f"wrote {args.report}")
    return 3 if bad and not args.accept_bad_fit else 0


def check_sweep_fit(radius_m: float, rmse_m: float, *, params=None, radius_tol_m: float = 0.05,
                    max_rmse_m: float = 0.03) -> str:
    """Check a theta2-sweep circle against the arm's geometry.

    In the sweep (theta1 = theta3 = 0) the disc moves about joint 2 at the
    distance link2 + link3 (``tudorvision.robot`` parameters), less the
    gravity sag, which stays well under ``radius_tol_m`` for the real arm.

    Parameters
    ----------
    radius_m, rmse_m : float
        Fitted circle radius and RMSE, metres.
    params : RobotParams, optional
        Robot parameters (default: ``load_robot_params()``).
    radius_tol_m, max_rmse_m : float
        Largest accepted radius deviation and circle RMSE, metres.

    Returns
    -------
    str
        A one-line reason when the fit does not fit the arm, else ``""``.

    Examples
    --------
    >>> check_sweep_fit(0.84, 0.005)
    ''
    >>> check_sweep_fit(0.48, 0.005)[:33]
    'circle radius 0.480 m, but the ar'
    """
    from ..robot import load_robot_params

    p = params or load_robot_params()
    expected = float(p.link2_length_m + p.link3_length_m)
    if not np.isfinite(radius_m) or abs(radius_m - expected) > radius_tol_m:
        return (f"circle radius {radius_m:.3f} m, but the arm's disc moves on {expected:.3f} m about joint 2 "
                f"(tolerance {radius_tol_m:.3f} m): the disc was probably lost or mistaken for another object")
    if not np.isfinite(rmse_m) or rmse_m > max_rmse_m:
        return f"circle RMSE {rmse_m * 100:.2f} cm exceeds {max_rmse_m * 100:.2f} cm: the disc track is unreliable"
    return ""


def register(calib_sub) -> None:
    """Add ``rgbd-depth``, ``rgbd-pattern`` and ``rgbd-base`` to the ``calib`` group."""
    from ..rgbd.base_spread import SPREAD_WARN_DEG, SPREAD_WARN_M

    p = calib_sub.add_parser(
        "rgbd-depth", help="depth noise model sigma_z(z) from planar-target sequences",
        description="Planar target perpendicular to the optical axis, one sequence per distance (about 100 "
                    "frames each). Per distance: mean per-pixel temporal std inside the planar region and the "
                    "bias of the plane fit against the nominal distance; fit of sigma_z(z) as a cubic.")
    p.add_argument("seq", metavar="SEQ", nargs="+", help="one RGB-D sequence per target distance")
    p.add_argument("--distances", help="nominal distances in metres, comma-separated, one per SEQ "
                                       "(default: the sequences' ground truth, if any)")
    p.add_argument("--roi", help="planar region u0,v0,u1,v1 in pixels (default: automatic at the image centre)")
    p.add_argument("--calib", help="intrinsics file when the sequences have none")
    p.add_argument("--out", help="calibration file to write or update (depth_model)")
    p.add_argument("--report", help="CSV table: distance_m, sigma_m, bias_m, n_pixels")
    p.add_argument("--plot", help="PNG plot of sigma_z(z)")
    p.set_defaults(func=_cmd_depth)

    q = calib_sub.add_parser(
        "rgbd-pattern", help="a depth camera's fixed depth pattern from frames of a flat wall",
        description="Frames of a flat wall (or any plane over most of the view) at one or more distances and "
                    "angles, distances not needed: every frame's plane fit in inverse depth leaves the camera's "
                    "fixed pattern (a structured-light camera's disparity offset) plus noise; their mean per "
                    "block is written as OpenCV YAML for --depth-pattern of 'calib rgbd-base' and "
                    "'detect ball'. Ten or more frames per distance, two or three distances.")
    q.add_argument("seq", metavar="SEQ", nargs="+", help="RGB-D sequences of a flat wall")
    q.add_argument("--out", required=True, help="depth pattern file to write (OpenCV YAML)")
    q.add_argument("--step-px", type=int, default=8, help="block size of the pattern's grid, pixels (default 8)")
    q.add_argument("--min-plane-fraction", type=float, default=0.5,
                   help="frames whose plane covers less of the image are left out (default 0.5)")
    q.add_argument("--plot", help="PNG image of the pattern (mm at 3 m)")
    q.set_defaults(func=_cmd_pattern)

    b = calib_sub.add_parser(
        "rgbd-base", help="wall camera to robot base from a theta2 sweep with a disc in the net",
        description="Track the disc (by default found in 3D as a planar disc of --disc-radius near its "
                    "predicted position, starting at --seed) through the theta2 sweep "
                    "(theta1 = theta3 = 0), fit the circle of its centroids and build the base frame as the "
                    "seed does: origin = circle centre (shifted to the base plate by link1_height with "
                    "--origin base), z towards the end effector at [0, 90, 0] deg, y from the circle normal, "
                    "x = y x z, y = z x x. The circle is checked against the arm: a radius more than "
                    "--radius-tol from link2 + link3 or an RMSE above --max-rmse prints a one-line warning "
                    "and exits 3 unless --accept-bad-fit.")
    b.add_argument("seq", metavar="SEQ", help="RGB-D sequence of the sweep (with joints.txt, or --vertical-frame)")
    b.add_argument("--seed", required=True, help="pixel U,V on the disc in the first frame")
    b.add_argument("--vertical-frame", type=int, help="frame index of the vertical posture (default: from joints.txt)")
    b.add_argument("--calib", help="intrinsics file when the sequence has none")
    b.add_argument("--depth-pattern", metavar="FILE",
                   help="the camera's fixed depth pattern ('calib rgbd-pattern'), removed from every frame")
    b.add_argument("--disc-radius", type=float, default=0.09, help="disc radius in metres (default 0.09: the 18 cm disc)")
    b.add_argument("--detector", choices=("disc3d", "uniform-depth"), default="disc3d",
                   help="'disc3d' (default): a planar disc of --disc-radius found in 3D (plane and circle fit on the "
                        "depth points near the position predicted from the previous frames and the joint angles); "
                        "'uniform-depth': the seed's region of uniform depth grown from --seed")
    b.add_argument("--origin", choices=("base", "joint2"), default="base",
                   help="'base': base plate (matches tudorvision.robot); 'joint2': the circle centre (default base)")
    b.add_argument("--vertical", choices=("combined", "seed", "plane"), default="combined",
                   help="estimate of the vertical point (default combined; see base_frame_from_theta2_sweep)")
    b.add_argument("--depth-window", choices=("disc", "ellipse", "segment"), default="disc",
                   help="uniform-depth detector only: pixels whose raw depths give the disc depth: 'disc' (default) the disc's whole image "
                        "circle of radius f R / z; 'ellipse' the grown region's moment ellipse; 'segment' the "
                        "region itself (both biased away from the camera under strong depth noise)")
    b.add_argument("--depth-annulus", default="0,1",
                   help="LO,HI: the disc depth averages the pixels between these fractions of the depth window "
                        "(default 0,1: all of it; 0.7,1 skips an occluded centre)")
    b.add_argument("--mirror", choices=("auto", "on", "off"), default="auto",
                   help="refine the frame's angle in the sweep plane from the sweep's mirror symmetry: the disc at "
                        "theta2 and at 180 deg - theta2 sags alike, so their chord is horizontal (no arm model; "
                        "assumes the disc centre on the link axis: an offset d across it tilts the result by d / "
                        "radius, as it does the vertical posture). 'auto' (default): when joints.txt gives "
                        "mirrored poses")
    b.add_argument("--yaw", choices=("auto", "on", "off"), default="auto",
                   help="refine the frame's tilt towards the camera from a theta1 sweep in the same recording "
                        "(theta1 turned through e.g. +-45 deg at one theta2, theta3 = 0): the disc on a horizontal "
                        "circle whose heights the image measures better than the sweep's depths. 'auto' (default): "
                        "when joints.txt has such frames (disc3d detector)")
    b.add_argument("--spread-refits", type=int, default=100,
                   help="refits on resampled sweep samples that estimate how far the depth noise lets the frame be "
                        "off (default 100, about 5 s; 0: off); a 95 %% spread beyond --max-spread-m or "
                        "--max-spread-deg prints a warning")
    b.add_argument("--max-spread-m", type=float, default=SPREAD_WARN_M,
                   help=f"spread warning level, metres (default {SPREAD_WARN_M:g}: half of 1 cm, as the lab's true "
                        f"errors reached up to twice the spread)")
    b.add_argument("--max-spread-deg", type=float, default=SPREAD_WARN_DEG,
                   help=f"spread warning level, degrees (default {SPREAD_WARN_DEG:g})")
    b.add_argument("--joint-tol-deg", type=float, default=0.5, help="joint tolerance for sweep/vertical frames")
    b.add_argument("--out", help="calibration file to write or update (transforms: T_base_cam)")
    b.add_argument("--report", help="JSON report")
    add_viewer_arguments(b, file_help="rerun recording (.rrd) of depth frames, the tracked disc and the fitted "
                                      "base frame")
    b.add_argument("--radius-tol", type=float, default=0.05,
                   help="largest accepted |circle radius - (link2 + link3)| in metres (default 0.05)")
    b.add_argument("--max-rmse", type=float, default=0.06,
                   help="largest accepted circle RMSE in metres (default 0.06; the seed reports 0.048)")
    b.add_argument("--accept-bad-fit", action="store_true",
                   help="exit 0 even when the circle does not fit the arm's geometry (the warning stays)")
    add_robot_option(b, "link1 height (base origin) and link2 + link3 (the sweep circle's expected radius)")
    b.set_defaults(func=_cmd_base)
