"""Video files as frame sources (``cv2.VideoCapture``, frame-exact random access).

Frame ``i`` is the ``i``-th frame decoded from the start. Seeking with
``CAP_PROP_POS_FRAMES`` is not used: on some H.264 files it lands one frame
early after a while (on two of the three real ball videos, 88 of 208
labelled frames were off by one), so a jump decodes forward from the
current position, or from the start for a jump back (about 0.7 ms per
skipped 640x480 frame).
"""
from __future__ import annotations

import math
from pathlib import Path

import cv2

from .._checks import TudorVisionError
from ._index import ImageProblem

__all__ = ["VideoSource"]


class VideoSource:
    """An open ``cv2.VideoCapture`` with frame-exact random access (module docstring)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        if not self.path.is_file():
            raise TudorVisionError(f"{self.path}: video file not found")
        self.cap = cv2.VideoCapture(str(self.path))
        if not self.cap.isOpened():
            raise TudorVisionError(f"{self.path}: cannot open as a video")
        fps = self.cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if fps and math.isfinite(fps) and fps > 0 else None
        self.count = max(int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT)), 0)
        self.size = (int(self.cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self.cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.next = 0

    def nominal_t(self, i: int) -> float:
        return i / self.fps if self.fps else float(i)

    def read(self, i: int):
        if self.cap is None:
            raise TudorVisionError(f"{self.path}: sequence is closed")
        if i < self.next or self.next < 0:           # back to the start: seeking is not frame-exact
            self.cap.release()
            self.cap = cv2.VideoCapture(str(self.path))
            self.next = 0
        ok = True
        while ok and self.next < i:                  # decode forward to frame i
            ok = self.cap.grab()
            self.next += 1
        if not ok:
            self.next = -1
            raise ImageProblem(f"cannot decode video frame {i}")
        ok, img = self.cap.read()
        self.next = i + 1 if ok else -1
        if not ok or img is None:
            raise ImageProblem(f"cannot decode video frame {i}")
        t_ms = self.cap.get(cv2.CAP_PROP_POS_MSEC)
        t = t_ms / 1000.0 if (t_ms > 0 or i == 0) else self.nominal_t(i)
        return img, t

    def close(self):
        if self.cap is not None:
            self.cap.release()
            self.cap = None
