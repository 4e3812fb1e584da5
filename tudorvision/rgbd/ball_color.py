"""Ball detection in colour-only video by background subtraction (the colour mode of :mod:`.ball`).

A background from the median of the first frames, updated as a running
average where no foreground is seen; foreground = largest absolute channel
difference above a threshold; opening; blobs whose radius and compactness
fit a ball give pixel detections.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ColorBallOptions", "ColorBallDetector", "PixelDetection"]


@dataclass(frozen=True, kw_only=True)
class ColorBallOptions:
    """Options of the colour-only detector (full-resolution pixels, 8-bit intensities).

    Parameters
    ----------
    min_radius_px, max_radius_px : float
        Plausible ball radius; compared with half the short side of the blob's
        minimum-area rectangle (motion blur stretches the long side only).
    max_elongation : float
        Largest long / short side ratio (motion blur streaks).
    min_fill : float
        Smallest blob area / rectangle area (a disc fills pi/4 of its square).
    diff_threshold : int
        Foreground when the largest channel difference to the background exceeds it.
    learning_rate : float
        Running-average rate of the background where no foreground is seen.
    n_background : int
        Initial frames whose median is the first background.
    downsample : int
        Processing scale (2: half resolution).
    """

    min_radius_px: float = 5.0
    max_radius_px: float = 40.0
    max_elongation: float = 5.0
    min_fill: float = 0.5
    diff_threshold: int = 25
    learning_rate: float = 0.05
    n_background: int = 5
    downsample: int = 2


@dataclass(frozen=True)
class PixelDetection:
    """A colour-only detection: ``uv`` (2,) blob centroid in full-resolution
    pixels (the mean position over the exposure under motion blur),
    ``radius_px`` half the blob's short side, ``elongation`` long / short side,
    ``fill`` blob area / rectangle area."""

    uv: np.ndarray
    radius_px: float
    elongation: float
    fill: float


class ColorBallDetector:
    """Ball detection in colour-only video by background subtraction.

    Among the plausible blobs, the one nearest the constant-velocity
    prediction of the track is taken; without a track (or when no blob lies
    in the gate) the most compact blob not touching the image border.

    Parameters
    ----------
    options : ColorBallOptions
        Blob size and shape limits, foreground threshold, background
        learning rate and processing scale.

    Examples
    --------
    >>> det = ColorBallDetector(ColorBallOptions(n_background=1, downsample=1))
    >>> wall = np.full((120, 160, 3), 200, np.uint8)
    >>> det.update(wall) is None
    True
    >>> f = wall.copy(); vv, uu = np.mgrid[:120, :160]
    >>> f[(uu - 50) ** 2 + (vv - 60) ** 2 <= 64] = (40, 160, 40)
    >>> np.round(det.update(f).uv).tolist()
    [50.0, 60.0]
    """

    def __init__(self, options: ColorBallOptions = ColorBallOptions()):
        self.options = options
        self._init: list[np.ndarray] = []
        self.background: np.ndarray | None = None
        self._track: list[np.ndarray] = []

    def _prep(self, frame) -> np.ndarray:
        import cv2

        img = np.asarray(frame)
        if img.ndim == 2:
            img = img[:, :, None]
        if img.ndim != 3 or img.dtype != np.uint8:
            raise ValueError(f"frame: expected a uint8 image (H, W) or (H, W, C), got {img.dtype} {img.shape}")
        n = self.options.downsample
        if n > 1:
            img = cv2.resize(img, (img.shape[1] // n, img.shape[0] // n), interpolation=cv2.INTER_AREA)
            if img.ndim == 2:
                img = img[:, :, None]
        return cv2.GaussianBlur(img, (3, 3), 0).reshape(img.shape).astype(np.float32)

    def _candidates(self, fg: np.ndarray) -> list[tuple]:
        import cv2

        o, n = self.options, self.options.downsample
        h, w = fg.shape
        out = []
        contours, _ = cv2.findContours(fg, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        for c in contours:
            area = cv2.contourArea(c) + 0.5 * cv2.arcLength(c, True) + 1.0   # pixel count incl. boundary
            (_, _), (rw, rh), _ = cv2.minAreaRect(c)
            short, long_ = sorted((rw + 1.0, rh + 1.0))
            r_full = 0.5 * short * n
            if not o.min_radius_px <= r_full <= o.max_radius_px:
                continue
            elong, fill = long_ / short, area / (short * long_)
            if elong > o.max_elongation or fill < o.min_fill:
                continue
            m = cv2.moments(c)
            if m["m00"] > 0:
                x, y = m["m10"] / m["m00"], m["m01"] / m["m00"]
            else:
                x, y = c[:, 0, 0].mean(), c[:, 0, 1].mean()
            bx, by, bw, bh = cv2.boundingRect(c)
            border = bx <= 0 or by <= 0 or bx + bw >= w or by + bh >= h
            uv = np.array([(x + 0.5) * n - 0.5, (y + 0.5) * n - 0.5])
            out.append((uv, r_full, elong, min(fill, 1.0), border))
        return out

    def update(self, frame) -> PixelDetection | None:
        """Feed the next frame; returns the best ball candidate or None.

        Parameters
        ----------
        frame : array_like, shape (H, W) or (H, W, C), uint8
            Next video frame (grey or colour, e.g. BGR); all frames must
            have the same shape. The first ``options.n_background`` frames
            build the background.

        Returns
        -------
        PixelDetection or None
            The ball candidate (centroid in full-resolution pixels, u right,
            v down); ``None`` while the background is being learnt or when
            no plausible blob is found.

        Raises
        ------
        ValueError
            If ``frame`` is not a uint8 image.
        """
        import cv2

        o = self.options
        img = self._prep(frame)
        if self.background is None:
            self._init.append(img)
            if len(self._init) >= o.n_background:
                self.background = np.median(np.stack(self._init), axis=0).astype(np.float32)
                self._init = []
            return None
        diff = np.abs(img - self.background).max(axis=2)
        fg = (diff > o.diff_threshold).astype(np.uint8)
        fg = cv2.morphologyEx(fg, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3)))
        still = cv2.dilate(fg, np.ones((5, 5), np.uint8)) == 0
        a = o.learning_rate
        self.background[still] = (1 - a) * self.background[still] + a * img[still]
        cands = self._candidates(fg)
        best = None
        if cands and self._track:
            last = self._track[-1]
            vel = self._track[-1] - self._track[-2] if len(self._track) > 1 else np.zeros(2)
            pred = last + vel
            gate = 4.0 * o.max_radius_px + 0.5 * float(np.linalg.norm(vel))
            dist = [float(np.linalg.norm(c[0] - pred)) for c in cands]
            k = int(np.argmin(dist))
            if dist[k] <= gate:
                best = cands[k]
        if best is None and cands:
            score = [c[3] - 0.1 * (c[2] - 1.0) - (1.0 if c[4] else 0.0) for c in cands]
            k = int(np.argmax(score))
            if not cands[k][4]:
                best = cands[k]
        if best is None:
            self._track = []
            return None
        self._track = (self._track + [best[0]])[-2:]
        return PixelDetection(best[0], float(best[1]), float(best[2]), float(best[3]))
