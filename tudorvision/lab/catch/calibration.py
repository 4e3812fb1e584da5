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
on the throws: it is cached in memory and as JSON in ``DemoOptions.cache_dir``; the default
placement's is shipped in ``tudorvision/catch/data`` (:func:`ship_calibration`). A cached JSON
names the code that computed it (a hash of :data:`CODE_FILES`, every file whose code runs in a
calibration: a test checks that list); one written by other code is computed again, not read. The
shipped one names its code too: the tests check that it is this code's, and
:func:`check_shipped_calibration` (``benchmarks/check_shipped_calibration.py``) computes it again,
compares and ships it anew.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from ..code_hash import source_hash

__all__ = ["wall_camera_position_world", "calibrate_wall_camera", "wall_depth_sensor", "wall_depth_pattern",
           "WALL_CAMERA_AIM_HEIGHT_M", "CALIBRATION_METHODS", "SWEEP_THETA2_DEG", "YAW_THETA1_RANGE_DEG", "YAW_POSES",
           "YAW_THETA2_DEG", "ship_calibration", "check_shipped_calibration", "shipped_calibration_codes",
           "ship_depth_pattern",
           "calibration_code_hash", "CODE_FILES", "CODE_EXEMPT"]

#: ``DemoOptions.calibration_method``: the seed's sweep construction alone, refined in the sweep plane
#: from the sweep's mirror symmetry (:func:`tudorvision.rgbd.base_calib.refine_sweep_mirror`, model-free),
#: with the agent's learnt deflection model (:func:`tudorvision.rgbd.base_calib.refine_sweep_in_plane`), or both.
#: A method that names ``yaw`` adds a theta1 sweep (:data:`YAW_THETA1_RANGE_DEG` at theta2 = :data:`YAW_THETA2_DEG`) and
#: turns the frame about base x so that z is normal to that sweep's plane
#: (:func:`tudorvision.rgbd.yaw_sweep.refine_tilt_from_yaw`): the tilt towards the camera from heights, not depths.
CALIBRATION_METHODS = ("seed", "seed+mirror", "seed+deflection", "seed+deflection+mirror", "seed+mirror+yaw")
#: theta1 range of the yaw sweep, degrees (the disc seen up to 45 deg off its face): joint 1 turned slowly through
#: it, one frame per pose, :data:`YAW_POSES` times ``calibration_frames_per_pose`` frames (1664 by default: 55 s
#: at 30 Hz; 104 left the tilt 0.01-0.16 deg off over calibration seeds 0-5, 416 0.00-0.08 deg, and over seeds 0-7
#: the rotation about base x 0.128 deg RMS with 416, 0.094 with 832, 0.056 with 1664); their theta2, degrees.
YAW_THETA1_RANGE_DEG = (-45.0, 45.0)
YAW_THETA2_DEG = 45.0
YAW_POSES = 52
#: The calibration sweep's theta2 poses, degrees. 10-170 deg: at 6.9 m the disc's depth in the horizontal
#: poses (0 and 180 deg, the disc 29 cm above the base plate) came out 4-23 mm too far (a tilt of the
#: fitted plane by 0.2-0.4 deg); the end poses are left out.
SWEEP_THETA2_DEG = tuple(float(a) for a in np.arange(10.0, 170.1, 10.0))
WALL_CAMERA_AIM_HEIGHT_M = 1.0       # the throw scene's camera looks at the point this high above the base
_MEMORY: dict = {}
#: The sources (relative to the package) whose code decides a calibration: every file whose code runs in one
#: (``tests/test_catch_calibration_cache.py`` profiles a short calibration against this list), and the robot's
#: parameter file; a cache entry written by other code is not read (:func:`calibration_code_hash`).
CODE_FILES = ("rgbd/disc_track.py", "rgbd/disc3d.py", "rgbd/base_calib.py", "rgbd/frames.py", "lab/disc_sweep.py",
              "lab/catch/calibration.py", "sim/depth_sensor.py", "rgbd/yaw_sweep.py", "rgbd/disc_search.py",
              "rgbd/depth_pattern.py", "lab/depth_wall.py", "geometry.py", "sensors.py", "lab/record.py",
              "lab/data_collection.py", "robot/actuators.py", "robot/kinematics.py", "robot/params.py",
              "robot/data/tudor.yaml", "sim/_shape_core.py", "sim/arm.py", "sim/beam.py", "sim/camera.py",
              "sim/joint_compliance.py", "sim/lighting.py", "sim/link_modes.py", "sim/model.py", "sim/primitives.py",
              "sim/raycast.py", "sim/scenes.py", "sim/scenes_rgbd.py", "sim/shapes.py", "sim/solids.py")
#: Files whose code runs in a calibration but decides no number of it: argument checks, file writes, this hash.
CODE_EXEMPT = ("_checks.py", "io/atomic.py", "lab/code_hash.py")


def calibration_code_hash() -> str:
    """A short hash of the calibration's sources (:data:`CODE_FILES`, line endings normalised; read once).

    Returns
    -------
    str
        16 hex digits (:func:`tudorvision.lab.code_hash.source_hash`).
    """
    return source_hash(CODE_FILES)


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
    [0.0, -6.8, 2.0]
    """
    from ..record import T_WORLD_BASE

    p = np.array([0.0, -float(options.camera_distance_m), float(options.camera_height_m), 1.0])
    return (T_WORLD_BASE @ p)[:3]


def wall_depth_sensor(options):
    """The wall camera's depth sensor: the Kinect model with the demo's depth range.

    The range ends at ``DemoOptions.camera_max_depth_m`` (default 8 m, where a
    Kinect v1 still reports depth) instead of the 6 m of the seed's noise fit
    (:data:`tudorvision.sensors.KINECT_RANGE_M`), so a camera behind the thrower
    sees the arm; beyond 6 m the noise is the seed's cubic ``sigma_z(z)``
    extrapolated (96 mm at 6.8 m, 166 mm at 8 m: harsher than published
    Kinect v1 studies, kept so the lab is not easier than the seed's fit).

    Parameters
    ----------
    options : DemoOptions
        ``camera_max_depth_m``, metres.

    The fixed depth pattern is ``options.depth_pattern_px``'s, unit ``options.calibration_seed``.

    Returns
    -------
    tudorvision.sim.depth_sensor.DepthSensorModel
        Range ``(0.6, camera_max_depth_m)`` m, noise :data:`tudorvision.sensors.KINECT_DEPTH_NOISE`.

    Examples
    --------
    >>> from tudorvision.lab.catch.options import DemoOptions
    >>> m = wall_depth_sensor(DemoOptions())
    >>> m.max_depth_m, round(float(m.noise.sigma_m(6.8)), 4)
    (8.0, 0.0959)
    """
    from ...sim.depth_sensor import DepthSensorModel

    return DepthSensorModel(max_depth_m=float(options.camera_max_depth_m),
                            pattern_disparity_px=float(options.depth_pattern_px),
                            pattern_seed=int(options.calibration_seed))


def wall_depth_pattern(options, K, width: int, height: int):
    """The agent's calibration of the wall camera's depth pattern, or None when the options leave it out.

    The lab renders 30 frames of a flat wall (2.5, 3.5 and 4.5 m, a random tilt each) through the wall
    camera's sensor (:func:`tudorvision.lab.depth_wall.render_wall_frames`); perception fits the pattern
    to them (:func:`tudorvision.rgbd.depth_pattern.calibrate_depth_pattern`). Cached in memory per sensor
    and camera, and in ``options.cache_dir`` as OpenCV YAML (``depth_pattern_<key>.yaml``, written whole or not
    at all; the key names the calibration's code): a worker process of an experiment reads it there instead of
    rendering and fitting again (about 9 s a session); a file that cannot be read is computed again and replaced.
    The default placement's is shipped with the package (:func:`ship_depth_pattern`), read when ``cache_dir``
    has none.

    Parameters
    ----------
    options : DemoOptions
        ``depth_pattern_correction``, the sensor (:func:`wall_depth_sensor`), ``calibration_seed``,
        ``cache_dir``.
    K : array_like, shape (3, 3)
        The wall camera's intrinsics, pixels.
    width, height : int
        Its image size, pixels.

    Returns
    -------
    tudorvision.rgbd.depth_pattern.DepthPatternCorrection or None
    """
    from ...rgbd.depth_pattern import write_depth_pattern

    if not options.depth_pattern_correction:
        return None
    key = _depth_pattern_key(options, K, width, height)
    if key in _MEMORY:
        return _MEMORY[key]
    path = Path(options.cache_dir) / f"depth_{key}.yaml"
    for source in (path, _packaged_pattern_path(key)):
        corr = _read_pattern(source, width, height)
        if corr is not None:
            _MEMORY[key] = corr
            return corr
    corr = _compute_depth_pattern(options, K, width, height)
    _MEMORY[key] = corr
    try:
        write_depth_pattern(path, corr)     # whole or not at all: another worker may be reading it
    except (OSError, ValueError):
        pass                                # the cache is an optimisation only; the memory cache serves
    return corr


def _depth_pattern_key(options, K, width: int, height: int) -> str:
    """``pattern_<16 hex digits>``: the sensor, the camera, the seed and the calibration's code."""
    key_src = json.dumps({"sensor": repr(wall_depth_sensor(options)), "K": np.asarray(K, float).round(9).tolist(),
                          "size": [width, height], "seed": int(options.calibration_seed),
                          "code": calibration_code_hash()}, sort_keys=True)
    return "pattern_" + hashlib.sha1(key_src.encode()).hexdigest()[:16]


def _packaged_pattern_path(key: str) -> Path:
    from ..data_collection import PACKAGED_DIR

    return PACKAGED_DIR / f"depth_{key}.yaml"


def _read_pattern(path: Path, width: int, height: int):
    """The correction in ``path`` for a ``width x height`` image, or None (absent, damaged, another size)."""
    from ..._checks import TudorVisionError
    from ...rgbd.depth_pattern import read_depth_pattern

    if not path.is_file():
        return None
    try:
        corr = read_depth_pattern(path)
    except TudorVisionError:
        return None                         # damaged: computed again, and replaced in the cache
    return corr if tuple(corr.image_size) == (int(width), int(height)) else None


def _compute_depth_pattern(options, K, width: int, height: int):
    from ...rgbd.depth_pattern import calibrate_depth_pattern
    from ..depth_wall import render_wall_frames

    walls = render_wall_frames(K, width, height, wall_depth_sensor(options),
                               np.random.default_rng([int(options.calibration_seed), 16]))
    return calibrate_depth_pattern(walls)


def ship_depth_pattern(options, K, width: int, height: int, *, ship: bool = False) -> dict:
    """Compute the depth-pattern calibration of ``options``' wall camera afresh, compare it with the shipped one and,
    with ``ship``, ship it (for maintainers, with :func:`check_shipped_calibration`).

    Only a file named by today's key (which names the code) is read by :func:`wall_depth_pattern`: after a change
    to :data:`CODE_FILES` the shipped file is simply not found (computed, about 9 s, and cached) until shipped anew.

    Parameters
    ----------
    options : DemoOptions
        The sensor, ``calibration_seed``, ``depth_pattern_correction`` (must be on).
    K : array_like, shape (3, 3)
        The wall camera's intrinsics, pixels.
    width, height : int
        Its image size, pixels.
    ship : bool
        Write the fresh calibration into the package data, and remove the shipped patterns of other keys.

    Returns
    -------
    dict
        ``shipped`` (bool: a file of today's key is shipped), ``max_abs_difference`` (its grid against the fresh
        one, 1/m; None without one), ``shipped_to`` (the path written, or None), ``removed`` (file names).
    """
    from ...rgbd.depth_pattern import write_depth_pattern

    if not options.depth_pattern_correction:
        raise ValueError("ship_depth_pattern: the options leave the depth-pattern correction out")
    key = _depth_pattern_key(options, K, width, height)
    target = _packaged_pattern_path(key)
    shipped = _read_pattern(target, width, height)
    fresh = _compute_depth_pattern(options, K, width, height)
    out = {"shipped": shipped is not None, "shipped_to": None, "removed": [],
           "max_abs_difference": None if shipped is None else
           float(np.max(np.abs(np.asarray(fresh.grid_inv_m) - np.asarray(shipped.grid_inv_m))))}
    if ship:
        if shipped is None or out["max_abs_difference"] > 0.0:
            write_depth_pattern(target, fresh)
        out["shipped_to"] = str(target)
        for other in sorted(target.parent.glob("depth_pattern_*.yaml")):
            if other != target:
                other.unlink()
                out["removed"].append(other.name)
    return out


def _sweep_params(options, params):
    """The disc-sweep set-up whose camera pose equals the throw scene's (same eye, same aim point)."""
    from ..disc_sweep import DiscSweepParams

    h1 = float(params.link1_height_m)
    yaw = ()
    if "yaw" in options.calibration_method.split("+"):
        n_yaw = YAW_POSES * int(options.calibration_frames_per_pose)
        yaw = tuple(float(a) for a in np.linspace(*YAW_THETA1_RANGE_DEG, n_yaw))
    d, h = float(options.camera_distance_m), float(options.camera_height_m)
    return DiscSweepParams(camera_distance_m=float(np.hypot(d, h - h1)), camera_height_m=h,
                           camera_azimuth_rad=0.0, camera_roll_rad=0.0,
                           aim_offset_m=(0.0, 0.0, WALL_CAMERA_AIM_HEIGHT_M - h1),
                           disc_tilt_rad=0.0, background="invalid", payload_plates=0,
                           theta2_deg=SWEEP_THETA2_DEG,
                           frames_per_pose=int(options.calibration_frames_per_pose),
                           n_vertical=6 * int(options.calibration_frames_per_pose),
                           yaw_theta1_deg=yaw, yaw_theta2_deg=YAW_THETA2_DEG, yaw_frames_per_pose=1)


def _errors(T_est, T_true):
    from ...geometry import invert_transform, rotation_angle

    pos = float(np.linalg.norm(invert_transform(T_est)[:3, 3] - invert_transform(T_true)[:3, 3]))
    rot = float(np.degrees(rotation_angle(T_est[:3, :3].T @ T_true[:3, :3])))
    aim = np.array([0.0, 0.0, WALL_CAMERA_AIM_HEIGHT_M, 1.0])          # a point at the arm, base frame
    at_arm = float(np.linalg.norm((T_est @ invert_transform(T_true) @ aim)[:3] - aim[:3]))
    return {"position_error_m": pos, "rotation_error_deg": rot, "error_at_arm_m": at_arm}


def _packaged_path(key: str) -> Path:
    from ..data_collection import PACKAGED_DIR

    return PACKAGED_DIR / f"wall_calibration_{key}.npz"


def _packaged(key: str):
    """The calibration shipped with the package for this key (the default placement), or None."""
    path = _packaged_path(key)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            return {"T_base_cam": z["T_base_cam"].tolist(), "T_base_cam_seed": z["T_base_cam_seed"].tolist(),
                    "report": json.loads(str(z["report_json"])), "code": str(z["code"]) if "code" in z else None}
    except (OSError, ValueError, KeyError):
        return None


def ship_calibration(cache_file) -> Path:
    """Copy a cached calibration (``wall_calibration_<key>.json`` in a ``cache_dir``) into the package data.

    For maintainers: the default placement's calibration is shipped, so that ``make demo`` and a fresh
    checkout read it instead of rendering and tracking the sweep (the key names the sweep, its
    seed, the sensor's range and noise, the method and the kinematics; any change gives a new key).

    Parameters
    ----------
    cache_file : str or Path
        A cache file written by :func:`calibrate_wall_camera`.

    Returns
    -------
    Path
        The written ``tudorvision/catch/data/wall_calibration_<key>.npz``.
    """
    src = Path(cache_file)
    entry = json.loads(src.read_text())
    key = src.stem.removeprefix("wall_calibration_")
    path = _packaged_path(key)
    np.savez(path, T_base_cam=np.asarray(entry["T_base_cam"], float),
             T_base_cam_seed=np.asarray(entry["T_base_cam_seed"], float),
             report_json=np.array(json.dumps(entry["report"])),        # key order as computed (summary.json)
             code=np.array(str(entry.get("code", ""))))
    return path


def shipped_calibration_codes() -> dict:
    """The code hash each shipped calibration names, by file name (None: a file shipped before it was recorded).

    Returns
    -------
    dict
        ``{"wall_calibration_<key>.npz": code or None}``; equal to :func:`calibration_code_hash` when this
        code computed it.
    """
    from ..data_collection import PACKAGED_DIR

    return {path.name: (_packaged(path.stem.removeprefix("wall_calibration_")) or {}).get("code")
            for path in sorted(PACKAGED_DIR.glob("wall_calibration_*.npz"))}


def check_shipped_calibration(options, params, T_base_cam_true, cache_dir, *, deflection=None, ship: bool = False,
                              atol: float = 1e-9) -> dict:
    """Compute the calibration of ``options``' placement afresh and compare it with the shipped one.

    For maintainers, after a change to any of :data:`CODE_FILES` (the tests then say that the shipped file
    is another code's): about 3 min on one core for the default 2400-frame sweep.

    Parameters
    ----------
    options : DemoOptions
        The placement (the default one is shipped); its ``cache_dir`` is replaced by ``cache_dir``.
    params : RobotParams
        The robot's parameters.
    T_base_cam_true : array_like, shape (4, 4)
        The throw scene's true camera pose (:func:`calibrate_wall_camera`).
    cache_dir : str or Path
        An empty folder for the fresh computation's cache file.
    deflection : callable, optional
        The agent's deflection model, for a method that names ``deflection`` (:func:`calibrate_wall_camera`).
    ship : bool
        Replace the shipped file (or add it) with the fresh computation; where the shipped transform agrees
        within ``atol``, only its code hash is replaced (the numbers every recorded run used stay, bit for bit).
    atol : float
        Largest difference of ``T_base_cam`` that counts as the same calibration.

    Returns
    -------
    dict
        ``shipped`` (bool: a file was shipped for this placement), ``max_abs_difference`` (of ``T_base_cam``
        against the shipped one; None without one), ``shipped_code``, ``code`` (this code's hash),
        ``shipped_to`` (the path written, or None).
    """
    from dataclasses import replace

    options = replace(options, cache_dir=str(cache_dir))
    key = _calibration_key(options, params)
    shipped = _packaged(key)
    before = dict(_MEMORY)
    _MEMORY.clear()
    try:
        T, _ = calibrate_wall_camera(options, params, T_base_cam_true, deflection=deflection, packaged=False)
    finally:
        _MEMORY.clear()
        _MEMORY.update(before)
    out = {"shipped": shipped is not None, "code": calibration_code_hash(),
           "shipped_code": None if shipped is None else shipped.get("code"),
           "max_abs_difference": None if shipped is None else
           float(np.max(np.abs(T - np.asarray(shipped["T_base_cam"], float)))), "shipped_to": None}
    if ship:
        fresh = Path(cache_dir) / f"wall_calibration_{key}.json"
        if shipped is not None and out["max_abs_difference"] <= atol:
            fresh.write_text(json.dumps(dict(shipped, code=out["code"])))
        out["shipped_to"] = str(ship_calibration(fresh))
    return out


def _entry_ok(entry) -> bool:
    """Whether a cached or shipped calibration entry holds two rigid 4x4 transforms and a report (a damaged or
    foreign file is computed again, not read)."""
    if not isinstance(entry, dict) or not isinstance(entry.get("report"), dict):
        return False
    for name in ("T_base_cam", "T_base_cam_seed"):
        try:
            T = np.asarray(entry.get(name), float)
        except (TypeError, ValueError):
            return False
        if T.shape != (4, 4) or not np.all(np.isfinite(T)) or not np.allclose(T[3], [0, 0, 0, 1]) \
                or not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6):
            return False
    return True


def _calibration_key(options, params) -> str:
    """16 hex digits naming a calibration: the sweep, its seed, the sensor, the method (and what it uses)."""
    from ..data_collection import robot_key

    sensor = wall_depth_sensor(options)
    method = options.calibration_method
    key_src = json.dumps({"sweep": repr(_sweep_params(options, params)), "seed": int(options.calibration_seed),
                          "v": 3, "max_depth_m": sensor.max_depth_m, "method": method,
                          "depth_noise": [list(sensor.noise.coeffs), list(sensor.noise_corr_px)],
                          **({"depth_pattern": [sensor.pattern_disparity_px, list(sensor.pattern_corr_px),
                                                bool(options.depth_pattern_correction)]}
                             if sensor.pattern_disparity_px > 0 else {}),
                          **({"kinematics": [repr(options.collection), options.plant]}
                             if "deflection" in method.split("+") else {}),
                          **({"robot": robot_key(params)} if robot_key(params) else {})}, sort_keys=True)
    return hashlib.sha1(key_src.encode()).hexdigest()[:16]


def calibrate_wall_camera(options, params, T_base_cam_true, *, deflection=None,
                          packaged: bool = True) -> tuple[np.ndarray, dict]:
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
    deflection : callable, optional
        The agent's learnt deflection model (:class:`~tudorvision.catch.kinematics.DeflectionModel`); with
        a ``options.calibration_method`` that names ``deflection`` the seed's frame is refined in the
        sweep plane against it (:func:`~tudorvision.rgbd.base_calib.refine_sweep_in_plane`). Must be the
        model of ``options.collection`` on ``options.plant`` (the cache key names those). A method that
        names ``mirror`` (the default ``"seed+mirror"``) then refines the in-plane angle from the sweep's
        mirror symmetry (:func:`~tudorvision.rgbd.base_calib.refine_sweep_mirror`).
    packaged : bool
        Read the calibration shipped with the package for this placement (default); False: computed (or read
        from ``cache_dir`` or memory) only.

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        The calibrated camera pose in the base frame (``p_base = T_base_cam @ p_cam``).
    report : dict
        ``position_error_m`` (camera centre), ``rotation_error_deg``, ``error_at_arm_m`` (a point 1 m
        above the base mapped through the calibrated against the true transform), ``circle_rmse_m``,
        ``circle_radius_m``, ``frames``, ``skipped_frames``, ``sweep_camera_offset_m`` (sweep
        camera against the throws' camera; 0 up to rounding), ``method``, ``seed_method`` (the errors of the
        seed's construction alone, before the refinement), ``in_plane_rotation_deg``, ``cached`` (bool).

    Raises
    ------
    TudorVisionError
        When the sweep's camera does not stand where the throws' does, or the disc is lost.
    """
    from ..._checks import TudorVisionError
    from ...rgbd.base_calib import base_frame_from_theta2_sweep, refine_sweep_in_plane, refine_sweep_mirror
    from ...rgbd.disc3d import Disc3DOptions
    from ...rgbd.disc_track import track_disc_sweep
    from ...rgbd.frames import Intrinsics
    from ...rgbd.yaw_sweep import measure_yaw_sweep, refine_tilt_from_yaw
    from ..disc_sweep import render_disc_sweep

    sp = _sweep_params(options, params)
    sensor = wall_depth_sensor(options)
    method = options.calibration_method
    uses_model = "deflection" in method.split("+")
    if uses_model and deflection is None:
        raise ValueError(f"calibrate_wall_camera: calibration_method {method!r} needs the deflection model")
    key = _calibration_key(options, params)
    T_true = np.asarray(T_base_cam_true, float)
    path = Path(options.cache_dir) / f"wall_calibration_{key}.json"
    cached = _MEMORY.get(key)
    code = calibration_code_hash()
    if cached is None and path.is_file():
        try:
            cached = json.loads(path.read_text())
        except (OSError, ValueError):
            cached = None
        if not _entry_ok(cached) or cached.get("code") != code:
            cached = None                   # written by other code (or damaged): computed again, then replaced
    if cached is None and packaged:
        cached = _packaged(key)
        cached = cached if _entry_ok(cached) else None
    if cached is not None:
        T = np.asarray(cached["T_base_cam"], float)
        rep = dict(cached["report"])
        _MEMORY[key] = cached
        rep.update(_errors(T, T_true))
        rep["seed_method"] = _errors(np.asarray(cached["T_base_cam_seed"], float), T_true)
        rep["cached"] = True
        return T, rep

    sweep = render_disc_sweep(sp, np.random.default_rng([int(options.calibration_seed), 15]), robot=params,
                              sensor=sensor)
    offset = float(np.max(np.abs(sweep.T_base_cam - T_true)))
    if offset > 1e-6:
        raise TudorVisionError(f"catch demo: the calibration sweep's camera is not the throws' camera "
                               f"(pose differs by {offset:.3g})")
    n, h, w = sweep.depth_m.shape
    K = Intrinsics.from_matrix(sweep.K, w, h)
    pattern = wall_depth_pattern(options, sweep.K, w, h)
    if pattern is not None:                 # the user's pattern calibration, removed before tracking
        for i in range(n):
            sweep.depth_m[i] = pattern.apply(sweep.depth_m[i])
    c0 = sweep.disc_centres_cam[0]          # the operator's click on the disc in the first frame
    seed_uv = (K.fx * c0[0] / c0[2] + K.cx, K.fy * c0[1] / c0[2] + K.cy)
    opts = Disc3DOptions(disc_radius_m=sp.disc_radius_m,
                         arm_radius_m=float(params.link2_length_m + params.link3_length_m))
    head = ~sweep.yaw                       # the theta2 sweep and the vertical posture, tracked from the click
    pts, skipped = track_disc_sweep(sweep.depth_m[head], K, seed_uv, sweep.theta_rad[head, 1], opts)
    sw = ~sweep.vertical[head]
    try:
        T, fit = base_frame_from_theta2_sweep(pts[sw], pts[~sw], theta2_rad=sweep.theta_rad[head][sw, 1])
    except (ValueError, TudorVisionError) as exc:
        raise TudorVisionError(f"catch demo: wall camera calibration failed: {exc}") from None
    rep = {"circle_rmse_m": float(fit["circle_rmse_m"]), "circle_radius_m": float(fit["circle_radius_m"]),
           "frames": int(n), "skipped_frames": len(skipped), "sweep_camera_offset_m": offset,
           "calibration_seed": int(options.calibration_seed), "method": method}
    T_seed = np.asarray(T, float)
    T = T_seed
    if uses_model:
        T, info = refine_sweep_in_plane(T, pts, sweep.theta_rad, deflection, payload_kg=0.0)
        rep.update(info)
    if "mirror" in method.split("+"):
        T, info = refine_sweep_mirror(T, pts, sweep.theta_rad[head])
        rep.update(info)
    if "yaw" in method.split("+"):
        yaw_pts, yaw_skipped = measure_yaw_sweep(sweep.depth_m[sweep.yaw], K, T, sweep.theta_rad[sweep.yaw], opts,
                                                 robot=params)
        try:
            T, info = refine_tilt_from_yaw(T, yaw_pts, pivot_cam=np.nanmean(pts[sw], axis=0),
                                           theta_rad=sweep.theta_rad[sweep.yaw], robot=params)
        except TudorVisionError as exc:
            raise TudorVisionError(f"catch demo: wall camera calibration failed: {exc}") from None
        rep.update(info, yaw_frames=int(sweep.yaw.sum()), yaw_skipped_frames=len(yaw_skipped))
    entry = {"T_base_cam": np.asarray(T, float).tolist(), "T_base_cam_seed": T_seed.tolist(), "report": rep,
             "code": code}
    _MEMORY[key] = entry
    try:
        from ...io.atomic import write_text_atomic
        write_text_atomic(path, json.dumps(entry, indent=1))
    except (OSError, TudorVisionError):
        pass                                # the cache is an optimisation only
    out = dict(rep)
    out.update(_errors(np.asarray(T, float), T_true))
    out["seed_method"] = _errors(T_seed, T_true)
    out["cached"] = False
    return np.asarray(T, float), out
