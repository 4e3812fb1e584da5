"""Specular highlights (Blinn–Phong) added on top of the Lambertian radiance of chosen objects.

The renderer (:mod:`tudorvision.sim.render`) is Lambertian; glossy tracking
spheres show a white, washed-out highlight toward each light. This module
computes that term from a :class:`~tudorvision.sim.raycast.GBuffer` (hit
points, normals, object ids) so that it can be added to
:func:`~tudorvision.sim.render.render_radiance` before the sensor model:

``L_spec = strength * I_light * color_light * max(n . h, 0) ** shininess`` for
each directional and point light (point lights with inverse-square falloff),
``h`` the half vector of the light and view directions, zero where the surface
faces away from the light. Ambient light adds no highlight. The highlight is
white (dielectric), not tinted by the albedo. Static scenes only (the G-buffer
is one instant).
"""
from __future__ import annotations

import numpy as np

from .camera import PinholeCamera, camera_center_world, ray_directions_world
from .lighting import DirectionalLight, PointLight, intensity_at
from .raycast import GBuffer

__all__ = ["specular_radiance"]


def specular_radiance(camera: PinholeCamera, gbuffer: GBuffer, lights, object_ids, *, strength: float,
                      shininess: float, t: float = 0.0) -> np.ndarray:
    """Blinn–Phong highlight radiance of the objects ``object_ids`` seen by ``camera``.

    Parameters
    ----------
    camera : PinholeCamera
        The camera that produced ``gbuffer``.
    gbuffer : GBuffer
        Ray-cast of the scene by ``camera`` (:func:`~tudorvision.sim.render.render_gbuffer`).
    lights : sequence of lights
        The scene's lights (:mod:`tudorvision.sim.lighting`).
    object_ids : iterable of int
        Ids (as in ``gbuffer.object_id``) of the glossy objects.
    strength : float
        Specular reflectance (>= 0; 0 gives no highlight).
    shininess : float
        Blinn–Phong exponent (> 0; larger is a smaller, sharper highlight).
    t : float
        Time at which light intensities are evaluated, seconds.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
        Linear RGB radiance to add to the Lambertian image; zero off the objects.

    Raises
    ------
    ValueError
        If ``strength`` is negative or ``shininess`` not positive.

    Examples
    --------
    >>> from tudorvision.sim.camera import intrinsic_matrix, look_at
    >>> from tudorvision.sim.lighting import DirectionalLight
    >>> from tudorvision.sim.raycast import render_gbuffer
    >>> from tudorvision.sim.shapes import Scene, Sphere
    >>> cam = look_at([0, -2, 0], [0, 0, 0], K=intrinsic_matrix(50, 15.5, 15.5), width=32, height=32)
    >>> scene = Scene(static=[Sphere(center=(0, 0, 0), radius=0.5)],
    ...               lights=[DirectionalLight(direction_world=(0, 1, 0), intensity=1.0)])
    >>> spec = specular_radiance(cam, render_gbuffer(cam, scene), scene.lights, [1], strength=0.5, shininess=50)
    >>> v, u = np.unravel_index(spec[..., 0].argmax(), spec.shape[:2])
    >>> (int(u), int(v)), round(float(spec.max()), 1)
    ((15, 15), 0.5)
    """
    if not strength >= 0:
        raise ValueError(f"strength: expected >= 0, got {strength!r}")
    if not shininess > 0:
        raise ValueError(f"shininess: expected > 0, got {shininess!r}")
    H, W = gbuffer.object_id.shape
    out = np.zeros((H, W, 3), np.float32)
    mask = np.isin(gbuffer.object_id, np.asarray(list(object_ids), dtype=np.int64))
    if strength == 0 or not mask.any():
        return out
    d = ray_directions_world(camera)[mask]
    dist = gbuffer.distance_m[mask][:, None]
    p = camera_center_world(camera) + dist * d
    n = gbuffer.normal_world[mask].astype(np.float64)
    view = -d
    acc = np.zeros_like(p)
    for light in lights:
        if isinstance(light, DirectionalLight):
            to_l = np.broadcast_to(-light.direction_world, p.shape)
            fall = 1.0
        elif isinstance(light, PointLight):
            rel = light.position_world - p
            d2 = np.einsum("ij,ij->i", rel, rel)
            to_l = rel / np.sqrt(d2)[:, None]
            fall = (1.0 / np.maximum(d2, 1e-6))[:, None]
        else:
            continue
        h = to_l + view
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        lit = np.einsum("ij,ij->i", n, to_l) > 0
        nh = np.clip(np.einsum("ij,ij->i", n, h), 0.0, 1.0) * lit
        acc += (intensity_at(light, t) * nh ** shininess)[:, None] * fall * light.color_rgb
    out[mask] = strength * acc
    return out
