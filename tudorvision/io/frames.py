"""Frames of recorded sequences and depth unit conversions.

Small frozen dataclasses, one per sequence kind; images are numpy arrays in
OpenCV conventions (u right, v down, BGR channel order).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["StereoFrame", "RGBDFrame", "MonoFrame", "JointLog", "depth_m_from_raw", "raw_from_depth_m"]


@dataclass(frozen=True, eq=False)
class StereoFrame:
    """A stereo pair. ``left``, ``right``: (H, W, 3) uint8 BGR (or (H, W) grey) images."""

    t: float
    index: int
    left: np.ndarray
    right: np.ndarray


@dataclass(frozen=True, eq=False)
class RGBDFrame:
    """A registered colour + depth frame.

    Attributes
    ----------
    t : float
        Colour timestamp, seconds.
    index : int
        0-based frame index in the sequence.
    rgb : ndarray, shape (H, W, 3), uint8
        Colour image in OpenCV **BGR** channel order (named after the
        stream; :attr:`bgr` is the same array).
    depth_raw : ndarray, shape (H, W), uint16
        Raw depth, 0 = invalid.
    depth_m : ndarray, shape (H, W), float32
        Depth along the optical axis in metres, NaN where invalid.
    t_depth : float
        Depth timestamp, seconds (differs from ``t`` in TUM recordings).
    """

    t: float
    index: int
    rgb: np.ndarray
    depth_raw: np.ndarray
    depth_m: np.ndarray
    t_depth: float

    @property
    def bgr(self) -> np.ndarray:
        return self.rgb

    @property
    def valid(self) -> np.ndarray:
        """(H, W) bool mask of pixels with a depth measurement."""
        return self.depth_raw > 0


@dataclass(frozen=True, eq=False)
class MonoFrame:
    """One image: (H, W, 3) uint8 BGR or (H, W) grey."""

    t: float
    index: int
    image: np.ndarray


@dataclass(frozen=True, eq=False)
class JointLog:
    """Joint angles as the joint-control layer logs them.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Timestamps, seconds, increasing.
    theta_rad : ndarray, shape (N, 3)
        ``[theta1, theta2, theta3]`` in radians.
    """

    t: np.ndarray
    theta_rad: np.ndarray

    def at(self, t) -> np.ndarray:
        """Joint angles linearly interpolated at time(s) ``t``; shape ``(3,)`` or ``(M, 3)``."""
        tq = np.asarray(t, dtype=np.float64)
        out = np.stack([np.interp(tq, self.t, self.theta_rad[:, k]) for k in range(3)], axis=-1)
        return out


# ----------------------------------------------------------------------------- depth units
def depth_m_from_raw(depth_raw, depth_scale: float, *, dtype=np.float32) -> np.ndarray:
    """Metres from raw 16-bit depth; 0 (invalid) becomes NaN.

    The one conversion of the package: :func:`tudorvision.rgbd.depth_m_from_raw`
    adds shape and plausibility checks on top of it.

    Parameters
    ----------
    depth_raw : array_like, shape (H, W), integer
        Raw depth values.
    depth_scale : float
        Raw units per metre (1000 for millimetres, 5000 for TUM).
    dtype : numpy dtype, optional
        Output type (float32 by default, half the memory of float64).

    Returns
    -------
    ndarray, shape (H, W), ``dtype``

    Examples
    --------
    >>> depth_m_from_raw(np.array([[0, 1500]], np.uint16), 1000.0)
    array([[nan, 1.5]], dtype=float32)
    """
    if not (isinstance(depth_scale, (int, float)) and math.isfinite(depth_scale) and depth_scale > 0):
        raise ValueError(f"depth_scale: expected a positive number of units per metre, got {depth_scale!r}")
    raw = np.asarray(depth_raw)
    dtype = np.dtype(dtype)
    out = raw.astype(dtype) / dtype.type(depth_scale)
    out[raw == 0] = np.nan
    return out


def raw_from_depth_m(depth_m, depth_scale: float) -> np.ndarray:
    """Raw uint16 depth from metres; NaN, non-positive and out-of-range values become 0.

    Examples
    --------
    >>> raw_from_depth_m(np.array([[np.nan, 1.5, 70.0]]), 1000.0)
    array([[   0, 1500,    0]], dtype=uint16)
    """
    if not (isinstance(depth_scale, (int, float)) and math.isfinite(depth_scale) and depth_scale > 0):
        raise ValueError(f"depth_scale: expected a positive number of units per metre, got {depth_scale!r}")
    d = np.asarray(depth_m, dtype=np.float64) * depth_scale
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(d) & (d >= 0.5) & (d < 65535.5)
    out = np.zeros(d.shape, np.uint16)
    out[ok] = np.rint(d[ok]).astype(np.uint16)
    return out
