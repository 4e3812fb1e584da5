"""Randomised wall-camera calibration sweeps: the disc in a net ring on the elastic arm (issue 15).

The lab's side of the RGB-D base calibration: :func:`sample_disc_sweep`
draws a set-up from a seed, :func:`render_disc_sweep` renders its theta2
sweep (theta1 = theta3 = 0), the vertical posture and, when asked for, a
theta1 sweep at one theta2 (the "yaw" poses: the disc on a horizontal circle
about the base z axis) as depth frames with the joint angles, and keeps the ground truth (``T_base_cam``, disc centres)
apart for the scorers. Perception gets only the depth frames, the
intrinsics and the joint angles.

What varies (uniform unless said):

- camera distance 3.0–5.8 m from the joint-2 axis (the disc stays inside the
  Kinect's 6 m range), height 1.2–2.4 m, azimuth ±20° about the front, roll
  ±5°, aim offset ±0.2 m per axis;
- disc tilt against the end effector's z axis 0–40° about a random axis in
  the end effector's x–y plane (the net faces the thrower only roughly);
- background: half the set-ups out of the sensor's range (invalid depth),
  half a wall 0.25–0.4 m behind the arm plane;
- payload plates 0–2 (the static sag of the elastic arm).

The disc is 18 cm across in a flat 3 cm net ring just behind it, link 3 ends on the ring;
depth noise is :data:`tudorvision.sensors.KINECT_DEPTH_NOISE` unless given.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..robot import load_robot_params
from ..sensors import DepthNoiseModel
from ..sim.arm import Payload, fk_elastic
from ..sim.depth_sensor import DepthSensorModel, depth_mm_from_gbuffer
from ..sim.raycast import render_gbuffer
from ..sim.scenes_rgbd import disc_on_arm
from .record import T_WORLD_BASE, elastic_arm_geometry, static_arm_state

__all__ = ["DiscSweepParams", "DiscSweep", "sample_disc_sweep", "render_disc_sweep"]


@dataclass(frozen=True, kw_only=True)
class DiscSweepParams:
    """One calibration set-up (SI units, radians).

    Parameters
    ----------
    camera_distance_m, camera_height_m, camera_azimuth_rad, camera_roll_rad : float
        Wall camera pose (see :func:`tudorvision.sim.scenes_rgbd.disc_on_arm`).
    aim_offset_m : tuple of 3 floats
        Optical axis offset from the joint-2 axis point, world, metres.
    disc_tilt_rad, disc_tilt_axis_rad : float
        Disc normal = the end effector's z axis turned by ``disc_tilt_rad``
        about the axis at angle ``disc_tilt_axis_rad`` in its x–y plane.
    disc_radius_m : float
        Disc radius, metres.
    background : str
        ``"invalid"`` or ``"near"``.
    near_gap_m : float
        Near wall distance behind the arm plane, metres.
    payload_plates : int
        Payload plates in the net (static sag).
    theta2_deg : tuple of float
        Sweep poses, degrees (theta1 = theta3 = 0).
    frames_per_pose, n_vertical : int
        Depth frames per sweep pose and of the vertical posture [0, 90, 0] deg.
    yaw_theta1_deg : tuple of float
        theta1 of the yaw poses [theta1, ``yaw_theta2_deg``, 0], degrees, rendered after the vertical
        posture with ``yaw_frames_per_pose`` frames each; empty (the default): none. Many poses a frame
        each are joint 1 turned slowly through the range (the disc at a new spot on the pixel grid in
        every frame).
    yaw_theta2_deg : float
        theta2 of the yaw poses, degrees.
    yaw_frames_per_pose : int
        Depth frames per yaw pose.
    """

    camera_distance_m: float = 5.0
    camera_height_m: float = 1.6
    camera_azimuth_rad: float = 0.0
    camera_roll_rad: float = 0.0
    aim_offset_m: tuple = (0.0, 0.0, 0.0)
    disc_tilt_rad: float = 0.0
    disc_tilt_axis_rad: float = 0.0
    disc_radius_m: float = 0.09
    background: str = "invalid"
    near_gap_m: float = 0.3
    payload_plates: int = 0
    theta2_deg: tuple = tuple(np.arange(0.0, 180.1, 5.0))
    frames_per_pose: int = 2
    n_vertical: int = 10
    yaw_theta1_deg: tuple = ()
    yaw_theta2_deg: float = 45.0
    yaw_frames_per_pose: int = 1


@dataclass(frozen=True)
class DiscSweep:
    """A rendered sweep: what perception gets, and the ground truth kept apart.

    Parameters
    ----------
    depth_m : ndarray, shape (N, H, W), float32
        Depth (z) in metres, NaN = invalid.
    theta_rad : ndarray, shape (N, 3)
        Joint angles per frame, rad.
    K : ndarray, shape (3, 3)
        Intrinsics of the depth camera, pixels.
    vertical : ndarray of bool, shape (N,)
        Frames of the vertical posture (after the sweep).
    yaw : ndarray of bool, shape (N,)
        Frames of the yaw poses (after the vertical posture; none unless
        ``params.yaw_theta1_deg`` names some).
    T_base_cam : ndarray, shape (4, 4)
        Ground truth: camera pose in the base frame.
    disc_centres_cam : ndarray, shape (N, 3)
        Ground truth: disc centre per frame, metres, camera frame.
    params : DiscSweepParams
        The set-up.
    """

    depth_m: np.ndarray
    theta_rad: np.ndarray
    K: np.ndarray
    vertical: np.ndarray
    yaw: np.ndarray
    T_base_cam: np.ndarray
    disc_centres_cam: np.ndarray
    params: DiscSweepParams


def sample_disc_sweep(rng: np.random.Generator, **overrides) -> DiscSweepParams:
    """Draw a randomised set-up (ranges in the module notes).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draw.
    **overrides
        Fields of :class:`DiscSweepParams` to fix instead (drawn first
        anyway, so a seed gives the same other values).

    Returns
    -------
    DiscSweepParams

    Examples
    --------
    >>> p = sample_disc_sweep(np.random.default_rng(0), background="near")
    >>> 3.0 <= p.camera_distance_m <= 5.8, p.background
    (True, 'near')
    """
    p = DiscSweepParams(
        camera_distance_m=float(rng.uniform(3.0, 5.8)),
        camera_height_m=float(rng.uniform(1.2, 2.4)),
        camera_azimuth_rad=float(np.radians(rng.uniform(-20.0, 20.0))),
        camera_roll_rad=float(np.radians(rng.uniform(-5.0, 5.0))),
        aim_offset_m=tuple(float(x) for x in rng.uniform(-0.2, 0.2, 3)),
        disc_tilt_rad=float(np.radians(rng.uniform(0.0, 40.0))),
        disc_tilt_axis_rad=float(rng.uniform(0.0, 2 * np.pi)),
        background=str(rng.choice(["invalid", "near"])),
        near_gap_m=float(rng.uniform(0.25, 0.4)),
        payload_plates=int(rng.integers(0, 3)),
    )
    return replace(p, **overrides)


def _tilt(T_ee, tilt, axis_angle):
    a = np.array([np.cos(axis_angle), np.sin(axis_angle), 0.0])
    X = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    R = np.eye(3) + np.sin(tilt) * X + (1 - np.cos(tilt)) * X @ X
    T = T_ee.copy()
    T[:3, :3] = T_ee[:3, :3] @ R
    return T


def render_disc_sweep(params: DiscSweepParams, rng: np.random.Generator, *, width: int = 640, height: int = 480,
                      noise: DepthNoiseModel | None = None, robot=None,
                      sensor: DepthSensorModel | None = None) -> DiscSweep:
    """Render the sweep of a set-up as depth frames (each pose ray-cast once, noise drawn per frame).

    Parameters
    ----------
    params : DiscSweepParams
        The set-up.
    rng : numpy.random.Generator
        Room, lighting and depth noise.
    width, height : int
        Image size, pixels.
    noise : tudorvision.sensors.DepthNoiseModel, optional
        Depth noise; default the simulated sensor's (the seed's Kinect fit as
        :mod:`tudorvision.sensors` reads it).
    robot : RobotParams, optional
        The simulated arm (``--robot``); default the packaged ``tudor.yaml``.
    sensor : tudorvision.sim.depth_sensor.DepthSensorModel, optional
        The depth sensor (range, noise, invalid edges); default
        ``DepthSensorModel()``, the Kinect's 0.6-6 m. The catching demo's wall
        camera passes one reaching 8 m (:func:`tudorvision.lab.catch.calibration.wall_depth_sensor`).
        ``noise``, when given too, replaces its noise.

    Returns
    -------
    DiscSweep
    """
    prm = robot or load_robot_params()
    payload = Payload.from_parts(prm, plates=params.payload_plates)
    poses = [np.radians([0.0, a, 0.0]) for a in params.theta2_deg] + [np.radians([0.0, 90.0, 0.0])]
    k_vertical = len(poses) - 1
    poses += [np.radians([a, params.yaw_theta2_deg, 0.0]) for a in params.yaw_theta1_deg]
    states = [(th, *static_arm_state(th, payload, prm)) for th in poses]
    T_disc = [_tilt(fk_elastic(*s, prm), params.disc_tilt_rad, params.disc_tilt_axis_rad) for s in states]
    geoms = [elastic_arm_geometry(*s, prm) for s in states]
    k_of = lambda t: int(round(t))           # time t = pose index (static poses)
    setup = disc_on_arm(lambda t: T_disc[k_of(t)], lambda t: geoms[k_of(t)], rng, T_world_base=T_WORLD_BASE,
                        disc_radius_m=params.disc_radius_m, camera_distance_m=params.camera_distance_m,
                        camera_height_m=params.camera_height_m, camera_azimuth_rad=params.camera_azimuth_rad,
                        camera_roll_rad=params.camera_roll_rad, aim_offset_m=params.aim_offset_m,
                        background=params.background, near_gap_m=params.near_gap_m, width=width, height=height)
    cam = setup.cameras["rgbd"]
    model = sensor if sensor is not None else DepthSensorModel()
    if noise is not None:
        model = replace(model, noise=noise)
    T_cam_base = np.linalg.inv(setup.meta["T_base_cam"])
    frames, thetas, vertical, truth = [], [], [], []
    for k in range(len(poses)):
        gb = render_gbuffer(cam, setup.scene, float(k))
        n = params.n_vertical if k == k_vertical else (params.yaw_frames_per_pose if k > k_vertical
                                                       else params.frames_per_pose)
        c = T_cam_base[:3, :3] @ T_disc[k][:3, 3] + T_cam_base[:3, 3]
        for _ in range(n):
            raw = depth_mm_from_gbuffer(gb, model, rng)
            d = raw.astype(np.float32) / np.float32(model.units_per_m)
            d[raw == 0] = np.nan
            frames.append(d)
            thetas.append(poses[k])
            vertical.append(k == k_vertical)
            truth.append(c)
    yaw = np.arange(len(frames)) >= len(frames) - len(params.yaw_theta1_deg) * params.yaw_frames_per_pose
    return DiscSweep(depth_m=np.stack(frames), theta_rad=np.array(thetas), K=np.asarray(cam.K, float),
                     vertical=np.array(vertical), yaw=yaw, T_base_cam=setup.meta["T_base_cam"],
                     disc_centres_cam=np.array(truth), params=params)
