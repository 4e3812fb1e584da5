"""Tracking mode: search a window around the predicted sphere position.

A :class:`SphereTracker` follows one sphere in one camera's frames. While the
sphere was found in the previous frame it predicts the next position with a
constant-velocity model from the detections in the last two frames and segments only a
window around the prediction (:func:`~tudorvision.stereo.segment.detect_sphere`
with ``roi``). The window's half size is

``max(min_half_window_px, window_scale * r + uncertainty_gain * e + 0.5 * s)``

with ``r`` the last region's equivalent radius (``sqrt(area / pi)``), ``e``
the recent constant-velocity prediction error (px, decaying) and ``s`` the predicted image speed
(px/frame: the blur streak extends about half of it to each side). Right after
a full-frame (re)acquisition the velocity is unknown: the prediction is the
last position and the window grows by ``1.5 s`` with the last known speed. The window
is clipped at the image border. Of the valid regions in the window the one
nearest the prediction is taken. If there is none, or it touches the window's
edge (the window was too small), the same frame is
searched in full (coarse to fine); once lost, the tracker searches full frames
until it finds the sphere again. A local colour model (``ColorModel.is_local``,
fitted where the frame holds the sphere's colour elsewhere) replaces each full
search by its window (``local_roi``) around :attr:`SphereTracker.anchor`, the
last position (the pick before the first sighting), and takes the valid region
nearest it. The window is segmented with the model's strict colour tables first
(so a sharp sphere gives exactly the full-frame result); when that finds
nothing and the predicted speed exceeds ``blur_speed * r`` px/frame, motion blur is assumed and the window is segmented
again with the blur-tolerant tables and the looser circularity limit
``min_circularity_blur`` (see :mod:`tudorvision.stereo.segment`). Full-frame searches use the strict tables
(unless ``segment.motion_blur`` is set), because the tolerant ones also accept
darker objects of the sphere's hue anywhere in the frame. Only in the frame
where a fast sphere (one expected to blur) is lost and the strict full search
fails, a large window (``max_half_window_px``) around the prediction is
searched with the tolerant tables, keeping regions of 0.5 to 2 times the last
area and taking the one nearest the prediction.

:class:`FrameTracker` runs one tracker per sphere of one camera and shares the
colour conversion of frames that need a full search.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from tudorvision._checks import TudorVisionError
from tudorvision.stereo._frame import FramePlanes
from tudorvision.stereo.colormodel import ColorModel
from tudorvision.stereo.detection import segment_params_for_radius
from tudorvision.stereo.segment import SegmentParams, SphereDetection, detect_on_planes, regions_in_window

__all__ = ["TrackerParams", "SphereTracker", "FrameTracker"]


@dataclass(frozen=True, kw_only=True)
class TrackerParams:
    """Options of the tracking mode.

    Parameters
    ----------
    segment : SegmentParams
        Segmentation thresholds and limits (``motion_blur`` is set per frame
        by the tracker from the predicted speed).
    window_scale : float
        Half window of at least ``window_scale`` sphere radii.
    min_half_window_px : int
        Smallest half window in pixels.
    uncertainty_gain : float
        Half window grows by this many recent prediction errors (px).
    blur_speed : float
        Blur is expected above ``blur_speed`` radii per frame of image speed.
    max_half_window_px : int
        Beyond this half size the tracker searches the full frame instead.
    moment_speed : float
        Blur-aware centroid: while the sphere moves smoothly (recent
        prediction error at most ``1 + speed / 4`` px) faster than this
        many radii per frame, the window is segmented with
        ``centroid="rim_moment"`` (a blur streak's first moment is the mean
        position over the exposure; the rim circle fit of
        ``centroid="shape"`` would take one end of the streak).
        ``inf``: always ``segment.centroid``; with ``segment.centroid=
        "moment"`` the moment is used throughout.
    """

    segment: SegmentParams = field(default_factory=SegmentParams)
    window_scale: float = 2.5
    min_half_window_px: int = 12
    uncertainty_gain: float = 3.0
    blur_speed: float = 1.0
    max_half_window_px: int = 160
    moment_speed: float = 1.5

    def __post_init__(self):
        if not isinstance(self.segment, SegmentParams):
            raise TudorVisionError(f"segment: expected SegmentParams, got {type(self.segment).__name__}")
        if not (self.moment_speed >= 0):
            raise TudorVisionError(f"moment_speed: must be non-negative, got {self.moment_speed}")
        for name in ("window_scale", "uncertainty_gain", "blur_speed"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise TudorVisionError(f"{name}: must be finite and non-negative, got {v}")
        if not (1 <= self.min_half_window_px <= self.max_half_window_px):
            raise TudorVisionError(
                "min_half_window_px, max_half_window_px: need 1 <= min <= max, got "
                f"{self.min_half_window_px}, {self.max_half_window_px}")


class SphereTracker:
    """Track one sphere in the frames of one camera.

    Parameters
    ----------
    model : ColorModel
        The sphere's colour model for this camera.
    params : TrackerParams, optional
        Window sizes, blur handling and segmentation options; default
        ``TrackerParams()``.

    Raises
    ------
    TudorVisionError
        If ``model`` is not a :class:`ColorModel` or ``params`` not
        :class:`TrackerParams`.

    Attributes
    ----------
    last : SphereDetection or None
        Result of the latest :meth:`update`.
    mode : str
        How the latest frame was searched: ``"window"`` or ``"full"``.
    n_window, n_full : int
        Frames searched by window only, and frames that needed a full search.

    Examples
    --------
    >>> import cv2
    >>> from tudorvision.stereo.colormodel import fit_color_model
    >>> img = np.full((120, 160, 3), 90, np.uint8)
    >>> _ = cv2.circle(img, (40, 60), 8, (40, 40, 200), -1)
    >>> trk = SphereTracker(fit_color_model(img, (40, 60), (48, 60)))
    >>> for du in (0, 4, 8, 12):                 # moves 4 px right per frame
    ...     det = trk.update(np.roll(img, du, axis=1))
    >>> round(det.uv[0], 2), trk.mode, trk.n_full
    (52.0, 'window', 1)
    """

    def __init__(self, model: ColorModel, *, params: TrackerParams | None = None):
        if not isinstance(model, ColorModel):
            raise TudorVisionError(f"model: expected a ColorModel, got {type(model).__name__}")
        self.model = model
        self.params = TrackerParams() if params is None else params
        if not isinstance(self.params, TrackerParams):
            raise TudorVisionError(f"params: expected TrackerParams, got {type(self.params).__name__}")
        seg = self.params.segment
        r_pick = float(getattr(model, "radius_px", float("nan")))
        if math.isfinite(r_pick) and 0.0 < r_pick < 5.0:
            # a small sphere (issue 15): no seed erosion, full-resolution search (segment_params_for_radius)
            seg = segment_params_for_radius(seg, r_pick)
            self.params = replace(self.params, segment=seg)
        self._seg_moving = seg if seg.centroid == "moment" else replace(seg, centroid="rim_moment")
        self.reset()

    def reset(self, anchor_uv=None) -> None:
        """Forget the track; the next frame is searched in full.

        Parameters
        ----------
        anchor_uv : array_like, shape (2,), optional
            Where a local colour model searches next (:attr:`anchor`);
            default: the model's picked centre.
        """
        self._anchor = None if anchor_uv is None else tuple(float(x) for x in anchor_uv)
        self._index = -1
        self._hist: list = []  # [(frame index, uv ndarray)] of the last two valid detections
        self._radius = float("nan")
        self._err = 0.0
        self._fast = False  # the last prediction expected motion blur
        self._area = float("nan")
        self._speed = 0.0  # last known image speed, px/frame
        self.last: SphereDetection | None = None
        self.mode = "full"
        self.n_window = 0
        self.n_full = 0

    def predict(self):
        """Predicted position and half window for the next frame.

        Returns
        -------
        (uv, half_window_px, speed_px_per_frame) or None
            ``None`` when the sphere was not found in the latest frame (the
            next frame is searched in full).
        """
        pred = self._prediction()
        return None if pred is None else pred[:3]

    def _prediction(self):
        """``(uv, half, speed, has_velocity)`` or None; does not change the state."""
        if not self._hist or self._hist[-1][0] != self._index:
            return None
        k1, uv1 = self._hist[-1]
        p = self.params
        if len(self._hist) == 2 and self._hist[0][0] == k1 - 1:
            vel = uv1 - self._hist[0][1]
            speed = float(np.hypot(*vel))
            has_velocity, extra = True, 0.5 * speed
        else:  # no velocity across a gap: the sphere may have jumped while unseen
            vel = np.zeros(2)
            speed = self._speed  # direction unknown: widen by the last known speed
            has_velocity, extra = False, 1.5 * speed
        half = p.window_scale * self._radius + p.uncertainty_gain * self._err + extra
        half = max(float(p.min_half_window_px), half)
        return uv1 + vel, half, speed, has_velocity

    def update(self, frame_bgr, *, hsv=None) -> SphereDetection:
        """Find the sphere in the next frame.

        Parameters
        ----------
        frame_bgr : ndarray, shape (H, W, 3), uint8
            The next BGR frame of this camera.
        hsv : ndarray, shape (H, W, 3), uint8, optional
            Its HSV image if already computed.

        Returns
        -------
        SphereDetection
        """
        return self.update_planes(FramePlanes.checked(frame_bgr, hsv))

    def update_planes(self, frame: FramePlanes) -> SphereDetection:
        """Find the sphere in the next frame, given as the per-frame plane cache.

        :class:`FrameTracker` shares one cache between the trackers of a
        camera's spheres; :meth:`update` is this after its input checks.

        Parameters
        ----------
        frame : FramePlanes
            The next frame of this camera and its cached colour planes
            (:class:`tudorvision.stereo._frame.FramePlanes`).

        Returns
        -------
        SphereDetection
        """
        pred = self._prediction()
        self._index += 1
        p = self.params
        det = None
        if pred is not None:
            uv, half, speed, has_velocity = pred
            if has_velocity:
                self._speed = speed
            self._fast = speed > p.blur_speed * self._radius
            if half <= p.max_half_window_px:
                h = int(math.ceil(half))
                x0, y0 = int(round(uv[0])) - h, int(round(uv[1])) - h
                x1, y1 = min(x0 + 2 * h + 1, frame.width), min(y0 + 2 * h + 1, frame.height)
                x0, y0 = max(x0, 0), max(y0, 0)
                if x1 - x0 >= 3 and y1 - y0 >= 3:
                    roi = (x0, y0, x1 - x0, y1 - y0)
                    # strict tables first (exactly the full-frame result when the sphere is sharp);
                    # the blur-tolerant ones only when that fails while the sphere moves fast
                    passes = [p.segment.motion_blur] + ([True] if self._fast and not p.segment.motion_blur else [])
                    moving = (has_velocity and speed > p.moment_speed * self._radius
                              and self._err <= 1.0 + 0.25 * speed)
                    seg = self._seg_moving if moving else p.segment
                    for blur in passes:
                        det = self._nearest(regions_in_window(frame, self.model, seg, roi, blur), uv)
                        if det is not None:
                            break
        if det is not None:
            self.mode = "window"
            self.n_window += 1
        else:
            # full frames use the strict colour tables unless the caller expects blur everywhere:
            # the blur-tolerant ones also accept darker objects of the sphere's hue
            self.mode = "full"
            self.n_full += 1
            roi = self.model.local_roi(self.anchor, frame.width, frame.height) if self.model.is_local else None
            if roi is None:
                det = detect_on_planes(frame, self.model, p.segment, None, p.segment.motion_blur)
            else:   # a local model: only its window around the last position, the region nearest that
                det = self._local(regions_in_window(frame, self.model, p.segment, roi, p.segment.motion_blur))
            if not det.valid and pred is not None and self._fast and not p.segment.motion_blur:
                det = self._reacquire_blurred(frame, pred[0], det)
        if det.valid:
            uv_now = np.array(det.uv, dtype=np.float64)
            if pred is not None and pred[3]:
                e = float(np.hypot(*(uv_now - pred[0])))
                self._err = max(0.5 * self._err, e)
            else:  # first sighting, or velocity unknown: no constant-velocity error to learn from
                self._err = 0.0
            self._radius = det.radius_px
            self._area = det.area_px
            self._hist = (self._hist + [(self._index, uv_now)])[-2:]
        self.last = det
        return det

    @property
    def anchor(self) -> tuple:
        """Where the sphere was last found, ``(u, v)`` pixels; before that, the ``reset`` anchor or the pick."""
        if self._hist:
            return tuple(float(x) for x in self._hist[-1][1])
        return self._anchor if self._anchor is not None else tuple(self.model.center_uv)

    def _local(self, found) -> SphereDetection:
        """A local model's detection in its window: the valid region nearest :attr:`anchor`, else invalid."""
        det = self._nearest(found, self.anchor)
        if det is not None:
            return det
        if found and found[0].valid:   # cut by the window: the sphere's colour runs on beyond it
            return replace(found[0], valid=False, reason="local colour model: region reaches the edge of its window")
        return found[0] if found else SphereDetection(
            uv=(math.nan, math.nan), area_px=0.0, mean_prob=0.0, circularity=0.0, valid=False,
            reason="local colour model: nothing in its window around the last position")

    @staticmethod
    def _nearest(found, uv):
        """The valid region nearest ``uv``; None if there is none or it touches the window edge."""
        ok = [d for d in found if d.valid]
        if not ok:
            return None
        det = min(ok, key=lambda d: math.hypot(d.uv[0] - uv[0], d.uv[1] - uv[1]))
        return None if det.touches_window else det  # cut by the window edge: search the full frame

    def _reacquire_blurred(self, frame: FramePlanes, uv_pred, fallback: SphereDetection) -> SphereDetection:
        """Lost while fast: a blur streak may only pass the blur-tolerant tables.

        Searched in a ``max_half_window_px`` window around the prediction, keeping
        regions of 0.5 to 2 times the last area, nearest to the prediction first.
        """
        h = int(self.params.max_half_window_px)
        x0, y0 = max(int(round(uv_pred[0])) - h, 0), max(int(round(uv_pred[1])) - h, 0)
        x1, y1 = min(x0 + 2 * h + 1, frame.width), min(y0 + 2 * h + 1, frame.height)
        if x1 - x0 < 3 or y1 - y0 < 3:
            return fallback
        found = regions_in_window(frame, self.model, self.params.segment, (x0, y0, x1 - x0, y1 - y0), True)
        ok = [d for d in found if d.valid and not d.touches_window and 0.5 <= d.area_px / self._area <= 2.0]
        if not ok:
            return fallback
        return min(ok, key=lambda d: math.hypot(d.uv[0] - uv_pred[0], d.uv[1] - uv_pred[1]))


class FrameTracker:
    """Track every sphere of one camera, sharing per-frame colour conversions.

    Parameters
    ----------
    models : mapping of str to ColorModel
        ``{sphere: model}`` for this camera (``ColorModelSet.for_camera(c)``).
    params : TrackerParams, optional

    Examples
    --------
    >>> import cv2
    >>> from tudorvision.stereo.colormodel import fit_color_model
    >>> img = np.full((120, 160, 3), 90, np.uint8)
    >>> _ = cv2.circle(img, (40, 60), 8, (40, 40, 200), -1)
    >>> _ = cv2.circle(img, (110, 60), 8, (50, 190, 40), -1)
    >>> models = {"red": fit_color_model(img, (40, 60), (48, 60)),
    ...           "green": fit_color_model(img, (110, 60), (118, 60))}
    >>> dets = FrameTracker(models).update(img)
    >>> {k: (round(d.uv[0], 1), d.valid) for k, d in dets.items()}
    {'red': (40.0, True), 'green': (110.0, True)}
    """

    def __init__(self, models: Mapping[str, ColorModel], *, params: TrackerParams | None = None):
        if not isinstance(models, Mapping) or not models:
            raise TudorVisionError("models: expected a non-empty mapping {sphere: ColorModel}")
        self.trackers = {name: SphereTracker(m, params=params) for name, m in models.items()}

    def reset(self) -> None:
        """Forget every track."""
        for t in self.trackers.values():
            t.reset()

    def update(self, frame_bgr, *, hsv=None) -> dict:
        """Detections ``{sphere: SphereDetection}`` in the next frame."""
        frame = FramePlanes.checked(frame_bgr, hsv)
        return {name: t.update_planes(frame) for name, t in self.trackers.items()}
