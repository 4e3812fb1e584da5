"""One BGR frame for segmentation: input checks and the per-frame plane cache (internal).

Shared by :mod:`.colormodel`, :mod:`.segment`, :mod:`.tracker2d` and
:mod:`.pipeline`; nothing here is part of the public API of
:mod:`tudorvision.stereo`.
"""
from __future__ import annotations

import cv2
import numpy as np

from tudorvision._checks import TudorVisionError

__all__ = ["check_frame", "check_hsv", "FramePlanes"]


def check_frame(frame_bgr, name: str = "frame_bgr") -> np.ndarray:
    """``frame_bgr`` as an array, checked to be a uint8 BGR image of shape (H, W, 3).

    Raises
    ------
    TudorVisionError
        Naming ``name``, the expected and the actual dtype and shape.
    """
    arr = np.asarray(frame_bgr)
    if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise TudorVisionError(
            f"{name}: expected a uint8 BGR image of shape (H, W, 3), got {arr.dtype} {arr.shape}")
    return arr


def check_hsv(hsv, shape) -> np.ndarray:
    """``hsv`` as an array, checked to be a uint8 image of the frame's ``shape``.

    Raises
    ------
    TudorVisionError
        Wrong dtype or shape.
    """
    arr = np.asarray(hsv)
    if arr.dtype != np.uint8 or arr.shape != shape:
        raise TudorVisionError(f"hsv: expected a uint8 HSV image of shape {shape}, got {arr.dtype} {arr.shape}")
    return arr


class FramePlanes:
    """Per-frame cache: HSV and the six 8-bit planes B, G, R, H, S, V, shared between spheres.

    Parameters
    ----------
    bgr : ndarray, shape (H, W, 3), uint8
        The checked frame (:func:`check_frame`).
    hsv : ndarray, shape (H, W, 3), uint8, optional
        Its OpenCV HSV image when already computed (:func:`check_hsv`).
    """

    def __init__(self, bgr: np.ndarray, hsv: np.ndarray | None = None):
        self.bgr = bgr
        self.hsv = hsv
        self.height, self.width = bgr.shape[:2]
        self._full = None
        self._coarse = {}
        #: per-frame memo of refinements keyed by their inputs (segment's chroma edge)
        self.results = {}

    @classmethod
    def checked(cls, frame_bgr, hsv=None) -> "FramePlanes":
        """The cache of a caller's frame, after :func:`check_frame` and (when given) :func:`check_hsv`."""
        bgr = check_frame(frame_bgr)
        return cls(bgr, None if hsv is None else check_hsv(hsv, bgr.shape))

    def full_planes(self):
        """The six full-resolution planes ``(B, G, R, H, S, V)``, computed once."""
        if self._full is None:
            if self.hsv is None:
                self.hsv = cv2.cvtColor(self.bgr, cv2.COLOR_BGR2HSV)
            self._full = (*cv2.split(self.bgr), *cv2.split(self.hsv))
        return self._full

    def coarse_planes(self, step: int):
        """The six planes of the frame decimated by ``step`` (nearest neighbour), computed once per step."""
        if step not in self._coarse:
            size = (self.width // step, self.height // step)
            small = cv2.resize(self.bgr, size, interpolation=cv2.INTER_NEAREST)
            self._coarse[step] = (*cv2.split(small), *cv2.split(cv2.cvtColor(small, cv2.COLOR_BGR2HSV)))
        return self._coarse[step]

    def window_planes(self, x0: int, y0: int, w: int, h: int):
        """The six planes of the window ``(x0, y0, w, h)`` (views of the full planes when computed)."""
        if self._full is not None:
            return tuple(p[y0:y0 + h, x0:x0 + w] for p in self._full)
        win = self.bgr[y0:y0 + h, x0:x0 + w]
        hw = cv2.cvtColor(win, cv2.COLOR_BGR2HSV) if self.hsv is None else self.hsv[y0:y0 + h, x0:x0 + w]
        return (*cv2.split(win), *cv2.split(hw))
