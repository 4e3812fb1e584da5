"""Kinect-like depth sensor model: range limits, sigma_z(z) noise, invalid edges and dark surfaces.

The noise is a :class:`tudorvision.sensors.DepthNoiseModel` (SI units); by
default the seed's Kinect fit :data:`tudorvision.sensors.KINECT_DEPTH_NOISE`
(sigma read in millimetres: 1.35 mm at 1 m, 35 mm at 5 m). The output is
rounded to ``1 / units_per_m`` (1 mm), which adds ``1 mm / sqrt(12)`` of
quantisation spread where sigma is of that order (below about 1.5 m).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..sensors import KINECT_DEPTH_NOISE, KINECT_RANGE_M, DepthNoiseModel
from .raycast import GBuffer

__all__ = ["DepthSensorModel", "depth_mm_from_gbuffer"]


@dataclass(frozen=True, kw_only=True)
class DepthSensorModel:
    """Kinect-like depth sensor model.

    Parameters
    ----------
    min_depth_m, max_depth_m : float
        Usable range, metres; pixels whose true z is outside give 0.
    noise : tudorvision.sensors.DepthNoiseModel
        Depth noise sigma_z(z) in metres (default: the seed's Kinect fit).
    edge_jump_rel : float
        A pixel is invalid when a 4-neighbour's depth differs by more than
        this fraction of its own depth (depth discontinuity).
    edge_width_px : int
        Dilation of the invalid edge band (1: just the pixels at the jump).
    min_albedo : float
        Surfaces darker than this (mean linear RGB albedo) return no depth.
    units_per_m : float
        Scale of the 16-bit output (1000: millimetres).

    Raises
    ------
    ValueError
        An empty range, a ``noise`` that is not a ``DepthNoiseModel``, a
        non-positive ``edge_jump_rel``, a bad ``edge_width_px`` or a scale
        that does not fit ``max_depth_m`` in 16 bits.

    Examples
    --------
    >>> m = DepthSensorModel()
    >>> (m.min_depth_m, m.max_depth_m, round(float(m.noise.sigma_m(1.0)), 5))    # 1.35 mm at 1 m
    (0.6, 6.0, 0.00135)
    """

    min_depth_m: float = KINECT_RANGE_M[0]
    max_depth_m: float = KINECT_RANGE_M[1]
    noise: DepthNoiseModel = KINECT_DEPTH_NOISE
    edge_jump_rel: float = 0.03
    edge_width_px: int = 1
    min_albedo: float = 0.03
    units_per_m: float = 1000.0

    def __post_init__(self):
        if not 0 <= self.min_depth_m < self.max_depth_m:
            raise ValueError(f"max_depth_m: expected 0 <= min_depth_m < max_depth_m, got "
                             f"{self.min_depth_m}, {self.max_depth_m}")
        if not isinstance(self.noise, DepthNoiseModel):
            raise ValueError(f"noise: expected a tudorvision.sensors.DepthNoiseModel, got {type(self.noise).__name__}")
        if not self.edge_jump_rel > 0:
            raise ValueError(f"edge_jump_rel: expected > 0, got {self.edge_jump_rel}")
        if int(self.edge_width_px) != self.edge_width_px or self.edge_width_px < 0:
            raise ValueError(f"edge_width_px: expected a non-negative integer, got {self.edge_width_px}")
        if not self.units_per_m > 0 or self.max_depth_m * self.units_per_m > 65535:
            raise ValueError(f"units_per_m: expected > 0 with max_depth_m * units_per_m <= 65535, "
                             f"got {self.units_per_m}")

    @property
    def sigma_coeffs_cm(self) -> DepthNoiseModel:
        """Deprecated stand-in for ``sim/roi_render.py`` until it calls ``model.noise.sigma_m``; remove then."""
        return self.noise


#: Old name, kept only while ``sim/render.py`` imports it; use :class:`DepthSensorModel`.
DepthModel = DepthSensorModel


def depth_sigma_m(z_m, noise: DepthNoiseModel = KINECT_DEPTH_NOISE) -> np.ndarray:
    """Deprecated: ``noise.sigma_m(z_m)``; kept only while ``sim/render.py`` and ``sim/roi_render.py`` import it."""
    return noise.sigma_m(z_m)


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


def depth_mm_from_gbuffer(gbuffer: GBuffer, model: DepthSensorModel,
                          rng: np.random.Generator | None) -> np.ndarray:
    """Registered 16-bit depth image from a ray-cast G-buffer.

    Depth is z along the optical axis plus Gaussian noise of std
    ``model.noise.sigma_m(z)``, rounded to ``1 / model.units_per_m`` metres;
    0 marks invalid pixels (out of range, no hit, depth edges, dark surfaces).

    Parameters
    ----------
    gbuffer : GBuffer
        Ray-cast buffers; ``depth_m`` (H, W) in metres, ``albedo_rgb`` (H, W, 3).
    model : DepthSensorModel
        Range, noise, edge and albedo rules, output scale.
    rng : numpy.random.Generator or None
        Noise source (one ``standard_normal((H, W))`` draw); None: no noise.

    Returns
    -------
    ndarray, shape (H, W), uint16
        Raw depth in ``1 / model.units_per_m`` metres, 0 = invalid.
    """
    z = gbuffer.depth_m
    valid = np.isfinite(z) & (z >= model.min_depth_m) & (z <= model.max_depth_m)
    valid &= ~_edge_mask(z, model.edge_jump_rel, int(model.edge_width_px))
    valid &= gbuffer.albedo_rgb.mean(axis=2) >= model.min_albedo
    zv = np.where(valid, z, 0.0)
    if rng is not None:
        zv = model.noise.noisy_depth_m(zv, rng)
    out = np.clip(np.rint(zv * model.units_per_m), 1, 65535)
    return np.where(valid, out, 0).astype(np.uint16)
