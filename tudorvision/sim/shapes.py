"""Analytic shapes of the virtual lab and the :class:`Scene` that holds them.

Shapes implement ``intersect(o, d) -> t`` for a common origin ``o`` (3,) and
unit directions ``d`` stored component-first, shape (3, ...) (t is ``inf`` on
a miss), ``normals(p)`` and ``albedo(p)`` for hit points ``p`` (N, 3), and
``corners()`` (points whose hull bounds the shape, or None if unbounded).
The shapes live in :mod:`~tudorvision.sim.primitives` (sphere, rectangle,
disc) and :mod:`~tudorvision.sim.solids` (box, capsule, cylinder); this
module re-exports them. Ray casting is in :mod:`tudorvision.sim.raycast`,
shading in :mod:`tudorvision.sim.render`.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from .primitives import Disc, Rectangle, Sphere
from .solids import Box, Capsule, Cylinder

__all__ = ["Sphere", "Rectangle", "Disc", "Box", "Capsule", "Cylinder", "Scene"]


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
