"""Visual servoing in the virtual lab: the simulated arm behind its joint layer, an eye-in-hand camera.

Lab side (:class:`ServoLab`): the simulated elastic arm (static deflection,
payload, oscillations) behind a :class:`~tudorvision.joint.server.JointLayerServer`
with the ``SimCore``, driven in *simulated* time (lockstep: the server's
control ticks and its datagram handling are run by the lab instead of a wall
clock thread, so a run is deterministic and faster than real time), and an
eye-in-hand RGB-D camera rendered from the arm's true, deflected pose.
The servo talks to the arm only through a :class:`~tudorvision.joint.adapter.JointAdapter`
over an in-process transport. Damping: the servo asks the layer for the
proportional strain feedback (``Damping.PROPORTIONAL`` in the mode switch);
the layer installs its own damper with the gains scheduled on the payload it
knows (:data:`tudorvision.joint.damping.PAYLOAD_SCHEDULE`), and the lab tells
it the mounted payload (camera and plates) through the adapter.

Geometry of the lab (all assumed; the seed gives none): the robot stands on
a pedestal ``pedestal_m`` above the floor (world z = 0) on which the black
square lies; the camera looks along link 3 (optical axis = end-effector x),
its x axis along the joint-3 axis. In the goal posture link 2 is horizontal
and link 3 hangs down, so the camera looks down on the square from about
0.75 m (the Kinect's minimum range is 0.6 m).

Timing: frames at 30 Hz; a frame captured at ``t`` is processed and its
command sent at ``t + latency_s`` (joint angles requested at capture time);
the layer's 100 ms watchdog stops the arm when commands cease.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..joint.protocol import Damping, Mode
from ..sensors import depth_m_from_raw
from ..robot import RobotParams, load_robot_params
from ..servo.loop import VisualServo, default_T_ee_cam
from .lockstep import LockstepLayer
from .simulation import SimCore

__all__ = ["LabConfig", "ServoLab", "teach_goal", "RunResult", "run_closed_loop", "DEFAULT_THETA_GOAL"]

#: Goal posture: link 2 horizontal, link 3 hanging 85 deg down (radians).
DEFAULT_THETA_GOAL = np.deg2rad([0.0, 0.0, -85.0])


# --------------------------------------------------------------------------- lab side
@dataclass(frozen=True, kw_only=True)
class LabConfig:
    """The virtual servoing lab (SI units; see the module notes for the geometry).

    Attributes
    ----------
    pedestal_m : float
        Height of the robot base above the floor.
    square_center_world : tuple
        Where the square lies on the floor (world frame = base frame shifted
        down by the pedestal). ``None``: below the goal camera.
    square_size_m : float
    theta_goal : tuple
        Posture in which the goal image is taught (camera payload only).
    T_ee_cam : ndarray
        True (and calibrated) hand-eye transform.
    frame_rate_hz, latency_s : float
        Camera rate and the delay from capture to command.
    server_rate_hz : float
        Joint-layer control rate (the plant sub-steps at 2 kHz).
    image_size : tuple
        ``(width, height)``; the focal length scales with the width.
    damping : bool
        Ask the joint layer for proportional strain feedback (its payload-scheduled gains).
    t_max_s : float
        Longest run.
    converge_tol_m : float
        Estimated distance to the goal (``||L^-1 e||``) counted as converged.
    converge_frames : int
        Consecutive frames within the tolerance that end a run.
    lost_stop_s : float
        A run also ends (not converged) after this long without a command
        (features lost or unusable): the layer has stopped the arm and the
        view no longer changes. ``inf`` disables it.
    roi_render : bool
        Ray-cast only the pixel box around the square and fill the rest of
        the frame with the ground's radiance and plane depth
        (:class:`~tudorvision.sim.roi_render.RoiRenderer`: the same image
        distribution as the full render, several times faster).
    supersample : int
        With ``roi_render``: ``k x k`` colour samples per pixel around the
        square (pixel-area integration; 1 = the simulator's point sampling).
    params : RobotParams or None
        The simulated robot (``--robot``); None: the packaged ``tudor.yaml``.
    """

    pedestal_m: float = 0.85
    square_center_world: tuple | None = None
    square_size_m: float = 0.1
    theta_goal: tuple = tuple(DEFAULT_THETA_GOAL)
    T_ee_cam: np.ndarray = field(default_factory=default_T_ee_cam)
    frame_rate_hz: float = 30.0
    latency_s: float = 0.05
    server_rate_hz: float = 500.0
    image_size: tuple = (640, 480)
    damping: bool = True
    t_max_s: float = 10.0
    converge_tol_m: float = 0.002
    converge_frames: int = 15
    lost_stop_s: float = 1.0
    roi_render: bool = True
    supersample: int = 1
    params: RobotParams | None = None

    @property
    def T_world_base(self) -> np.ndarray:
        T = np.eye(4)
        T[2, 3] = self.pedestal_m
        return T


def _true_camera_pose(arm, cfg: LabConfig) -> np.ndarray:
    return cfg.T_world_base @ arm.T_base_ee() @ cfg.T_ee_cam


class ServoLab:
    """The simulated arm behind its joint layer, with an eye-in-hand RGB-D camera.

    Parameters
    ----------
    config : LabConfig
    theta_start : array_like, shape (3,)
        Start posture (the arm starts at rest, statically deflected).
    plates : int
        100 g payload plates in addition to the camera.
    rng : numpy.random.Generator
        Sensor noise.
    noise : bool
        Sensor noise on colour and depth.
    scene_seed : int
        Seeds the scene's randomisation (ground shade, lights): the same
        seed gives the same room as the goal image.
    """

    def __init__(self, config: LabConfig, theta_start, *, plates: int = 0, rng: np.random.Generator,
                 noise: bool = True, scene_seed: int = 0):
        from ..sensors import DepthNoiseModel
        from ..sim import DepthSensorModel, Payload, eye_in_hand
        from ..sim.render import pixel_bboxes
        self.config = cfg = config
        self.params = cfg.params or load_robot_params()
        self.rng = rng
        self.noise = noise
        payload = Payload.from_parts(self.params, plates=plates, camera=True)
        #: payload the user mounted (camera and plates), kg: told to the joint layer
        self.payload_kg = float(payload.mass_kg)
        self.core = SimCore(theta_start, payload=payload, params=self.params)
        #: the real joint-layer server and adapter, advanced in simulated time
        self.layer = LockstepLayer(self.core, rate_hz=cfg.server_rate_hz)
        self.server, self.adapter = self.layer.server, self.layer.adapter
        self.square_center_world = (np.asarray(cfg.square_center_world, float) if cfg.square_center_world
                                    is not None else _goal_square_center(cfg, self.params))
        w, h = cfg.image_size
        self.setup = eye_in_hand(_true_camera_pose(self.core.arm, cfg), np.random.default_rng(scene_seed),
                                 square_center_world=self.square_center_world, square_size_m=cfg.square_size_m,
                                 width=int(w), height=int(h))
        self.camera = self.setup.cameras["rgbd"]
        # fill the camera's ray and field-of-view caches once; with_pose() hands them to every moved copy
        pixel_bboxes(self.camera, [self.setup.meta["square_corners_world"]])
        self.depth_model = DepthSensorModel() if noise else \
            DepthSensorModel(noise=DepthNoiseModel(coeffs=(0.0,), floor_m=0.0))
        self.t = 0.0
        self._renderer = None

    # -- joint-layer side -------------------------------------------------------------------
    def advance(self, dt: float) -> None:
        """Run the joint layer (and the plant) for ``dt`` seconds of simulated time."""
        period = 1.0 / self.config.server_rate_hz
        n = max(1, int(round(dt / period)))
        for _ in range(n):
            self.server.tick(period)
        self.t += n * period

    # -- camera side ------------------------------------------------------------------------
    def T_world_cam(self) -> np.ndarray:
        """True camera pose now (ground truth, for scoring only)."""
        return _true_camera_pose(self.core.arm, self.config)

    def capture(self):
        """Render the eye-in-hand RGB-D frame now: ``(bgr, depth_m)`` with NaN invalid depth."""
        from ..sim import render_rgbd, with_pose
        from ..sim.roi_render import RoiRenderer
        cam = with_pose(self.camera, self.T_world_cam())
        rng = self.rng if self.noise else None
        if self.config.roi_render:
            if self._renderer is None or self._renderer.scene is not self.setup.scene:
                self._renderer = RoiRenderer(self.setup.scene, self.depth_model,
                                             supersample=self.config.supersample)
            bgr, depth = self._renderer.render(cam, self.t, rng=rng)
        else:
            bgr, depth, _ = render_rgbd(cam, self.setup.scene, self.t, rng=rng, depth_model=self.depth_model)
        return bgr, depth_m_from_raw(depth, self.depth_model.units_per_m)

    @property
    def K(self) -> np.ndarray:
        return self.camera.K


def _goal_square_center(cfg: LabConfig, params) -> np.ndarray:
    """Square on the floor where the goal camera's optical axis meets it (camera-only payload)."""
    from ..sim import ElasticArm, Payload
    arm = ElasticArm(np.asarray(cfg.theta_goal, float), payload=Payload.from_parts(params, camera=True),
                     params=params)
    T = _true_camera_pose(arm, cfg)
    o, d = T[:3, 3], T[:3, 2]
    s = -o[2] / d[2]
    p = o + s * d
    return np.array([p[0], p[1], 0.0])


def teach_goal(config: LabConfig, rng: np.random.Generator, *, noise: bool = True, scene_seed: int = 0):
    """Teach the goal as an image: arm at ``theta_goal`` with the camera only, one frame.

    Returns
    -------
    goal : GoalFeatures
    p_goal_world : ndarray, shape (3,)
        True camera position at the goal (ground truth, for scoring).
    frame : tuple
        ``(bgr, depth_m)`` of the goal image.

    Raises
    ------
    ValueError
        If the goal image shows no square with valid depth.
    """
    lab = ServoLab(config, config.theta_goal, plates=0, rng=rng, noise=noise, scene_seed=scene_seed)
    bgr, depth = lab.capture()
    servo = VisualServo.from_goal_image(bgr, depth, lab.K, config.T_ee_cam)
    return servo.goal, lab.T_world_cam()[:3, 3].copy(), (bgr, depth)


@dataclass(frozen=True, kw_only=True, eq=False)
class RunResult:
    """One closed-loop run.

    Attributes
    ----------
    history : dict of ndarray
        Per frame: ``t`` (s, capture time), ``e_u``, ``e_v`` (px, ``s* - s``),
        ``e_z`` (m), ``error_est_m`` (``||L^-1 e||``), ``error_true_m`` (true
        camera distance to the goal camera position), ``ok`` (command sent
        non-zero), ``theta`` (N, 3), ``p_cam_world`` (N, 3), ``T_world_cam``
        (N, 4, 4) (true camera poses at capture).
    converged : bool
    settling_time_s : float
        First capture time from which the estimated error stayed within the
        tolerance until the end (NaN if not converged).
    final_error_m : float
        True camera position error at the end of the run, metres.
    final_offset_world : ndarray, shape (3,)
        ``p_cam - p_goal`` at the end, world frame.
    end_reason : str
        ``"converged"``, ``"stalled"`` (no command for ``lost_stop_s``) or
        ``"timeout"``.
    """

    history: dict
    converged: bool
    settling_time_s: float
    final_error_m: float
    final_offset_world: np.ndarray
    p_goal_world: np.ndarray
    end_reason: str = ""


def run_closed_loop(lab: ServoLab, servo: VisualServo, p_goal_world, *, on_frame=None) -> RunResult:
    """Servo the simulated arm to the goal view through the joint layer.

    The run ends when the estimated error stayed below ``converge_tol_m`` for
    ``converge_frames`` frames, when no command could be sent for
    ``lost_stop_s`` (features lost, depth invalid, or the joint map stopped
    at a range end or singularity: the arm stands still), or at
    ``t_max_s``; then the commands stop and
    the true camera position is compared with the goal's.

    Parameters
    ----------
    lab : ServoLab
    servo : VisualServo
    p_goal_world : array_like, shape (3,)
        True goal camera position (scoring only; the servo never sees it).
    on_frame : callable, optional
        ``f(t, bgr, depth_m, step)`` after each processed frame (recording).
    """
    cfg = lab.config
    ad = lab.adapter
    ad.set_payload(lab.payload_kg)
    ad.set_mode(Mode.VELOCITY, damping=Damping.PROPORTIONAL if cfg.damping else Damping.OFF)
    period = 1.0 / cfg.frame_rate_hz
    tick = 1.0 / cfg.server_rate_hz
    pending = []                                   # (t_send, t_capture, bgr, depth, theta)
    next_capture = 0.0
    hist = {k: [] for k in ("t", "e_u", "e_v", "e_z", "error_est_m", "error_true_m", "ok", "image_error_px")}
    hist_theta, hist_p, hist_T = [], [], []
    streak, t_streak = 0, np.nan
    p_goal = np.asarray(p_goal_world, float)
    converged = stalled = False
    t_last_ok = 0.0
    while lab.t < cfg.t_max_s - 1e-9:
        if lab.t >= next_capture - 1e-9:
            st = ad.request_state()
            bgr, depth = lab.capture()
            pending.append((lab.t + cfg.latency_s, lab.t, bgr, depth, np.asarray(st.theta, float),
                            lab.T_world_cam()))
            next_capture += period
        while pending and lab.t >= pending[0][0] - 1e-9:
            _, t_cap, bgr, depth, theta, T_true = pending.pop(0)
            p_true = T_true[:3, 3]
            step = servo.step(bgr, depth, theta)
            ad.send_velocity(step.theta_dot)
            c = step.command
            hist["t"].append(t_cap)
            e = c.error if c.error is not None else np.full(3, np.nan)
            hist["e_u"].append(e[0]), hist["e_v"].append(e[1]), hist["e_z"].append(e[2])
            hist["error_est_m"].append(c.error_m)
            hist["image_error_px"].append(c.image_error_px)
            hist["error_true_m"].append(float(np.linalg.norm(p_true - p_goal)))
            hist["ok"].append(bool(c.ok and step.joint.ok))
            hist_theta.append(theta)
            hist_p.append(p_true)
            hist_T.append(T_true)
            if on_frame is not None:
                on_frame(t_cap, bgr, depth, step)
            if c.ok and c.error_m < cfg.converge_tol_m:
                if streak == 0:
                    t_streak = t_cap
                streak += 1
            else:
                streak = 0
            if streak >= cfg.converge_frames:
                converged = True
                break
            if hist["ok"][-1]:
                t_last_ok = t_cap
            elif t_cap - t_last_ok >= cfg.lost_stop_s:
                stalled = True
                break
        if converged or stalled:
            break
        lab.advance(tick)
    # stop: no more commands; the layer's watchdog brakes the arm; let it come to rest
    lab.advance(0.5)
    p_end = lab.T_world_cam()[:3, 3]
    off = p_end - p_goal
    h = {k: np.asarray(v) for k, v in hist.items()}
    h["theta"] = np.asarray(hist_theta).reshape(-1, 3)
    h["p_cam_world"] = np.asarray(hist_p).reshape(-1, 3)
    h["T_world_cam"] = np.asarray(hist_T).reshape(-1, 4, 4)
    return RunResult(history=h, converged=converged, settling_time_s=float(t_streak) if converged else float("nan"),
                     final_error_m=float(np.linalg.norm(off)), final_offset_world=off, p_goal_world=p_goal,
                     end_reason="converged" if converged else ("stalled" if stalled else "timeout"))
