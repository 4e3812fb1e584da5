"""The simulated plant and cameras: an elastic TUDOR under gravity and rendered recordings with ground truth.

``sim`` holds the plant and the cameras only: it never imports perception
(stereo, rgbd, servo, catch) nor the joint layer, and trackers never read its
ground truth.
The plant under the joint layer's controller (``simulate_ptp``, ``SimCore``)
and the recordings (``lab.record``) are wired in :mod:`tudorvision.lab`.
"""
from .arm import (ASSUMPTIONS, ElasticArm, Payload, PlantConfig, SimLog, SpringDamperObstacle, fk_elastic,
                  spheres_from_T)
from .beam import ModalBasis, cantilever_static, modal_basis, surface_strain
from .camera import (PinholeCamera, intrinsic_matrix, look_at, project_points, sphere_silhouette_centroid,
                     with_pose)
from .lighting import AmbientLight, DirectionalLight, PointLight, SensorModel, Varying
from .roi_render import RoiRenderer
from .depth_sensor import DepthSensorModel, depth_mm_from_gbuffer
from .render import (Box, Capsule, Cylinder, Disc, GBuffer, Rectangle, Scene, Sphere, render_bgr, render_gbuffer,
                     render_rgbd)
from .scenes import (ArmGeometry, SimSetup, StereoRigConfig, arm_geometry_from_joints, ball_throw,
                     checkerboard_lab, eye_in_hand, planar_target, sphere_image_truth, stereo_lab, stereo_rig,
                     wall_disc)

__all__ = [
    "ASSUMPTIONS", "ElasticArm", "Payload", "PlantConfig", "SimLog",
    "SpringDamperObstacle", "fk_elastic", "spheres_from_T",
    "ModalBasis", "cantilever_static", "modal_basis", "surface_strain",
    "PinholeCamera", "intrinsic_matrix", "look_at", "project_points", "sphere_silhouette_centroid", "with_pose",
    "AmbientLight", "DirectionalLight", "PointLight", "SensorModel", "Varying",
    "RoiRenderer",
    "DepthSensorModel", "depth_mm_from_gbuffer",
    "Box", "Capsule", "Cylinder", "Disc", "GBuffer", "Rectangle", "Scene", "Sphere",
    "render_bgr", "render_gbuffer", "render_rgbd",
    "ArmGeometry", "SimSetup", "StereoRigConfig", "arm_geometry_from_joints", "ball_throw", "checkerboard_lab",
    "eye_in_hand", "planar_target", "sphere_image_truth", "stereo_lab", "stereo_rig", "wall_disc",
]
