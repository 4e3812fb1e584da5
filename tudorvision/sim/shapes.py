"""Analytic shapes of the virtual lab and the :class:`Scene` that holds them.

Shapes implement ``intersect(o, d) -> t`` for a common origin ``o`` (3,) and
unit directions ``d`` stored component-first, shape (3, ...) (t is ``inf`` on
a miss), ``normals(p)`` and ``albedo(p)`` for hit points ``p`` (N, 3), and
``corners()`` (points whose hull bounds the shape, or None if unbounded).
Ray casting is in :mod:`tudorvision.sim.raycast`, shading in
:mod:`tudorvision.sim.render`.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from .._checks import check_array

__all__ = ["Sphere", "Rectangle", "Disc", "Box", "Capsule", "Cylinder", "Scene"]


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

    Parameters
    ----------
    center : array_like, shape (3,)
        Centre, metres, world frame.
    radius : float
        Radius, metres (> 0).
    color_rgb : array_like, shape (3,)
        Linear RGB albedo in [0, 1].
    name : str
        Object name; named shapes get an id in :meth:`Scene.object_ids`.

    Raises
    ------
    ValueError
        On a non-finite centre, a non-positive radius or a colour outside [0, 1].

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
        """Corners of a box that bounds the shape (for pixel bounding boxes).

        Returns
        -------
        ndarray, shape (8, 3)
            Box corners, metres, world frame.
        """
        r = self.radius
        return self.center + r * _CUBE

    def intersect(self, o, d):
        """Distance along each ray to the first hit.

        Parameters
        ----------
        o : ndarray, shape (3,)
            Common ray origin, metres, world frame.
        d : ndarray, shape (3, ...)
            Unit ray directions, component-first, world frame.

        Returns
        -------
        t : ndarray, shape (...)
            Hit distance in front of the origin, metres; ``inf`` on a miss.
        """
        oc = o - self.center
        b = _dot(d, oc)
        disc = b * b - (oc @ oc - self.radius ** 2)
        sq = np.sqrt(np.maximum(disc, 0.0))
        t = -b - sq
        t = np.where(t > _EPS, t, -b + sq)
        return np.where((disc >= 0) & (t > _EPS), t, _INF)

    def normals(self, p):
        """Unit surface normals at hit points.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the surface, metres, world frame.

        Returns
        -------
        n : ndarray, shape (N, 3)
            Outward unit normals, world frame.
        """
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
    color2_rgb : array_like, shape (3,)
        Linear RGB albedo of the dark checker squares, in [0, 1].
    color_rgb : array_like, shape (3,)
        Linear RGB albedo in [0, 1].
    name : str
        Object name; named shapes get an id in :meth:`Scene.object_ids`.

    Raises
    ------
    ValueError
        On non-orthogonal or zero axes, non-positive sizes, an invalid
        checker specification or a colour outside [0, 1].
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
        """The four corners of the rectangle.

        Returns
        -------
        ndarray, shape (4, 3) or None
            Corners at ``(-u, -v), (+u, -v), (+u, +v), (-u, +v)``, metres,
            world frame; None for an infinite plane.
        """
        if not np.all(np.isfinite(self.half_size)):
            return None
        hu, hv = self.half_size
        s = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
        return self.center + (s[:, :1] * hu) * self.axis_u + (s[:, 1:] * hv) * self.axis_v

    def intersect(self, o, d):
        """Distance along each ray to the first hit.

        Parameters
        ----------
        o : ndarray, shape (3,)
            Common ray origin, metres, world frame.
        d : ndarray, shape (3, ...)
            Unit ray directions, component-first, world frame.

        Returns
        -------
        t : ndarray, shape (...)
            Hit distance in front of the origin, metres; ``inf`` on a miss.
        """
        rel = o - self.center
        dn, du, dv = _dot(d, self.normal), _dot(d, self.axis_u), _dot(d, self.axis_v)
        on, ou, ov = rel @ self.normal, rel @ self.axis_u, rel @ self.axis_v
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -on / dn
        ok = (t > _EPS) & (np.abs(ou + t * du) <= self.half_size[0]) & (np.abs(ov + t * dv) <= self.half_size[1])
        return np.where(ok, t, _INF)

    def normals(self, p):
        """Unit surface normals at hit points.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the surface, metres, world frame.

        Returns
        -------
        n : ndarray, shape (N, 3)
            The plane normal ``axis_u x axis_v`` for every point (two-sided: not flipped
            toward the viewer), world frame; a read-only broadcast view.
        """
        return np.broadcast_to(self.normal, p.shape)

    def albedo(self, p):
        """Surface colour at points on the rectangle (checker texture if any).

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the rectangle, metres, world frame.

        Returns
        -------
        ndarray, shape (N, 3)
            Linear RGB albedo in [0, 1] per point.
        """
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

        Returns
        -------
        ndarray, shape ((nu-1)*(nv-1), 3)
            Inner corners, metres, world frame; u varies fastest.

        Raises
        ------
        ValueError
            If the rectangle has no ``checker_squares``.
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
    """Flat two-sided disc of ``radius`` at ``center`` with unit ``normal``.

    Parameters
    ----------
    center : array_like, shape (3,)
        Centre, metres, world frame.
    normal : array_like, shape (3,)
        Normal, world frame (made unit; non-zero).
    radius : float
        Radius, metres (> 0).
    color_rgb : array_like, shape (3,)
        Linear RGB albedo in [0, 1].
    name : str
        Object name; named shapes get an id in :meth:`Scene.object_ids`.

    Raises
    ------
    ValueError
        On a non-finite centre, a zero normal, a non-positive radius or a
        colour outside [0, 1].
    """

    center: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    radius: float = 0.075

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "normal", _unit(self.normal, "normal"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def corners(self):
        """Corners of a box that bounds the shape (for pixel bounding boxes).

        Returns
        -------
        ndarray, shape (8, 3)
            Box corners, metres, world frame.
        """
        return self.center + self.radius * _CUBE

    def intersect(self, o, d):
        """Distance along each ray to the first hit.

        Parameters
        ----------
        o : ndarray, shape (3,)
            Common ray origin, metres, world frame.
        d : ndarray, shape (3, ...)
            Unit ray directions, component-first, world frame.

        Returns
        -------
        t : ndarray, shape (...)
            Hit distance in front of the origin, metres; ``inf`` on a miss.
        """
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.center - o) @ self.normal) / _dot(d, self.normal)
        oc = o - self.center
        r2 = (oc[0] + t * d[0]) ** 2 + (oc[1] + t * d[1]) ** 2 + (oc[2] + t * d[2]) ** 2
        ok = (t > _EPS) & (r2 <= self.radius ** 2)
        return np.where(ok, t, _INF)

    def normals(self, p):
        """Unit surface normals at hit points.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the surface, metres, world frame.

        Returns
        -------
        n : ndarray, shape (N, 3)
            The disc normal for every point (two-sided: not flipped toward the
            viewer), world frame; a read-only broadcast view.
        """
        return np.broadcast_to(self.normal, p.shape)


@dataclass(frozen=True, kw_only=True, eq=False)
class Box(_Shape):
    """Oriented box: ``R_world_box`` columns are its axes, ``half_extents`` (3,) in metres.

    Parameters
    ----------
    center : array_like, shape (3,)
        Centre, metres, world frame.
    half_extents : array_like, shape (3,)
        Half side lengths along the box axes, metres (> 0).
    R_world_box : array_like, shape (3, 3)
        Rotation whose columns are the box axes in the world frame.
    color_rgb : array_like, shape (3,)
        Linear RGB albedo in [0, 1].
    name : str
        Object name; named shapes get an id in :meth:`Scene.object_ids`.

    Raises
    ------
    ValueError
        On a non-finite centre, non-positive half extents, an improper
        rotation or a colour outside [0, 1].
    """

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
        """The eight corners of the box.

        Returns
        -------
        ndarray, shape (8, 3)
            Corners, metres, world frame.
        """
        return self.center + (_CUBE * self.half_extents) @ self.R_world_box.T

    def intersect(self, o, d):
        """Distance along each ray to the first hit.

        Parameters
        ----------
        o : ndarray, shape (3,)
            Common ray origin, metres, world frame.
        d : ndarray, shape (3, ...)
            Unit ray directions, component-first, world frame.

        Returns
        -------
        t : ndarray, shape (...)
            Hit distance in front of the origin, metres; ``inf`` on a miss.
        """
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
        """Unit surface normals at hit points.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the surface, metres, world frame.

        Returns
        -------
        n : ndarray, shape (N, 3)
            Outward unit normals of the face each point lies on, world frame.
        """
        pl = _rowmat(p - self.center, self.R_world_box) / self.half_extents
        k = np.argmax(np.abs(pl), axis=1)
        sign = np.sign(pl[np.arange(len(pl)), k])
        return self.R_world_box.T[k] * sign[:, None]


@dataclass(frozen=True, kw_only=True, eq=False)
class Capsule(_Shape):
    """Segment ``p0``–``p1`` (world, m) swept by a sphere of ``radius``: a link of the arm.

    Parameters
    ----------
    p0, p1 : array_like, shape (3,)
        End points of the axis segment, metres, world frame.
    radius : float
        Radius, metres (> 0).
    color_rgb : array_like, shape (3,)
        Linear RGB albedo in [0, 1].
    name : str
        Object name; named shapes get an id in :meth:`Scene.object_ids`.

    Raises
    ------
    ValueError
        On non-finite end points, a non-positive radius or a colour outside [0, 1].
    """

    p0: tuple = (0.0, 0.0, 0.0)
    p1: tuple = (0.0, 0.0, 1.0)
    radius: float = 0.01

    def __post_init__(self):
        self._init_color()
        object.__setattr__(self, "p0", _vec3(self.p0, "p0"))
        object.__setattr__(self, "p1", _vec3(self.p1, "p1"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def corners(self):
        """Corners of a box that bounds the shape (for pixel bounding boxes).

        Returns
        -------
        ndarray, shape (8, 3)
            Box corners, metres, world frame.
        """
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
        """Distance along each ray to the first hit.

        Parameters
        ----------
        o : ndarray, shape (3,)
            Common ray origin, metres, world frame.
        d : ndarray, shape (3, ...)
            Unit ray directions, component-first, world frame.

        Returns
        -------
        t : ndarray, shape (...)
            Hit distance in front of the origin, metres; ``inf`` on a miss.
        """
        t = self._body(o, d)
        for cap in (self.p0, self.p1):
            t = np.minimum(t, Sphere(center=cap, radius=self.radius).intersect(o, d))
        return t

    def normals(self, p):
        """Unit surface normals at hit points.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the surface, metres, world frame.

        Returns
        -------
        n : ndarray, shape (N, 3)
            Outward unit normals (from the nearest axis point), world frame.
        """
        ba = self.p1 - self.p0
        s = np.clip(_rowdot(p - self.p0, ba) / max(ba @ ba, 1e-300), 0.0, 1.0)
        return (p - self.p0 - s[:, None] * ba) / self.radius


@dataclass(frozen=True, kw_only=True, eq=False)
class Cylinder(Capsule):
    """Capped solid cylinder with axis ``p0``–``p1`` and ``radius`` (the robot base).

    Parameters
    ----------
    p0, p1 : array_like, shape (3,)
        Centres of the two end caps, metres, world frame.
    radius : float
        Radius, metres (> 0).
    color_rgb : array_like, shape (3,)
        Linear RGB albedo in [0, 1].
    name : str
        Object name; named shapes get an id in :meth:`Scene.object_ids`.

    Raises
    ------
    ValueError
        On non-finite end points, a non-positive radius or a colour outside [0, 1].
    """

    def intersect(self, o, d):
        """Distance along each ray to the first hit.

        Parameters
        ----------
        o : ndarray, shape (3,)
            Common ray origin, metres, world frame.
        d : ndarray, shape (3, ...)
            Unit ray directions, component-first, world frame.

        Returns
        -------
        t : ndarray, shape (...)
            Hit distance in front of the origin, metres; ``inf`` on a miss.
        """
        t = self._body(o, d)
        axis = _unit(self.p1 - self.p0, "p1")
        for cap in (self.p0, self.p1):
            t = np.minimum(t, Disc(center=cap, normal=axis, radius=self.radius).intersect(o, d))
        return t

    def normals(self, p):
        """Unit surface normals at hit points.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the surface, metres, world frame.

        Returns
        -------
        n : ndarray, shape (N, 3)
            Outward unit normals: the axis direction on the caps, radial on
            the side, world frame.
        """
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

    def cached_for(self, camera, make: Callable[[], Any]) -> Any:
        """Data this scene keeps per camera (the static shapes' ray-cast), computed by ``make()`` on first use.

        Parameters
        ----------
        camera : PinholeCamera
            The camera (held weakly: the entry goes with the camera).
        make : callable
            ``make() -> value``, called only when nothing is cached for ``camera``.

        Returns
        -------
        object
            The cached value (treat it as read-only).
        """
        value = self._cache.get(camera)
        if value is None:
            value = make()
            self._cache[camera] = value
        return value

    def object_ids(self, t: float = 0.0) -> dict:
        """Map shape name -> object id for every named shape (dynamic ones evaluated at ``t``).

        Parameters
        ----------
        t : float, optional
            Time at which the dynamic shapes are evaluated, seconds.

        Returns
        -------
        dict of str to int
            Object id per name: static shapes ``1 .. n_static`` in order, then
            the dynamic ones (0 means no hit in a ``GBuffer``).
        """
        out = {}
        for i, s in enumerate(self.static):
            if s.name:
                out[s.name] = i + 1
        if self.dynamic is not None:
            for j, s in enumerate(self.dynamic(t)):
                if s.name:
                    out[s.name] = self.n_static + 1 + j
        return out
