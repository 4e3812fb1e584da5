"""The simulated plant and cameras: an elastic TUDOR under gravity and rendered recordings with ground truth.

``sim`` holds the plant and the cameras only: it never imports perception
(stereo, rgbd, servo, catch) nor the joint layer, and trackers never read its
ground truth.
The plant under the joint layer's controller (``simulate_ptp``, ``SimCore``)
and the recordings (``lab.record``) are wired in :mod:`tudorvision.lab`.
"""
from .arm import ElasticArm, Payload, PlantConfig, SimLog, SpringDamperObstacle, fk_elastic
from .camera import PinholeCamera, intrinsic_matrix, look_at, project_points, with_pose
from .lighting import AmbientLight, DirectionalLight, PointLight, SensorModel
from .roi_render import RoiRenderer
from .depth_sensor import DepthSensorModel
from .render import Box, Capsule, Cylinder, Disc, Rectangle, Scene, Sphere, render_bgr, render_rgbd
from .scenes import SimSetup, StereoRigConfig, checkerboard_lab, stereo_lab, stereo_rig
from .scenes_rgbd import ball_throw, eye_in_hand, planar_target, wall_disc

__all__ = [
    "ElasticArm", "Payload", "PlantConfig", "SimLog", "SpringDamperObstacle", "fk_elastic",
    "PinholeCamera", "intrinsic_matrix", "look_at", "project_points", "with_pose",
    "AmbientLight", "DirectionalLight", "PointLight", "SensorModel",
    "RoiRenderer", "DepthSensorModel",
    "Box", "Capsule", "Cylinder", "Disc", "Rectangle", "Scene", "Sphere", "render_bgr", "render_rgbd",
    "SimSetup", "StereoRigConfig", "ball_throw", "checkerboard_lab", "eye_in_hand", "planar_target", "stereo_lab",
    "stereo_rig", "wall_disc",
]
