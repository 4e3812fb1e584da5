"""External stereo tracking of the end effector (section 2.4 of the seed).

Colour models (:mod:`.colormodel`), sphere segmentation (:mod:`.segment`, with
the luma-edge rim of :mod:`.rim_edge`),
tracking mode (:mod:`.tracker2d`), triangulation with rolling-shutter
compensation (:mod:`.triangulate`), trajectories (:mod:`.trajectory`), the
per-frame tracking loop (:mod:`.pipeline`), checkerboard stereo calibration
(:mod:`.calibrate`) and the robot base frame from a theta1 sweep
(:mod:`.base_frame`). :class:`RerunStereoLog` writes rerun recordings (rerun itself is
imported only when one is made).
"""
from .base_frame import BaseFrameReport, base_frame_from_theta1_sweep
from .calibrate import (StereoCalibrationResult, calibrate_stereo, calibrate_stereo_from_images, parse_board,
                        plot_view_errors)
from .colormodel import (ColorModel, ColorModelSet, fit_color_model, fit_color_model_set, load_color_models,
                         parse_pick, save_color_models)
from .rerun_log import RerunStereoLog
from .pipeline import PipelineOptions, StereoFrameResult, StereoPipeline
from .tracking import (MonoTrackResult, StereoTrackResult, TrackStats, iter_stereo, read_mono_track_csv, track_mono,
                       track_stereo, write_mono_track_csv)
from .segment import SegmentParams, SphereDetection, detect_sphere, detect_spheres
from .tracker2d import SphereTracker, TrackerParams
from .trajectory import (Trajectory, plot_trajectory, read_trajectory_csv, trajectory_from_points,
                         write_trajectory_csv)
from .triangulate import SphereTriangulation, triangulate_points, triangulate_spheres, undistort_points

__all__ = [
    # colour models
    "ColorModel", "ColorModelSet", "fit_color_model", "fit_color_model_set", "load_color_models", "parse_pick",
    "save_color_models",
    # segmentation and tracking mode
    "SegmentParams", "SphereDetection", "detect_sphere", "detect_spheres", "SphereTracker", "TrackerParams",
    # triangulation and trajectories
    "SphereTriangulation", "triangulate_points", "triangulate_spheres", "undistort_points",
    "Trajectory", "plot_trajectory", "read_trajectory_csv", "trajectory_from_points", "write_trajectory_csv",
    # the tracking loop
    "PipelineOptions", "StereoFrameResult", "StereoPipeline", "StereoTrackResult", "TrackStats", "iter_stereo",
    "track_stereo", "MonoTrackResult", "track_mono", "write_mono_track_csv", "read_mono_track_csv",
    "RerunStereoLog",
    # calibration
    "BaseFrameReport", "base_frame_from_theta1_sweep", "StereoCalibrationResult", "calibrate_stereo",
    "calibrate_stereo_from_images", "parse_board", "plot_view_errors",
]
