"""Vectorised ray casting of simple shapes, colour frames and Kinect-like depth.

Shapes implement ``intersect(o, d) -> t`` for a common origin ``o`` (3,) and
unit directions ``d`` stored component-first, shape (3, ...) (t is ``inf`` on
a miss), ``normals(p)`` and ``albedo(p)`` for hit points ``p`` (N, 3), and
``corners()`` (points whose hull bounds the shape, or None if unbounded).

The renderer casts one ray per pixel centre (:func:`~tudorvision.sim.camera.ray_directions_world`,
distortion included) against a handful of analytic shapes: spheres,
rectangles (bounded or infinite planes, optionally checker-textured), discs,
oriented boxes, capsules and capped cylinders. Each shape is intersected only
inside its projected bounding box.

A :class:`Scene` has *static* shapes (rendered once per camera and cached) and
optional *dynamic* shapes given as a function of time ``t -> [shapes]``. A
colour frame integrates the dynamic shapes over the exposure (motion blur from
``n_subframes`` sub-frames) and, with a rolling shutter, exposes row ``r`` from
``t + r * line_time_s``. Only the dynamic shapes are re-cast per sub-frame.

Object ids: 0 is "no hit", static shape ``i`` has id ``i + 1`` and dynamic shape
``j`` (in the order the time function returns them) has id ``n_static + 1 + j``.

Assumptions: Lambertian surfaces, no shadows or inter-reflections, lighting
evaluated at the middle of the exposure, pinhole rays through pixel centres
(no anti-aliasing).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import Callable, Sequence

import cv2
import numpy as np

from .._checks import check_array
from .camera import (PinholeCamera, camera_center_world, distort_normalized,
                     ray_directions_cam, ray_directions_world_soa, _pixels_from_normalized)
from .lighting import SensorModel, apply_sensor, intensity_at, light_terms, weighted_sum

__all__ = [
    "Sphere", "Rectangle", "Disc", "Box", "Capsule", "Cylinder", "Scene", "GBuffer",
    "render_gbuffer", "render_radiance", "render_bgr", "DepthModel", "depth_sigma_m",
    "depth_mm_from_gbuffer", "render_rgbd", "exposure_times", "cast_rays", "pixel_bbox", "pixel_bboxes",
]

_EPS = 1e-6
_INF = np.inf


def _dot(d, v):
    """Dot product of component-first rays ``d`` (3, ...) with a 3-vector (no BLAS: numpy's
    threaded matmul is slow for an inner dimension of 3)."""
    return d[0] * v[0] + d[1] * v[1] + d[2] * v[2]


def _rowdot(p, v):
    """``p @ v`` for row points ``p`` (N, 3) and a 3-vector."""
    return p[:, 0] * v[0] + p[:, 1] * v[1] + p[:, 2] * v[2]


def _rowmat(p, M):
    """``p @ M`` for row points ``p`` (N, 3) and a 3x3 matrix."""
    return p[:, 0:1] * M[0] + p[:, 1:2] * M[1] + p[:, 2:3] * M[2]


def _vec3(value, name):
    """Fast check of a finite 3-vector (shapes are built per sub-frame, so this is a hot path)."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"{name}: expected shape (3,), got {a.shape}")
    x, y, z = a.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return a


def _color(value, name):
    c = _vec3(value, name)
    if not all(0.0 <= x <= 1.0 for x in c.tolist()):
        raise ValueError(f"{name}: expected linear RGB in [0, 1], got {c.tolist()}")
    return c


def _positive(value, name):
    v = float(value)
    if not v > 0:
        raise ValueError(f"{name}: expected > 0, got {value!r}")
    return v


def _unit(value, name):
    v = _vec3(value, name)
    n = math.sqrt(v @ v)
    if n < 1e-12:
        raise ValueError(f"{name}: must be non-zero")
    return v / n


@dataclass(frozen=True, kw_only=True, eq=False)
class _Shape:
    color_rgb: tuple = (0.5, 0.5, 0.5)
    name: str = ""

    def _init_color(self):
        object.__setattr__(self, "color_rgb", _color(self.color_rgb, "color_rgb"))

    def albedo(self, points: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.color_rgb, points.shape)


@dataclass(frozen=True, kw_only=True, eq=False)
class Sphere(_Shape):
    """Sphere of ``radius`` (m) centred at ``center`` (world, m).

    Examples
    --------
    >>> s = Sphere(center=(0, 0, 2), radius=0.5)
    >>> s.intersect(np.zeros(3), np.array([[0.0], [0.0], [1.0]])).tolist()
    [1.5]
    """

    center: tuple = (0.0, 0.0, 0.0)
    radius: float = 0.05

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def corners(self):
        r = self.radius
        return self.center + r * _CUBE

    def intersect(self, o, d):
        oc = o - self.center
        b = _dot(d, oc)
        disc = b * b - (oc @ oc - self.radius ** 2)
        sq = np.sqrt(np.maximum(disc, 0.0))
        t = -b - sq
        t = np.where(t > _EPS, t, -b + sq)
        return np.where((disc >= 0) & (t > _EPS), t, _INF)

    def normals(self, p):
        return (p - self.center) / self.radius


@dataclass(frozen=True, kw_only=True, eq=False)
class Rectangle(_Shape):
    """Planar rectangle (two-sided), optionally with a checker texture.

    Parameters
    ----------
    center : (3,)
        World, metres.
    axis_u, axis_v : (3,)
        In-plane directions (made unit; must be orthogonal).
    half_size : (2,)
        Half extents along u and v in metres; ``inf`` gives an infinite plane.
    checker_square_m : float, optional
        Side of the checker squares; squares alternate ``color_rgb`` /
        ``color2_rgb``.
    checker_squares : (int, int), optional
        Number of squares along u and v, centred on ``center``; outside that
        area the surface is ``color_rgb`` (a board's white border). Without it
        the checker tiles the whole rectangle. The square touching the corner
        at ``-u, -v`` has ``color2_rgb``.
    """

    center: tuple = (0.0, 0.0, 0.0)
    axis_u: tuple = (1.0, 0.0, 0.0)
    axis_v: tuple = (0.0, 1.0, 0.0)
    half_size: tuple = (0.5, 0.5)
    checker_square_m: float | None = None
    checker_squares: tuple | None = None
    color2_rgb: tuple = (0.05, 0.05, 0.05)

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "color2_rgb", _color(self.color2_rgb, "color2_rgb"))
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        u, v = _unit(self.axis_u, "axis_u"), _unit(self.axis_v, "axis_v")
        if abs(u @ v) > 1e-6:
            raise ValueError("axis_v: must be orthogonal to axis_u")
        object.__setattr__(self, "axis_u", u)
        object.__setattr__(self, "axis_v", v)
        hs = check_array(self.half_size, "half_size", (2,), finite=False)
        if np.any(~(hs > 0)):
            raise ValueError(f"half_size: expected positive values, got {hs.tolist()}")
        object.__setattr__(self, "half_size", hs)
        if self.checker_square_m is not None:
            _positive(self.checker_square_m, "checker_square_m")
        if self.checker_squares is not None:
            n = np.asarray(self.checker_squares)
            if n.shape != (2,) or np.any(n < 1) or np.any(n != np.round(n)):
                raise ValueError(f"checker_squares: expected two positive integers, got {self.checker_squares!r}")
            if self.checker_square_m is None:
                raise ValueError("checker_square_m: required with checker_squares")

    @property
    def normal(self):
        return np.cross(self.axis_u, self.axis_v)

    def corners(self):
        if not np.all(np.isfinite(self.half_size)):
            return None
        hu, hv = self.half_size
        s = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
        return self.center + (s[:, :1] * hu) * self.axis_u + (s[:, 1:] * hv) * self.axis_v

    def intersect(self, o, d):
        rel = o - self.center
        dn, du, dv = _dot(d, self.normal), _dot(d, self.axis_u), _dot(d, self.axis_v)
        on, ou, ov = rel @ self.normal, rel @ self.axis_u, rel @ self.axis_v
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -on / dn
        ok = (t > _EPS) & (np.abs(ou + t * du) <= self.half_size[0]) & (np.abs(ov + t * dv) <= self.half_size[1])
        return np.where(ok, t, _INF)

    def normals(self, p):
        return np.broadcast_to(self.normal, p.shape)

    def albedo(self, p):
        if self.checker_square_m is None:
            return np.broadcast_to(self.color_rgb, p.shape)
        rel = p - self.center
        a, b = _rowdot(rel, self.axis_u), _rowdot(rel, self.axis_v)
        sq = self.checker_square_m
        if self.checker_squares is not None:
            au, av = self.checker_squares[0] * sq / 2, self.checker_squares[1] * sq / 2
            inside = (np.abs(a) < au) & (np.abs(b) < av)
            a, b = a + au, b + av
        else:
            inside = True
        dark = ((np.floor(a / sq) + np.floor(b / sq)) % 2 == 0) & inside
        return np.where(dark[:, None], self.color2_rgb, self.color_rgb)

    def inner_corners(self) -> np.ndarray:
        """Inner checker corners in the world, shape ((nu-1)*(nv-1), 3), row-major along u.

        Only for a board with ``checker_squares``; this is the grid OpenCV's
        ``findChessboardCorners`` detects (pattern size ``(nu-1, nv-1)``).
        """
        if self.checker_squares is None:
            raise ValueError("checker_squares: the rectangle is not a finite checkerboard")
        nu, nv = (int(n) for n in self.checker_squares)
        sq = self.checker_square_m
        a = (np.arange(1, nu) - nu / 2) * sq
        b = (np.arange(1, nv) - nv / 2) * sq
        bb, aa = np.meshgrid(b, a, indexing="ij")
        return self.center + aa.reshape(-1, 1) * self.axis_u + bb.reshape(-1, 1) * self.axis_v


@dataclass(frozen=True, kw_only=True, eq=False)
class Disc(_Shape):
    """Flat two-sided disc of ``radius`` at ``center`` with unit ``normal``."""

    center: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    radius: float = 0.075

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "normal", _unit(self.normal, "normal"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def corners(self):
        return self.center + self.radius * _CUBE

    def intersect(self, o, d):
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.center - o) @ self.normal) / _dot(d, self.normal)
        oc = o - self.center
        r2 = (oc[0] + t * d[0]) ** 2 + (oc[1] + t * d[1]) ** 2 + (oc[2] + t * d[2]) ** 2
        ok = (t > _EPS) & (r2 <= self.radius ** 2)
        return np.where(ok, t, _INF)

    def normals(self, p):
        return np.broadcast_to(self.normal, p.shape)


@dataclass(frozen=True, kw_only=True, eq=False)
class Box(_Shape):
    """Oriented box: ``R_world_box`` columns are its axes, ``half_extents`` (3,) in metres."""

    center: tuple = (0.0, 0.0, 0.0)
    half_extents: tuple = (0.1, 0.1, 0.1)
    R_world_box: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        h = _vec3(self.half_extents, "half_extents")
        if np.any(h <= 0):
            raise ValueError(f"half_extents: expected positive values, got {h.tolist()}")
        object.__setattr__(self, "half_extents", h)
        R = check_array(self.R_world_box, "R_world_box", (3, 3))
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ValueError("R_world_box: not a proper rotation matrix")
        object.__setattr__(self, "R_world_box", R)

    def corners(self):
        return self.center + (_CUBE * self.half_extents) @ self.R_world_box.T

    def intersect(self, o, d):
        R, h = self.R_world_box, self.half_extents
        ol = (o - self.center) @ R
        tmin, tmax = -_INF, _INF
        with np.errstate(divide="ignore", invalid="ignore"):
            for k in range(3):
                inv = 1.0 / _dot(d, R[:, k])
                t1 = (-h[k] - ol[k]) * inv
                t2 = (h[k] - ol[k]) * inv
                tmin = np.maximum(tmin, np.minimum(t1, t2))
                tmax = np.minimum(tmax, np.maximum(t1, t2))
        t = np.where(tmin > _EPS, tmin, tmax)
        return np.where((tmax >= tmin) & (t > _EPS), t, _INF)

    def normals(self, p):
        pl = _rowmat(p - self.center, self.R_world_box) / self.half_extents
        k = np.argmax(np.abs(pl), axis=1)
        sign = np.sign(pl[np.arange(len(pl)), k])
        return self.R_world_box.T[k] * sign[:, None]


@dataclass(frozen=True, kw_only=True, eq=False)
class Capsule(_Shape):
    """Segment ``p0``–``p1`` (world, m) swept by a sphere of ``radius``: a link of the arm."""

    p0: tuple = (0.0, 0.0, 0.0)
    p1: tuple = (0.0, 0.0, 1.0)
    radius: float = 0.01

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "p0", _vec3(self.p0, "p0"))
        object.__setattr__(self, "p1", _vec3(self.p1, "p1"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def corners(self):
        lo = np.minimum(self.p0, self.p1) - self.radius
        hi = np.maximum(self.p0, self.p1) + self.radius
        return _box_corners(lo, hi)

    def _body(self, o, d):
        ba = self.p1 - self.p0
        oa = o - self.p0
        baba, baoa = ba @ ba, ba @ oa
        bard, rdoa = _dot(d, ba), _dot(d, oa)
        a = baba - bard * bard
        b = baba * rdoa - baoa * bard
        c = baba * (oa @ oa) - baoa * baoa - self.radius ** 2 * baba
        h = b * b - a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (-b - np.sqrt(np.maximum(h, 0.0))) / a
        y = baoa + t * bard
        ok = (h >= 0) & (a > 1e-12) & (t > _EPS) & (y > 0) & (y < baba)
        return np.where(ok, t, _INF)

    def intersect(self, o, d):
        t = self._body(o, d)
        for cap in (self.p0, self.p1):
            t = np.minimum(t, Sphere(center=cap, radius=self.radius).intersect(o, d))
        return t

    def normals(self, p):
        ba = self.p1 - self.p0
        s = np.clip(_rowdot(p - self.p0, ba) / max(ba @ ba, 1e-300), 0.0, 1.0)
        return (p - self.p0 - s[:, None] * ba) / self.radius


@dataclass(frozen=True, kw_only=True, eq=False)
class Cylinder(Capsule):
    """Capped solid cylinder with axis ``p0``–``p1`` and ``radius`` (the robot base)."""

    def intersect(self, o, d):
        t = self._body(o, d)
        axis = _unit(self.p1 - self.p0, "p1")
        for cap in (self.p0, self.p1):
            t = np.minimum(t, Disc(center=cap, normal=axis, radius=self.radius).intersect(o, d))
        return t

    def normals(self, p):
        ba = self.p1 - self.p0
        L = np.linalg.norm(ba)
        axis = ba / L
        s = _rowdot(p - self.p0, axis)
        radial = p - self.p0 - s[:, None] * axis
        rn = np.linalg.norm(radial, axis=1)
        on_cap = rn < self.radius * (1 - 1e-6)
        cap_n = np.where((s < L / 2)[:, None], -axis, axis)
        with np.errstate(divide="ignore", invalid="ignore"):
            side = radial / rn[:, None]
        return np.where(on_cap[:, None], cap_n, side)


_CUBE = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def _box_corners(lo, hi):
    return lo + (_CUBE + 1.0) / 2.0 * (hi - lo)


@dataclass(frozen=True, kw_only=True, eq=False)
class Scene:
    """Shapes and lights of one virtual set.

    Parameters
    ----------
    static : sequence of shapes
        Shapes that never move (cached per camera after the first render).
    lights : sequence of lights
        :mod:`tudorvision.sim.lighting` lights; intensities may be functions of time.
    dynamic : callable, optional
        ``dynamic(t) -> sequence of shapes`` at time ``t`` (seconds). Must
        return the same number of shapes, in the same order, at every time.
    """

    static: tuple
    lights: tuple
    dynamic: Callable[[float], Sequence] | None = None
    _cache: weakref.WeakKeyDictionary = field(default_factory=weakref.WeakKeyDictionary, init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "static", tuple(self.static))
        object.__setattr__(self, "lights", tuple(self.lights))
        if not self.lights:
            raise ValueError("lights: at least one light is required")
        if self.dynamic is not None and not callable(self.dynamic):
            raise ValueError("dynamic: expected a callable t -> shapes")

    @property
    def n_static(self) -> int:
        return len(self.static)

    def object_ids(self, t: float = 0.0) -> dict:
        """Map shape name -> object id for every named shape (dynamic ones evaluated at ``t``)."""
        out = {}
        for i, s in enumerate(self.static):
            if s.name:
                out[s.name] = i + 1
        if self.dynamic is not None:
            for j, s in enumerate(self.dynamic(t)):
                if s.name:
                    out[s.name] = self.n_static + 1 + j
        return out


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
    uv = _pixels_from_normalized(camera, distort_normalized(edge, camera.dist))
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
    box = camera._cache.get("fov_box")
    if box is None:
        r = ray_directions_cam(camera)
        border = np.concatenate([r[0], r[-1], r[:, 0], r[:, -1]])
        xy = border[:, :2] / border[:, 2:]
        span = xy.max(axis=0) - xy.min(axis=0)
        box = (xy.min(axis=0) - 0.02 * span, xy.max(axis=0) + 0.02 * span)
        camera._cache["fov_box"] = box
    return box


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
    t = np.full((H, W), _INF) if t_init is None else t_init.copy()
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


def _surface(camera, shape, rr, cc, t):
    """Hit points (N, 3), camera-facing unit normals and albedo of ``shape`` at pixels (rr, cc)."""
    flat = rr * camera.width + cc
    d = _rays_soa(camera).reshape(3, -1)[:, flat]
    p = np.ascontiguousarray((camera_center_world(camera)[:, None] + t * d).T)
    n = np.array(np.broadcast_to(shape.normals(p), p.shape), dtype=np.float64)
    n /= np.sqrt(n[:, 0] ** 2 + n[:, 1] ** 2 + n[:, 2] ** 2)[:, None]
    flip = n[:, 0] * d[0] + n[:, 1] * d[1] + n[:, 2] * d[2] > 0
    n[flip] *= -1.0
    return p, n, np.asarray(shape.albedo(p), dtype=np.float64)


@dataclass(eq=False)
class _StaticCache:
    t: np.ndarray
    ids: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray
    terms: np.ndarray   # (L, H, W, 3) float32


def _static(camera: PinholeCamera, scene: Scene) -> _StaticCache:
    st = scene._cache.get(camera)
    if st is not None:
        return st
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
        _, n, a = _surface(camera, shape, rr, cc, t_flat[flat])
        normal[flat] = n
        albedo[flat] = a
    # light terms over the whole frame at once (no per-object scatter)
    d = _rays_soa(camera).reshape(3, -1)
    tt = np.where(np.isfinite(t_flat), t_flat, 0.0)
    p = np.ascontiguousarray((camera_center_world(camera)[:, None] + tt * d).T)
    terms = light_terms(scene.lights, p, normal, albedo).reshape(len(scene.lights), H, W, 3)
    st = _StaticCache(t=t, ids=ids, normal=normal.reshape(H, W, 3), albedo=albedo.reshape(H, W, 3), terms=terms)
    scene._cache[camera] = st
    return st


def _dynamic_hits(camera, shapes, full_boxes, st, rows):
    """Cast dynamic ``shapes`` (with their full-image ``full_boxes``) over the static depth in row range ``rows``.

    Returns a list of (j, shape, rr, cc, t) per shape with the pixels it wins.
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
    >>> cam = look_at([0, -2, 0], [0, 0, 0], K=intrinsic_matrix(50, 15.5, 11.5), width=32, height=24)
    >>> g = render_gbuffer(cam, Scene(static=[Sphere(center=(0, 0, 0), radius=0.5)], lights=[AmbientLight()]))
    >>> round(float(g.depth_m[11:13, 15:17].mean()), 2), int(g.object_id[0, 0])
    (1.5, 0)
    """
    st = _static(camera, scene)
    dist = st.t.copy()
    ids = st.ids.copy()
    normal = st.normal.copy()
    albedo = st.albedo.copy()
    if scene.dynamic is not None:
        shapes = list(scene.dynamic(t))
        boxes = pixel_bboxes(camera, [sh.corners() for sh in shapes])
        for j, shape, rr, cc, tj in _dynamic_hits(camera, shapes, boxes, st, (0, camera.height)):
            _, n, a = _surface(camera, shape, rr, cc, tj)
            dist[rr, cc] = tj
            ids[rr, cc] = scene.n_static + 1 + j
            normal[rr, cc] = n
            albedo[rr, cc] = a
    depth = dist * ray_directions_cam(camera)[..., 2]
    return GBuffer(distance_m=dist, depth_m=depth, normal_world=normal, object_id=ids, albedo_rgb=albedo)


def _check_timing(exposure_s, n_subframes, line_time_s, band_rows):
    if not exposure_s >= 0:
        raise ValueError(f"exposure_s: expected >= 0, got {exposure_s!r}")
    if int(n_subframes) != n_subframes or n_subframes < 1:
        raise ValueError(f"n_subframes: expected a positive integer, got {n_subframes!r}")
    if not line_time_s >= 0:
        raise ValueError(f"line_time_s: expected >= 0, got {line_time_s!r}")
    if int(band_rows) != band_rows or band_rows < 1:
        raise ValueError(f"band_rows: expected a positive integer, got {band_rows!r}")


def exposure_times(t: float, *, exposure_s: float = 0.0, n_subframes: int = 1, row: int = 0,
                   line_time_s: float = 0.0) -> np.ndarray:
    """Times at which :func:`render_radiance` samples the dynamic shapes for image row ``row``.

    Average ground truth (e.g. a sphere's silhouette centroid) over these
    times to match a blurred frame. With a rolling shutter the renderer
    rounds them to its band grid (see :func:`render_radiance`).

    Examples
    --------
    >>> exposure_times(1.0, exposure_s=0.02, n_subframes=4).round(4).tolist()
    [1.0025, 1.0075, 1.0125, 1.0175]
    """
    _check_timing(exposure_s, n_subframes, line_time_s, 1)
    start = t + row * line_time_s
    if exposure_s == 0:
        return np.array([start])
    K = int(n_subframes)
    return start + exposure_s * (np.arange(K) + 0.5) / K


def render_radiance(camera: PinholeCamera, scene: Scene, t: float, *, exposure_s: float = 0.0,
                    n_subframes: int = 1, line_time_s: float = 0.0, band_rows: int = 4) -> np.ndarray:
    """Linear RGB radiance of a frame whose exposure starts at ``t``.

    Row ``r`` integrates ``[t + r line_time_s, t + r line_time_s + exposure_s]``
    with ``n_subframes`` samples at the sub-interval midpoints (one sample at
    the start when ``exposure_s`` is 0). With a rolling shutter
    (``line_time_s > 0``) the dynamic shapes are evaluated on a time grid of
    ``band_rows`` line times: each band of ``band_rows`` rows takes the time
    of its middle row and sub-frame offsets are rounded to the grid, so the
    timing error is at most about ``band_rows / 2`` line times.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
    """
    _check_timing(exposure_s, n_subframes, line_time_s, band_rows)
    H = camera.height
    st = _static(camera, scene)
    t_light = t + 0.5 * exposure_s + 0.5 * (H - 1) * line_time_s
    gains = np.array([intensity_at(light, t_light) for light in scene.lights], np.float32)
    base = weighted_sum(gains, st.terms)
    if scene.dynamic is None:
        return base
    K = int(n_subframes) if exposure_s > 0 else 1
    offsets = exposure_s * (np.arange(K) + 0.5) / K if exposure_s > 0 else np.zeros(1)
    if line_time_s > 0:
        # time grid of one band: shapes evaluated once per grid time and shared by the bands
        step = band_rows * line_time_s
        bands = _rolling_bands(camera, scene, t, exposure_s, line_time_s, int(band_rows))
        jobs = [((r0, r1), (r0 // band_rows) + int(round(off / step))) for r0, r1 in bands for off in offsets]

        def time_of(k):
            return t + (k * band_rows + 0.5 * (band_rows - 1)) * line_time_s
    else:
        jobs = [((0, H), k) for k in range(K)]

        def time_of(k):
            return t + offsets[k]
    cache = {}
    out = base.copy()
    for rows, k in jobs:
        if k not in cache:
            shapes = list(scene.dynamic(time_of(k)))
            cache[k] = (shapes, pixel_bboxes(camera, [sh.corners() for sh in shapes]))
        shapes, boxes = cache[k]
        for j, shape, rr, cc, tj in _dynamic_hits(camera, shapes, boxes, st, rows):
            p, n, a = _surface(camera, shape, rr, cc, tj)
            rad = weighted_sum(gains, light_terms(scene.lights, p, n, a))
            out[rr, cc] += (rad - base[rr, cc]) / K
    return out


def _rolling_bands(camera, scene, t, exposure_s, line_time_s, band_rows):
    """Row bands that a dynamic shape can touch during the rolling read-out."""
    H = camera.height
    times = t + np.linspace(0.0, (H - 1) * line_time_s + exposure_s, 9)
    rows = []
    for tt in times:
        boxes = pixel_bboxes(camera, [shape.corners() for shape in scene.dynamic(tt)])
        rows.append([(b[0], b[1]) if b is not None else (np.nan, np.nan) for b in boxes])
    rows = np.array(rows, dtype=float).reshape(len(times), -1, 2)
    if rows.size == 0 or np.all(np.isnan(rows)):
        return []
    # pad by the largest row motion of a shape between two samples
    pad = 4 + int(np.nan_to_num(np.abs(np.diff(rows, axis=0)), nan=0.0).max(initial=0))
    lo, hi = max(int(np.nanmin(rows[..., 0])) - pad, 0), min(int(np.nanmax(rows[..., 1])) + pad, H)
    start = (lo // band_rows) * band_rows
    return [(r0, min(r0 + band_rows, H)) for r0 in range(start, hi, band_rows)]


def render_bgr(camera: PinholeCamera, scene: Scene, t: float, *, rng: np.random.Generator | None = None,
               sensor: SensorModel = SensorModel(), exposure_s: float = 0.0, n_subframes: int = 1,
               line_time_s: float = 0.0, band_rows: int = 4) -> np.ndarray:
    """8-bit BGR colour frame (see :func:`render_radiance` for the timing options).

    Parameters
    ----------
    rng : numpy.random.Generator, optional
        Sensor-noise source; None renders without noise.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8, BGR order
    """
    rad = render_radiance(camera, scene, t, exposure_s=exposure_s, n_subframes=n_subframes,
                          line_time_s=line_time_s, band_rows=band_rows)
    return apply_sensor(rad, sensor, rng)


_SEED_SIGMA_CM = (0.51, -2.1, 5.12, -2.18)


def depth_sigma_m(z_m, coeffs_cm=_SEED_SIGMA_CM) -> np.ndarray:
    """Depth noise of the seed's Kinect fit, sigma_z(z) = 0.51 z^3 - 2.1 z^2 + 5.12 z - 2.18 (cm, z in m).

    Returns metres, clipped at zero.

    Examples
    --------
    >>> round(float(depth_sigma_m(1.0)) * 100, 2)
    1.35
    """
    return np.maximum(np.polyval(coeffs_cm, np.asarray(z_m, dtype=np.float64)), 0.0) / 100.0


@dataclass(frozen=True, kw_only=True)
class DepthModel:
    """Kinect-like depth sensor model.

    Parameters
    ----------
    min_depth_m, max_depth_m : float
        Usable range; pixels whose true z is outside give 0.
    sigma_coeffs_cm : tuple of 4 floats
        Cubic for sigma_z in cm with z in m (highest power first).
    edge_jump_rel : float
        A pixel is invalid when a 4-neighbour's depth differs by more than
        this fraction of its own depth (depth discontinuity).
    edge_width_px : int
        Dilation of the invalid edge band (1: just the pixels at the jump).
    min_albedo : float
        Surfaces darker than this (mean linear RGB albedo) return no depth.
    units_per_m : float
        Scale of the 16-bit output (1000: millimetres).
    """

    min_depth_m: float = 0.6
    max_depth_m: float = 6.0
    sigma_coeffs_cm: tuple = _SEED_SIGMA_CM
    edge_jump_rel: float = 0.03
    edge_width_px: int = 1
    min_albedo: float = 0.03
    units_per_m: float = 1000.0

    def __post_init__(self):
        if not 0 <= self.min_depth_m < self.max_depth_m:
            raise ValueError(f"max_depth_m: expected 0 <= min_depth_m < max_depth_m, got "
                             f"{self.min_depth_m}, {self.max_depth_m}")
        if len(self.sigma_coeffs_cm) != 4:
            raise ValueError(f"sigma_coeffs_cm: expected 4 coefficients, got {len(self.sigma_coeffs_cm)}")
        if not self.edge_jump_rel > 0:
            raise ValueError(f"edge_jump_rel: expected > 0, got {self.edge_jump_rel}")
        if int(self.edge_width_px) != self.edge_width_px or self.edge_width_px < 0:
            raise ValueError(f"edge_width_px: expected a non-negative integer, got {self.edge_width_px}")
        if not self.units_per_m > 0 or self.max_depth_m * self.units_per_m > 65535:
            raise ValueError(f"units_per_m: expected > 0 with max_depth_m * units_per_m <= 65535, "
                             f"got {self.units_per_m}")


def _edge_mask(z: np.ndarray, rel: float, width: int) -> np.ndarray:
    zf = np.where(np.isfinite(z), z, 1e9)
    edge = np.zeros(z.shape, bool)
    for a, b in ((np.s_[:, 1:], np.s_[:, :-1]), (np.s_[1:, :], np.s_[:-1, :])):
        jump = np.abs(zf[a] - zf[b]) > rel * np.minimum(zf[a], zf[b])
        edge[a] |= jump
        edge[b] |= jump
    if width > 1:
        edge = cv2.dilate(edge.view(np.uint8), np.ones((2 * width - 1, 2 * width - 1), np.uint8)).astype(bool)
    return edge if width > 0 else np.zeros_like(edge)


def depth_mm_from_gbuffer(gbuffer: GBuffer, model: DepthModel, rng: np.random.Generator | None) -> np.ndarray:
    """Registered 16-bit depth image from a ray-cast G-buffer.

    Depth is z along the optical axis plus Gaussian noise of std
    sigma_z(z), rounded to ``1 / model.units_per_m`` metres; 0 marks invalid
    pixels (out of range, no hit, depth edges, dark surfaces).

    Returns
    -------
    ndarray, shape (H, W), uint16
    """
    z = gbuffer.depth_m
    valid = np.isfinite(z) & (z >= model.min_depth_m) & (z <= model.max_depth_m)
    valid &= ~_edge_mask(z, model.edge_jump_rel, int(model.edge_width_px))
    valid &= gbuffer.albedo_rgb.mean(axis=2) >= model.min_albedo
    zv = np.where(valid, z, 0.0)
    if rng is not None:
        zv = zv + depth_sigma_m(zv, model.sigma_coeffs_cm) * rng.standard_normal(z.shape)
    out = np.clip(np.rint(zv * model.units_per_m), 1, 65535)
    return np.where(valid, out, 0).astype(np.uint16)


def render_rgbd(camera: PinholeCamera, scene: Scene, t: float, *, rng: np.random.Generator | None = None,
                depth_model: DepthModel = DepthModel(), sensor: SensorModel = SensorModel(),
                exposure_s: float = 0.0, n_subframes: int = 1):
    """Kinect-like frame: colour and registered depth from the same viewpoint at time ``t``.

    Returns
    -------
    bgr : ndarray, shape (H, W, 3), uint8
    depth : ndarray, shape (H, W), uint16
        z in ``1 / depth_model.units_per_m`` metres (millimetres by default), 0 invalid.
    gbuffer : GBuffer
        The noise-free snapshot at ``t`` (ground truth).
    """
    gb = render_gbuffer(camera, scene, t)
    bgr = render_bgr(camera, scene, t, rng=rng, sensor=sensor, exposure_s=exposure_s, n_subframes=n_subframes)
    return bgr, depth_mm_from_gbuffer(gb, depth_model, rng), gb
