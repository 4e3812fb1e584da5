"""Kinect-like depth sensor model: range limits, sigma_z(z) noise, invalid edges and dark surfaces."""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .raycast import GBuffer

__all__ = ["DepthModel", "depth_sigma_m", "depth_mm_from_gbuffer"]


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
