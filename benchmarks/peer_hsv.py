"""Peer baseline: coloured-ball detection the way tutorials write it.

Gaussian blur, ``cv2.cvtColor`` to HSV (once per frame, shared by the
colours), ``cv2.inRange`` with hand-set ranges (two ranges for red, whose hue
wraps), erosion and dilation with the default 3x3 element (two iterations
each), ``cv2.findContours``, the largest contour, ``cv2.minEnclosingCircle``:
its centre is the ball position. Used by ``bench_segment.py`` for speed and
accuracy ratios; not part of the package.
"""
from __future__ import annotations

import cv2
import numpy as np

# hand-set for the benchmark's sphere colours (OpenCV HSV: H 0..179, S and V 0..255)
RANGES = {
    "red": [((0, 150, 120), (8, 255, 255)), ((170, 150, 120), (179, 255, 255))],
    "green": [((45, 120, 100), (75, 255, 255))],
}


def detect_peer(frame_bgr: np.ndarray, ranges=RANGES) -> dict:
    """``{name: (u, v) or None}`` for each colour range set, tutorial style."""
    blurred = cv2.GaussianBlur(frame_bgr, (11, 11), 0)
    hsv = cv2.cvtColor(blurred, cv2.COLOR_BGR2HSV)
    out = {}
    for name, parts in ranges.items():
        mask = None
        for lo, hi in parts:
            m = cv2.inRange(hsv, np.array(lo, np.uint8), np.array(hi, np.uint8))
            mask = m if mask is None else cv2.bitwise_or(mask, m)
        mask = cv2.erode(mask, None, iterations=2)
        mask = cv2.dilate(mask, None, iterations=2)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if not contours:
            out[name] = None
            continue
        c = max(contours, key=cv2.contourArea)
        (x, y), _radius = cv2.minEnclosingCircle(c)
        out[name] = (float(x), float(y))
    return out
