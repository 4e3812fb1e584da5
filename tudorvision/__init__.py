"""tudorvision: vision-based sensing and servoing for the elastic-link arm TUDOR.

Subpackages
-----------
robot   rigid-equivalent kinematics and the robot parameter file
io      recorded sequences (TUM-style indices, video) and calibration files
stereo  colour models, sphere segmentation, triangulation, trajectories
rgbd    RGB-D frames, point clouds, depth model, circle-fit calibration, ball detection
servo   features, interaction matrices, IBVS laws
catch   EKF, intercept, data-based kinematics, demo launcher
joint   joint-control layer: cascade, damping, collision, thin adapter
sim     virtual lab: elastic arm plant, scenes, rendered cameras, recordings
"""
__version__ = "0.1.0"
__all__ = ["__version__"]
