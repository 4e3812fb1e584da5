"""Primitive shapes of the virtual lab: spheres, rectangles and discs.

Same interface as every shape (``intersect``, ``normals``, ``albedo``,
``corners``; see :mod:`~tudorvision.sim.shapes`, which re-exports them).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array
from ._shape_core import EPS, INF, CUBE, ShapeBase, color, dot, init_color, positive, rowdot, unit, vec3

__all__ = ["Sphere", "Rectangle", "Disc"]


@dataclass(frozen=True, kw_only=True, eq=False)
class Sphere(ShapeBase):
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
        init_color(self)
        object.__setattr__(self, "center", vec3(self.center, "center"))
        object.__setattr__(self, "radius", positive(self.radius, "radius"))

    def corners(self):
        """Corners of a box that bounds the shape (for pixel bounding boxes).

        Returns
        -------
        ndarray, shape (8, 3)
            Box corners, metres, world frame.
        """
        r = self.radius
        return self.center + r * CUBE

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
        b = dot(d, oc)
        disc = b * b - (oc @ oc - self.radius ** 2)
        sq = np.sqrt(np.maximum(disc, 0.0))
        t = -b - sq
        t = np.where(t > EPS, t, -b + sq)
        return np.where((disc >= 0) & (t > EPS), t, INF)

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
class Rectangle(ShapeBase):
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
        init_color(self)
        object.__setattr__(self, "color2_rgb", color(self.color2_rgb, "color2_rgb"))
        object.__setattr__(self, "center", vec3(self.center, "center"))
        u, v = unit(self.axis_u, "axis_u"), unit(self.axis_v, "axis_v")
        if abs(u @ v) > 1e-6:
            raise ValueError("axis_v: must be orthogonal to axis_u")
        object.__setattr__(self, "axis_u", u)
        object.__setattr__(self, "axis_v", v)
        hs = check_array(self.half_size, "half_size", (2,), finite=False)
        if np.any(~(hs > 0)):
            raise ValueError(f"half_size: expected positive values, got {hs.tolist()}")
        object.__setattr__(self, "half_size", hs)
        if self.checker_square_m is not None:
            positive(self.checker_square_m, "checker_square_m")
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
        dn, du, dv = dot(d, self.normal), dot(d, self.axis_u), dot(d, self.axis_v)
        on, ou, ov = rel @ self.normal, rel @ self.axis_u, rel @ self.axis_v
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -on / dn
        ok = (t > EPS) & (np.abs(ou + t * du) <= self.half_size[0]) & (np.abs(ov + t * dv) <= self.half_size[1])
        return np.where(ok, t, INF)

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
        a, b = rowdot(rel, self.axis_u), rowdot(rel, self.axis_v)
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
class Disc(ShapeBase):
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
        init_color(self)
        object.__setattr__(self, "center", vec3(self.center, "center"))
        object.__setattr__(self, "normal", unit(self.normal, "normal"))
        object.__setattr__(self, "radius", positive(self.radius, "radius"))

    def corners(self):
        """Corners of a box that bounds the shape (for pixel bounding boxes).

        Returns
        -------
        ndarray, shape (8, 3)
            Box corners, metres, world frame.
        """
        return self.center + self.radius * CUBE

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
            t = ((self.center - o) @ self.normal) / dot(d, self.normal)
        oc = o - self.center
        r2 = (oc[0] + t * d[0]) ** 2 + (oc[1] + t * d[1]) ** 2 + (oc[2] + t * d[2]) ** 2
        ok = (t > EPS) & (r2 <= self.radius ** 2)
        return np.where(ok, t, INF)

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


