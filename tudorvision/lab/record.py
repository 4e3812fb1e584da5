"""Deterministic recordings of the virtual lab (``tudorvision sim record KIND``).

Every recording is a sequence directory (see ``docs/sequence_format.md``)
written with :class:`tudorvision.io.SequenceWriter`: images, ``joints.txt``
where the arm moves, a ``calibration.yaml`` with what a lab would have
calibrated (camera intrinsics, stereo extrinsics; never the quantity the
recording is meant to measure), and ``groundtruth/*.csv`` with the truth
that trackers never read. The same ``seed`` gives the same files.

The lab only simulates and renders: it never imports a tracker.

Kinds
-----
stereo-step          step motion [0, 45, -45] -> [0, 135, 45] deg at full speed, 50 Hz, blur
stereo-static        static poses spread over the workspace (accuracy benchmark)
stereo-sweep         theta1 sweep with theta2 = theta3 = 0, then the vertical posture
stereo-checkerboard  checkerboard pairs for stereo calibration
rgbd-plane           planar target at stepped distances (one sequence per distance)
rgbd-disc            wall camera, disc in the net, theta2 sweep, the vertical posture, a theta1 sweep
rgbd-throws          9 cm balls thrown towards the robot, wall camera 5 m away (as for rgbd-disc)
rgbd-wall            a flat wall at 2.5 / 3.5 / 4.5 m: the depth camera's fixed pattern (calib rgbd-pattern)
servo-views          eye-in-hand views of a black square on white ground
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .._checks import TudorVisionError
from .._progress import progress
from ..robot import load_robot_params
from ..robot.params import RobotParams
from ..sim.arm import Payload, fk_elastic, spheres_from_T, ElasticArm
from .depth_wall import record_rgbd_wall
from .simulation import simulate_ptp
from ..sim.camera import PinholeCamera, look_at
from ..sim.render import render_bgr, render_rgbd
from ..sim.scenes import (ArmGeometry, StereoRigConfig, checkerboard_lab, sphere_image_truth, stereo_lab,
                          KINECT_RATE_HZ, STEREO_RATE_HZ)
from ..sim.scenes_rgbd import ball_throw, eye_in_hand, kinect_camera, planar_target, wall_disc

__all__ = ["RecordOptions", "KINDS", "record", "elastic_arm_geometry", "T_WORLD_BASE",
           "calibration_from_cameras", "static_arm_state"]

#: Checkerboard square edge of the calibration recordings, metres.
SQUARE_M = 0.08

#: Robot base pose in the lab world (floor at z = 0, base on the floor).
T_WORLD_BASE = np.eye(4)
#: the wall RGB-D camera of rgbd-disc and rgbd-throws stands this far in front of the base (base -y), m
WALL_CAMERA_STANDOFF_M = 5.0


@dataclass(frozen=True, kw_only=True)
class RecordOptions:
    """Options shared by all recording kinds.

    Attributes
    ----------
    seed : int
        Seeds scene randomisation (lighting, clutter) and sensor noise.
    small : bool
        Fewer frames (the sizes committed in ``sample_data/``).
    frames : int or None
        Override the number of frames (per distance for ``rgbd-plane``,
        throws for ``rgbd-throws``, views for the others).
    exposure_s, n_subframes : float, int
        Stereo exposure and the sub-frames integrated for motion blur.
    rolling_shutter : bool
        Render the stereo cameras with a rolling shutter (line time
        ``line_time_s``); the calibration then records the line time.
    line_time_s : float
        Rolling-shutter time between successive image rows, seconds.
    payload_plates : int
        100 g plates on the end effector (stereo recordings carry the camera
        rig and spheres, 450 g, in addition).
    image_ext, jpeg_quality : str, int
        Colour image format.
    jitter_rig : bool
        Randomise the stereo rig pose a little per seed.
    show_progress : bool or None
        Draw progress bars on stderr; ``None``: only when stderr is a terminal.
    force : bool
        Write into a non-empty output folder, deleting only the files a
        recording writes (:meth:`tudorvision.io.SequenceWriter.own_outputs`);
        without it a non-empty folder is refused.
    params : RobotParams or None
        The simulated robot (``--robot``); None: the packaged ``tudor.yaml``.
    """

    seed: int = 0
    small: bool = False
    frames: int | None = None
    exposure_s: float = 0.006
    n_subframes: int = 6
    rolling_shutter: bool = False
    line_time_s: float = 30e-6
    payload_plates: int = 0
    image_ext: str = ".jpg"
    jpeg_quality: int = 92
    jitter_rig: bool = False
    show_progress: bool | None = None
    force: bool = False
    params: RobotParams | None = None


# --------------------------------------------------------------------------- helpers

def elastic_arm_geometry(theta, tip2, tip3, params: RobotParams) -> ArmGeometry:
    """What the cameras see of the deflected arm: link polylines and sphere centres.

    Parameters
    ----------
    theta : array_like, shape (3,)
        Joint angles, radians.
    tip2, tip3 : array_like, shape (2,)
        Tip deflection (m) and slope (rad) of links 2 and 3 (plant convention).

    Returns
    -------
    ArmGeometry
        In the robot base frame.
    """
    th = np.asarray(theta, dtype=np.float64)
    w2 = np.asarray(tip2, dtype=np.float64)
    T_ee = fk_elastic(th, w2, tip3, params)
    a = th[1]
    c1, s1 = np.cos(th[0]), np.sin(th[0])
    h1, l2 = params.link1_height_m, params.link2_length_m
    joint2 = np.array([0.0, 0.0, h1])
    # link 2 drawn through three points of the deflected blade (tip-load cantilever shape)
    pts2 = []
    for s in (0.0, 0.5, 1.0):
        w = w2[0] * s * s * (3.0 - s) / 2.0
        r = s * l2 * np.cos(a) - w * np.sin(a)
        z = h1 + s * l2 * np.sin(a) + w * np.cos(a)
        pts2.append([r * c1, r * s1, z])
    pts2 = np.array(pts2)
    pts2[0] = joint2
    link3 = np.stack([pts2[-1], T_ee[:3, 3]])
    spheres = spheres_from_T(T_ee, params)
    return ArmGeometry(link_points_base=(pts2, link3), sphere_centers_base=spheres)


class _LogInterp:
    """Linear interpolation of a plant log at arbitrary times (for blur sub-frames)."""

    def __init__(self, t, theta, tip2, tip3, params):
        self.t, self.theta, self.tip2, self.tip3, self.params = t, theta, tip2, tip3, params

    def state(self, t: float):
        f = lambda a: np.array([np.interp(t, self.t, a[:, j]) for j in range(a.shape[1])])
        return f(self.theta), f(self.tip2), f(self.tip3)

    def geometry(self, t: float) -> ArmGeometry:
        return elastic_arm_geometry(*self.state(t), self.params)

    def T_base_ee(self, t: float) -> np.ndarray:
        th, w2, w3 = self.state(t)
        return fk_elastic(th, w2, w3, self.params)


def static_arm_state(theta, payload: Payload, params: RobotParams):
    """Settled (static equilibrium) tip deflections of the elastic arm at ``theta``."""
    arm = ElasticArm(np.asarray(theta, float), payload=payload, params=params)
    return np.asarray(arm.tip2, float), np.asarray(arm.tip3, float)


def _to_base(T_world_base, p_world):
    T = np.linalg.inv(T_world_base)
    return p_world @ T[:3, :3].T + T[:3, 3]


def calibration_from_cameras(cameras: dict, *, stereo: tuple | None = None, line_time_s: float | None = None,
                             depth_model=None, note: str = ""):
    """The lab's calibration of the simulated cameras (what a checkerboard calibration would give).

    Parameters
    ----------
    cameras : dict of str to PinholeCamera
    stereo : (str, str), optional
        Names of the left and right camera of a stereo pair.
    """
    from ..io import Calibration, CameraModel, StereoExtrinsics
    models = {name: CameraModel(K=cam.K, dist=cam.dist, width=cam.width, height=cam.height,
                                line_time_s=line_time_s) for name, cam in cameras.items()}
    ext = None
    if stereo is not None:
        left, right = (cameras[n] for n in stereo)
        T_right_left = np.linalg.inv(right.T_world_cam) @ left.T_world_cam
        ext = StereoExtrinsics(R=T_right_left[:3, :3], T=T_right_left[:3, 3], left=stereo[0], right=stereo[1])
    return Calibration(cameras=models, stereo=ext, depth_model=depth_model,
                       metadata={"source": "tudorvision virtual lab (nominal camera models)", "note": note})


def _writer(out: Path, kind: str, rate_hz: float, opts: RecordOptions, *, calibration=None, description=""):
    from ..io import SequenceWriter
    return SequenceWriter(out, kind=kind, rate_hz=rate_hz, depth_scale=1000.0, calibration=calibration,
                          image_ext=opts.image_ext, jpeg_quality=opts.jpeg_quality, description=description,
                          meta={"generator": "tudorvision sim record", "seed": int(opts.seed)},
                          overwrite=opts.force)


def _rig_cameras(setup):
    return setup.cameras["left"], setup.cameras["right"]


def _stereo_truth_rows(cams, T_world_base, T_ee_fn, params, times, exposure_s, n_sub, line_time_s=0.0):
    """Ground-truth rows: EE and sphere centres (base frame, mid-exposure) and image centroids.

    Image positions are the first moments of the exact (blurred, rolling-shutter
    timed) silhouettes, :func:`tudorvision.sim.scenes.sphere_image_truth`.
    """
    rows = []
    r = params.sphere_radius_m
    R, o = T_world_base[:3, :3], T_world_base[:3, 3]

    def centre_world(name):
        return lambda ts: R @ spheres_from_T(T_ee_fn(ts), params)[name] + o

    for t in times:
        T_mid = T_ee_fn(t + exposure_s / 2)
        sph_mid = spheres_from_T(T_mid, params)
        row = [t, *T_mid[:3, 3], *sph_mid["red"], *sph_mid["green"]]
        for cam in cams:
            for name in ("red", "green"):
                try:
                    uv = sphere_image_truth(cam, centre_world(name), r, float(t), exposure_s=exposure_s,
                                            n_subframes=n_sub, line_time_s=line_time_s)
                except ValueError:
                    uv = [np.nan, np.nan]
                row += list(uv)
        rows.append(row)
    names = ["t", "ee_x_m", "ee_y_m", "ee_z_m", "red_x_m", "red_y_m", "red_z_m", "green_x_m", "green_y_m",
             "green_z_m"]
    for cam in ("left", "right"):
        for name in ("red", "green"):
            names += [f"{cam}_{name}_u_px", f"{cam}_{name}_v_px"]
    return names, np.array(rows)


def _stereo_truth_transforms(w, left: PinholeCamera, right: PinholeCamera, T_world_base):
    T_base_left = np.linalg.inv(T_world_base) @ left.T_world_cam
    T_base_right = np.linalg.inv(T_world_base) @ right.T_world_cam
    names = ["T_base_left", "T_base_right", "T_world_base"]
    mats = [T_base_left, T_base_right, T_world_base]
    table = {f"m{i}{j}": np.array([m[i, j] for m in mats]) for i in range(4) for j in range(4)}
    table = {"index": np.arange(len(mats)), **table}
    w.write_groundtruth("transforms", table, comment="rows: " + ", ".join(
        f"{k}={n}" for k, n in enumerate(names)) + "; 4x4 row-major, metres")


def _render_stereo_pair(setup, t, rng, opts):
    left, right = _rig_cameras(setup)
    kw = dict(exposure_s=opts.exposure_s, n_subframes=opts.n_subframes,
              line_time_s=opts.line_time_s if opts.rolling_shutter else 0.0)
    return (render_bgr(left, setup.scene, t, rng=rng, **kw), render_bgr(right, setup.scene, t, rng=rng, **kw))


def _stereo_payload(params, opts):
    return Payload.from_parts(params, plates=opts.payload_plates, camera=True)


# --------------------------------------------------------------------------- stereo kinds

def _record_stereo_motion(out: Path, opts: RecordOptions, *, start_deg, goal_deg, duration_s, description,
                          max_speed: bool):
    p = opts.params or load_robot_params()
    rng = np.random.default_rng(opts.seed)
    payload = _stereo_payload(p, opts)
    kw = dict(v_max=p.max_speed_rad_s, a_max=p.max_accel_rad_s2) if max_speed else {}
    log = simulate_ptp(np.deg2rad(start_deg), np.deg2rad(goal_deg), duration_s, payload=payload, t_move=0.2, params=p, **kw)
    interp = _LogInterp(log.t, log.theta, log.tip2, log.tip3, p)
    setup = stereo_lab(rng, arm=interp.geometry, T_world_base=T_WORLD_BASE, jitter_rig=opts.jitter_rig)
    left, right = _rig_cameras(setup)
    cal = calibration_from_cameras({"left": left, "right": right}, stereo=("left", "right"),
                                   line_time_s=opts.line_time_s if opts.rolling_shutter else None)
    n = opts.frames or int(duration_s * STEREO_RATE_HZ)
    times = np.arange(n) / STEREO_RATE_HZ
    with _writer(out, "stereo", STEREO_RATE_HZ, opts, calibration=cal, description=description) as w:
        for t in progress(times, desc="stereo frames", enabled=opts.show_progress):
            w.add_stereo(float(t), *_render_stereo_pair(setup, float(t), rng, opts))
        for k in range(0, len(log.t), 10):       # joint log at 200 Hz
            w.add_joints(float(log.t[k]), log.theta[k])
        names, rows = _stereo_truth_rows((left, right), T_WORLD_BASE, interp.T_base_ee, p, times,
                                         opts.exposure_s, opts.n_subframes,
                                         opts.line_time_s if opts.rolling_shutter else 0.0)
        w.write_groundtruth("ee", (names, rows), comment="positions in the robot base frame, metres, averaged "
                            "over the exposure; pixel centroids are exposure-averaged exact silhouette centroids")
        _stereo_truth_transforms(w, left, right, T_WORLD_BASE)
    return out


def record_stereo_step(out, opts: RecordOptions):
    """Step motion [0, 45, -45] -> [0, 135, 45] deg at the joints' maximum speed."""
    dur = 1.6 if opts.small else 3.0
    return _record_stereo_motion(Path(out), opts, start_deg=[0, 45, -45], goal_deg=[0, 135, 45], duration_s=dur,
                                 description="stereo step motion [0,45,-45] -> [0,135,45] deg, max speed",
                                 max_speed=True)


def _record_stereo_poses(out: Path, opts: RecordOptions, thetas, *, description, frames_per_pose=1,
                         truth_name="ee"):
    p = opts.params or load_robot_params()
    rng = np.random.default_rng(opts.seed)
    payload = _stereo_payload(p, opts)
    states = [(th, *static_arm_state(th, payload, p)) for th in thetas]
    times = np.arange(len(states) * frames_per_pose) / STEREO_RATE_HZ
    idx = lambda t: min(int(round(t * STEREO_RATE_HZ)) // frames_per_pose, len(states) - 1)
    geom = lambda t: elastic_arm_geometry(*states[idx(t)], p)
    T_fn = lambda t: fk_elastic(*states[idx(t)], p)
    setup = stereo_lab(rng, arm=geom, T_world_base=T_WORLD_BASE, jitter_rig=opts.jitter_rig)
    left, right = _rig_cameras(setup)
    cal = calibration_from_cameras({"left": left, "right": right}, stereo=("left", "right"))
    static_opts = RecordOptions(**{**opts.__dict__, "exposure_s": 0.0, "n_subframes": 1})
    with _writer(out, "stereo", STEREO_RATE_HZ, opts, calibration=cal, description=description) as w:
        for k, t in enumerate(progress(times, desc="stereo frames", enabled=opts.show_progress)):
            w.add_stereo(float(t), *_render_stereo_pair(setup, float(t), rng, static_opts))
            w.add_joints(float(t), states[idx(float(t))][0])
        names, rows = _stereo_truth_rows((left, right), T_WORLD_BASE, T_fn, p, times, 0.0, 1)
        w.write_groundtruth(truth_name, (names, rows), comment="static poses; robot base frame, metres; "
                            "exact silhouette centroids in pixels")
        _stereo_truth_transforms(w, left, right, T_WORLD_BASE)
    return out


def record_stereo_static(out, opts: RecordOptions):
    """Static poses spread over the workspace seen by the stereo rig."""
    p = opts.params or load_robot_params()
    rng = np.random.default_rng(opts.seed + 1000)
    n = opts.frames or (12 if opts.small else 40)
    thetas = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(0.3, 2.4, n), rng.uniform(-1.2, 1.2, n)])
    return _record_stereo_poses(Path(out), opts, thetas, description="stereo static poses")


def record_stereo_sweep(out, opts: RecordOptions):
    """theta1 sweep with theta2 = theta3 = 0 (settled poses), then the vertical posture [0, 90, 0] deg."""
    n = opts.frames or (19 if opts.small else 37)
    t1 = np.deg2rad(np.linspace(-90.0, 90.0, n))
    thetas = [np.array([a, 0.0, 0.0]) for a in t1] + [np.deg2rad([0.0, 90.0, 0.0])]
    return _record_stereo_poses(Path(out), opts, thetas, frames_per_pose=2,
                                description="base calibration: theta1 sweep at theta2 = theta3 = 0, "
                                            "last pose the vertical posture [0, 90, 0] deg")


def record_stereo_checkerboard(out, opts: RecordOptions):
    """Checkerboard pairs (9x7 squares, 8x6 inner corners, 60 mm) at random poses in view of both cameras."""
    out = Path(out)
    rng = np.random.default_rng(opts.seed)
    n = opts.frames or (10 if opts.small else 20)
    cfg = StereoRigConfig()
    poses = []
    for _ in range(n):
        c = np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.5, 0.3), rng.uniform(0.5, 1.3)])
        # board normal points roughly at the rig (towards -y, up)
        normal = np.array([rng.uniform(-0.35, 0.35), -1.0, rng.uniform(0.6, 1.2)])
        z = -normal / np.linalg.norm(normal)
        x = np.cross([0.0, 0.0, 1.0], z)
        x /= np.linalg.norm(x)
        ang = rng.uniform(-0.3, 0.3)
        y = np.cross(z, x)
        x, y = np.cos(ang) * x + np.sin(ang) * y, -np.sin(ang) * x + np.cos(ang) * y
        T = np.eye(4)
        T[:3, :3] = np.column_stack([x, y, z])
        T[:3, 3] = c
        poses.append(T)
    first = checkerboard_lab(poses[0], rng, rig=cfg, square_m=SQUARE_M)
    left, right = _rig_cameras(first)
    cal = calibration_from_cameras({"left": left, "right": right}, stereo=("left", "right"),
                                   note="nominal models; re-derive with 'tudorvision calib stereo'")
    rows = []
    with _writer(out, "stereo", 1.0, RecordOptions(**{**opts.__dict__, "jpeg_quality": 95}), calibration=cal,
                 description=f"checkerboard pairs: 9x7 squares (8x6 inner corners), {SQUARE_M * 1000:.0f} mm squares") as w:
        for k, T in enumerate(progress(poses, desc="checkerboard pairs", enabled=opts.show_progress)):
            setup = checkerboard_lab(T, np.random.default_rng([opts.seed, k]), rig=cfg, square_m=SQUARE_M)
            l, r = _rig_cameras(setup)
            w.add_stereo(float(k), render_bgr(l, setup.scene, 0.0, rng=rng), render_bgr(r, setup.scene, 0.0, rng=rng))
            rows.append([k, *T[:3, :4].ravel()])
        names = ["index"] + [f"T_world_board_{i}{j}" for i in range(3) for j in range(4)]
        w.write_groundtruth("board_poses", (names, np.array(rows, float)), comment="board pose per pair")
        _stereo_truth_transforms(w, left, right, T_WORLD_BASE)
    return out


# --------------------------------------------------------------------------- RGB-D kinds

def _kinect_calibration(cam, note=""):
    from ..io import DepthModel
    from ..sensors import KINECT_RANGE_M, KINECT_SIGMA_UNIT, KINECT_SIGMA_Z_COEFFS
    dm = DepthModel(sigma_z_poly=list(KINECT_SIGMA_Z_COEFFS), z_unit="m", sigma_unit=KINECT_SIGMA_UNIT,
                    valid_range_m=KINECT_RANGE_M)
    return calibration_from_cameras({"rgbd": cam}, depth_model=dm, note=note)


def record_rgbd_plane(out, opts: RecordOptions):
    """Planar target at stepped distances; one sequence per distance under ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    distances = [0.6, 2.0, 4.0, 6.0] if opts.small else [0.6, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0,
                                                                5.5, 6.0]
    n = opts.frames or (5 if opts.small else 100)
    for i, d in enumerate(distances):
        rng = np.random.default_rng([opts.seed, i])
        setup = planar_target(d, rng)
        cam = setup.cameras["rgbd"]
        sub = out / f"plane_{d:.2f}m"
        with _writer(sub, "rgbd", KINECT_RATE_HZ, opts, calibration=_kinect_calibration(cam),
                     description=f"planar target perpendicular to the optical axis at {d:.2f} m") as w:
            for k in progress(range(n), desc=f"plane {d:.2f} m", enabled=opts.show_progress):
                bgr, depth, _ = render_rgbd(cam, setup.scene, k / KINECT_RATE_HZ, rng=rng)
                w.add_rgbd(k / KINECT_RATE_HZ, bgr, depth)
            corners = setup.meta["target_corners_world"]
            cam_corners = (corners - cam.T_world_cam[:3, 3]) @ cam.T_world_cam[:3, :3]
            w.write_groundtruth("target", {"distance_m": np.full(4, d), "corner_x_cam_m": cam_corners[:, 0],
                                           "corner_y_cam_m": cam_corners[:, 1], "corner_z_cam_m": cam_corners[:, 2]},
                                comment="target corners in the camera optical frame")
    return out


def _wall_camera_truth(w, cam, T_world_base):
    T_base_cam = np.linalg.inv(T_world_base) @ cam.T_world_cam
    w.write_groundtruth("T_base_cam", {f"m{i}{j}": np.array([T_base_cam[i, j]]) for i in range(4) for j in range(4)},
                        comment="true camera pose: p_base = T_base_cam @ p_cam, row-major")


def record_rgbd_disc(out, opts: RecordOptions):
    """Wall camera calibration sweep: theta2 from -10 to 190 deg (theta1 = theta3 = 0), disc in the net, the
    vertical posture, then joint 1 turned through -45..45 deg at theta2 = 45 deg (one frame a pose: the theta1
    sweep of ``calib rgbd-base --yaw``)."""
    out = Path(out)
    p = opts.params or load_robot_params()
    rng = np.random.default_rng(opts.seed)
    payload = Payload.from_parts(p, plates=opts.payload_plates)
    n = opts.frames or (11 if opts.small else 41)
    t2 = np.deg2rad(np.linspace(-10.0, 190.0, n))
    thetas = [np.array([0.0, a, 0.0]) for a in t2] + [np.deg2rad([0.0, 90.0, 0.0])]
    n_yaw = 8 if opts.small else 26       # theta1 sweep poses, a frame each
    thetas += [np.array([a, np.deg2rad(45.0), 0.0]) for a in np.deg2rad(np.linspace(-45.0, 45.0, n_yaw))]
    states = [(th, *static_arm_state(th, payload, p)) for th in thetas]
    per = 1 if opts.small else 6          # frames per sweep pose
    n_vertical = 4 if opts.small else 20  # frames of the vertical posture
    frame_pose = np.concatenate([np.repeat(np.arange(len(t2)), per), np.full(n_vertical, len(t2)),
                                 np.arange(len(t2) + 1, len(states))])
    idx = lambda t: int(frame_pose[min(int(round(t * KINECT_RATE_HZ)), len(frame_pose) - 1)])
    disc = lambda t: fk_elastic(*states[idx(t)], p)[:3, 3]
    geom = lambda t: elastic_arm_geometry(*states[idx(t)], p)
    setup = wall_disc(disc, rng, T_world_base=T_WORLD_BASE, arm=geom, camera_standoff_m=WALL_CAMERA_STANDOFF_M)
    cam = setup.cameras["rgbd"]
    times = np.arange(len(frame_pose)) / KINECT_RATE_HZ
    rows = []
    with _writer(out, "rgbd", KINECT_RATE_HZ, opts, calibration=_kinect_calibration(cam),
                 description="wall RGB-D camera, disc in the net, theta2 sweep at theta1 = theta3 = 0, then "
                             "the vertical posture [0, 90, 0] deg, then theta1 -45..45 deg at theta2 = 45 deg") as w:
        for t in progress(times, desc="disc sweep", enabled=opts.show_progress):
            bgr, depth, _ = render_rgbd(cam, setup.scene, float(t), rng=rng)
            w.add_rgbd(float(t), bgr, depth)
            th = states[idx(float(t))][0]
            w.add_joints(float(t), th)
            c_world = setup.meta["disc_center_world"](float(t))
            c_cam = (c_world - cam.T_world_cam[:3, 3]) @ cam.T_world_cam[:3, :3]
            rows.append([t, *disc(float(t)), *c_cam])
        w.write_groundtruth("disc", (["t", "ee_x_m", "ee_y_m", "ee_z_m", "disc_x_cam_m", "disc_y_cam_m",
                                      "disc_z_cam_m"], np.array(rows)),
                            comment="disc centre = deflected end effector; base frame and camera frame, metres")
        _wall_camera_truth(w, cam, T_WORLD_BASE)
    return out


def throw_trajectory(p0, v0, *, drag_k_per_m: float = 0.012, gravity_m_s2: float = 9.81, dt: float = 1e-3,
                     duration_s: float = 2.0):
    """Ball flight with gravity and quadratic drag, ``a = g - k |v| v`` (RK4 on a fine grid).

    Returns
    -------
    t, p, v : ndarray, shapes (N,), (N, 3), (N, 3)
    """
    g = np.array([0.0, 0.0, -gravity_m_s2])
    f = lambda v: g - drag_k_per_m * np.linalg.norm(v) * v
    n = int(duration_s / dt) + 1
    p = np.zeros((n, 3))
    v = np.zeros((n, 3))
    p[0], v[0] = p0, v0
    for i in range(n - 1):
        k1v = f(v[i]); k1p = v[i]
        k2v = f(v[i] + dt / 2 * k1v); k2p = v[i] + dt / 2 * k1v
        k3v = f(v[i] + dt / 2 * k2v); k3p = v[i] + dt / 2 * k2v
        k4v = f(v[i] + dt * k3v); k4p = v[i] + dt * k3v
        v[i + 1] = v[i] + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        p[i + 1] = p[i] + dt / 6 * (k1p + 2 * k2p + 2 * k3p + k4p)
    return np.arange(n) * dt, p, v


def random_throw(rng: np.random.Generator, *, T_world_base=T_WORLD_BASE, thrower_y_m: float = -6.0,
                 target_height_m: float = (0.9, 1.6)):
    """A throw from about 6 m in front of the robot towards its working plane (world frame).

    Returns ``(p0, v0)``: release point and velocity, with a flight time of 0.8-1.1 s.
    """
    base = T_world_base[:3, 3]
    p0 = np.array([base[0] + rng.uniform(-0.4, 0.4), base[1] + thrower_y_m + rng.uniform(-0.3, 0.3),
                   rng.uniform(1.4, 1.9)])
    target = np.array([base[0] + rng.uniform(-0.45, 0.45), base[1] + rng.uniform(-0.1, 0.1),
                       rng.uniform(*target_height_m)])
    T = rng.uniform(0.8, 1.1)
    v0 = (target - p0) / T - 0.5 * np.array([0.0, 0.0, -9.81]) * T
    v0 *= 1.0 + 0.012 * np.linalg.norm(v0) * T / 2   # rough drag compensation
    return p0, v0


def record_rgbd_throws(out, opts: RecordOptions):
    """Balls thrown from about 6 m; wall RGB-D camera 5 m in front of the robot, where rgbd-disc has it (30 Hz, depth noise)."""
    out = Path(out)
    rng = np.random.default_rng(opts.seed)
    n_throws = opts.frames or (1 if opts.small else 5)
    p = opts.params or load_robot_params()
    geom0 = elastic_arm_geometry(np.deg2rad([0.0, 90.0, 0.0]), *static_arm_state(np.deg2rad([0.0, 90.0, 0.0]),
                                 Payload.from_parts(p), p), p)
    gap_s, bg_s = (0.1, 0.25) if opts.small else (0.5, 0.5)
    flights = []
    t_cursor = bg_s
    for _ in range(n_throws):
        p0, v0 = random_throw(rng)
        tt, pp, vv = throw_trajectory(p0, v0)
        # flight ends when the ball passes the robot plane (world y = base y + 0.3) or hits the floor
        end = np.argmax((pp[:, 1] > T_WORLD_BASE[1, 3] + 0.3) | (pp[:, 2] < 0.05))
        end = end if end > 0 else len(tt) - 1
        flights.append((t_cursor, tt[:end + 1], pp[:end + 1], vv[:end + 1]))
        t_cursor += tt[end] + gap_s
    parked = np.array([5.0, 5.0, -5.0])   # below the floor: out of sight

    def ball(t):
        for t0, tt, pp, _ in flights:
            if t0 <= t <= t0 + tt[-1]:
                return np.array([np.interp(t - t0, tt, pp[:, j]) for j in range(3)])
        return parked

    setup = ball_throw(ball, rng, T_world_base=T_WORLD_BASE, arm=geom0,
                       camera_position_world=(0.0, -WALL_CAMERA_STANDOFF_M, 2.0))
    cam = setup.cameras["rgbd"]
    n_frames = int(np.ceil(t_cursor * KINECT_RATE_HZ))
    rows = []
    with _writer(out, "rgbd", KINECT_RATE_HZ, opts, calibration=_kinect_calibration(cam),
                 description=f"{n_throws} ball throw(s) from about 6 m, wall camera 5 m from the robot") as w:
        for k in progress(range(n_frames), desc="throw frames", enabled=opts.show_progress):
            t = k / KINECT_RATE_HZ
            bgr, depth, _ = render_rgbd(cam, setup.scene, t, rng=rng)
            w.add_rgbd(t, bgr, depth)
            c = ball(t)
            visible = bool(c[2] > -1.0)
            throw_id = next((i for i, (t0, tt, _, _) in enumerate(flights) if t0 <= t <= t0 + tt[-1]), -1)
            c_cam = (c - cam.T_world_cam[:3, 3]) @ cam.T_world_cam[:3, :3] if visible else np.full(3, np.nan)
            c_base = _to_base(T_WORLD_BASE, c) if visible else np.full(3, np.nan)
            rows.append([k, t, throw_id, *c_cam, *c_base])
        w.write_groundtruth("ball", (["frame", "t", "throw", "x_cam_m", "y_cam_m", "z_cam_m", "x_base_m", "y_base_m",
                                      "z_base_m"], np.array(rows, float)),
                            comment="ball centre (radius 0.045 m); NaN when no ball is in flight")
        launch = np.array([[i, t0, *pp[0], *vv[0]] for i, (t0, tt, pp, vv) in enumerate(flights)])
        w.write_groundtruth("throws", (["throw", "t_release", "p0_x_world_m", "p0_y_world_m", "p0_z_world_m",
                                        "v0_x_world_m_s", "v0_y_world_m_s", "v0_z_world_m_s"], launch),
                            comment="release state; drag a = g - k|v|v with k = 0.012 1/m")
        _wall_camera_truth(w, cam, T_WORLD_BASE)
    return out


def record_servo_views(out, opts: RecordOptions):
    """Eye-in-hand RGB-D views of a black square from the goal pose and start poses around it."""
    out = Path(out)
    rng = np.random.default_rng(opts.seed)
    n = opts.frames or (9 if opts.small else 17)
    square = np.array([0.6, 0.0, 0.0])
    goal_eye = square + [0.0, 0.0, 0.8]   # Kinect-type depth needs >= 0.6 m
    setup = eye_in_hand(look_at(goal_eye, square, K=np.eye(3), up_world=(1.0, 0.0, 0.0)).T_world_cam, rng,
                        square_center_world=square)
    base_cam = setup.cameras["rgbd"]
    from ..sim.camera import with_pose
    rows = []
    with _writer(out, "rgbd", KINECT_RATE_HZ, opts, calibration=_kinect_calibration(base_cam),
                 description="eye-in-hand views of a black square; frame 0 is the goal view") as w:
        for k in progress(range(n), desc="servo views", enabled=opts.show_progress):
            if k == 0:
                eye = goal_eye
            else:
                ang = 2 * np.pi * (k - 1) / max(n - 1, 1)
                rad = 0.06 if k % 2 else 0.12
                eye = goal_eye + [rad * np.cos(ang), rad * np.sin(ang), rng.uniform(-0.08, 0.12)]
            cam = with_pose(base_cam, look_at(eye, eye - [0, 0, 1.0], K=np.eye(3), up_world=(1.0, 0.0, 0.0)).T_world_cam)
            bgr, depth, _ = render_rgbd(cam, setup.scene, k / KINECT_RATE_HZ, rng=rng)
            w.add_rgbd(k / KINECT_RATE_HZ, bgr, depth)
            rows.append([k, *cam.T_world_cam[:3, :4].ravel()])
        corners = setup.meta["square_corners_world"]
        w.write_groundtruth("camera_poses", (["frame"] + [f"T_world_cam_{i}{j}" for i in range(3) for j in range(4)],
                                             np.array(rows, float)), comment="camera pose per frame")
        w.write_groundtruth("square", {"x_world_m": corners[:, 0], "y_world_m": corners[:, 1],
                                       "z_world_m": corners[:, 2]}, comment="square corners, world frame")
    return out


KINDS: dict[str, Callable] = {
    "stereo-step": record_stereo_step,
    "stereo-static": record_stereo_static,
    "stereo-sweep": record_stereo_sweep,
    "stereo-checkerboard": record_stereo_checkerboard,
    "rgbd-plane": record_rgbd_plane,
    "rgbd-disc": record_rgbd_disc,
    "rgbd-throws": record_rgbd_throws,
    "rgbd-wall": lambda o, p: record_rgbd_wall(o, p, calibration=_kinect_calibration(kinect_camera(np.eye(4)))),
    "servo-views": record_servo_views,
}



def record(kind: str, out, opts: RecordOptions = RecordOptions()) -> Path:
    """Write one recording of ``kind`` to directory ``out``.

    Parameters
    ----------
    kind : str
        Recording kind, a key of :data:`KINDS` (``"stereo-step"``,
        ``"stereo-static"``, ``"stereo-sweep"``, ``"stereo-checkerboard"``,
        ``"rgbd-plane"``, ``"rgbd-disc"``, ``"rgbd-throws"``, ``"servo-views"``).
    out : str or path-like
        Output directory (created; must be empty unless ``opts.force``).
    opts : RecordOptions, optional
        Seed, sizes, exposure and image format options.

    Returns
    -------
    pathlib.Path
        The directory written (for ``rgbd-plane``, a folder of one sequence per
        distance).

    Raises
    ------
    TudorVisionError
        For an unknown kind, or a non-empty ``out`` without ``opts.force``.
        An interrupted recording (Ctrl-C, a full disk) keeps its frames and
        is marked incomplete (see :mod:`tudorvision.io.writer`).
    """
    if kind not in KINDS:
        raise TudorVisionError(f"KIND: unknown recording kind {kind!r}; choose from {', '.join(KINDS)}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise TudorVisionError(f"{out}: exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not opts.force:
        raise TudorVisionError(f"{out}: folder is not empty; pass --force to replace a previous recording "
                               "there (only the files a recording writes are deleted)")
    return Path(KINDS[kind](out, opts))
