"""Solid shapes of the virtual lab: oriented boxes, capsules and cylinders.

Same interface as :mod:`~tudorvision.sim.shapes` (``intersect``, ``normals``,
``albedo``, ``corners``); :mod:`tudorvision.sim.shapes` re-exports them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks import check_array
from .primitives import Disc, Sphere
from ._shape_core import EPS, INF, CUBE, ShapeBase, box_corners, dot, init_color, positive, rowdot, rowmat, unit, vec3

__all__ = ["Box", "Capsule", "Cylinder"]


@dataclass(frozen=True, kw_only=True, eq=False)
class Box(ShapeBase):
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
        init_color(self)
        object.__setattr__(self, "center", vec3(self.center, "center"))
        h = vec3(self.half_extents, "half_extents")
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
        return self.center + (CUBE * self.half_extents) @ self.R_world_box.T

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
        tmin, tmax = -INF, INF
        with np.errstate(divide="ignore", invalid="ignore"):
            for k in range(3):
                inv = 1.0 / dot(d, R[:, k])
                t1 = (-h[k] - ol[k]) * inv
                t2 = (h[k] - ol[k]) * inv
                tmin = np.maximum(tmin, np.minimum(t1, t2))
                tmax = np.minimum(tmax, np.maximum(t1, t2))
        t = np.where(tmin > EPS, tmin, tmax)
        return np.where((tmax >= tmin) & (t > EPS), t, INF)

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
        pl = rowmat(p - self.center, self.R_world_box) / self.half_extents
        k = np.argmax(np.abs(pl), axis=1)
        sign = np.sign(pl[np.arange(len(pl)), k])
        return self.R_world_box.T[k] * sign[:, None]


@dataclass(frozen=True, kw_only=True, eq=False)
class Capsule(ShapeBase):
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
        init_color(self)
        object.__setattr__(self, "p0", vec3(self.p0, "p0"))
        object.__setattr__(self, "p1", vec3(self.p1, "p1"))
        object.__setattr__(self, "radius", positive(self.radius, "radius"))

    def corners(self):
        """Corners of a box that bounds the shape (for pixel bounding boxes).

        Returns
        -------
        ndarray, shape (8, 3)
            Box corners, metres, world frame.
        """
        lo = np.minimum(self.p0, self.p1) - self.radius
        hi = np.maximum(self.p0, self.p1) + self.radius
        return box_corners(lo, hi)

    def _body(self, o, d):
        ba = self.p1 - self.p0
        oa = o - self.p0
        baba, baoa = ba @ ba, ba @ oa
        bard, rdoa = dot(d, ba), dot(d, oa)
        a = baba - bard * bard
        b = baba * rdoa - baoa * bard
        c = baba * (oa @ oa) - baoa * baoa - self.radius ** 2 * baba
        h = b * b - a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (-b - np.sqrt(np.maximum(h, 0.0))) / a
        y = baoa + t * bard
        ok = (h >= 0) & (a > 1e-12) & (t > EPS) & (y > 0) & (y < baba)
        return np.where(ok, t, INF)

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
        s = np.clip(rowdot(p - self.p0, ba) / max(ba @ ba, 1e-300), 0.0, 1.0)
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
        axis = unit(self.p1 - self.p0, "p1")
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
        s = rowdot(p - self.p0, axis)
        radial = p - self.p0 - s[:, None] * axis
        rn = np.linalg.norm(radial, axis=1)
        on_cap = rn < self.radius * (1 - 1e-6)
        cap_n = np.where((s < L / 2)[:, None], -axis, axis)
        with np.errstate(divide="ignore", invalid="ignore"):
            side = radial / rn[:, None]
        return np.where(on_cap[:, None], cap_n, side)


