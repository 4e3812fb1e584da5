"""Ball catching with the elastic arm (sections 9.2, 9.3).

EKF prediction of the thrown ball (:mod:`.ekf`), the intercept with the
robot's working plane (:mod:`.intercept`), a drag-free ballistic peer
(:mod:`.ballistic`), the perception stream that combines them
(:mod:`.perception`) and data-based kinematics under load (:mod:`.kinematics`).
The simulated catching demo lives in :mod:`tudorvision.lab.catch_demo`.
"""
from .ballistic import BallisticPredictor, fit_ballistic
from .ball_model import BallModel, propagate
from .ekf import BallEKF, EKFOptions, init_from_detections, predict, update
from .intercept import (Intercept, InterceptOptions, InterceptPlanner, PlaneCrossing, net_target, plane_crossing,
                        reachable_solutions, working_plane_normal)
from .perception import CatchPerception, detection_to_base

__all__ = [
    "BallisticPredictor", "fit_ballistic",
    "BallEKF", "BallModel", "EKFOptions", "init_from_detections", "predict", "propagate", "update",
    "Intercept", "InterceptOptions", "InterceptPlanner", "PlaneCrossing", "net_target", "plane_crossing",
    "reachable_solutions", "working_plane_normal",
    "CatchPerception", "detection_to_base",
]
