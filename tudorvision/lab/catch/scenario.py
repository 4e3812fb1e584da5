"""The catching demo's world: thrower, throws and their ground truth, plant, wall camera, operator.

Everything the catching agent must not see lives here (and in the scorer,
:mod:`.score`): the true flight of each throw, the simulated elastic arm
(its deflected net position, its true payload), the rendered scene and the
detection-noise model. The agent (:mod:`.agent`) receives only what the wall
camera delivers (:class:`CameraFrame`) and talks to the arm only through the
joint layer (:class:`~tudorvision.lab.lockstep.LockstepLayer`).

The ball is a sphere (``DemoOptions.ball_radius_m``, 4.5 cm): rendered as one,
it touches the floor when its centre is a radius high, and the scorer checks
it against the net's rim (:func:`~tudorvision.lab.catch.score.ring_passage`).

Frames: the lab places the robot base at the world origin
(:data:`~tudorvision.lab.record.T_WORLD_BASE`); flights are generated in the
base frame (x right, y from the thrower towards the robot, z up) and placed
in the world through ``T_WORLD_BASE`` for rendering.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sim.arm import Payload
from ...sim.net_balls import SwingingBalls
from ..lockstep import LockstepLayer
from ..simulation import SimCore

__all__ = ["CameraFrame", "CatchScenario", "Throw", "simulated_detection", "true_crossing", "FRAME_RATE_HZ"]

FRAME_RATE_HZ = 30.0            # the wall RGB-D camera
_PARKED_WORLD = np.array([5.0, 5.0, -5.0])     # the ball between throws: off stage, below the floor


def simulated_detection(p_cam, intrinsics, rng, *, options=None, scale: float = 1.0, area_ratio: float = 0.8):
    """The RGB-D detector's output without rendering: noisy centre and its covariance.

    The covariance is the detector's (``sigma_z(z)^2 / n_pixels`` along the
    viewing ray, ``(z / f)^2`` pixel^2 across, ``n_pixels = area_ratio pi (f R / z)^2``);
    the noise is drawn from ``scale^2`` times it.

    Parameters
    ----------
    p_cam : array_like, shape (3,)
        True ball centre, metres, camera optical frame (x right, y down, z forward).
    intrinsics : Intrinsics
        The camera's pinhole intrinsics and image size (pixels).
    rng : numpy.random.Generator
        Source of the detection noise.
    options : BallDetectorOptions, optional
        The detector's options (range, ball radius, depth-noise model, pixel noise).
    scale : float
        Factor on the noise's standard deviations (the covariance returned is not scaled).
    area_ratio : float
        Fraction of the ball's projected disc the detector's silhouette covers.

    Returns
    -------
    tuple of ndarray or None
        ``(p_cam, cov_cam)``: noisy centre (3,) in metres and its covariance
        (3, 3) in m^2, camera frame; ``None`` when the ball is out of the
        detection range or its silhouette is not wholly inside the image
        (``options.border_margin_px``, as the detector).

    Examples
    --------
    >>> from tudorvision.rgbd.frames import Intrinsics
    >>> K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    >>> p, C = simulated_detection([0.0, 0.0, 2.0], K, np.random.default_rng(0))
    >>> p.shape, C.shape
    ((3,), (3, 3))
    >>> simulated_detection([0.0, 0.0, 6.0], K, np.random.default_rng(0)) is None
    True
    """
    from ...rgbd.ball import BallDetectorOptions, cut_by_border, detection_covariance

    o = options or BallDetectorOptions()
    p = np.asarray(p_cam, float)
    z = p[2]
    if not (o.min_range_m < np.linalg.norm(p) <= o.max_range_m) or z <= 0:
        return None
    K = intrinsics
    u, v = K.fx * p[0] / z + K.cx, K.fy * p[1] / z + K.cy
    r_px = float(np.sqrt(K.fx * K.fy)) * o.ball_radius_m / z
    if cut_by_border(u, v, r_px, K, o):
        return None            # the detector drops a ball cut by the image border
    C = detection_covariance(p, area_ratio * np.pi * r_px ** 2, K, o)
    return rng.multivariate_normal(p, scale ** 2 * C), C


def true_crossing(times_s, points_base, *, ball_radius_m: float = 0.0, normal=(0.0, 1.0, 0.0)):
    """Where and when a sampled flight first crosses the working plane ``normal . p = 0`` (linear interpolation).

    Parameters
    ----------
    times_s : ndarray, shape (N,)
        Sample times, s.
    points_base : ndarray, shape (N, 3)
        Ball centres, metres, base frame (y towards the robot, z up).
    ball_radius_m : float, optional
        Ball radius, m: the ball (a sphere) touches the floor when its centre is this high.
    normal : array_like, shape (3,), optional
        Normal of the plane through the base origin, pointing the way the ball goes (default the fixed working
        plane's, base y; a plane turned by joint 1: :func:`~tudorvision.catch.intercept.working_plane_normal`).

    Returns
    -------
    tuple
        ``(t_s, p_base)``: crossing time (s, on the flight's clock) and point
        (3,); ``(None, None)`` if the flight never crosses, starts beyond
        the plane, or hits the floor (``z < ball_radius_m``) first.

    Examples
    --------
    >>> t, p = true_crossing(np.array([0.0, 1.0]), np.array([[0.0, -1.0, 1.0], [0.0, 1.0, 1.0]]))
    >>> float(t), p.tolist()
    (0.5, [0.0, 0.0, 1.0])
    """
    tt, pp = np.asarray(times_s, float), np.asarray(points_base, float)
    h = pp @ np.asarray(normal, float)
    above = np.nonzero(h > 0.0)[0]
    if len(above) == 0 or above[0] == 0:
        return None, None
    i = above[0]
    if np.any(pp[:i + 1, 2] < ball_radius_m):
        return None, None
    a = -h[i - 1] / (h[i] - h[i - 1])
    return tt[i - 1] + a * (tt[i] - tt[i - 1]), pp[i - 1] + a * (pp[i] - pp[i - 1])


@dataclass(frozen=True)
class Throw:
    """One throw and its ground truth (never shown to the agent).

    Parameters
    ----------
    index : int
        Throw number in the run.
    t_release_s : float
        Release time on the demo's clock, s.
    times_s : ndarray, shape (N,)
        Flight sample times from the release, s (trimmed 30 cm past the plane or once the ball's bottom is 5 cm
        above the floor).
    points_base : ndarray, shape (N, 3)
        Ball centres of the trimmed flight, metres, base frame.
    t_cross_rel_s : float or None
        Time from the release to the true crossing of the working plane, s (None: no crossing).
    p_cross_base : ndarray, shape (3,), or None
        True crossing point, metres, base frame.
    t_cross_s : float
        Crossing time on the demo's clock, s; without a crossing, the end of the trimmed flight.
    ball_radius_m : float
        The ball is a sphere of this radius, m (the scorer checks it against the net's rim).
    """

    index: int
    t_release_s: float
    times_s: np.ndarray
    points_base: np.ndarray
    t_cross_rel_s: float | None
    p_cross_base: np.ndarray | None
    t_cross_s: float
    ball_radius_m: float = 0.045

    @property
    def crosses(self) -> bool:
        """Whether the flight crosses the working plane above the floor."""
        return self.t_cross_rel_s is not None


@dataclass(frozen=True)
class CameraFrame:
    """What the wall camera delivers to perception for one frame.

    Parameters
    ----------
    t : float
        Frame time, s.
    depth_mm : ndarray, shape (H, W), uint16, or None
        Rendered raw depth image, millimetres (rendered mode).
    detection_cam : tuple of ndarray or None
        ``(p_cam (3,), cov_cam (3, 3))`` from the detection-noise model, metres and m^2,
        camera frame (modelled mode).
    """

    t: float
    depth_mm: np.ndarray | None = None
    detection_cam: tuple | None = None


class CatchScenario:
    """The simulated lab of the catching demo: arm, joint layer, wall camera, thrower, operator.

    Parameters
    ----------
    options : DemoOptions
        The demo's options (seed, rendering, noise, ball, net capacity, layer rate).
    params : RobotParams
        The robot's parameters.
    theta_start : array_like, shape (3,)
        Joint angles the arm starts at rest in, rad.
    damping_model : StrainDynamicsModel, optional
        The joint layer's identified strain model for the model-assisted static strain cancellation
        (``SimCore(damping_model=...)``; :func:`~tudorvision.lab.catch.run.demo_damping_model`).

    Attributes
    ----------
    layer : LockstepLayer
        The joint-control layer around the simulated arm, advanced in simulated time:
        the agent's only way to the arm.
    T_base_cam : ndarray, shape (4, 4)
        The wall camera's true extrinsics (camera frame to base frame): ground truth, for the
        calibration's error and ``DemoOptions.true_calibration`` only.
    intrinsics : Intrinsics
        The wall camera's intrinsics.
    depth_sensor : tudorvision.sim.depth_sensor.DepthSensorModel
        The wall camera's depth sensor (:func:`~tudorvision.lab.catch.calibration.wall_depth_sensor`),
        the same for the throws and the calibration sweep.
    balls : int
        Balls in the net now.
    emptied : int
        How often the operator emptied the net.
    """

    def __init__(self, options, params, theta_start, *, damping_model=None):
        from ...rgbd.ball import BallDetectorOptions
        from ...rgbd.frames import Intrinsics
        from ...sim.scenes_rgbd import ball_throw
        from ..record import T_WORLD_BASE, elastic_arm_geometry

        o = self.options = options
        self.params = params
        self._rng_throw = np.random.default_rng([o.seed, 1])
        self._rng_render = np.random.default_rng([o.seed, 2])
        self._rng_noise = np.random.default_rng([o.seed, 3])
        self.mount_kg = float(params.end_effector_mount_mass_kg)
        self.balls, self.emptied = 0, 0
        self._payload = Payload.from_parts(params, balls=0)
        from ..data_collection import plant_config
        from .options import layer_damping

        config = plant_config(o.plant)
        # the balls hang in the net and swing (``ball_swing_length_m`` > 0): the plant's point payload stays the
        # bare mount, the balls' weight and swing reach the end effector through the bag
        self.swing = SwingingBalls(config.dt, length_m=o.ball_swing_length_m) if o.ball_swing_length_m > 0 else None
        self.sim = SimCore(theta_start, payload=self._payload, params=params, config=config, replan=o.replan,
                           obstacles=() if self.swing is None else (self.swing,), damping_model=damping_model,
                           damping_gains=layer_damping(o)[1])
        self.layer = LockstepLayer(self.sim, rate_hz=o.layer_rate_hz)
        self._T_world_base = T_WORLD_BASE
        self._flight = None          # (times_s, points_base) of the ball in the air
        self._t_release = 0.0

        def arm_geometry(t):
            a = self.sim.arm
            return elastic_arm_geometry(a.theta, a.tip2, a.tip3, params)

        from .calibration import wall_camera_position_world

        self.setup = ball_throw(self.ball_world, np.random.default_rng([o.seed, 4]), T_world_base=T_WORLD_BASE,
                                arm=arm_geometry, ball_radius_m=o.ball_radius_m,
                                camera_position_world=wall_camera_position_world(o))
        self.camera = self.setup.cameras["rgbd"]
        self.T_base_cam = np.linalg.inv(T_WORLD_BASE) @ self.camera.T_world_cam     # the true extrinsics
        self._T_cam_world = np.linalg.inv(self.camera.T_world_cam)
        self.intrinsics = Intrinsics.from_matrix(self.camera.K, self.camera.width, self.camera.height)
        self.detector_options = BallDetectorOptions(ball_radius_m=o.ball_radius_m)
        from .calibration import wall_depth_sensor

        self.depth_sensor = wall_depth_sensor(o)        # 0.6-8 m: the arm is in range from behind the thrower

    # ---------------------------------------------------------------- ground truth
    def ball_world(self, t: float) -> np.ndarray:
        """True ball centre at demo time ``t`` (s), metres, world frame (off stage between throws)."""
        if self._flight is None:
            return _PARKED_WORLD
        tt, pp = self._flight
        s = t - self._t_release
        if s < 0 or s > tt[-1]:
            return _PARKED_WORLD
        T = self._T_world_base
        return T[:3, :3] @ np.array([np.interp(s, tt, pp[:, j]) for j in range(3)]) + T[:3, 3]

    def net_position(self) -> np.ndarray:
        """The deflected end effector (net centre) now, metres, base frame (ground truth)."""
        return self.sim.arm.ee_position().copy()

    @property
    def payload_added_kg(self) -> float:
        """True payload on top of the end-effector mount (the balls in the net), kg."""
        return self.balls * float(self.params.ball_mass_kg)

    # ---------------------------------------------------------------- the thrower
    def throw(self, index: int, t_now: float) -> Throw:
        """Draw the next throw, released within one frame after ``t_now`` (s), and put the ball in the air."""
        from ..record import random_throw, throw_trajectory

        o = self.options
        p0, v0 = random_throw(self._rng_throw, target_height_m=o.target_height_m)
        tt, pp, _ = throw_trajectory(p0, v0, drag_k_per_m=o.drag_k_per_m, duration_s=2.0)
        t_rel = t_now + self._rng_throw.uniform(0.0, 1.0 / FRAME_RATE_HZ)
        r = o.ball_radius_m
        tc_rel, p_cross = true_crossing(tt, pp, ball_radius_m=r)
        end = np.argmax((pp[:, 1] > 0.3) | (pp[:, 2] < r + 0.05))
        end = end if end > 0 else len(tt) - 1
        self._flight = (tt[:end + 1], pp[:end + 1])
        self._t_release = t_rel
        t_cross = t_rel + tc_rel if tc_rel is not None else t_rel + tt[end]
        return Throw(index=index, t_release_s=t_rel, times_s=tt[:end + 1], points_base=pp[:end + 1],
                     t_cross_rel_s=tc_rel, p_cross_base=p_cross, t_cross_s=t_cross, ball_radius_m=r)

    def end_throw(self) -> None:
        """The ball leaves the stage."""
        self._flight = None

    # ---------------------------------------------------------------- the wall camera
    def render_depth(self, t: float) -> np.ndarray:
        """Render the wall camera's depth image at ``t`` (s), uint16 millimetres, shape (H, W)."""
        from ...sim.render import render_rgbd

        _, depth, _ = render_rgbd(self.camera, self.setup.scene, t, rng=self._rng_render,
                                  depth_model=self.depth_sensor)
        return depth

    def observe(self, t: float) -> CameraFrame | None:
        """The wall camera's frame at ``t`` (s): a rendered depth image or a modelled detection.

        Frames are rendered only while the ball is within the sensor's range
        (plus 30 cm); nothing could be detected in the others. ``None``: no
        frame, or (modelled mode) no detection.
        """
        p_world = self.ball_world(t)
        p_cam = (self._T_cam_world @ np.r_[p_world, 1.0])[:3]
        o, det = self.options, self.detector_options
        if o.render:
            if np.linalg.norm(p_cam) > det.max_range_m + 0.3:
                return None
            return CameraFrame(t=t, depth_mm=self.render_depth(t))
        if p_world[2] <= -1.0:
            return None
        d = simulated_detection(self.pattern_moved(p_cam), self.intrinsics, self._rng_noise, options=det,
                                scale=o.noise_scale)
        return None if d is None else CameraFrame(t=t, detection_cam=d)

    def pattern_moved(self, p_cam: np.ndarray) -> np.ndarray:
        """Where the sensor's fixed depth pattern puts a point (moved along its ray; modelled mode).

        The detector averages the depth over the ball's few pixels; the pattern, smooth over tens of
        pixels, is the one at its centre (:func:`~tudorvision.sim.depth_sensor.pattern_field`).

        Parameters
        ----------
        p_cam : ndarray, shape (3,)
            True point, metres, camera optical frame.

        Returns
        -------
        ndarray, shape (3,)
            The point at the depth ``1 / (1 / z + c)`` on the same ray (``p_cam`` itself without a pattern).
        """
        if self.depth_sensor.pattern_disparity_px == 0 or p_cam[2] <= 0:
            return p_cam
        from ...sim.depth_sensor import with_pattern

        K = self.intrinsics
        u = int(np.clip(np.rint(K.fx * p_cam[0] / p_cam[2] + K.cx), 0, K.width - 1))
        v = int(np.clip(np.rint(K.fy * p_cam[1] / p_cam[2] + K.cy), 0, K.height - 1))
        z = with_pattern(np.array([[p_cam[2]]]), self.depth_sensor, (K.height, K.width), origin=(v, u))[0, 0]
        return p_cam * (z / p_cam[2])

    # ---------------------------------------------------------------- the net and the operator
    def catch_ball(self) -> None:
        """A caught ball stays in the net: the arm's payload grows by one ball.

        Only a ball that passed wholly through the ring is caught (the scorer's
        ``caught``); one that touched the rim bounced off and adds nothing.
        """
        self.balls += 1
        if self.swing is not None:
            self.swing.set_mass(self.payload_added_kg)
            return
        self._payload = Payload.from_parts(self.params, balls=self.balls)
        self.sim.arm.set_payload(self._payload)

    @property
    def net_full(self) -> bool:
        """Whether the net holds ``net_capacity_balls`` balls."""
        return self.balls >= self.options.net_capacity_balls

    def empty_net(self) -> None:
        """The operator empties the net (arm at rest) and tells the joint layer the bare mount's mass.

        With the loaded net's gains kept, the bare mount's link-3 mode would
        turn a large swing into a limit cycle (``docs/joint_layer.md``, "Payload").
        """
        self.balls = 0
        self.emptied += 1
        if self.swing is not None:
            self.swing.set_mass(0.0)
        self._payload = Payload.from_parts(self.params, balls=0)
        self.sim.arm.set_payload(self._payload)
        self.layer.adapter.set_payload(self.mount_kg)

    def close(self) -> None:
        """Close the joint layer's adapter."""
        self.layer.close()
