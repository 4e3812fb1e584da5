"""Hybrid visual servoing of TUDOR with the eye-in-hand RGB-D camera (section 9.1).

Features of a black square (:mod:`.features`), interaction matrices with
their sign convention (:mod:`.interaction`), control laws (:mod:`.laws`), the
joint map through the rigid-equivalent Jacobian (:mod:`.joint_map`) and the
perception-side controller that combines them (:mod:`.loop`). The closed loop
in the virtual lab and the repeatability experiment are in
:mod:`tudorvision.lab.servo_lab` and :mod:`tudorvision.lab.servo_experiments`.
"""
from .features import (FeatureConfig, SquareFeatures, depth_at, depth_at_many, diagonal_intersection,
                       extract_square, order_corners, polygon_centroid)
from .interaction import (hybrid_error, hybrid_matrix, point_interaction, project_cam, seed_image_jacobian,
                          stacked_interaction)
from .joint_map import JointCommand, JointMapConfig, base_from_cam_velocity, joint_velocity, point_jacobian
from .laws import (AdaptiveGain, GoalFeatures, LawConfig, ServoCommand, adaptive_gain, hybrid_law, ibvs_law,
                   limit_velocity, servo_command)
from .loop import DEFAULT_SMOOTHING_FRAMES, ServoStep, VisualServo, average_features, default_T_ee_cam, servo_step

__all__ = [
    "FeatureConfig", "SquareFeatures", "depth_at", "depth_at_many", "diagonal_intersection", "extract_square",
    "order_corners", "polygon_centroid",
    "hybrid_error", "hybrid_matrix", "point_interaction", "project_cam", "seed_image_jacobian",
    "stacked_interaction",
    "JointCommand", "JointMapConfig", "base_from_cam_velocity", "joint_velocity", "point_jacobian",
    "AdaptiveGain", "GoalFeatures", "LawConfig", "ServoCommand", "adaptive_gain", "hybrid_law", "ibvs_law",
    "limit_velocity", "servo_command",
    "DEFAULT_SMOOTHING_FRAMES", "ServoStep", "VisualServo", "average_features", "default_T_ee_cam", "servo_step",
]
