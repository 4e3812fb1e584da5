"""Frames of recorded sequences.

Small frozen dataclasses, one per sequence kind; images are numpy arrays in
OpenCV conventions (u right, v down, BGR channel order). Depth unit
conversions live in :mod:`tudorvision.sensors`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Not part of this module: re-exported only while io/sequence.py and io/writer.py import them from here.
from ..sensors import depth_m_from_raw, raw_from_depth_m  # noqa: F401

__all__ = ["StereoFrame", "RGBDFrame", "MonoFrame", "JointLog"]


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
