"""RGB-D perception: frames and point clouds, depth-noise calibration, wall-camera base calibration, ball detection.

Depth conversions and the depth-noise model are in :mod:`tudorvision.sensors`.
"""
from .ball import (BallDetection, BallDetector, BallDetectorOptions, ColorBallDetector, ColorBallOptions,
                   DepthBackground, detect_balls)
from .base_calib import base_frame_from_theta2_sweep
from .base_spread import sweep_calibration_spread
from .cloud import cloud_from_points, cloud_from_rgbd, read_ply, write_ply
from .depth_model import (calibrate_depth_model, fit_depth_model, plot_depth_model, read_depth_table_csv,
                          write_depth_table_csv)
from .disc import DiscObservation, DiscOptions, DiscTracker, track_disc
from .frames import Intrinsics, points_cam_from_depth, uv_from_points_cam

__all__ = [
    "BallDetection", "BallDetector", "BallDetectorOptions", "ColorBallDetector", "ColorBallOptions",
    "DepthBackground", "detect_balls",
    "base_frame_from_theta2_sweep", "sweep_calibration_spread",
    "cloud_from_points", "cloud_from_rgbd", "read_ply", "write_ply",
    "calibrate_depth_model", "fit_depth_model", "plot_depth_model", "read_depth_table_csv", "write_depth_table_csv",
    "DiscObservation", "DiscOptions", "DiscTracker", "track_disc",
    "Intrinsics", "points_cam_from_depth", "uv_from_points_cam",
]
