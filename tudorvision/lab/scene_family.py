"""A randomised family of static stereo sphere scenes, for benchmarks over many set-ups instead of one.

Issue 15: perception must hold for spheres of any apparent size, with
highlights, real textures and imperfect cameras. :func:`sample_family`
draws :class:`SceneParams` from a seed; :func:`render_family_scene` renders
one set-up (both cameras) and returns the frames with the ground truth that
only the lab's scorers read.

What varies (uniform unless said):

- sphere radius 15–50 mm (both spheres the same, 0.16 m apart on the end
  effector bar), arm pose (joint angles in the workspace);
- camera distance 1.5–5 m (baseline midpoint to the end effector), baseline
  0.5–1.0 of the distance (at most 3 m), elevation 8–60° (cameras below a
  3.2 m ceiling), azimuth ±35° about the front, focal length 600–1400 px
  (640×480, the lab's mild barrel distortion), aim offset up to ±20 % of the
  field of view;
- glossy spheres: Blinn–Phong specular strength 0–2 (the upper part saturates a
  white spot), exponent 20–200;
- floor and back-wall textures: crops of real photographs
  (``../shared/realdata/rgbd_kinect_room/color/*.png`` and
  ``../shared/realdata/rgbd_tum_desk/*.png`` relative to the repository
  root), procedural noise textures when those files are absent (the
  parameters then say ``texture_source = "procedural"``);
- white balance: red and blue gains 0.8–1.2 (green 1); exposure: sensor gain
  0.6–1.6; sensor noise: full well 3000–12000 e⁻, read noise 5–25 e⁻;
  JPEG quality 60–95 (20 % of set-ups lossless PNG-like, ``None``);
- partial occlusion: in 30 % of set-ups a link-like capsule (8 mm radius)
  crosses in front of one sphere at 0.2–0.9 of its radius from the centre.

Ground truth per camera and sphere: the exact silhouette centroid of the
whole (unoccluded) sphere (:func:`~tudorvision.sim.scenes.sphere_image_truth`),
the apparent radius in pixels, and the 3D centre in the left camera optical
frame (x right, y down, z forward).
"""
from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..sim.camera import PinholeCamera, intrinsic_matrix, look_at
from ..sim.lighting import SensorModel, apply_sensor
from ..sim.render import render_gbuffer, render_radiance
from ..sim.scenes import arm_geometry_from_joints, arm_shapes, lab_room, robot_base_shapes, sphere_image_truth
from ..sim.shapes import Capsule, Scene
from ..sim.specular import specular_radiance
from ..sim.textures import TexturedRectangle, load_texture_crop, procedural_texture

__all__ = ["SceneParams", "FamilyScene", "RANGES", "sample_scene_params", "sample_family", "photo_texture_paths",
           "render_family_scene", "apparent_radius_px"]

SPHERES = ("red", "green")

#: Closed ranges of the uniformly drawn parameters (SI units, pixels for f_px).
RANGES = {
    "sphere_radius_m": (0.015, 0.050),
    "distance_m": (1.5, 5.0),
    "baseline_ratio": (0.5, 1.0),
    "elevation_rad": (np.radians(8.0), np.radians(60.0)),
    "azimuth_rad": (np.radians(-35.0), np.radians(35.0)),
    "f_px": (600.0, 1400.0),
    "aim_offset_fov": (-0.2, 0.2),
    "specular_strength": (0.0, 2.0),
    "shininess": (20.0, 200.0),
    "wb_gain": (0.8, 1.2),
    "exposure_gain": (0.6, 1.6),
    "full_well_e": (3000.0, 12000.0),
    "read_noise_e": (5.0, 25.0),
    "jpeg_quality": (60, 95),
    "occlusion_offset": (0.2, 0.9),
}
P_JPEG = 0.8
P_OCCLUSION = 0.3
MAX_BASELINE_M = 3.0
CEILING_M = 3.2
WIDTH, HEIGHT = 640, 480
DIST = (-0.12, 0.05, 3e-4, -2e-4, 0.0)


def photo_texture_paths(root=None) -> list:
    """Real photographs usable as textures, sorted (empty when the shared data are absent).

    Parameters
    ----------
    root : str or Path, optional
        Directory holding ``rgbd_kinect_room`` and ``rgbd_tum_desk``; default
        ``../shared/realdata`` relative to the repository root.

    Returns
    -------
    list of str
        Colour PNGs (depth images excluded).
    """
    root = Path(__file__).resolve().parents[2].parent / "shared" / "realdata" if root is None else Path(root)
    paths = sorted(glob.glob(str(root / "rgbd_kinect_room" / "color" / "*.png")))
    paths += sorted(p for p in glob.glob(str(root / "rgbd_tum_desk" / "*.png")) if "depth" not in Path(p).name)
    return paths


@dataclass(frozen=True, kw_only=True)
class SceneParams:
    """Parameters of one static stereo set-up of the family (drawn by :func:`sample_scene_params`).

    Attributes
    ----------
    index : int
        Position in the family.
    theta_rad : tuple of 3 floats
        Joint angles of the (rigid-drawn) arm, radians.
    sphere_radius_m, distance_m, baseline_m, elevation_rad, azimuth_rad : float
        Sphere radius; distance from the baseline midpoint to the end
        effector; baseline; elevation above the horizontal and azimuth of the
        viewing direction about the front (base −y), metres and radians.
    f_px : float
        Focal length of both cameras, pixels.
    aim_offset_m : tuple of 3 floats
        Offset of the aim point from the end effector, metres, base frame.
    specular_strength, shininess : float
        Blinn–Phong highlight of the spheres.
    wb_gains : tuple of 3 floats
        White-balance gains applied to linear RGB before the sensor.
    exposure_gain, full_well_e, read_noise_e : float
        Sensor gain (exposure), full-well capacity and read noise (electrons).
    jpeg_quality : int or None
        JPEG quality of the frames; None: lossless.
    texture_source : str
        ``"photo"`` (crops of real photographs) or ``"procedural"`` (fallback).
    texture_files : tuple of 2 str
        Photographs used for the floor and back wall ("" when procedural).
    occluded_sphere : str or None
        Sphere crossed by a link-like capsule in front of it, or None.
    occlusion_offset : float
        Distance of the occluder's axis from the sphere centre, in sphere radii.
    occlusion_angle_rad : float
        Direction of the occluder's axis in the image-facing plane.
    seed : int
        Seed of everything else (clutter, lights, texture crops, noise).
    """

    index: int
    theta_rad: tuple
    sphere_radius_m: float
    distance_m: float
    baseline_m: float
    elevation_rad: float
    azimuth_rad: float
    f_px: float
    aim_offset_m: tuple
    specular_strength: float
    shininess: float
    wb_gains: tuple
    exposure_gain: float
    full_well_e: float
    read_noise_e: float
    jpeg_quality: int | None
    texture_source: str
    texture_files: tuple
    occluded_sphere: str | None
    occlusion_offset: float
    occlusion_angle_rad: float
    seed: int


def _u(rng, key):
    lo, hi = RANGES[key]
    return float(rng.uniform(lo, hi))


def sample_scene_params(rng: np.random.Generator, index: int = 0, *, textures=None) -> SceneParams:
    """Draw one set-up of the family.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every random choice.
    index : int
        Position in the family (stored in the result).
    textures : list of str, optional
        Photographs to crop textures from; default :func:`photo_texture_paths`.
        Empty: procedural textures.

    Returns
    -------
    SceneParams

    Examples
    --------
    >>> p = sample_scene_params(np.random.default_rng(3), textures=[])
    >>> 0.015 <= p.sphere_radius_m <= 0.05, 1.5 <= p.distance_m <= 5.0, p.texture_source
    (True, True, 'procedural')
    """
    textures = photo_texture_paths() if textures is None else list(textures)
    theta = (float(rng.uniform(-0.6, 0.6)), float(rng.uniform(0.2, 1.4)), float(rng.uniform(-1.0, 0.6)))
    ee_z = 0.35 + 0.43 * np.sin(theta[1]) + 0.41 * np.sin(theta[1] + theta[2])
    d = _u(rng, "distance_m")
    el_hi = min(RANGES["elevation_rad"][1], np.arcsin(np.clip((CEILING_M - 0.3 - ee_z) / d, 0.0, 1.0)))
    el = float(rng.uniform(RANGES["elevation_rad"][0], max(el_hi, RANGES["elevation_rad"][0])))
    f = _u(rng, "f_px")
    fov_m = d * WIDTH / f
    aim = tuple(float(x) for x in rng.uniform(*RANGES["aim_offset_fov"], 3) * fov_m * np.array([1.0, 1.0, 0.75]))
    jpeg = int(rng.integers(RANGES["jpeg_quality"][0], RANGES["jpeg_quality"][1] + 1)) if rng.uniform() < P_JPEG \
        else None
    occluded = str(rng.choice(SPHERES)) if rng.uniform() < P_OCCLUSION else None
    files = tuple(str(rng.choice(textures)) for _ in range(2)) if textures else ("", "")
    return SceneParams(
        index=int(index), theta_rad=theta, sphere_radius_m=_u(rng, "sphere_radius_m"), distance_m=d,
        baseline_m=min(MAX_BASELINE_M, _u(rng, "baseline_ratio") * d), elevation_rad=el,
        azimuth_rad=_u(rng, "azimuth_rad"), f_px=f, aim_offset_m=aim,
        specular_strength=_u(rng, "specular_strength"), shininess=_u(rng, "shininess"),
        wb_gains=(_u(rng, "wb_gain"), 1.0, _u(rng, "wb_gain")), exposure_gain=_u(rng, "exposure_gain"),
        full_well_e=_u(rng, "full_well_e"), read_noise_e=_u(rng, "read_noise_e"), jpeg_quality=jpeg,
        texture_source="photo" if textures else "procedural", texture_files=files, occluded_sphere=occluded,
        occlusion_offset=_u(rng, "occlusion_offset"), occlusion_angle_rad=float(rng.uniform(0, np.pi)),
        seed=int(rng.integers(0, 2 ** 31 - 1)))


def sample_family(seed: int, n: int, *, textures=None) -> list:
    """``n`` set-ups drawn from ``np.random.default_rng(seed)`` (the same list for the same seed).

    Parameters
    ----------
    seed : int
        Family seed.
    n : int
        Number of set-ups (>= 1).
    textures : list of str, optional
        See :func:`sample_scene_params`.

    Returns
    -------
    list of SceneParams

    Raises
    ------
    ValueError
        If ``n`` is not a positive integer.

    Examples
    --------
    >>> sample_family(1, 2, textures=[]) == sample_family(1, 2, textures=[])
    True
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a positive integer, got {n!r}")
    rng = np.random.default_rng(seed)
    return [sample_scene_params(rng, k, textures=textures) for k in range(int(n))]


@dataclass(frozen=True, kw_only=True, eq=False)
class FamilyScene:
    """One rendered set-up: frames, cameras and ground truth (for the lab's scorers only).

    Attributes
    ----------
    params : SceneParams
        What was drawn.
    frames : dict of str to ndarray
        ``{"left", "right"}``: (H, W, 3) uint8 BGR frames to track.
    pick_frames : dict of str to ndarray
        The same views with independent sensor noise (and JPEG): the frames a
        user picks the colour models on.
    cameras : dict of str to PinholeCamera
        The true cameras (world frame).
    uv_true : dict
        ``uv_true[camera][sphere]``: (2,) exact silhouette centroid, pixels.
    radius_px : dict
        ``radius_px[camera][sphere]``: apparent radius, pixels.
    centers_left : dict of str to ndarray
        True sphere centres, shape (3,), metres, left camera optical frame.
    note : str
        Texture fallback note ("" when photographs were used).
    static_frames : tuple of dict
        More frames of the same static view (``{"left", "right"}`` each), every one with its own sensor noise
        (and JPEG): a static sphere recorded for a while (empty unless asked for).
    sphere_masks : dict
        ``sphere_masks[camera][sphere]``: (H, W) bool, the pixels where the sphere is seen (not hidden by the
        other sphere, a link or the occluder): what a user sees to click on.
    """

    params: SceneParams
    frames: dict
    pick_frames: dict
    cameras: dict
    uv_true: dict
    radius_px: dict
    centers_left: dict
    note: str = ""
    static_frames: tuple = ()
    sphere_masks: dict | None = None


def apparent_radius_px(camera: PinholeCamera, center_world, radius_m: float) -> float:
    """Apparent radius of a sphere, pixels: ``f asin(R / D)`` with D the distance to the optical centre.

    Parameters
    ----------
    camera : PinholeCamera
    center_world : array_like, shape (3,)
        Sphere centre, metres, world frame.
    radius_m : float
        Sphere radius, metres.

    Returns
    -------
    float
        Half the cone angle of the sphere times the focal length (the
        radius of its image near the principal point, distortion ignored).

    Examples
    --------
    >>> cam = look_at([0, -2, 0], [0, 0, 0], K=intrinsic_matrix(100, 49.5, 49.5), width=100, height=100)
    >>> round(apparent_radius_px(cam, [0, 0, 0], 0.1), 2)
    5.0
    """
    D = float(np.linalg.norm(np.asarray(center_world, float) - camera.T_world_cam[:3, 3]))
    return float(camera.K[0, 0] * np.arcsin(min(radius_m / D, 1.0)))


def _cameras(p: SceneParams, ee_world):
    view = np.array([np.sin(p.azimuth_rad) * np.cos(p.elevation_rad), -np.cos(p.azimuth_rad) * np.cos(p.elevation_rad),
                     np.sin(p.elevation_rad)])
    mid = ee_world + p.distance_m * view
    lateral = np.cross(view, [0.0, 0.0, 1.0])  # right of a viewer looking along -view
    lateral /= np.linalg.norm(lateral)
    aim = ee_world + np.asarray(p.aim_offset_m)
    K = intrinsic_matrix(p.f_px, (WIDTH - 1) / 2, (HEIGHT - 1) / 2)
    return {name: look_at(mid + side * p.baseline_m / 2 * lateral, aim, K=K, dist=np.asarray(DIST), width=WIDTH,
                          height=HEIGHT) for name, side in (("left", 1.0), ("right", -1.0))}


def _textures(p: SceneParams, rng):
    if p.texture_source == "photo":
        try:
            return [load_texture_crop(f, rng) for f in p.texture_files], ""
        except ValueError as exc:
            note = f"photo textures unreadable ({exc}); procedural textures used"
    else:
        note = "real photographs not found under ../shared/realdata; procedural textures used"
    return [procedural_texture(rng) for _ in range(2)], note


def _room(p: SceneParams, rng):
    shapes, lights = lab_room(rng, size_m=(14.0, 14.0, CEILING_M), keepout_radius_m=1.2, n_clutter=8,
                              n_distractors=4, clutter_region_y=(-1.0, 3.0))
    (floor_tex, wall_tex), note = _textures(p, rng)
    out = []
    for s in shapes:
        if s.name == "floor":
            s = TexturedRectangle(center=s.center, half_size=s.half_size, texture_rgb=floor_tex,
                                  texture_size_m=(1.2, 1.2), name="floor")
        elif s.name == "wall_back":
            s = TexturedRectangle(center=s.center, axis_u=s.axis_u, axis_v=s.axis_v, half_size=s.half_size,
                                  texture_rgb=wall_tex, texture_size_m=(2.0, 2.0), name="wall_back")
        out.append(s)
    return out, lights, note


def _occluder(p: SceneParams, center, cam_mid):
    """A link-like capsule between the sphere and the cameras, its axis ``offset`` radii from the centre."""
    to_cam = cam_mid - center
    to_cam /= np.linalg.norm(to_cam)
    a = np.cross(to_cam, [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(to_cam, a)
    axis = np.cos(p.occlusion_angle_rad) * a + np.sin(p.occlusion_angle_rad) * b
    side = np.cross(to_cam, axis)
    mid = center + 3.0 * p.sphere_radius_m * to_cam + p.occlusion_offset * p.sphere_radius_m * side
    return Capsule(p0=mid - 0.15 * axis, p1=mid + 0.15 * axis, radius=0.008, color_rgb=(0.55, 0.56, 0.58),
                   name="occluder")


def render_family_scene(params: SceneParams, *, static_frames: int = 0) -> FamilyScene:
    """Render one set-up of the family with both cameras.

    Parameters
    ----------
    params : SceneParams
        A set-up from :func:`sample_scene_params`.
    static_frames : int
        How many more frames of the same static view to render, each with its own sensor noise; drawn from a
        random stream of their own, so that the other frames do not depend on it.

    Returns
    -------
    FamilyScene
        Frames for tracking and for picking, true cameras and ground truth.
    """
    import cv2
    p = params
    rng = np.random.default_rng(p.seed)
    T = np.eye(4)
    arm = arm_geometry_from_joints(p.theta_rad)
    shapes, lights, note = _room(p, rng)
    shapes += robot_base_shapes(T, 0.35)
    shapes += arm_shapes(arm, T, sphere_radius_m=p.sphere_radius_m)
    ee = 0.5 * (arm.sphere_centers_base["red"] + arm.sphere_centers_base["green"])
    cams = _cameras(p, ee)
    if p.occluded_sphere is not None:
        mid = 0.5 * (cams["left"].T_world_cam[:3, 3] + cams["right"].T_world_cam[:3, 3])
        shapes.append(_occluder(p, arm.sphere_centers_base[p.occluded_sphere], mid))
    scene = Scene(static=shapes, lights=lights)
    ids = scene.object_ids()
    sphere_ids = [ids["red_sphere"], ids["green_sphere"]]
    sensor = SensorModel(gain=p.exposure_gain, full_well_e=p.full_well_e, read_noise_e=p.read_noise_e)
    frames, picks, uv_true, radius_px, masks = {}, {}, {}, {}, {}
    more = [{} for _ in range(int(static_frames))]
    rng_more = np.random.default_rng([p.seed, 1])

    def expose(rad, rng):
        img = apply_sensor(rad, sensor, rng)
        if p.jpeg_quality is not None:
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(p.jpeg_quality)])
            img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return img

    for name, cam in cams.items():
        rad = render_radiance(cam, scene, 0.0)
        gbuffer = render_gbuffer(cam, scene)
        rad = rad + specular_radiance(cam, gbuffer, lights, sphere_ids,
                                      strength=p.specular_strength, shininess=p.shininess)
        masks[name] = {s: gbuffer.object_id == ids[f"{s}_sphere"] for s in SPHERES}
        rad *= np.asarray(p.wb_gains, np.float32)
        for store in (frames, picks):
            store[name] = expose(rad, rng)
        for store in more:
            store[name] = expose(rad, rng_more)
        uv_true[name] = {s: sphere_image_truth(cam, lambda t, c=arm.sphere_centers_base[s]: c, p.sphere_radius_m, 0.0)
                         for s in SPHERES}
        radius_px[name] = {s: apparent_radius_px(cam, arm.sphere_centers_base[s], p.sphere_radius_m) for s in SPHERES}
    T_left_world = np.linalg.inv(cams["left"].T_world_cam)
    centers_left = {s: T_left_world[:3, :3] @ arm.sphere_centers_base[s] + T_left_world[:3, 3] for s in SPHERES}
    return FamilyScene(params=p, frames=frames, pick_frames=picks, cameras=cams, uv_true=uv_true,
                       radius_px=radius_px, centers_left=centers_left, note=note, static_frames=tuple(more),
                       sphere_masks=masks)
