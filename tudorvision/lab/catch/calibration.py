"""The catching demo's wall camera, calibrated from a simulated disc sweep (``calib rgbd-base``'s perception).

The wall camera stands at one place for the throws and for its calibration
(:func:`wall_camera_position_world`). Before the throws the lab renders the
theta2 sweep with the disc in the net (:func:`tudorvision.lab.disc_sweep.render_disc_sweep`,
camera at that same pose); the perception side then finds the disc in 3D in
every depth frame (:func:`tudorvision.rgbd.disc_track.track_disc_sweep`, the
``disc3d`` detector of ``tudorvision calib rgbd-base``) and fits the base frame
to the sweep circle and the vertical posture
(:func:`tudorvision.rgbd.base_calib.base_frame_from_theta2_sweep`). Only the
depth frames, the intrinsics, the joint angles and one pixel on the disc in
the first frame (the operator's click, ``--seed`` of ``calib rgbd-base``; the
lab clicks the projected disc centre) reach perception. The true transform is
used afterwards, lab side, to report the calibration's error.

A calibration depends only on the camera placement and the sweep's seed, not
on the throws: it is cached in memory and as JSON in ``DemoOptions.cache_dir``.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

__all__ = ["wall_camera_position_world", "calibrate_wall_camera", "WALL_CAMERA_AIM_HEIGHT_M"]

WALL_CAMERA_AIM_HEIGHT_M = 1.0       # the throw scene's camera looks at the point this high above the base
_MEMORY: dict = {}


def wall_camera_position_world(options) -> np.ndarray:
    """The wall camera's position for throws and calibration, metres, world frame.

    Parameters
    ----------
    options : DemoOptions
        ``camera_distance_m`` (in front of the base, along base -y) and ``camera_height_m``.

    Returns
    -------
    ndarray, shape (3,)
        Camera position, metres, world frame (the base at the world origin).

    Examples
    --------
    >>> from tudorvision.lab.catch.options import DemoOptions
    >>> wall_camera_position_world(DemoOptions()).tolist()
    [0.0, -5.8, 2.0]
    """
    from ..record import T_WORLD_BASE

    p = np.array([0.0, -float(options.camera_distance_m), float(options.camera_height_m), 1.0])
    return (T_WORLD_BASE @ p)[:3]


def _sweep_params(options, params):
    """The disc-sweep set-up whose camera pose equals the throw scene's (same eye, same aim point)."""
    from ..disc_sweep import DiscSweepParams

    h1 = float(params.link1_height_m)
    d, h = float(options.camera_distance_m), float(options.camera_height_m)
    return DiscSweepParams(camera_distance_m=float(np.hypot(d, h - h1)), camera_height_m=h,
                           camera_azimuth_rad=0.0, camera_roll_rad=0.0,
                           aim_offset_m=(0.0, 0.0, WALL_CAMERA_AIM_HEIGHT_M - h1),
                           disc_tilt_rad=0.0, background="invalid", payload_plates=0,
                           theta2_deg=tuple(float(a) for a in np.arange(0.0, 180.1, 10.0)),
                           frames_per_pose=1, n_vertical=6)


def _errors(T_est, T_true):
    from ...geometry import invert_transform, rotation_angle

    pos = float(np.linalg.norm(invert_transform(T_est)[:3, 3] - invert_transform(T_true)[:3, 3]))
    rot = float(np.degrees(rotation_angle(T_est[:3, :3].T @ T_true[:3, :3])))
    aim = np.array([0.0, 0.0, WALL_CAMERA_AIM_HEIGHT_M, 1.0])          # a point at the arm, base frame
    at_arm = float(np.linalg.norm((T_est @ invert_transform(T_true) @ aim)[:3] - aim[:3]))
    return {"position_error_m": pos, "rotation_error_deg": rot, "error_at_arm_m": at_arm}


def calibrate_wall_camera(options, params, T_base_cam_true) -> tuple[np.ndarray, dict]:
    """``T_base_cam`` of the demo's wall camera from a simulated disc sweep, and its error against the truth.

    Parameters
    ----------
    options : DemoOptions
        Camera placement (``camera_distance_m``, ``camera_height_m``), ``calibration_seed``,
        ``cache_dir``.
    params : RobotParams
        The robot's parameters (link lengths for the sweep circle).
    T_base_cam_true : array_like, shape (4, 4)
        The throw scene's true camera pose in the base frame: lab side, only to report the error
        and to check that the sweep's camera stands where the throws' does.

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        The calibrated camera pose in the base frame (``p_base = T_base_cam @ p_cam``).
    report : dict
        ``position_error_m`` (camera centre), ``rotation_error_deg``, ``error_at_arm_m`` (a point 1 m
        above the base mapped through the calibrated against the true transform), ``circle_rmse_m``,
        ``circle_radius_m``, ``frames``, ``skipped_frames``, ``sweep_camera_offset_m`` (sweep
        camera against the throws' camera; 0 up to rounding), ``cached`` (bool).

    Raises
    ------
    TudorVisionError
        When the sweep's camera does not stand where the throws' does, or the disc is lost.
    """
    from ..._checks import TudorVisionError
    from ...rgbd.base_calib import base_frame_from_theta2_sweep
    from ...rgbd.disc3d import Disc3DOptions
    from ...rgbd.disc_track import track_disc_sweep
    from ...rgbd.frames import Intrinsics
    from ..disc_sweep import render_disc_sweep

    sp = _sweep_params(options, params)
    from ..data_collection import robot_key
    key_src = json.dumps({"sweep": repr(sp), "seed": int(options.calibration_seed), "v": 1,
                          **({"robot": robot_key(params)} if robot_key(params) else {})}, sort_keys=True)
    key = hashlib.sha1(key_src.encode()).hexdigest()[:16]
    T_true = np.asarray(T_base_cam_true, float)
    path = Path(options.cache_dir) / f"wall_calibration_{key}.json"
    cached = _MEMORY.get(key)
    if cached is None and path.is_file():
        try:
            cached = json.loads(path.read_text())
        except (OSError, ValueError):
            cached = None
    if cached is not None:
        T = np.asarray(cached["T_base_cam"], float)
        rep = dict(cached["report"])
        _MEMORY[key] = cached
        rep.update(_errors(T, T_true))
        rep["cached"] = True
        return T, rep

    sweep = render_disc_sweep(sp, np.random.default_rng([int(options.calibration_seed), 15]), robot=params)
    offset = float(np.max(np.abs(sweep.T_base_cam - T_true)))
    if offset > 1e-6:
        raise TudorVisionError(f"catch demo: the calibration sweep's camera is not the throws' camera "
                               f"(pose differs by {offset:.3g})")
    n, h, w = sweep.depth_m.shape
    K = Intrinsics.from_matrix(sweep.K, w, h)
    c0 = sweep.disc_centres_cam[0]          # the operator's click on the disc in the first frame
    seed_uv = (K.fx * c0[0] / c0[2] + K.cx, K.fy * c0[1] / c0[2] + K.cy)
    opts = Disc3DOptions(disc_radius_m=sp.disc_radius_m,
                         arm_radius_m=float(params.link2_length_m + params.link3_length_m))
    pts, skipped = track_disc_sweep(sweep.depth_m, K, seed_uv, sweep.theta_rad[:, 1], opts)
    sw = ~sweep.vertical
    try:
        T, fit = base_frame_from_theta2_sweep(pts[sw], pts[sweep.vertical], theta2_rad=sweep.theta_rad[sw, 1])
    except (ValueError, TudorVisionError) as exc:
        raise TudorVisionError(f"catch demo: wall camera calibration failed: {exc}") from None
    rep = {"circle_rmse_m": float(fit["circle_rmse_m"]), "circle_radius_m": float(fit["circle_radius_m"]),
           "frames": int(n), "skipped_frames": len(skipped), "sweep_camera_offset_m": offset,
           "calibration_seed": int(options.calibration_seed)}
    entry = {"T_base_cam": np.asarray(T, float).tolist(), "report": rep}
    _MEMORY[key] = entry
    try:
        from ...io.atomic import write_text_atomic
        write_text_atomic(path, json.dumps(entry, indent=1))
    except (OSError, TudorVisionError):
        pass                                # the cache is an optimisation only
    out = dict(rep)
    out.update(_errors(np.asarray(T, float), T_true))
    out["cached"] = False
    return np.asarray(T, float), out
