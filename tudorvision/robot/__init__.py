"""TUDOR robot model: parameters and rigid-equivalent kinematics."""
from .params import DEFAULT_PARAMS_PATH, LinkParams, RobotParams, load_robot_params
from .kinematics import (T_base_ee, clip_to_limits, fk_ee, fk_spheres, ik, ik_all,
                         jacobian_ee, planar_from_joints, within_limits)
from .urdf import is_urdf, load_robot, load_urdf_params, urdf_from_params

__all__ = [
    "DEFAULT_PARAMS_PATH", "LinkParams", "RobotParams", "load_robot_params",
    "T_base_ee", "clip_to_limits", "fk_ee", "fk_spheres", "ik", "ik_all",
    "jacobian_ee", "planar_from_joints", "within_limits",
    "is_urdf", "load_robot", "load_urdf_params", "urdf_from_params",
]
