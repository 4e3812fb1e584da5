"""The virtual lab: a simulated elastic TUDOR under gravity and rendered cameras with ground truth.

The lab never imports perception code (stereo, rgbd, servo, catch); trackers
never read its ground truth. Recordings are written as sequence directories
(:func:`record`), the plant runs at 2 kHz with the joint cascade
(:func:`simulate_ptp`, :class:`ControlledArm`, :class:`SimCore`).
"""
from .arm import (ASSUMPTIONS, ElasticArm, Payload, PlantConfig, SimLog, SpringDamperObstacle, fk_elastic,
                  spheres_from_T)
from .controlled import ControlledArm, SimCore, simulate, simulate_ptp
from .beam import ModalBasis, cantilever_static, modal_basis, surface_strain
from .camera import (PinholeCamera, intrinsic_matrix, look_at, project_points, sphere_silhouette_centroid,
                     with_pose)
from .lighting import AmbientLight, DirectionalLight, PointLight, SensorModel, Varying
from .record import KINDS, RecordOptions, elastic_arm_geometry, record
from .roi_render import RoiRenderer
from .render import (Box, Capsule, Cylinder, Disc, GBuffer, Rectangle, Scene, Sphere, depth_sigma_m,
                     render_bgr, render_gbuffer, render_rgbd)
from .render import DepthModel as DepthNoiseModel
from .scenes import (ArmGeometry, SimSetup, StereoRigConfig, arm_geometry_from_joints, ball_throw,
                     checkerboard_lab, eye_in_hand, planar_target, sphere_image_truth, stereo_lab, stereo_rig,
                     wall_disc)

__all__ = [
    "ASSUMPTIONS", "ControlledArm", "ElasticArm", "Payload", "PlantConfig", "SimCore", "SimLog",
    "SpringDamperObstacle", "fk_elastic", "simulate", "simulate_ptp", "spheres_from_T",
    "ModalBasis", "cantilever_static", "modal_basis", "surface_strain",
    "PinholeCamera", "intrinsic_matrix", "look_at", "project_points", "sphere_silhouette_centroid", "with_pose",
    "AmbientLight", "DirectionalLight", "PointLight", "SensorModel", "Varying",
    "KINDS", "RecordOptions", "elastic_arm_geometry", "record", "RoiRenderer",
    "Box", "Capsule", "Cylinder", "Disc", "GBuffer", "Rectangle", "Scene", "Sphere", "depth_sigma_m",
    "render_bgr", "render_gbuffer", "render_rgbd", "DepthNoiseModel",
    "ArmGeometry", "SimSetup", "StereoRigConfig", "arm_geometry_from_joints", "ball_throw", "checkerboard_lab",
    "eye_in_hand", "planar_target", "sphere_image_truth", "stereo_lab", "stereo_rig", "wall_disc",
]
