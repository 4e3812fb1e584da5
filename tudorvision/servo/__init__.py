"""Hybrid visual servoing of TUDOR with the eye-in-hand RGB-D camera (section 9.1).

Features of a black square (:mod:`.features`), interaction matrices with
their sign convention (:mod:`.interaction`), control laws (:mod:`.laws`), the
joint map through the rigid-equivalent Jacobian (:mod:`.joint_map`) and the
perception-side controller that combines them (:mod:`.loop`). The closed loop
in the virtual lab and the repeatability experiment are in
:mod:`tudorvision.lab.servo_lab` and :mod:`tudorvision.lab.servo_experiments`.
"""
from .features import FeatureConfig, SquareFeatures, extract_square
from .interaction import hybrid_matrix, point_interaction
from .joint_map import JointCommand, JointMapConfig, joint_velocity
from .laws import AdaptiveGain, GoalFeatures, LawConfig, ServoCommand, hybrid_law, ibvs_law, servo_command
from .loop import ServoStep, VisualServo, default_T_ee_cam, servo_step

__all__ = [
    "FeatureConfig", "SquareFeatures", "extract_square",
    "hybrid_matrix", "point_interaction",
    "JointCommand", "JointMapConfig", "joint_velocity",
    "AdaptiveGain", "GoalFeatures", "LawConfig", "ServoCommand", "hybrid_law", "ibvs_law", "servo_command",
    "ServoStep", "VisualServo", "default_T_ee_cam", "servo_step",
]
