"""Hybrid visual servoing of TUDOR with the eye-in-hand RGB-D camera (section 9.1).

Features of a black square (:mod:`.features`), interaction matrices with
their sign convention (:mod:`.interaction`), control laws (:mod:`.laws`), the
joint map through the rigid-equivalent Jacobian (:mod:`.joint_map`), the
closed loop in the virtual lab (:mod:`.loop`, frames from
:mod:`tudorvision.sim.roi_render`) and the repeatability experiment (:mod:`.experiments`).
"""
from .features import (FeatureConfig, SquareFeatures, depth_at, depth_at_many, depth_m_from_raw,
                       diagonal_intersection, extract_square, order_corners, polygon_centroid)
from .interaction import (hybrid_error, hybrid_matrix, point_interaction, project_cam, seed_image_jacobian,
                          stacked_interaction)
from .joint_map import JointCommand, JointMapConfig, base_from_cam_velocity, joint_velocity, point_jacobian
from .laws import (AdaptiveGain, GoalFeatures, LawConfig, ServoCommand, adaptive_gain, hybrid_law, ibvs_law,
                   limit_velocity, servo_command)
from .loop import (DEFAULT_THETA_GOAL, LabConfig, RunResult, ServoLab, ServoStep, VisualServo, default_T_ee_cam,
                   run_closed_loop, servo_step, teach_goal)

__all__ = [
    "FeatureConfig", "SquareFeatures", "depth_at", "depth_at_many", "depth_m_from_raw", "diagonal_intersection", "extract_square",
    "order_corners", "polygon_centroid",
    "hybrid_error", "hybrid_matrix", "point_interaction", "project_cam", "seed_image_jacobian",
    "stacked_interaction",
    "JointCommand", "JointMapConfig", "base_from_cam_velocity", "joint_velocity", "point_jacobian",
    "AdaptiveGain", "GoalFeatures", "LawConfig", "ServoCommand", "adaptive_gain", "hybrid_law", "ibvs_law",
    "limit_velocity", "servo_command",
    "DEFAULT_THETA_GOAL", "LabConfig", "RunResult", "ServoLab", "ServoStep", "VisualServo", "default_T_ee_cam",
    "run_closed_loop", "servo_step", "teach_goal",
]
