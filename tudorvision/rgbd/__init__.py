"""RGB-D perception: frames and point clouds, depth-noise calibration, wall-camera base calibration, ball detection.

Depth conversions and the depth-noise model are in :mod:`tudorvision.sensors`.
"""
from .ball import (BallDetection, BallDetector, BallDetectorOptions, ColorBallDetector, ColorBallOptions,
                   DepthBackground, PixelDetection, ball_center_cam_from_pixels, detect_balls)
from .base_calib import base_frame_from_sweep
from .cloud import cloud_from_points, cloud_from_rgbd, colored_points_cam_from_rgbd, read_ply, write_ply
from .depth_model import (DepthStepStats, calibrate_depth_model, depth_step_stats, fit_depth_model,
                          plot_depth_model, planar_region_mask, read_depth_table_csv, write_depth_table_csv)
from .disc import DiscObservation, DiscOptions, DiscTracker, observe_disc, segment_uniform_depth, track_disc
from .frames import (Intrinsics, check_depth, organized_points_cam_from_depth, points_cam_from_depth,
                     rays_cam_from_uv, uv_from_points_cam)

__all__ = [
    "BallDetection", "BallDetector", "BallDetectorOptions", "ColorBallDetector", "ColorBallOptions",
    "DepthBackground", "PixelDetection", "ball_center_cam_from_pixels", "detect_balls",
    "base_frame_from_sweep",
    "cloud_from_points", "cloud_from_rgbd", "colored_points_cam_from_rgbd", "read_ply", "write_ply",
    "DepthStepStats", "calibrate_depth_model", "depth_step_stats",
    "fit_depth_model", "plot_depth_model", "planar_region_mask", "read_depth_table_csv", "write_depth_table_csv",
    "DiscObservation", "DiscOptions", "DiscTracker", "observe_disc", "segment_uniform_depth", "track_disc",
    "Intrinsics", "check_depth", "organized_points_cam_from_depth", "points_cam_from_depth",
    "rays_cam_from_uv", "uv_from_points_cam",
]
