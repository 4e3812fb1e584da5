"""Vectorised ray casting: one ray per pixel centre against a few analytic shapes.

Rays come from :func:`~tudorvision.sim.camera.ray_directions_world` (distortion
included); each shape is intersected only inside its projected bounding box.
Static shapes are cast once per camera and cached on the :class:`Scene`;
dynamic shapes are re-cast over that cached depth. See
:mod:`tudorvision.sim.render` for the object ids and the shading.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .camera import (PinholeCamera, camera_center_world, distort_normalized, pixels_from_normalized,
                     ray_directions_cam, ray_directions_world_soa)
from .lighting import light_terms
from .shapes import Scene

__all__ = ["GBuffer", "render_gbuffer", "cast_rays", "pixel_bbox", "pixel_bboxes"]


@dataclass(frozen=True, kw_only=True, eq=False)
class GBuffer:
    """Per-pixel ray-cast result (all arrays indexed ``[v, u]``).

    Attributes
    ----------
    distance_m : (H, W) float64
        Ray length from the optical centre; ``inf`` where nothing is hit.
    depth_m : (H, W) float64
        z along the optical axis (``distance_m * ray_z``); ``inf`` where nothing is hit.
    normal_world : (H, W, 3) float32
        Unit normals facing the camera; zero where nothing is hit.
    object_id : (H, W) int32
        0 for no hit, see the module notes.
    albedo_rgb : (H, W, 3) float32
        Linear RGB reflectance.
    """

    distance_m: np.ndarray
    depth_m: np.ndarray
    normal_world: np.ndarray
    object_id: np.ndarray
    albedo_rgb: np.ndarray


def pixel_bbox(camera: PinholeCamera, corners_world, *, pad: int = 2):
    """Pixel bounding box ``(v0, v1, u0, u1)`` (half-open) of the convex hull of ``corners_world`` (N, 3).

    Returns the full image when ``corners_world`` is None (an unbounded shape)
    and None when the hull misses the image or lies behind the camera. A hull
    that crosses the image plane is clipped at z = 1 mm first. See
    :func:`pixel_bboxes` for many shapes at once.
    """
    return pixel_bboxes(camera, [corners_world], pad=pad)[0]


def pixel_bboxes(camera: PinholeCamera, corners_list, *, pad: int = 2) -> list:
    """Vectorised :func:`pixel_bbox` for a list of corner arrays (or None entries).

    The hull of the corners is bounded in undistorted normalized coordinates
    (exact for a convex shape in front of the camera), clamped to the field of
    view, and its border is sampled and distorted to pixels.
    """
    H, W = camera.height, camera.width
    out = [(0, H, 0, W)] * len(corners_list)
    idx = [i for i, c in enumerate(corners_list) if c is not None]
    if not idx:
        return out
    corners = [np.asarray(corners_list[i], float).reshape(-1, 3) for i in idx]
    m = max(8, max(len(c) for c in corners))
    pts = np.stack([np.concatenate([c, np.repeat(c[:1], m - len(c), axis=0)]) for c in corners])  # (n, m, 3)
    T = camera.T_world_cam
    pc = (pts - T[:3, 3]) @ T[:3, :3]
    front = np.all(pc[..., 2] > _NEAR, axis=1)
    for k in np.nonzero(~front)[0]:
        clipped = _clip_hull_near(pc[k])
        pc[k] = np.concatenate([clipped, np.repeat(clipped[:1], m - 8, axis=0)])
    front = np.all(np.isfinite(pc[..., 2]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = pc[..., :2] / pc[..., 2:]
    lo, hi = xy.min(axis=1), xy.max(axis=1)
    flo, fhi = _fov_box(camera)
    visible = ~(np.any(hi < flo, axis=1) | np.any(lo > fhi, axis=1))
    lo, hi = np.maximum(lo, flo), np.minimum(hi, fhi)
    s = _EDGE_SAMPLES
    edge = lo[:, None, :] + s[None] * (hi - lo)[:, None, :]                   # (n, 36, 2)
    uv = pixels_from_normalized(camera, distort_normalized(edge, camera.dist))
    umin, umax = np.floor(uv[..., 0].min(axis=1)), np.ceil(uv[..., 0].max(axis=1))
    vmin, vmax = np.floor(uv[..., 1].min(axis=1)), np.ceil(uv[..., 1].max(axis=1))
    for k, i in enumerate(idx):
        if not front[k] or not visible[k]:
            out[i] = None
            continue
        u0, u1 = max(int(umin[k]) - pad, 0), min(int(umax[k]) + pad + 1, W)
        v0, v1 = max(int(vmin[k]) - pad, 0), min(int(vmax[k]) + pad + 1, H)
        out[i] = (v0, v1, u0, u1) if (u0 < u1 and v0 < v1) else None
    return out


_NEAR = 1e-3


def _clip_hull_near(pc: np.ndarray) -> np.ndarray:
    """Eight points whose hull contains (hull of ``pc``) cut by z >= _NEAR; NaN if nothing is in front.

    The clipped hull's vertices are the corners in front and the crossings of
    segments between a corner in front and one behind; all such crossings are
    taken, then reduced to their normalized-plane extremes.
    """
    inside = pc[:, 2] > _NEAR
    if not inside.any():
        return np.full((8, 3), np.nan)
    a, b = pc[inside], pc[~inside]
    s = (a[:, None, 2] - _NEAR) / (a[:, None, 2] - b[None, :, 2])
    cross = (a[:, None] + s[..., None] * (b[None] - a[:, None])).reshape(-1, 3)
    pts = np.concatenate([a, cross])
    xy = pts[:, :2] / np.maximum(pts[:, 2:], _NEAR)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    box = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    out = np.concatenate([box, box]) * _NEAR
    return np.concatenate([out, np.full((8, 1), _NEAR)], axis=1)


_s9 = np.linspace(0.0, 1.0, 9)
_EDGE_SAMPLES = np.concatenate([np.stack([_s9, np.zeros(9)], 1), np.stack([_s9, np.ones(9)], 1),
                                np.stack([np.zeros(9), _s9], 1), np.stack([np.ones(9), _s9], 1)])


def _fov_box(camera):
    """Normalised-coordinate box ``(lo, hi)`` around the camera's field of view (2 % margin), cached."""
    def make():
        r = ray_directions_cam(camera)
        border = np.concatenate([r[0], r[-1], r[:, 0], r[:, -1]])
        xy = border[:, :2] / border[:, 2:]
        span = xy.max(axis=0) - xy.min(axis=0)
        return (xy.min(axis=0) - 0.02 * span, xy.max(axis=0) + 0.02 * span)

    return camera.cached("fov_box", make)


def cast_rays(camera: PinholeCamera, shapes: Sequence, *, cull: bool = True,
              t_init: np.ndarray | None = None, id_offset: int = 0):
    """Nearest hit of every pixel ray among ``shapes``.

    Parameters
    ----------
    camera : PinholeCamera
    shapes : sequence of shapes
    cull : bool
        Intersect each shape only inside its projected bounding box (the
        fast path); ``False`` intersects every shape with every ray.
    t_init : ndarray, shape (H, W), optional
        Existing hit distances (occluders); a shape must be nearer to win.
    id_offset : int
        Shape ``i`` gets id ``id_offset + i + 1``.

    Returns
    -------
    distance_m : ndarray, shape (H, W)
        ``inf`` where no shape is hit (or ``t_init`` where it wins).
    object_id : ndarray, shape (H, W), int32
        0 where no shape in ``shapes`` wins.
    bboxes : list
        The pixel box used for each shape (None when off-screen).
    """
    H, W = camera.height, camera.width
    rays = _rays_soa(camera)
    o = camera_center_world(camera)
    t = np.full((H, W), np.inf) if t_init is None else t_init.copy()
    ids = np.zeros((H, W), dtype=np.int32)
    bboxes = []
    boxes = pixel_bboxes(camera, [sh.corners() for sh in shapes]) if cull else [(0, H, 0, W)] * len(shapes)
    for i, (shape, bb) in enumerate(zip(shapes, boxes)):
        bboxes.append(bb)
        if bb is None:
            continue
        v0, v1, u0, u1 = bb
        ti = shape.intersect(o, rays[:, v0:v1, u0:u1])
        tv, iv = t[v0:v1, u0:u1], ids[v0:v1, u0:u1]
        closer = ti < tv
        tv[closer] = ti[closer]
        iv[closer] = id_offset + i + 1
    return t, ids, bboxes


def _rays_soa(camera: PinholeCamera) -> np.ndarray:
    return ray_directions_world_soa(camera)


def surface_at(camera, shape, rr, cc, t):
    """Hit points (N, 3), camera-facing unit normals and albedo of ``shape`` at pixels (rr, cc).

    ``t`` (N,) is the ray length to the hit in metres. For the renderer; not
    in ``__all__``.
    """
    flat = rr * camera.width + cc
    d = _rays_soa(camera).reshape(3, -1)[:, flat]
    p = np.ascontiguousarray((camera_center_world(camera)[:, None] + t * d).T)
    n = np.array(np.broadcast_to(shape.normals(p), p.shape), dtype=np.float64)
    n /= np.sqrt(n[:, 0] ** 2 + n[:, 1] ** 2 + n[:, 2] ** 2)[:, None]
    flip = n[:, 0] * d[0] + n[:, 1] * d[1] + n[:, 2] * d[2] > 0
    n[flip] *= -1.0
    return p, n, np.asarray(shape.albedo(p), dtype=np.float64)


@dataclass(eq=False)
class StaticCast:
    """The static shapes of a scene ray-cast by one camera (cached on the scene), arrays indexed ``[v, u]``."""

    t: np.ndarray       # (H, W) ray length in metres, inf where nothing is hit
    ids: np.ndarray     # (H, W) int32 object ids
    normal: np.ndarray  # (H, W, 3) float32 camera-facing unit normals, world frame
    albedo: np.ndarray  # (H, W, 3) float32 linear RGB reflectance
    terms: np.ndarray   # (L, H, W, 3) float32


def static_cast(camera: PinholeCamera, scene: Scene) -> StaticCast:
    """The static shapes of ``scene`` ray-cast and lit for ``camera``, once per camera (cached on the scene).

    For the renderer; not in ``__all__``.
    """
    return scene.cached_for(camera, lambda: _cast_static(camera, scene))


def _cast_static(camera: PinholeCamera, scene: Scene) -> StaticCast:
    H, W = camera.height, camera.width
    t, ids, bboxes = cast_rays(camera, scene.static)
    normal = np.zeros((H * W, 3), np.float32)
    albedo = np.zeros((H * W, 3), np.float32)
    t_flat = t.reshape(-1)
    for i, (shape, bb) in enumerate(zip(scene.static, bboxes)):
        if bb is None:
            continue
        v0, v1, u0, u1 = bb
        rr, cc = np.nonzero(ids[v0:v1, u0:u1] == i + 1)
        if rr.size == 0:
            continue
        rr += v0
        cc += u0
        flat = rr * W + cc
        _, n, a = surface_at(camera, shape, rr, cc, t_flat[flat])
        normal[flat] = n
        albedo[flat] = a
    # light terms over the whole frame at once (no per-object scatter)
    d = _rays_soa(camera).reshape(3, -1)
    tt = np.where(np.isfinite(t_flat), t_flat, 0.0)
    p = np.ascontiguousarray((camera_center_world(camera)[:, None] + tt * d).T)
    terms = light_terms(scene.lights, p, normal, albedo).reshape(len(scene.lights), H, W, 3)
    return StaticCast(t=t, ids=ids, normal=normal.reshape(H, W, 3), albedo=albedo.reshape(H, W, 3), terms=terms)


def dynamic_hits(camera, shapes, full_boxes, st, rows):
    """Cast dynamic ``shapes`` (with their full-image ``full_boxes``) over the static depth in row range ``rows``.

    ``st`` is the camera's :class:`StaticCast`. Returns a list of (j, shape, rr, cc, t) per shape with the
    pixels it wins. For the renderer; not in ``__all__``.
    """
    r0, r1 = rows
    boxes = []
    for bb in full_boxes:
        if bb is not None:
            bb = (max(bb[0], r0), min(bb[1], r1), bb[2], bb[3])
            if bb[0] >= bb[1]:
                bb = None
        boxes.append(bb)
    live = [b for b in boxes if b is not None]
    if not live:
        return []
    V0, V1 = min(b[0] for b in live), max(b[1] for b in live)
    U0, U1 = min(b[2] for b in live), max(b[3] for b in live)
    rays = _rays_soa(camera)
    o = camera_center_world(camera)
    t = st.t[V0:V1, U0:U1].copy()
    ids = np.zeros(t.shape, np.int32)
    for j, (shape, bb) in enumerate(zip(shapes, boxes)):
        if bb is None:
            continue
        v0, v1, u0, u1 = bb
        ti = shape.intersect(o, rays[:, v0:v1, u0:u1])
        tv, iv = t[v0 - V0:v1 - V0, u0 - U0:u1 - U0], ids[v0 - V0:v1 - V0, u0 - U0:u1 - U0]
        closer = ti < tv
        tv[closer] = ti[closer]
        iv[closer] = j + 1
    out = []
    for j, shape in enumerate(shapes):
        if boxes[j] is None:
            continue
        rr, cc = np.nonzero(ids == j + 1)
        if rr.size:
            out.append((j, shape, rr + V0, cc + U0, t[rr, cc]))
    return out


def render_gbuffer(camera: PinholeCamera, scene: Scene, t: float = 0.0) -> GBuffer:
    """Ray-cast ``scene`` at time ``t`` (an instantaneous, blur-free snapshot).

    Returns
    -------
    GBuffer

    Examples
    --------
    >>> from tudorvision.sim.camera import look_at, intrinsic_matrix
    >>> from tudorvision.sim.lighting import AmbientLight
    >>> from tudorvision.sim.shapes import Scene, Sphere
    >>> cam = look_at([0, -2, 0], [0, 0, 0], K=intrinsic_matrix(50, 15.5, 11.5), width=32, height=24)
    >>> g = render_gbuffer(cam, Scene(static=[Sphere(center=(0, 0, 0), radius=0.5)], lights=[AmbientLight()]))
    >>> round(float(g.depth_m[11:13, 15:17].mean()), 2), int(g.object_id[0, 0])
    (1.5, 0)
    """
    st = static_cast(camera, scene)
    dist = st.t.copy()
    ids = st.ids.copy()
    normal = st.normal.copy()
    albedo = st.albedo.copy()
    if scene.dynamic is not None:
        shapes = list(scene.dynamic(t))
        boxes = pixel_bboxes(camera, [sh.corners() for sh in shapes])
        for j, shape, rr, cc, tj in dynamic_hits(camera, shapes, boxes, st, (0, camera.height)):
            _, n, a = surface_at(camera, shape, rr, cc, tj)
            dist[rr, cc] = tj
            ids[rr, cc] = scene.n_static + 1 + j
            normal[rr, cc] = n
            albedo[rr, cc] = a
    depth = dist * ray_directions_cam(camera)[..., 2]
    return GBuffer(distance_m=dist, depth_m=depth, normal_world=normal, object_id=ids, albedo_rgb=albedo)
