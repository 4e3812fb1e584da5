"""Scene builders for the virtual TUDOR lab: rooms, the drawn arm, the stereo rig, checkerboards.

The RGB-D sets (wall Kinect, planar target, disc sweep, throws, eye-in-hand) are in
:mod:`tudorvision.sim.scenes_rgbd`.

Every builder takes explicit parameters and a ``numpy.random.Generator`` that
randomises what should not matter (lighting, clutter positions and colours), so
that nothing downstream is tuned to one picture. Each returns a
:class:`SimSetup`: the :class:`~tudorvision.sim.render.Scene`, its cameras and
a ``meta`` dict with the ground truth needed to write labels (object ids by
name, poses, target geometry).

World frame: z up, floor at z = 0. The arm is never simulated here: its
drawing comes in as :class:`ArmGeometry` (points in the robot base frame),
constant or as a function of time.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .._checks import check_points, check_transform, check_vector
from .camera import PinholeCamera, intrinsic_matrix, look_at, sphere_silhouette_centroid
from .lighting import AmbientLight, DirectionalLight, PointLight, Varying
from .render import Box, Capsule, Cylinder, Rectangle, Scene, Sphere, exposure_times

__all__ = [
    "ArmGeometry", "arm_geometry_from_joints", "arm_shapes", "SimSetup", "StereoRigConfig",
    "stereo_rig", "stereo_lab", "checkerboard_lab", "lab_room", "sphere_image_truth", "KINECT_RATE_HZ",
    "STEREO_RATE_HZ",
]

KINECT_RATE_HZ = 30.0
STEREO_RATE_HZ = 50.0

RED_RGB = (0.75, 0.06, 0.05)
GREEN_RGB = (0.08, 0.55, 0.12)


@dataclass(frozen=True, kw_only=True, eq=False)
class SimSetup:
    """A scene, its cameras by name and ground-truth metadata.

    Attributes
    ----------
    scene : Scene
        Static and dynamic shapes (world frame, metres) and lights.
    cameras : dict of str to PinholeCamera
        Cameras by name (e.g. ``"left"``, ``"right"``, ``"rgbd"``).
    meta : dict
        Ground truth of the set (poses, object ids, rates), documented by
        the function that builds it.
    """

    scene: Scene
    cameras: dict
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True, kw_only=True, eq=False)
class ArmGeometry:
    """What the cameras see of the arm, in the robot base frame (metres).

    Parameters
    ----------
    link_points_base : sequence of ndarray, each shape (N_i, 3), N_i >= 2
        Polylines along the elastic links (joint 2 -> elbow, elbow -> end
        effector), deflection included. Each segment is drawn as a capsule.
    sphere_centers_base : dict
        ``{"red": (3,), "green": (3,)}`` tracking-sphere centres.
    """

    link_points_base: tuple
    sphere_centers_base: dict

    def __post_init__(self):
        links = tuple(check_points(p, f"link_points_base[{i}]") for i, p in enumerate(self.link_points_base))
        for i, p in enumerate(links):
            if len(p) < 2:
                raise ValueError(f"link_points_base[{i}]: expected at least 2 points, got {len(p)}")
        object.__setattr__(self, "link_points_base", links)
        if set(self.sphere_centers_base) != {"red", "green"}:
            raise ValueError("sphere_centers_base: expected keys 'red' and 'green', "
                             f"got {sorted(self.sphere_centers_base)}")
        object.__setattr__(self, "sphere_centers_base", {
            k: check_vector(v, f"sphere_centers_base[{k!r}]", 3) for k, v in self.sphere_centers_base.items()})


def positive_float(v, name: str) -> float:
    """``float(v)`` if it is > 0, else a ``ValueError`` naming ``name``."""
    if not v > 0:
        raise ValueError(f"{name}: expected > 0, got {v!r}")
    return float(v)


def arm_geometry_from_joints(theta, params=None, *, n_points: int = 2) -> ArmGeometry:
    """Rigid-equivalent arm drawing (straight links) from joint angles, for scenes and tests.

    The elastic plant supplies deflected polylines instead; this uses
    :mod:`tudorvision.robot` rigid kinematics only.

    Examples
    --------
    >>> g = arm_geometry_from_joints([0.0, np.pi / 2, 0.0])
    >>> np.round(g.link_points_base[1][-1], 3).tolist()
    [0.0, 0.0, 1.19]
    """
    from ..robot import fk_ee, fk_spheres
    p = params or default_robot_params()
    th = check_vector(theta, "theta", 3)
    joint2 = np.array([0.0, 0.0, p.link1_height_m])
    c1, s1 = np.cos(th[0]), np.sin(th[0])
    elbow = joint2 + p.link2_length_m * np.array([np.cos(th[1]) * c1, np.cos(th[1]) * s1, np.sin(th[1])])
    ee = fk_ee(th, p)
    s = np.linspace(0.0, 1.0, max(int(n_points), 2))[:, None]
    links = (joint2 + s * (elbow - joint2), elbow + s * (ee - elbow))
    return ArmGeometry(link_points_base=links, sphere_centers_base=fk_spheres(th, p))


@functools.lru_cache(maxsize=1)
def default_robot_params():
    from ..robot import load_robot_params
    return load_robot_params()


def to_world(T, p):
    return p @ T[:3, :3].T + T[:3, 3]


def arm_shapes(arm: ArmGeometry, T_world_base, *, sphere_radius_m: float, link_radius_m: float = 0.008,
               red_rgb=RED_RGB, green_rgb=GREEN_RGB, spheres: bool = True) -> list:
    """Shapes of the moving arm in the world: the two spheres, actuators 2 and 3, link capsules, end-effector bar.

    Names: ``"red_sphere"``, ``"green_sphere"``, ``"actuator2"``, ``"actuator3"``,
    ``"link{k}_{i}"`` (link k = 2, 3; segment i) and ``"ee_bar"``. The order is
    fixed for a given number of link points. ``spheres=False`` leaves out the
    tracking spheres and their bar (the catching net replaces them).
    """
    T = check_transform(T_world_base, "T_world_base")
    red = to_world(T, arm.sphere_centers_base["red"])
    green = to_world(T, arm.sphere_centers_base["green"])
    grey, dark = (0.55, 0.56, 0.58), (0.12, 0.12, 0.13)
    shapes = [Sphere(center=red, radius=sphere_radius_m, color_rgb=red_rgb, name="red_sphere"),
              Sphere(center=green, radius=sphere_radius_m, color_rgb=green_rgb, name="green_sphere")] if spheres else []
    links = [to_world(T, p) for p in arm.link_points_base]
    shapes.append(Sphere(center=links[0][0], radius=0.05, color_rgb=dark, name="actuator2"))
    if len(links) > 1:
        shapes.append(Sphere(center=links[1][0], radius=0.035, color_rgb=dark, name="actuator3"))
    for k, pts in enumerate(links):
        for i in range(len(pts) - 1):  # a zero-length segment is a sphere: the shape count never changes
            shapes.append(Capsule(p0=pts[i], p1=pts[i + 1], radius=link_radius_m, color_rgb=grey,
                                  name=f"link{k + 2}_{i}"))
    if spheres:
        shapes.append(Capsule(p0=red, p1=green, radius=0.6 * link_radius_m, color_rgb=dark, name="ee_bar"))
    return shapes


def _rand_color(rng, kind="any"):
    if kind == "reddish":
        return np.clip([rng.uniform(0.45, 0.85), rng.uniform(0.08, 0.35), rng.uniform(0.05, 0.3)], 0, 1)
    if kind == "greenish":
        return np.clip([rng.uniform(0.05, 0.3), rng.uniform(0.4, 0.7), rng.uniform(0.05, 0.35)], 0, 1)
    return rng.uniform(0.15, 0.85, 3)


def lab_room(rng: np.random.Generator, *, size_m=(8.0, 7.0, 3.0), center_xy=(0.0, 0.0), keepout_xy=(0.0, 0.0),
             keepout_radius_m: float = 1.3, n_clutter: int = 8, n_distractors: int = 4,
             clutter_region_y=(-1.0, 3.0), clutter_max_radius_m: float = 2.6):
    """Static lab background and lights: floor, ceiling, four walls, tables, clutter, distractors.

    Parameters
    ----------
    rng : numpy.random.Generator
        Randomises colours, clutter placement and lighting.
    size_m : (3,)
        Room length (x), width (y), height (z).
    keepout_xy, keepout_radius_m
        No clutter within this horizontal radius (the robot's workspace).
    clutter_max_radius_m : float
        Clutter stands at most this far (horizontally) from ``keepout_xy``,
        so that it is in the cameras' view behind and beside the robot.
    n_clutter : int
        Random boxes on the floor and on two tables.
    n_distractors : int
        Reddish and greenish objects (spheres, boxes, posters) alternating.
    clutter_region_y : (2,)
        World-y band for clutter (keep it out of the cameras' line of sight).

    Returns
    -------
    shapes : list
    lights : list
        Ambient, daylight (directional, slowly varying) and ceiling (point) light.
    """
    Lx, Ly, Lz = check_vector(size_m, "size_m", 3)
    cx, cy = check_vector(center_xy, "center_xy", 2)
    kx, ky = check_vector(keepout_xy, "keepout_xy", 2)
    for name, n in (("n_clutter", n_clutter), ("n_distractors", n_distractors)):
        if int(n) != n or n < 0:
            raise ValueError(f"{name}: expected a non-negative integer, got {n!r}")
    floor_a = rng.uniform(0.35, 0.55)
    wall = rng.uniform(0.6, 0.8) * np.array([1.0, rng.uniform(0.95, 1.0), rng.uniform(0.85, 0.95)])
    shapes = [
        Rectangle(center=(cx, cy, 0.0), half_size=(Lx / 2, Ly / 2), checker_square_m=0.6,
                  color_rgb=np.full(3, floor_a), color2_rgb=np.full(3, floor_a * 0.85), name="floor"),
        Rectangle(center=(cx, cy, Lz), half_size=(Lx / 2, Ly / 2), color_rgb=(0.8, 0.8, 0.8), name="ceiling"),
        Rectangle(center=(cx, cy + Ly / 2, Lz / 2), axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=(Lx / 2, Lz / 2),
                  color_rgb=wall, name="wall_back"),
        Rectangle(center=(cx, cy - Ly / 2, Lz / 2), axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=(Lx / 2, Lz / 2),
                  color_rgb=wall * 0.97, name="wall_front"),
        Rectangle(center=(cx - Lx / 2, cy, Lz / 2), axis_u=(0, 1, 0), axis_v=(0, 0, 1), half_size=(Ly / 2, Lz / 2),
                  color_rgb=wall * 0.95, name="wall_left"),
        Rectangle(center=(cx + Lx / 2, cy, Lz / 2), axis_u=(0, 1, 0), axis_v=(0, 0, 1), half_size=(Ly / 2, Lz / 2),
                  color_rgb=wall * 0.93, name="wall_right"),
    ]

    def free_spot(half, tries=100):
        r_lo = keepout_radius_m + half
        r_hi = max(clutter_max_radius_m, r_lo + 0.2)
        for _ in range(tries):
            r = np.sqrt(rng.uniform(r_lo ** 2, r_hi ** 2))
            a = rng.uniform(0, 2 * np.pi)
            x, y = kx + r * np.cos(a), ky + r * np.sin(a)
            if (abs(x - cx) < Lx / 2 - half - 0.1 and abs(y - cy) < Ly / 2 - half - 0.1
                    and clutter_region_y[0] <= y <= clutter_region_y[1]):
                return x, y
        return None

    tables = []
    for k in range(2):
        spot = free_spot(0.6)
        if spot is None:
            continue
        hx, hy, h = rng.uniform(0.5, 0.8), rng.uniform(0.3, 0.45), 0.75
        yaw = rng.uniform(-0.3, 0.3)
        R = yaw_matrix(yaw)
        shapes.append(Box(center=(spot[0], spot[1], h - 0.02), half_extents=(hx, hy, 0.02), R_world_box=R,
                          color_rgb=_rand_color(rng) * 0.6 + 0.3, name=f"table{k}"))
        for sx in (-1, 1):
            for sy in (-1, 1):
                leg = np.array(spot) + R[:2, :2] @ [sx * (hx - 0.05), sy * (hy - 0.05)]
                shapes.append(Box(center=(leg[0], leg[1], (h - 0.04) / 2), half_extents=(0.025, 0.025, (h - 0.04) / 2),
                                  R_world_box=R, color_rgb=(0.25, 0.25, 0.27), name=f"table{k}_leg"))
        tables.append((spot, hx, hy, h, R))

    def clutter_pose(half):
        if tables and rng.uniform() < 0.5:
            spot, hx, hy, h, R = tables[rng.integers(len(tables))]
            local = [rng.uniform(-hx + half, hx - half), rng.uniform(-hy + half, hy - half)]
            xy = np.array(spot) + R[:2, :2] @ local
            return xy, h
        spot = free_spot(half)
        return (None, 0.0) if spot is None else (np.array(spot), 0.0)

    for k in range(int(n_clutter)):
        he = rng.uniform(0.05, 0.25, 3)
        xy, z0 = clutter_pose(he[:2].max())
        if xy is None:
            continue
        shapes.append(Box(center=(xy[0], xy[1], z0 + he[2]), half_extents=he, R_world_box=yaw_matrix(rng.uniform(0, np.pi)),
                          color_rgb=_rand_color(rng), name=f"clutter{k}"))
    for k in range(int(n_distractors)):
        kind = "reddish" if k % 2 == 0 else "greenish"
        col = _rand_color(rng, kind)
        form = k // 2 % 3
        if form == 2:   # a poster on the back wall
            shapes.append(Rectangle(center=(rng.uniform(cx - Lx / 3, cx + Lx / 3), cy + Ly / 2 - 0.01,
                                            rng.uniform(1.2, 2.0)),
                                    axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=rng.uniform(0.15, 0.4, 2),
                                    color_rgb=col, name=f"distractor{k}"))
            continue
        r = rng.uniform(0.03, 0.12)
        xy, z0 = clutter_pose(r)
        if xy is None:
            continue
        if form == 0:
            shapes.append(Sphere(center=(xy[0], xy[1], z0 + r), radius=r, color_rgb=col, name=f"distractor{k}"))
        else:
            shapes.append(Box(center=(xy[0], xy[1], z0 + r), half_extents=(r, 1.5 * r, r),
                              R_world_box=yaw_matrix(rng.uniform(0, np.pi)), color_rgb=col, name=f"distractor{k}"))
    lights = _lab_lights(rng, ceiling_xy=(kx, ky), ceiling_z=Lz - 0.05)
    return shapes, lights


def yaw_matrix(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _lab_lights(rng, *, ceiling_xy, ceiling_z):
    az = rng.uniform(0, 2 * np.pi)
    elev = rng.uniform(0.4, 1.0)
    sun_dir = -np.array([np.cos(az) * np.cos(elev), np.sin(az) * np.cos(elev), np.sin(elev)])
    return [
        AmbientLight(intensity=rng.uniform(0.18, 0.3), color_rgb=(1.0, 1.0, 1.0)),
        DirectionalLight(direction_world=sun_dir, color_rgb=(0.95, 0.98, 1.05),
                         intensity=Varying(base=rng.uniform(0.25, 0.5), rel_amplitude=rng.uniform(0.1, 0.35),
                                           period_s=rng.uniform(20.0, 120.0), phase_rad=rng.uniform(0, 2 * np.pi))),
        PointLight(position_world=(ceiling_xy[0] + rng.uniform(-0.5, 0.5), ceiling_xy[1] + rng.uniform(-0.5, 0.5),
                                   ceiling_z),
                   color_rgb=(1.05, 0.97, 0.85),
                   intensity=Varying(base=rng.uniform(2.5, 4.0), rel_amplitude=rng.uniform(0.0, 0.1),
                                     period_s=rng.uniform(5.0, 30.0), phase_rad=rng.uniform(0, 2 * np.pi))),
    ]


@dataclass(frozen=True, kw_only=True)
class StereoRigConfig:
    """Geometry of the convergent ceiling stereo rig (BRIEF "External stereo tracking").

    The baseline midpoint sits ``standoff_m`` in front of the robot base
    (along base −y, horizontally) at world height ``height_m``; the cameras
    are ``baseline_m`` apart along base x and look at ``aim_base`` (a point in
    the base frame, by default above the base so that the workspace is in
    view). Left camera at base −x.

    Attributes
    ----------
    baseline_m : float
        Distance between the two optical centres, metres (> 0).
    height_m : float
        World height of the cameras, metres (> 0).
    standoff_m : float
        Horizontal distance of the baseline midpoint in front of the base
        (along base −y), metres.
    aim_base : tuple of 3 floats
        Point both cameras look at, metres, base frame.
    f_px : float
        Focal length, pixels (> 0).
    width, height : int
        Image size, pixels.
    dist : tuple of 5 floats
        Brown–Conrady coefficients ``(k1, k2, p1, p2, k3)`` of both cameras.
    pose_jitter_m : float
        Largest random offset of each camera position when jittered, metres.
    aim_jitter_m : float
        Largest random offset of each aim point when jittered, metres.

    Raises
    ------
    ValueError
        If ``baseline_m``, ``height_m`` or ``f_px`` is not positive.
    """

    baseline_m: float = 3.0
    height_m: float = 2.7
    standoff_m: float = 2.0
    aim_base: tuple = (0.0, 0.0, 0.5)
    f_px: float = 700.0
    width: int = 640
    height: int = 480
    dist: tuple = (-0.12, 0.05, 3e-4, -2e-4, 0.0)
    pose_jitter_m: float = 0.02
    aim_jitter_m: float = 0.05

    def __post_init__(self):
        for name in ("baseline_m", "height_m", "f_px"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: expected > 0, got {getattr(self, name)!r}")


def stereo_rig(T_world_base, *, config: StereoRigConfig = StereoRigConfig(),
               rng: np.random.Generator | None = None) -> tuple[PinholeCamera, PinholeCamera]:
    """Left and right cameras of the convergent ceiling rig.

    With ``rng`` the positions and aim points are jittered by up to
    ``pose_jitter_m`` / ``aim_jitter_m`` (the true poses are in the returned
    cameras; calibration must recover them).

    Parameters
    ----------
    T_world_base : array_like, shape (4, 4)
        Robot base pose in the world: ``p_world = T_world_base @ p_base``.
    config : StereoRigConfig, optional
        Rig geometry and intrinsics.
    rng : numpy.random.Generator, optional
        Jitters the camera positions and aim points; None: nominal poses.

    Returns
    -------
    left, right : PinholeCamera
        The two cameras (left at base −x), poses in the world frame.

    Raises
    ------
    ValueError
        If ``T_world_base`` is not a rigid transform.

    Examples
    --------
    >>> left, right = stereo_rig(np.eye(4))
    >>> round(float(np.linalg.norm(left.T_world_cam[:3, 3] - right.T_world_cam[:3, 3])), 3)
    3.0
    """
    T = check_transform(T_world_base, "T_world_base")
    c = config
    K = intrinsic_matrix(c.f_px, (c.width - 1) / 2, (c.height - 1) / 2)
    aim = to_world(T, check_vector(c.aim_base, "aim_base", 3))
    cams = []
    for side in (-1.0, 1.0):
        eye = to_world(T, np.array([side * c.baseline_m / 2, -c.standoff_m, 0.0]))
        eye[2] = c.height_m
        target = aim.copy()
        if rng is not None:
            eye = eye + rng.uniform(-c.pose_jitter_m, c.pose_jitter_m, 3)
            target = target + rng.uniform(-c.aim_jitter_m, c.aim_jitter_m, 3)
        cams.append(look_at(eye, target, K=K, dist=np.asarray(c.dist), width=c.width, height=c.height))
    return cams[0], cams[1]


def arm_at_time(arm):
    if arm is None:
        return None
    if isinstance(arm, ArmGeometry):
        return lambda t: arm
    if callable(arm):
        return arm
    raise ValueError("arm: expected an ArmGeometry, a callable t -> ArmGeometry or None")


def sphere_radius_at_time(sphere_radius_m):
    if sphere_radius_m is None:
        return default_robot_params().sphere_radius_m
    if not sphere_radius_m > 0:
        raise ValueError(f"sphere_radius_m: expected > 0, got {sphere_radius_m!r}")
    return float(sphere_radius_m)


def robot_base_shapes(T, link1_height_m):
    base = to_world(T, np.zeros(3))
    top = to_world(T, np.array([0.0, 0.0, link1_height_m - 0.05]))
    return [Cylinder(p0=base, p1=top, radius=0.09, color_rgb=(0.35, 0.36, 0.4), name="robot_base"),
            Cylinder(p0=base, p1=to_world(T, np.array([0.0, 0.0, 0.02])), radius=0.2, color_rgb=(0.3, 0.3, 0.3),
                     name="base_plate")]


def stereo_lab(rng: np.random.Generator, *, arm=None, T_world_base=np.eye(4),
               rig: StereoRigConfig = StereoRigConfig(), sphere_radius_m: float | None = None,
               link1_height_m: float | None = None, n_clutter: int = 8, n_distractors: int = 4,
               jitter_rig: bool = False, t0: float = 0.0) -> SimSetup:
    """The external stereo tracking set: ceiling rig, lab clutter, robot, red and green spheres.

    Parameters
    ----------
    rng : numpy.random.Generator
        Randomises lighting, clutter and (with ``jitter_rig``) the rig.
    arm : ArmGeometry or callable t -> ArmGeometry, optional
        The arm drawing in the base frame, constant or moving with time
        (e.g. ``lambda t: plant_geometry_at(t)``). None draws no arm.
    T_world_base : ndarray, shape (4, 4)
        Robot base pose in the world (floor at world z = 0).
    rig : StereoRigConfig
        Geometry and intrinsics of the ceiling stereo rig.
    sphere_radius_m, link1_height_m : float, optional
        Tracking-sphere radius and base column height, metres; default to
        :func:`tudorvision.robot.load_robot_params`.
    n_clutter : int
        Random boxes on the floor and on two tables.
    n_distractors : int
        Reddish and greenish distractor objects.
    jitter_rig : bool
        Jitter the rig poses with ``rng`` (see :func:`stereo_rig`).
    t0 : float
        A time at which ``arm`` is defined (used once to list object names).

    Returns
    -------
    SimSetup
        ``cameras = {"left", "right"}``; ``meta`` holds ``T_world_base``,
        ``sphere_radius_m``, ``object_ids`` (name -> id; the arm's ids are
        those of the dynamic shapes, e.g. ``"red_sphere"``), ``rate_hz``.

    Raises
    ------
    ValueError
        If ``T_world_base`` is not a rigid transform, ``arm`` has the wrong
        type or ``sphere_radius_m`` is not positive.

    Examples
    --------
    >>> setup = stereo_lab(np.random.default_rng(0), arm=arm_geometry_from_joints([0.0, 0.8, 0.5]))
    >>> sorted(setup.cameras), "red_sphere" in setup.meta["object_ids"]
    (['left', 'right'], True)
    """
    T = check_transform(T_world_base, "T_world_base")
    radius = sphere_radius_at_time(sphere_radius_m)
    if link1_height_m is None:
        link1_height_m = default_robot_params().link1_height_m
    left, right = stereo_rig(T, config=rig, rng=rng if jitter_rig else None)
    base_xy = T[:2, 3]
    shapes, lights = lab_room(rng, center_xy=base_xy + [0.0, 0.0], keepout_xy=base_xy, n_clutter=n_clutter,
                              n_distractors=n_distractors, size_m=(8.0, 7.0, rig.height_m + 0.3),
                              clutter_region_y=(base_xy[1] - 0.8, base_xy[1] + 3.4))
    shapes += robot_base_shapes(T, link1_height_m)
    arm_at = arm_at_time(arm)
    dynamic = None
    if arm_at is not None:
        def dynamic(t):
            return arm_shapes(arm_at(t), T, sphere_radius_m=radius)
    scene = Scene(static=shapes, lights=lights, dynamic=dynamic)
    return SimSetup(scene=scene, cameras={"left": left, "right": right},
                    meta={"T_world_base": T, "sphere_radius_m": radius, "object_ids": scene.object_ids(t0),
                          "rate_hz": STEREO_RATE_HZ})


def checkerboard_lab(T_world_board, rng: np.random.Generator, *, squares=(9, 7), square_m: float = 0.06,
                     border_m: float = 0.04, T_world_base=np.eye(4), rig: StereoRigConfig = StereoRigConfig(),
                     n_clutter: int = 6) -> SimSetup:
    """A checkerboard held in the stereo lab, for calibration image pairs.

    Parameters
    ----------
    T_world_board : ndarray, shape (4, 4), or callable t -> (4, 4)
        Board pose: origin at the board centre, x along the ``squares[0]``
        direction, y along ``squares[1]``, z the board normal. A callable
        makes the board a dynamic shape (e.g. ``lambda t: poses[int(t)]``), so
        a series of poses re-casts only the board, not the lab.
    rng : numpy.random.Generator
        Randomises lighting and clutter.
    squares : (int, int)
        Number of squares; OpenCV's pattern size is ``(squares[0] - 1, squares[1] - 1)``.
    square_m : float
        Square edge length, metres (> 0).
    border_m : float
        White border around the squares, metres.
    T_world_base : array_like, shape (4, 4)
        Robot base pose in the world (places the room and the rig).
    rig : StereoRigConfig
        Geometry and intrinsics of the ceiling stereo rig.
    n_clutter : int
        Random boxes on the floor and on two tables.

    Returns
    -------
    SimSetup
        ``cameras = {"left", "right"}``; ``meta``: ``inner_corners_world``
        (N, 3) in the row-major order of ``Rectangle.inner_corners`` (a
        function of t for a moving board), ``pattern_size``, ``square_m``,
        ``T_world_board``, ``object_ids``.

    Raises
    ------
    ValueError
        If a pose is not a rigid transform, ``square_m`` is not positive or
        ``squares`` is not two integers >= 2.

    Examples
    --------
    >>> Tb = np.eye(4); Tb[:3, 3] = [0.0, 0.0, 1.0]
    >>> cb = checkerboard_lab(Tb, np.random.default_rng(0), squares=(4, 3), square_m=0.1)
    >>> cb.meta["pattern_size"], cb.meta["inner_corners_world"].shape
    ((3, 2), (6, 3))
    """
    T = check_transform(T_world_base, "T_world_base")
    sq = positive_float(square_m, "square_m")
    n = np.asarray(squares)
    if n.shape != (2,) or np.any(n < 2):
        raise ValueError(f"squares: expected two integers >= 2, got {squares!r}")

    def board_at(Tb):
        Tb = check_transform(Tb, "T_world_board")
        return Rectangle(center=Tb[:3, 3], axis_u=Tb[:3, 0], axis_v=Tb[:3, 1],
                         half_size=(n[0] * sq / 2 + border_m, n[1] * sq / 2 + border_m), checker_square_m=sq,
                         checker_squares=tuple(int(k) for k in n), color_rgb=(0.88, 0.88, 0.86),
                         color2_rgb=(0.04, 0.04, 0.04), name="board")

    left, right = stereo_rig(T, config=rig)
    shapes, lights = lab_room(rng, center_xy=T[:2, 3], keepout_xy=T[:2, 3], n_clutter=n_clutter,
                              size_m=(8.0, 7.0, rig.height_m + 0.3), clutter_region_y=(T[1, 3] - 0.8, T[1, 3] + 3.4))
    meta = {"pattern_size": (int(n[0]) - 1, int(n[1]) - 1), "square_m": sq}
    if callable(T_world_board):
        scene = Scene(static=shapes, lights=lights, dynamic=lambda t: [board_at(T_world_board(t))])
        meta.update(inner_corners_world=lambda t: board_at(T_world_board(t)).inner_corners(),
                    T_world_board=T_world_board, object_ids={"board": len(shapes) + 1})
    else:
        board = board_at(T_world_board)
        scene = Scene(static=[board] + shapes, lights=lights)
        meta.update(inner_corners_world=board.inner_corners(),
                    T_world_board=check_transform(T_world_board, "T_world_board"), object_ids={"board": 1})
    return SimSetup(scene=scene, cameras={"left": left, "right": right}, meta=meta)


def sphere_image_truth(camera: PinholeCamera, center_world_at: Callable[[float], np.ndarray], radius_m: float,
                       t: float, *, exposure_s: float = 0.0, n_subframes: int = 1, line_time_s: float = 0.0,
                       iterations: int = 3, n_radial: int = 16, n_angular: int = 32) -> np.ndarray:
    """Ground-truth image position (pixels) of a moving sphere in a frame starting at ``t``.

    The exact silhouette centroid (:func:`~tudorvision.sim.camera.sphere_silhouette_centroid`)
    averaged over the sub-frame times of :func:`~tudorvision.sim.render.exposure_times`,
    i.e. the first moment of the blurred silhouette. With a rolling shutter
    the sphere is sampled at the read-out time of the row of its own
    centroid, found by fixed-point iteration (exact to first order in the
    image-plane motion during the read-out of the silhouette).

    Parameters
    ----------
    center_world_at : callable
        ``t -> (3,)`` sphere centre in the world (metres).

    Returns
    -------
    ndarray, shape (2,)
        ``(u, v)`` pixels.

    Examples
    --------
    >>> from tudorvision.sim.camera import intrinsic_matrix
    >>> cam = look_at([0, -2, 0], [0, 0, 0], K=intrinsic_matrix(100, 49.5, 49.5), width=100, height=100)
    >>> sphere_image_truth(cam, lambda t: np.array([t, 0.0, 0.0]), 0.1, 0.0, exposure_s=0.2).round(2).tolist()
    [54.51, 49.5]
    """
    row = 0.0
    for _ in range(int(iterations) if line_time_s > 0 else 1):
        times = exposure_times(t + row * line_time_s, exposure_s=exposure_s, n_subframes=n_subframes)
        uv = np.mean([sphere_silhouette_centroid(camera, center_world_at(tt), radius_m, n_radial=n_radial,
                                                 n_angular=n_angular) for tt in times], axis=0)
        row = float(uv[1])
    return uv
