"""Visual servoing in the loop, perception side: images, depth and joint angles in, joint velocities out.

:class:`VisualServo` (and the pure :func:`servo_step`) extract the square's
features, apply the hybrid or IBVS law and map the camera velocity to joint
rates with the rigid-equivalent Jacobian. It never reads ground truth and
talks to the arm only through what its caller passes in; the virtual lab
that closes the loop through the joint layer is :mod:`tudorvision.lab.servo_lab`.
"""
from __future__ import annotations

import collections
from dataclasses import dataclass

import numpy as np

from .._checks import check_array, check_transform
from ..robot import load_robot_params
from .features import FeatureConfig, SquareFeatures, extract_square
from .joint_map import JointCommand, JointMapConfig, joint_velocity_checked, joint_velocity
from .laws import GoalFeatures, LawConfig, ServoCommand, servo_command

__all__ = ["default_T_ee_cam", "VisualServo", "ServoStep", "servo_step", "average_features",
           "DEFAULT_SMOOTHING_FRAMES"]

#: Feature moving average used by the lab runs and the CLI (about one period of the first mode).
DEFAULT_SMOOTHING_FRAMES = 15


def default_T_ee_cam(offset_m: float = 0.05) -> np.ndarray:
    """Nominal hand-eye transform: optical axis along end-effector x, camera x along end-effector z.

    Parameters
    ----------
    offset_m : float, optional
        Distance of the optical centre from the end-effector origin along its x axis, metres.

    Returns
    -------
    T_ee_cam : ndarray, shape (4, 4)
        Maps camera-frame points into the end-effector frame.

    Examples
    --------
    >>> default_T_ee_cam()[:3, :3].tolist()
    [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]
    """
    T = np.eye(4)
    T[:3, 0] = [0.0, 0.0, 1.0]     # x_cam = z_ee (joint axis)
    T[:3, 1] = [0.0, -1.0, 0.0]    # y_cam = -y_ee
    T[:3, 2] = [1.0, 0.0, 0.0]     # z_cam = x_ee (along link 3)
    T[:3, 3] = [offset_m, 0.0, 0.0]
    return T


# --------------------------------------------------------------------------- perception side
@dataclass(frozen=True, kw_only=True, eq=False)
class ServoStep:
    """Everything one frame produced: features, camera command, joint command.

    Parameters
    ----------
    features : SquareFeatures
        Features of the frame (after the moving-average filter).
    command : ServoCommand
        Camera velocity command, m/s, camera frame.
    joint : JointCommand
        Joint velocity command, rad/s.
    """

    features: SquareFeatures
    command: ServoCommand
    joint: JointCommand

    @property
    def theta_dot(self) -> np.ndarray:
        """The joint velocity to send (zero unless both stages are ok)."""
        return self.joint.theta_dot if (self.command.ok and self.joint.ok) else np.zeros(3)


def servo_step(bgr, depth_m, theta, goal: GoalFeatures, T_ee_cam, *, law: LawConfig = LawConfig(),
               joint_map: JointMapConfig = JointMapConfig(), features: FeatureConfig = FeatureConfig(),
               params=None) -> ServoStep:
    """One frame of visual servoing: features -> camera velocity -> joint velocity.

    Parameters
    ----------
    bgr : ndarray, shape (H, W, 3) uint8
        Colour image of the eye-in-hand camera (BGR).
    depth_m : ndarray, shape (H, W)
        Metres, NaN invalid.
    theta : array_like, shape (3,)
        Joint angles from the joint layer, radians.
    goal : GoalFeatures
        Taught goal features.
    T_ee_cam : array_like, shape (4, 4)
        Hand-eye calibration.
    law : LawConfig, optional
        Control law, interaction matrix choice, gain and velocity limit.
    joint_map : JointMapConfig, optional
        Damping, singularity stop, joint-range margin and speed limits.
    features : FeatureConfig, optional
        Square-extraction thresholds.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.

    Returns
    -------
    ServoStep
        Its :attr:`ServoStep.theta_dot` is zero when features are lost,
        depth is invalid, or the arm is near a singularity or a range end.
    """
    f = extract_square(bgr, depth_m, config=features)
    cmd = servo_command(f, goal, law)
    if not cmd.ok:
        return ServoStep(features=f, command=cmd, joint=JointCommand(theta_dot=np.zeros(3), ok=False,
                                                                      reason=cmd.reason))
    jc = joint_velocity(cmd.v_cam, theta, T_ee_cam, params=params, config=joint_map)
    return ServoStep(features=f, command=cmd, joint=jc)


def average_features(history) -> SquareFeatures:
    """Mean of the found features of consecutive frames (a moving-average filter).

    Examples
    --------
    >>> a = SquareFeatures(found=True, centroid_uv=np.array([1.0, 2.0]), center_uv=np.array([1.0, 2.0]),
    ...                    corners_uv=np.zeros((4, 2)), depth_m=np.ones(5))
    >>> average_features([a, a]).centroid_uv.tolist()
    [1.0, 2.0]
    """
    fs = list(history)
    return SquareFeatures(found=True, centroid_uv=np.mean([f.centroid_uv for f in fs], axis=0),
                          center_uv=np.mean([f.center_uv for f in fs], axis=0),
                          corners_uv=np.mean([f.corners_uv for f in fs], axis=0),
                          depth_m=np.mean([f.depth_m for f in fs], axis=0),
                          area_px=float(np.mean([f.area_px for f in fs])))


class VisualServo:
    """The servo controller: goal, hand-eye, options and the feature filter held between frames.

    Parameters
    ----------
    goal : GoalFeatures
        Taught goal features.
    T_ee_cam : array_like, shape (4, 4)
        Hand-eye calibration (``p_ee = T_ee_cam @ p_cam``).
    law : LawConfig, optional
        Control law, interaction matrix choice, gain and velocity limit.
    joint_map : JointMapConfig, optional
        Damping, singularity stop, joint-range margin and speed limits.
    features : FeatureConfig, optional
        Square-extraction thresholds.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    smoothing_frames : int
        Moving average over this many consecutive frames with found
        features (1: none). The elastic arm's first mode (1.5-2.7 Hz) makes
        the camera swing; averaging over about one period (15 frames at
        30 Hz) keeps the servo from feeding it. A frame without features
        empties the filter (and gives a zero command).

    Raises
    ------
    ValueError
        If ``T_ee_cam`` is not a rigid transform or ``smoothing_frames < 1``.
    """

    def __init__(self, goal: GoalFeatures, T_ee_cam, *, law: LawConfig = LawConfig(),
                 joint_map: JointMapConfig = JointMapConfig(), features: FeatureConfig = FeatureConfig(),
                 params=None, smoothing_frames: int = 1):
        self.goal = goal
        self.T_ee_cam = check_transform(T_ee_cam, "T_ee_cam")
        self.law, self.joint_map, self.features = law, joint_map, features
        self.params = params or load_robot_params()
        if int(smoothing_frames) < 1:
            raise ValueError(f"smoothing_frames: expected >= 1, got {smoothing_frames!r}")
        self._hist = collections.deque(maxlen=int(smoothing_frames))

    @classmethod
    def from_goal_image(cls, bgr, depth_m, K, T_ee_cam, **options) -> "VisualServo":
        """Teach the goal as an image: extract its features (raises ValueError without a square).

        Parameters
        ----------
        bgr : ndarray, shape (H, W, 3) uint8
            Goal image (BGR) of the eye-in-hand camera.
        depth_m : ndarray, shape (H, W)
            Registered depth, metres, NaN invalid.
        K : array_like, shape (3, 3)
            Camera matrix (pixels).
        T_ee_cam : array_like, shape (4, 4)
            Hand-eye calibration.
        **options
            Keyword options of :class:`VisualServo`.

        Returns
        -------
        VisualServo
            A controller with this goal.

        Raises
        ------
        ValueError
            If no square (or no depth at it) is found in the goal image.
        """
        fcfg = options.get("features", FeatureConfig())
        f = extract_square(bgr, depth_m, config=fcfg)
        if not f.found:
            raise ValueError(f"goal image: no square found ({f.reason})")
        K = np.asarray(K, dtype=np.float64)
        goal = GoalFeatures(features=f, f_px=float(0.5 * (K[0, 0] + K[1, 1])), principal_uv=K[:2, 2].copy())
        return cls(goal, T_ee_cam, **options)

    def reset(self) -> None:
        """Forget the filtered features."""
        self._hist.clear()

    def step(self, bgr, depth_m, theta) -> ServoStep:
        """Process one frame (see :func:`servo_step`), with the moving-average feature filter.

        Parameters
        ----------
        bgr : ndarray, shape (H, W, 3) uint8
            Current colour image (BGR).
        depth_m : ndarray, shape (H, W)
            Registered depth, metres, NaN invalid.
        theta : array_like, shape (3,)
            Joint angles from the joint layer, radians.

        Returns
        -------
        ServoStep
            Features, camera command and joint command of this frame.
        """
        f = extract_square(bgr, depth_m, config=self.features)
        ok = f.found and (f.centroid_depth_ok if self.law.law == "hybrid" else f.all_depth_ok)
        if not ok:
            self._hist.clear()
            used = f
        else:
            self._hist.append(f)
            used = average_features(self._hist) if len(self._hist) > 1 else f
        return self.step_features(used, theta, raw=f)

    def step_features(self, features: SquareFeatures, theta, *, raw: SquareFeatures | None = None) -> ServoStep:
        """Law and joint map for already extracted (and filtered) features.

        Parameters
        ----------
        features : SquareFeatures
            Features to steer by (already filtered).
        theta : array_like, shape (3,)
            Joint angles, radians.
        raw : SquareFeatures, optional
            The unfiltered features, reported in the step (default ``features``).

        Returns
        -------
        ServoStep
            Features, camera command and joint command.
        """
        cmd = servo_command(features, self.goal, self.law)
        if not cmd.ok:
            jc = JointCommand(theta_dot=np.zeros(3), ok=False, reason=cmd.reason)
        else:
            jc = joint_velocity_checked(cmd.v_cam, check_array(theta, "theta", (3,)), self.T_ee_cam, self.params,
                                 self.joint_map)
        return ServoStep(features=raw if raw is not None else features, command=cmd, joint=jc)
