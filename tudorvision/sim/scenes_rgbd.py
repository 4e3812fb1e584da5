"""RGB-D scene builders for the virtual TUDOR lab: wall Kinect, planar target, disc sweep, throws, eye-in-hand.

Same conventions as :mod:`tudorvision.sim.scenes`: explicit parameters, a
``numpy.random.Generator`` for what should not matter, a :class:`SimSetup`
with the scene, its cameras and the ground truth in ``meta``. World frame:
z up, floor at z = 0.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .._checks import check_transform, check_vector
from .camera import PinholeCamera, intrinsic_matrix, look_at
from .lighting import AmbientLight, DirectionalLight
from .render import Capsule, Disc, Rectangle, Scene, Sphere
from .scenes import (KINECT_RATE_HZ, SimSetup, arm_at_time, arm_shapes, default_robot_params, lab_room, positive_float,
                     robot_base_shapes, sphere_radius_at_time, to_world, yaw_matrix)

__all__ = ["kinect_camera", "planar_target", "wall_disc", "disc_on_arm", "ballistic", "ball_throw", "eye_in_hand"]


def kinect_camera(T_world_cam, *, width: int = 640, height: int = 480, f_px: float = 525.0,
                  dist=(0.0, 0.0, 0.0, 0.0, 0.0)) -> PinholeCamera:
    """Kinect-like RGB-D camera (colour and registered depth share these intrinsics).

    Examples
    --------
    >>> kinect_camera(np.eye(4)).K[0, 0]
    np.float64(525.0)
    """
    return PinholeCamera(K=intrinsic_matrix(f_px * width / 640.0, (width - 1) / 2, (height - 1) / 2),
                         dist=np.asarray(dist, float), width=width, height=height, T_world_cam=T_world_cam)


def _room_for_rgbd(rng, *, size_m, center_xy, keepout_xy, keepout_radius_m, n_clutter, n_distractors, region_y):
    return lab_room(rng, size_m=size_m, center_xy=center_xy, keepout_xy=keepout_xy,
                    keepout_radius_m=keepout_radius_m, n_clutter=n_clutter, n_distractors=n_distractors,
                    clutter_region_y=region_y)


def planar_target(distance_m: float, rng: np.random.Generator, *, width: int = 640, height: int = 480,
                  target_size_m=(1.2, 0.9), textured: bool = True, square_m: float = 0.1) -> SimSetup:
    """Planar target perpendicular to the optical axis at ``distance_m`` (depth-noise calibration).

    The camera sits at world (0, 0, 1.2) looking along +y; the target is
    centred on the optical axis. The back wall is beyond the Kinect range.

    Parameters
    ----------
    distance_m : float
        Distance of the target from the camera along the optical axis, metres (> 0).
    rng : numpy.random.Generator
        Randomises lighting and clutter.
    width, height : int
        Image size, pixels.
    target_size_m : (float, float)
        Target width and height, metres.
    textured : bool
        Checker texture (``square_m`` squares) instead of a plain grey target.
    square_m : float
        Checker square size, metres.

    Returns
    -------
    SimSetup
        ``cameras = {"rgbd"}``; ``meta``: ``target_id``, ``distance_m``,
        ``target_corners_world`` (4, 3), ``rate_hz``.

    Raises
    ------
    ValueError
        If ``distance_m`` is not positive or ``target_size_m`` is not two values.
    """
    if not distance_m > 0:
        raise ValueError(f"distance_m: expected > 0, got {distance_m!r}")
    eye = np.array([0.0, 0.0, 1.2])
    cam = kinect_camera(look_at(eye, eye + [0, 1, 0], K=np.eye(3)).T_world_cam, width=width, height=height)
    ts = check_vector(target_size_m, "target_size_m", 2)
    board = Rectangle(center=eye + [0, distance_m, 0], axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=ts / 2,
                      checker_square_m=square_m if textured else None, color_rgb=(0.85, 0.85, 0.85),
                      color2_rgb=(0.08, 0.08, 0.08), name="target")
    shapes, lights = _room_for_rgbd(rng, size_m=(8.0, 2 * (distance_m + 8.0), 3.0), center_xy=(0.0, 0.0),
                                    keepout_xy=(0.0, distance_m / 2), keepout_radius_m=distance_m / 2 + 1.0,
                                    n_clutter=4, n_distractors=2, region_y=(-1.0, distance_m + 6.0))
    scene = Scene(static=[board] + shapes, lights=lights)
    return SimSetup(scene=scene, cameras={"rgbd": cam},
                    meta={"target_id": 1, "distance_m": float(distance_m), "target_corners_world": board.corners(),
                          "rate_hz": KINECT_RATE_HZ})


def wall_disc(disc_center_base, rng: np.random.Generator, *, T_world_base=np.eye(4), arm=None,
              disc_radius_m: float = 0.075, camera_standoff_m: float = 3.5, camera_height_m: float = 1.6,
              draw_spheres: bool = False,
              width: int = 640, height: int = 480, t0: float = 0.0) -> SimSetup:
    """Wall-mounted RGB-D camera facing the robot, a disc in the catching net (base calibration sweep).

    Parameters
    ----------
    disc_center_base : array_like, shape (3,), or callable t -> (3,)
        Disc centre in the base frame (the net at the end effector), metres.
    rng : numpy.random.Generator
        Randomises lighting and clutter.
    T_world_base : array_like, shape (4, 4)
        Robot base pose in the world (floor at world z = 0).
    arm : ArmGeometry or callable t -> ArmGeometry, optional
        Drawn as in :func:`stereo_lab`; the tracking spheres only with
        ``draw_spheres`` (the net holds the disc, as in the seed's set-up).
    disc_radius_m : float
        7.5 cm: a 15 cm disc in the 18 cm net.
    camera_standoff_m : float
        Horizontal distance of the camera in front of the base (base −y), metres.
    camera_height_m : float
        World height of the camera, metres.
    draw_spheres : bool
        Also draw the arm's tracking spheres.
    width, height : int
        Image size, pixels.
    t0 : float
        A time at which ``disc_center_base`` and ``arm`` are defined (used
        once to list object names).

    Returns
    -------
    SimSetup
        ``cameras = {"rgbd"}``; ``meta``: ``object_ids`` (``"disc"``),
        ``T_world_base``, ``disc_center_world(t)`` (a function), ``rate_hz``.

    Raises
    ------
    ValueError
        If ``T_world_base`` is not a rigid transform, ``disc_radius_m`` is not
        positive or ``arm`` has the wrong type.

    Notes
    -----
    The camera is ``camera_standoff_m`` in front of the base (base −y) at
    world height ``camera_height_m``, looking at the point 0.6 m above the base.
    The disc faces the camera.
    """
    T = check_transform(T_world_base, "T_world_base")
    radius = positive_float(disc_radius_m, "disc_radius_m")
    disc_fn = disc_center_base if callable(disc_center_base) else (
        lambda t, c=check_vector(disc_center_base, "disc_center_base", 3): c)
    eye = to_world(T, np.array([0.0, -camera_standoff_m, 0.0]))
    eye[2] = camera_height_m
    cam = kinect_camera(look_at(eye, to_world(T, np.array([0.0, 0.0, 0.6])), K=np.eye(3)).T_world_cam,
                        width=width, height=height)
    shapes, lights = _room_for_rgbd(rng, size_m=(8.0, 2 * camera_standoff_m + 2.0, 3.0), center_xy=T[:2, 3],
                                    keepout_xy=T[:2, 3], keepout_radius_m=1.4, n_clutter=6, n_distractors=2,
                                    region_y=(T[1, 3] - 0.5, T[1, 3] + camera_standoff_m))
    shapes += robot_base_shapes(T, default_robot_params().link1_height_m)
    arm_at = arm_at_time(arm)
    sphere_r = sphere_radius_at_time(None)

    def disc_world(t):
        return to_world(T, check_vector(disc_fn(t), "disc_center_base", 3))

    def dynamic(t):
        c = disc_world(t)
        out = [Disc(center=c, normal=eye - c, radius=radius, color_rgb=(0.9, 0.85, 0.2), name="disc")]
        if arm_at is not None:
            out += arm_shapes(arm_at(t), T, sphere_radius_m=sphere_r, spheres=draw_spheres)
        return out

    scene = Scene(static=shapes, lights=lights, dynamic=dynamic)
    return SimSetup(scene=scene, cameras={"rgbd": cam},
                    meta={"object_ids": scene.object_ids(t0), "T_world_base": T, "disc_center_world": disc_world,
                          "disc_radius_m": radius, "rate_hz": KINECT_RATE_HZ})


def _ring_and_arm(arm, T_world_base, T_base_disc, disc_radius_m, ring_width_m):
    """Arm capsules with link 3 ending on a flat net ring just behind the disc, world frame."""
    T = T_world_base
    c = T_base_disc[:3, 3]
    n = T_base_disc[:3, 2]
    shapes = [s for s in arm_shapes(arm, T, sphere_radius_m=0.01, spheres=False)]
    r_ring = disc_radius_m + ring_width_m
    pts3 = arm.link_points_base[-1]
    last = f"link3_{len(pts3) - 2}"
    toward = pts3[-2] - c                                  # from the disc toward the elbow, in the disc plane
    toward = toward - (toward @ n) * n
    toward /= max(np.linalg.norm(toward), 1e-12)
    attach = c + (r_ring - 0.005) * toward
    out = []
    for sh in shapes:
        if sh.name == last:
            sh = Capsule(p0=sh.p0, p1=to_world(T, attach), radius=sh.radius, color_rgb=sh.color_rgb, name=last)
        out.append(sh)
    # the ring 4 mm behind the disc: in depth one surface with the disc and the link's end
    out.append(Disc(center=to_world(T, c - 0.004 * n), normal=T[:3, :3] @ n, radius=r_ring,
                    color_rgb=(0.2, 0.2, 0.22), name="ring"))
    return out


def disc_on_arm(T_base_disc_at, arm_at, rng: np.random.Generator, *, T_world_base=np.eye(4),
                disc_radius_m: float = 0.09, ring_width_m: float = 0.03,
                camera_distance_m: float = 5.0, camera_height_m: float = 1.6, camera_azimuth_rad: float = 0.0,
                camera_roll_rad: float = 0.0, aim_offset_m=(0.0, 0.0, 0.0), background: str = "invalid",
                near_gap_m: float = 0.3, width: int = 640, height: int = 480, t0: float = 0.0) -> SimSetup:
    """Wall RGB-D camera and the calibration disc in a net ring at the end of the arm's thin links.

    The disc (radius ``disc_radius_m``) sits in a flat net ring (``ring_width_m``
    wide, 4 mm behind it); link 3 ends on the ring, so in depth the disc, the
    ring and the link are one connected surface.
    The disc's pose follows the end effector (its normal is not made to face
    the camera).

    Parameters
    ----------
    T_base_disc_at : callable t -> ndarray, shape (4, 4)
        Disc pose in the base frame at time ``t``: origin at the disc centre,
        z axis along the disc normal.
    arm_at : callable t -> ArmGeometry
        The arm's links in the base frame (drawn without tracking spheres).
    rng : numpy.random.Generator
        Randomises lighting and clutter.
    T_world_base : array_like, shape (4, 4)
        Robot base pose in the world (floor at world z = 0).
    disc_radius_m, ring_width_m : float
        Disc radius and width of the ring around it, metres.
    camera_distance_m : float
        Distance from the camera to the joint-2 axis point above the base, metres.
    camera_height_m : float
        World height of the camera, metres.
    camera_azimuth_rad : float
        Camera direction about the base z axis, 0 = straight in front (base -y).
    camera_roll_rad : float
        Roll of the camera about its optical axis, rad.
    aim_offset_m : array_like, shape (3,)
        The optical axis passes this far (world) from the joint-2 axis point.
    background : {"invalid", "near"}
        ``"invalid"``: the room's back wall lies beyond the sensor's range;
        ``"near"``: a wall ``near_gap_m`` behind the arm plane (base +y).
    near_gap_m : float
        Gap between the arm plane and the near wall, metres.
    width, height : int
        Image size, pixels.
    t0 : float
        A time at which the callables are defined (object names are listed once).

    Returns
    -------
    SimSetup
        ``cameras = {"rgbd"}``; ``meta``: ``object_ids``, ``T_world_base``,
        ``T_base_cam`` (true camera pose in the base frame), ``disc_radius_m``,
        ``background``, ``rate_hz``.

    Raises
    ------
    ValueError
        On a bad transform, a non-positive radius or distance, an unknown
        ``background`` or a camera distance shorter than its height offset.
    """
    T = check_transform(T_world_base, "T_world_base")
    radius = positive_float(disc_radius_m, "disc_radius_m")
    ring_w = positive_float(ring_width_m, "ring_width_m")
    dist = positive_float(camera_distance_m, "camera_distance_m")
    if background not in ("invalid", "near"):
        raise ValueError(f"background: expected 'invalid' or 'near', got {background!r}")
    h1 = default_robot_params().link1_height_m
    pivot = to_world(T, np.array([0.0, 0.0, h1]))
    dz = camera_height_m - pivot[2]
    if dist <= abs(dz):
        raise ValueError(f"camera_distance_m: {dist} m is shorter than the camera's height offset {abs(dz):.2f} m")
    horiz = np.sqrt(dist ** 2 - dz ** 2)
    eye = to_world(T, np.array([-horiz * np.sin(camera_azimuth_rad), -horiz * np.cos(camera_azimuth_rad), 0.0]))
    eye[2] = camera_height_m
    T_wc = look_at(eye, pivot + check_vector(aim_offset_m, "aim_offset_m", 3), K=np.eye(3)).T_world_cam.copy()
    c, s = np.cos(camera_roll_rad), np.sin(camera_roll_rad)
    T_wc[:3, :3] = T_wc[:3, :3] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    cam = kinect_camera(T_wc, width=width, height=height)
    shapes, lights = _room_for_rgbd(rng, size_m=(8.0, 2 * horiz + 4.0, 3.0), center_xy=T[:2, 3],
                                    keepout_xy=T[:2, 3], keepout_radius_m=1.4, n_clutter=6, n_distractors=2,
                                    region_y=(T[1, 3] - 0.5, T[1, 3] + horiz))
    shapes += robot_base_shapes(T, h1)
    if background == "near":
        shapes.append(Rectangle(center=to_world(T, np.array([0.0, near_gap_m, 1.4])), axis_u=T[:3, 0],
                                axis_v=T[:3, 2], half_size=(3.0, 1.4), color_rgb=(0.7, 0.7, 0.68), name="near_wall"))

    def dynamic(t):
        Tbd = np.asarray(T_base_disc_at(t), float)
        c_w = to_world(T, Tbd[:3, 3])
        out = [Disc(center=c_w, normal=T[:3, :3] @ Tbd[:3, 2], radius=radius, color_rgb=(0.9, 0.85, 0.2),
                    name="disc")]
        return out + _ring_and_arm(arm_at(t), T, Tbd, radius, ring_w)

    scene = Scene(static=shapes, lights=lights, dynamic=dynamic)
    T_base_cam = np.linalg.inv(T) @ T_wc
    return SimSetup(scene=scene, cameras={"rgbd": cam},
                    meta={"object_ids": scene.object_ids(t0), "T_world_base": T, "T_base_cam": T_base_cam,
                          "disc_radius_m": radius, "background": background, "rate_hz": KINECT_RATE_HZ})


def ballistic(p0_world, v0_world, *, t0: float = 0.0, gravity_m_s2: float = 9.81) -> Callable[[float], np.ndarray]:
    """Drag-free flight ``p(t) = p0 + v0 (t - t0) - g/2 (t - t0)^2 e_z`` (world, m).

    Examples
    --------
    >>> ballistic([0, 0, 1], [1, 0, 0])(1.0).round(3).tolist()
    [1.0, 0.0, -3.905]
    """
    p0 = check_vector(p0_world, "p0_world", 3)
    v0 = check_vector(v0_world, "v0_world", 3)
    g = np.array([0.0, 0.0, -gravity_m_s2])

    def at(t):
        dt = t - t0
        return p0 + v0 * dt + 0.5 * g * dt * dt
    return at


def ball_throw(ball_center_world: Callable[[float], np.ndarray], rng: np.random.Generator, *,
               T_world_base=np.eye(4), arm=None, ball_radius_m: float = 0.045,
               camera_position_world=(0.0, -6.8, 2.0), width: int = 640, height: int = 480,
               t0: float = 0.0) -> SimSetup:
    """RGB-D camera on the wall behind the thrower, looking at the robot; a 9 cm ball in flight.

    The ball is the only moving object within 4.5 m of the sensor (the arm,
    if drawn, stands about 6.8 m away). ``ball_center_world(t)`` gives the
    ball centre (see :func:`ballistic`).

    Parameters
    ----------
    ball_center_world : callable t -> ndarray, shape (3,)
        Ball centre at time ``t`` (s), metres, world frame.
    rng : numpy.random.Generator
        Randomises lighting, clutter and the ball colour.
    T_world_base : array_like, shape (4, 4)
        Robot base pose in the world (floor at world z = 0).
    arm : ArmGeometry or callable t -> ArmGeometry, optional
        Drawn as in :func:`stereo_lab`; None draws no arm.
    ball_radius_m : float
        Ball radius, metres (> 0).
    camera_position_world : array_like, shape (3,)
        Camera position, metres, world frame; it looks at the point 1 m above the base.
    width, height : int
        Image size, pixels.
    t0 : float
        A time at which the ball and ``arm`` are defined (used once to list
        object names).

    Returns
    -------
    SimSetup
        ``cameras = {"rgbd"}``; ``meta``: ``object_ids`` (``"ball"``),
        ``ball_center_world`` (the function), ``ball_radius_m``, ``T_world_base``, ``rate_hz``.

    Raises
    ------
    ValueError
        If ``ball_center_world`` is not callable, ``T_world_base`` is not a
        rigid transform or ``ball_radius_m`` is not positive.
    """
    if not callable(ball_center_world):
        raise ValueError("ball_center_world: expected a callable t -> (3,) centre")
    T = check_transform(T_world_base, "T_world_base")
    r = positive_float(ball_radius_m, "ball_radius_m")
    eye = check_vector(camera_position_world, "camera_position_world", 3)
    cam = kinect_camera(look_at(eye, to_world(T, np.array([0.0, 0.0, 1.0])), K=np.eye(3)).T_world_cam,
                        width=width, height=height)
    span = abs(eye[1] - T[1, 3])
    shapes, lights = _room_for_rgbd(rng, size_m=(8.0, span + 3.0, 3.2), center_xy=(T[0, 3], (eye[1] + T[1, 3]) / 2),
                                    keepout_xy=T[:2, 3], keepout_radius_m=1.4, n_clutter=8, n_distractors=2,
                                    region_y=(T[1, 3] - 1.0, T[1, 3] + 1.5))
    shapes += robot_base_shapes(T, default_robot_params().link1_height_m)
    ball_rgb = rng.choice([(0.9, 0.8, 0.1), (0.95, 0.45, 0.05), (0.2, 0.5, 0.9)])
    arm_at = arm_at_time(arm)
    sphere_r = sphere_radius_at_time(None)

    def dynamic(t):
        out = [Sphere(center=ball_center_world(t), radius=r, color_rgb=ball_rgb, name="ball")]
        if arm_at is not None:
            out += arm_shapes(arm_at(t), T, sphere_radius_m=sphere_r)
        return out

    scene = Scene(static=shapes, lights=lights, dynamic=dynamic)
    return SimSetup(scene=scene, cameras={"rgbd": cam},
                    meta={"object_ids": scene.object_ids(t0), "ball_center_world": ball_center_world,
                          "ball_radius_m": r, "T_world_base": T, "rate_hz": KINECT_RATE_HZ})


def eye_in_hand(T_world_cam, rng: np.random.Generator, *, square_center_world=(0.6, 0.0, 0.0),
                square_size_m: float = 0.1, square_yaw_rad: float = 0.0, width: int = 640,
                height: int = 480) -> SimSetup:
    """Eye-in-hand RGB-D view of a black square on white ground (visual servoing).

    The ground is the plane z = 0 (white, slightly randomised); the square
    lies 1 mm above it. For a moving camera re-pose the returned camera with
    :func:`tudorvision.sim.camera.with_pose` and render the same scene.

    Parameters
    ----------
    T_world_cam : array_like, shape (4, 4)
        Camera pose: ``p_world = T_world_cam @ p_cam`` (optical frame x right,
        y down, z forward).
    rng : numpy.random.Generator
        Randomises the ground shade and the lighting.
    square_center_world : array_like, shape (3,)
        Square centre on the ground, metres, world frame.
    square_size_m : float
        Square edge length, metres (> 0).
    square_yaw_rad : float
        Rotation of the square about world z, rad.
    width, height : int
        Image size, pixels.

    Returns
    -------
    SimSetup
        ``cameras = {"rgbd"}``; ``meta``: ``object_ids`` (``"square"``),
        ``square_corners_world`` (4, 3), ``rate_hz``.

    Raises
    ------
    ValueError
        If ``square_center_world`` is not three finite values or
        ``square_size_m`` is not positive.
    """
    c = check_vector(square_center_world, "square_center_world", 3)
    s = positive_float(square_size_m, "square_size_m")
    cam = kinect_camera(T_world_cam, width=width, height=height)
    R = yaw_matrix(square_yaw_rad)
    white = rng.uniform(0.8, 0.92)
    ground = Rectangle(center=(c[0], c[1], 0.0), half_size=(3.0, 3.0), color_rgb=np.full(3, white), name="ground")
    square = Rectangle(center=c + [0, 0, 0.001], axis_u=R[:, 0], axis_v=R[:, 1], half_size=(s / 2, s / 2),
                       color_rgb=(0.05, 0.05, 0.05), name="square")
    lights = [AmbientLight(intensity=rng.uniform(0.3, 0.45)),
              DirectionalLight(direction_world=(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), -1.0),
                               intensity=rng.uniform(0.3, 0.5))]
    scene = Scene(static=[ground, square], lights=lights)
    return SimSetup(scene=scene, cameras={"rgbd": cam},
                    meta={"object_ids": scene.object_ids(), "square_corners_world": square.corners(),
                          "rate_hz": KINECT_RATE_HZ})
