"""Shared pieces of the analytic shapes: fast argument checks, row/ray dot products, the base class.

Private to :mod:`tudorvision.sim`; the shapes themselves are in
:mod:`~tudorvision.sim.shapes` and :mod:`~tudorvision.sim.solids`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

EPS = 1e-6
INF = np.inf


def dot(d, v):
    """Dot product of component-first rays ``d`` (3, ...) with a 3-vector (no BLAS: numpy's
    threaded matmul is slow for an inner dimension of 3)."""
    return d[0] * v[0] + d[1] * v[1] + d[2] * v[2]


def rowdot(p, v):
    """``p @ v`` for row points ``p`` (N, 3) and a 3-vector."""
    return p[:, 0] * v[0] + p[:, 1] * v[1] + p[:, 2] * v[2]


def rowmat(p, M):
    """``p @ M`` for row points ``p`` (N, 3) and a 3x3 matrix."""
    return p[:, 0:1] * M[0] + p[:, 1:2] * M[1] + p[:, 2:3] * M[2]


def vec3(value, name):
    """Fast check of a finite 3-vector (shapes are built per sub-frame, so this is a hot path)."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"{name}: expected shape (3,), got {a.shape}")
    x, y, z = a.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return a


def color(value, name):
    c = vec3(value, name)
    if not all(0.0 <= x <= 1.0 for x in c.tolist()):
        raise ValueError(f"{name}: expected linear RGB in [0, 1], got {c.tolist()}")
    return c


def positive(value, name):
    v = float(value)
    if not v > 0:
        raise ValueError(f"{name}: expected > 0, got {value!r}")
    return v


def unit(value, name):
    v = vec3(value, name)
    n = math.sqrt(v @ v)
    if n < 1e-12:
        raise ValueError(f"{name}: must be non-zero")
    return v / n



def init_color(shape) -> None:
    """Validate and store ``shape.color_rgb`` as a linear-RGB array (frozen dataclasses)."""
    object.__setattr__(shape, "color_rgb", color(shape.color_rgb, "color_rgb"))


@dataclass(frozen=True, kw_only=True, eq=False)
class ShapeBase:
    color_rgb: tuple = (0.5, 0.5, 0.5)
    name: str = ""

    def albedo(self, points: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.color_rgb, points.shape)


CUBE = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def box_corners(lo, hi):
    return lo + (CUBE + 1.0) / 2.0 * (hi - lo)


