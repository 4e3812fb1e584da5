"""The stereo tracking loop: frames in, end-effector trajectory out (section 2.4).

Per stereo pair, :class:`StereoPipeline` runs the colour segmentation of
every tracking sphere in both images (tracking mode, :class:`FrameTracker`,
or full-frame search), triangulates each sphere seen in *both* cameras and
takes the midpoint of the sphere centres as the end effector. A sphere
missing in either image gives NaN and ``valid = False``; there is never a 3D
point from one view.

:func:`iter_stereo` feeds a recorded :class:`~tudorvision.io.Sequence` through
a pipeline, either as fast as possible or paced at the recorded rate
(``live=True``: :meth:`Sequence.play` delivers the newest due frame and drops
older ones when the tracker falls behind; each result carries its latency and
the number of frames dropped before it). Defective frames of lenient
sequences are skipped and counted.

:func:`track_stereo` collects the per-frame results into a trajectory. The
per-frame 3D points are instantaneous; the trajectory is triangulated once
more from the whole pixel tracks so that, when the calibration gives the
cameras a rolling-shutter ``line_time_s``, every centroid is first moved
from its row's read-out time to the frame timestamp
(:func:`~tudorvision.stereo.triangulate.compensate_rolling_shutter`).
Velocity and acceleration are central finite differences
(:func:`~tudorvision.stereo.trajectory.trajectory_from_points`).

The same segmentation on one camera gives a pixel track: :func:`track_mono`.

Time convention: a sample's ``t`` is the frame timestamp of the recording
(for the virtual lab the start of the exposure of row 0); under motion blur
the centroid is the mean position over the exposure.

The pipeline never reads ground truth.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Mapping

import numpy as np

from .._checks import TudorVisionError, check_transform
from ..io.atomic import write_text_atomic
from ._frame import FramePlanes
from .colormodel import ColorModel, ColorModelSet
from .segment import SegmentParams, SphereDetection, detect_spheres, regions_in_window
from .tracker2d import FrameTracker, SphereTracker, TrackerParams
from .trajectory import Trajectory, trajectory_from_points
from .triangulate import SphereTriangulation, triangulate_spheres

__all__ = [
    "PipelineOptions", "StereoFrameResult", "StereoPipeline", "TrackStats", "StereoTrackResult",
    "iter_stereo", "track_stereo", "MonoTrackResult", "track_mono", "write_mono_track_csv",
    "read_mono_track_csv",
]

_NAN2 = (float("nan"), float("nan"))


@dataclass(frozen=True, kw_only=True)
class PipelineOptions:
    """Options of the stereo tracking loop.

    Parameters
    ----------
    tracking : bool
        Search a window around each sphere's predicted position
        (:class:`~tudorvision.stereo.tracker2d.FrameTracker`, full frame
        when lost); False searches every full frame.
    tracker : TrackerParams
        Tracking-mode options, including the segmentation parameters
        (``tracker.segment`` is also used by the full-frame mode).
    method : {"normalized", "rectified"}
        Triangulation route (:func:`~tudorvision.stereo.triangulate.triangulate_stereo`).
    rolling_shutter : bool
        Compensate the rolling shutter in the trajectory when the calibration
        gives the cameras a ``line_time_s`` (False: triangulate the raw
        centroids, for comparison).
    max_gap_frames : float
        Velocity and acceleration are not differenced across gaps longer
        than this many nominal frame periods.
    max_epipolar_px : float or None
        Stereo consistency: a sphere's left and right centroids must lie
        within this distance (pixels, undistorted) of each other's epipolar
        line. When they do not (one camera locked onto a look-alike object),
        every valid candidate region of that sphere in both full frames is
        paired and the consistent pair nearest the previous 3D position (or
        with the smallest epipolar distance) is taken; failing that the
        sphere is flagged missing. A sphere found in one camera only is
        looked for among the other camera's candidate regions the same way. None disables the check. The default
        leaves room for rolling-shutter skew of fast motion.
    sphere_separation_m : float or None
        Known distance between the sphere centres (two spheres); a frame
        whose triangulated distance differs by more than
        ``separation_tol_m`` is flagged invalid. None disables the check.
    separation_tol_m : float
        Tolerance of that check, metres.
    """

    tracking: bool = True
    tracker: TrackerParams = field(default_factory=TrackerParams)
    method: str = "normalized"
    rolling_shutter: bool = True
    max_gap_frames: float = 2.5
    max_epipolar_px: float | None = 6.0
    sphere_separation_m: float | None = None
    separation_tol_m: float = 0.03

    def __post_init__(self):
        if not isinstance(self.tracker, TrackerParams):
            raise TudorVisionError(f"tracker: expected TrackerParams, got {type(self.tracker).__name__}")
        if self.method not in ("normalized", "rectified"):
            raise TudorVisionError(f"method: expected 'normalized' or 'rectified', got {self.method!r}")
        if not (self.max_gap_frames > 1.0):
            raise TudorVisionError(f"max_gap_frames: must exceed 1, got {self.max_gap_frames}")
        if self.max_epipolar_px is not None and not (self.max_epipolar_px > 0):
            raise TudorVisionError(f"max_epipolar_px: must be positive or None, got {self.max_epipolar_px}")
        if self.sphere_separation_m is not None and not (self.sphere_separation_m > 0):
            raise TudorVisionError(f"sphere_separation_m: must be positive or None, got {self.sphere_separation_m}")
        if not (self.separation_tol_m > 0):
            raise TudorVisionError(f"separation_tol_m: must be positive, got {self.separation_tol_m}")


@dataclass(frozen=True, eq=False)
class StereoFrameResult:
    """What the pipeline found in one stereo pair.

    Attributes
    ----------
    index : int
        0-based frame index in the sequence.
    t : float
        Frame timestamp, seconds.
    detections : dict
        ``{"left": {sphere: SphereDetection}, "right": {...}}``.
    spheres : dict of str to ndarray, shape (3,)
        Sphere centres in metres, frame ``frame``, triangulated from this pair
        alone (no rolling-shutter compensation); NaN where the sphere is
        missing in either image.
    ee : ndarray, shape (3,)
        End effector (midpoint of the spheres), NaN unless ``valid``.
    valid : bool
        Every sphere was found in both images.
    frame : str
        ``"base"`` (robot base frame) or ``"left"`` (left camera optical frame).
    latency_s : float
        Live playback: wall time from the frame being due to its result
        (decode, segmentation and triangulation); NaN when not live.
    dropped : int
        Live playback: frames dropped just before this one.
    """

    index: int
    t: float
    detections: dict
    spheres: dict
    ee: np.ndarray
    valid: bool
    frame: str
    latency_s: float = float("nan")
    dropped: int = 0

    def uv(self, camera: str, sphere: str) -> tuple:
        """Centroid ``(u, v)`` of a valid detection, else ``(nan, nan)``."""
        d = self.detections[camera][sphere]
        return d.uv if d.valid else _NAN2


def _check_models(color_models, calibration, stereo_names) -> tuple:
    if not isinstance(color_models, ColorModelSet):
        raise TudorVisionError(f"color_models: expected a ColorModelSet, got {type(color_models).__name__}")
    for cam in ("left", "right"):
        if cam not in color_models.cameras:
            raise TudorVisionError(f"colour models: no models for the {cam} camera "
                                   f"(have {', '.join(color_models.cameras)}); pick both cameras")
    names = [s for s in color_models.spheres("left") if s in color_models.spheres("right")]
    if not names:
        raise TudorVisionError("colour models: no sphere is modelled in both cameras")
    for cam, cname in zip(("left", "right"), stereo_names):
        cm = calibration.camera(cname)
        for s in names:
            w, h = color_models.get(cam, s).image_size
            if (w, h) != (0, 0) and (w, h) != (cm.width, cm.height):
                raise TudorVisionError(
                    f"colour models: {cam}/{s} was picked on a {w}x{h} image, but the calibration's "
                    f"{cam} camera is {cm.width}x{cm.height}")
    return tuple(names)


class StereoPipeline:
    """Per-frame stereo tracking: segmentation in both images, triangulation, midpoint.

    State between frames: the per-camera trackers and each sphere's last
    consistent 3D position (for re-pairing look-alikes); ``n_inconsistent``
    and ``n_repaired`` count the epipolar failures and the repaired ones.

    Parameters
    ----------
    calibration : tudorvision.io.Calibration
        Stereo calibration (two cameras and ``stereo`` extrinsics).
    color_models : ColorModelSet
        Models for cameras ``left`` and ``right``; spheres modelled in both
        are tracked.
    T_base_left : array_like, shape (4, 4), optional
        ``p_base = T_base_left @ p_left``; results are then in the base frame,
        otherwise in the left camera optical frame (x right, y down, z
        forward).
    options : PipelineOptions, optional

    Raises
    ------
    TudorVisionError
        No stereo part in the calibration, colour models missing a camera or
        picked on images of another size than the calibration's.

    Examples
    --------
    Two parallel cameras 0.2 m apart see a red and a green disc 2 m ahead:

    >>> import cv2
    >>> from tudorvision.io import Calibration, CameraModel, StereoExtrinsics
    >>> from tudorvision.io.frames import StereoFrame
    >>> from tudorvision.stereo.colormodel import fit_color_model
    >>> cam = CameraModel(K=[[500, 0, 160], [0, 500, 120], [0, 0, 1]], width=320, height=240)
    >>> cal = Calibration(cameras={"left": cam, "right": cam},
    ...                   stereo=StereoExtrinsics(R=np.eye(3), T=[-0.2, 0.0, 0.0]))
    >>> imgs, models = {}, {}
    >>> for name, du in (("left", 0), ("right", -50)):          # disparity 500 * 0.2 / 2 = 50 px
    ...     img = np.full((240, 320, 3), 90, np.uint8)
    ...     _ = cv2.circle(img, (140 + du, 120), 8, (40, 40, 200), -1)   # red, x = -0.08 m
    ...     _ = cv2.circle(img, (180 + du, 120), 8, (50, 190, 40), -1)   # green, x = +0.08 m
    ...     imgs[name] = img
    ...     models[name] = {"red": fit_color_model(img, (140 + du, 120), (147 + du, 120)),
    ...                     "green": fit_color_model(img, (180 + du, 120), (187 + du, 120))}
    >>> pipe = StereoPipeline(cal, ColorModelSet(models))
    >>> res = pipe.process(StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"]))
    >>> res.valid, res.frame, (np.round(res.ee, 6) + 0.0).tolist(), (np.round(res.spheres["red"], 6) + 0.0).tolist()
    (True, 'left', [0.0, 0.0, 2.0], [-0.08, 0.0, 2.0])
    """

    def __init__(self, calibration, color_models: ColorModelSet, *, T_base_left=None,
                 options: PipelineOptions | None = None):
        self.options = PipelineOptions() if options is None else options
        if not isinstance(self.options, PipelineOptions):
            raise TudorVisionError(f"options: expected PipelineOptions, got {type(self.options).__name__}")
        stereo = getattr(calibration, "stereo", None)
        if stereo is None:
            raise TudorVisionError("calibration: has no stereo extrinsics (run 'tudorvision calib stereo')")
        self.calibration = calibration
        self.cameras = {"left": calibration.camera(stereo.left), "right": calibration.camera(stereo.right)}
        self.spheres = _check_models(color_models, calibration, (stereo.left, stereo.right))
        self.color_models = color_models
        self.T_base_left = None if T_base_left is None else check_transform(T_base_left, "T_base_left")
        self.frame = "left" if self.T_base_left is None else "base"
        self._models = {cam: {s: color_models.get(cam, s) for s in self.spheres} for cam in ("left", "right")}
        self._trackers = {cam: FrameTracker(m, params=self.options.tracker) for cam, m in self._models.items()}
        tx, ty, tz = stereo.T
        self._E = np.array([[0.0, -tz, ty], [tz, 0.0, -tx], [-ty, tx, 0.0]]) @ stereo.R  # x_r^T E x_l = 0
        self._f_right = 0.5 * (self.cameras["right"].fx + self.cameras["right"].fy)
        self._last_left = {s: None for s in self.spheres}   # last consistent sphere centre, left frame
        self.n_repaired = 0
        self.n_inconsistent = 0

    @property
    def rolling_shutter(self) -> bool:
        """Whether the trajectory is rolling-shutter compensated."""
        return bool(self.options.rolling_shutter and self.cameras["left"].line_time_s
                    and self.cameras["right"].line_time_s)

    def reset(self) -> None:
        """Forget the tracks (the next pair is searched in full)."""
        for trk in self._trackers.values():
            trk.reset()
        self._last_left = {s: None for s in self.spheres}

    def epipolar_px(self, uv_left, uv_right) -> np.ndarray:
        """Distance of right centroids from the epipolar lines of left ones, pixels.

        Parameters
        ----------
        uv_left, uv_right : array_like, shape (N, 2)
            Raw (distorted) centroids; NaN rows give NaN.

        Returns
        -------
        ndarray, shape (N,)
            Distance in the right image, undistorted, in pixels of its mean focal length.
        """
        from .triangulate import undistort_points

        cl, cr = self.cameras["left"], self.cameras["right"]
        xl = undistort_points(np.asarray(uv_left, float).reshape(-1, 2), cl.K, cl.dist)
        xr = undistort_points(np.asarray(uv_right, float).reshape(-1, 2), cr.K, cr.dist)
        hl = np.column_stack([xl, np.ones(len(xl))])
        hr = np.column_stack([xr, np.ones(len(xr))])
        lines = hl @ self._E.T                    # epipolar lines in the right normalised image
        num = np.abs(np.sum(lines * hr, axis=1))
        return self._f_right * num / np.hypot(lines[:, 0], lines[:, 1])

    def _left_points(self, uv_left, uv_right) -> np.ndarray:
        from .triangulate import triangulate_stereo
        return triangulate_stereo(np.reshape(uv_left, (-1, 2)), np.reshape(uv_right, (-1, 2)), self.calibration,
                                  method=self.options.method)

    def _candidates(self, img, cam: str, sphere: str) -> list:
        """Valid regions of one sphere in a full frame (full resolution), heaviest first."""
        h, w = img.shape[:2]
        found = regions_in_window(FramePlanes(img), self._models[cam][sphere], self.options.tracker.segment,
                                  (0, 0, w, h), False)
        return [d for d in found if d.valid][:6]

    def _make_consistent(self, dets: dict, images: dict) -> dict:
        """Check each sphere's stereo pair against the epipolar geometry; re-pair when it fails."""
        tol = self.options.max_epipolar_px
        if tol is None:
            return dets
        for s in self.spheres:
            dl, dr = dets["left"][s], dets["right"][s]
            if not (dl.valid or dr.valid):
                continue
            if dl.valid and dr.valid:
                if self.epipolar_px([dl.uv], [dr.uv])[0] <= tol:
                    continue
                self.n_inconsistent += 1
                cands = {cam: self._candidates(images[cam], cam, s) for cam in ("left", "right")}
            else:   # found in one camera only: look for a region on its epipolar line in the other
                have, miss = ("left", "right") if dl.valid else ("right", "left")
                cands = {have: [dets[have][s]], miss: self._candidates(images[miss], miss, s)}
                if not cands[miss]:
                    continue
            pairs = [(a, b) for a in cands["left"] for b in cands["right"]]
            best = None
            if pairs:
                ua = np.array([a.uv for a, _ in pairs])
                ub = np.array([b.uv for _, b in pairs])
                epi = self.epipolar_px(ua, ub)
                ok = epi <= tol
                if ok.any():
                    prev = self._last_left[s]
                    if prev is not None:
                        pts = self._left_points(ua, ub)
                        score = np.where(ok, np.linalg.norm(pts - prev, axis=1), np.inf)
                    else:
                        score = np.where(ok, epi, np.inf)
                    best = pairs[int(np.argmin(score))]
            if best is not None:
                new = {"left": best[0], "right": best[1]}
            elif dl.valid and dr.valid:
                new = {"left": _invalid(dl, "stereo-inconsistent (epipolar)"),
                       "right": _invalid(dr, "stereo-inconsistent (epipolar)")}
            else:
                continue
            for cam in ("left", "right"):
                if new[cam] is not dets[cam][s]:
                    dets[cam] = {**dets[cam], s: new[cam]}
                    if self.options.tracking:   # do not predict from the look-alike next frame
                        self._trackers[cam].trackers[s].reset()
            self.n_repaired += best is not None
        return dets

    def _check_image(self, img, cam: str, index: int) -> np.ndarray:
        arr = np.asarray(img)
        if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] != 3:
            raise TudorVisionError(f"frame {index}: the {cam} image is {arr.dtype} {arr.shape}; colour "
                                   "tracking needs 8-bit BGR images")
        cm = self.cameras[cam]
        if arr.shape[1] != cm.width or arr.shape[0] != cm.height:
            raise TudorVisionError(f"frame {index}: the {cam} image is {arr.shape[1]}x{arr.shape[0]}, but the "
                                   f"calibration's {cam} camera is {cm.width}x{cm.height}; wrong calibration file?")
        return arr

    def detect(self, left_bgr, right_bgr, *, index: int = 0) -> dict:
        """Sphere detections ``{"left": {sphere: SphereDetection}, "right": {...}}`` in one pair."""
        out = {}
        for cam, img in (("left", left_bgr), ("right", right_bgr)):
            arr = self._check_image(img, cam, index)
            if self.options.tracking:
                out[cam] = self._trackers[cam].update(arr)
            else:
                out[cam] = detect_spheres(arr, self._models[cam], params=self.options.tracker.segment)
        return out

    def process(self, frame, *, latency_s: float = float("nan"), dropped: int = 0) -> StereoFrameResult:
        """Track one stereo frame.

        Parameters
        ----------
        frame : StereoFrame
            ``t``, ``index``, ``left`` and ``right`` BGR images.
        latency_s, dropped : float, int
            Passed through to the result (live playback).

        Returns
        -------
        StereoFrameResult

        Raises
        ------
        TudorVisionError
            An image that is not 8-bit BGR or not of the calibrated size.
        """
        index = int(getattr(frame, "index", 0))
        dets = self.detect(frame.left, frame.right, index=index)
        dets = self._make_consistent(dets, {"left": frame.left, "right": frame.right})
        opt = self.options
        if opt.sphere_separation_m is not None and len(self.spheres) == 2 and \
                all(dets[c][s].valid for c in ("left", "right") for s in self.spheres):
            a, b = self.spheres
            pts = self._left_points([dets["left"][a].uv, dets["left"][b].uv],
                                    [dets["right"][a].uv, dets["right"][b].uv])
            sep = float(np.linalg.norm(pts[0] - pts[1]))
            if not abs(sep - opt.sphere_separation_m) <= opt.separation_tol_m:
                why = f"sphere separation {sep:.3f} m, expected {opt.sphere_separation_m:.3f} m"
                dets = {c: {s: _invalid(d, why) for s, d in dets[c].items()} for c in dets}
        uvl = {s: np.array([dets["left"][s].uv if dets["left"][s].valid else _NAN2]) for s in self.spheres}
        uvr = {s: np.array([dets["right"][s].uv if dets["right"][s].valid else _NAN2]) for s in self.spheres}
        tri = triangulate_spheres(uvl, uvr, self.calibration, T_base_left=None, method=opt.method)
        for s in self.spheres:
            if tri.sphere_valid[s][0]:
                self._last_left[s] = tri.spheres[s][0]
        spheres = {s: tri.spheres[s][0] for s in self.spheres}
        ee = tri.ee[0]
        if self.T_base_left is not None:
            R, o = self.T_base_left[:3, :3], self.T_base_left[:3, 3]
            spheres = {s: R @ p + o for s, p in spheres.items()}
            ee = R @ ee + o
        return StereoFrameResult(index=index, t=float(frame.t), detections=dets, spheres=spheres, ee=ee,
                                 valid=bool(tri.ee_valid[0]), frame=self.frame, latency_s=float(latency_s),
                                 dropped=int(dropped))

    def triangulate_tracks(self, t, uv_left: Mapping, uv_right: Mapping) -> SphereTriangulation:
        """Triangulate whole pixel tracks, rolling-shutter compensated when configured.

        Parameters
        ----------
        t : array_like, shape (N,)
            Frame timestamps, increasing; both images of a pair share it.
        uv_left, uv_right : mapping of str to array_like, shape (N, 2)
            Raw centroids per sphere, NaN rows where missing.

        Returns
        -------
        SphereTriangulation
            At the frame timestamps ``t``.
        """
        t = np.asarray(t, dtype=np.float64)
        kw = dict(t_left=t, t_right=t, t_target=t) if self.rolling_shutter and len(t) else {}
        return triangulate_spheres(uv_left, uv_right, self.calibration, T_base_left=self.T_base_left,
                                   method=self.options.method, **kw)


def _invalid(det: SphereDetection, reason: str) -> SphereDetection:
    """``det`` marked invalid with ``reason`` (the region is kept for diagnostics)."""
    from dataclasses import replace
    return replace(det, valid=False, reason=reason)


def iter_stereo(sequence, pipeline: StereoPipeline, *, live: bool = False, speed: float = 1.0,
                stats: "TrackStats | None" = None, clock=None, sleep=None) -> Iterator[StereoFrameResult]:
    """Run a pipeline over a stereo sequence, yielding one result per processed frame.

    Parameters
    ----------
    sequence : Sequence
        A stereo sequence (:func:`tudorvision.io.open_sequence`); with
        ``strict=False`` defective frames are skipped and counted.
    pipeline : StereoPipeline
    live : bool
        Pace playback at the recorded rate (times ``speed``), dropping the
        frames the pipeline is too slow for; results carry ``latency_s``
        (frame due -> result ready, decode and tracking included) and
        ``dropped``.
    speed : float
        Playback speed factor for ``live``.
    stats : TrackStats, optional
        Updated in place (frames processed, skipped, dropped, latencies).
    clock, sleep : callable, optional
        Fakes for the live playback's time source and sleep (tests).

    Yields
    ------
    StereoFrameResult
    """
    for res, _frame in _iter_pairs(sequence, pipeline, live=live, speed=speed, stats=stats, clock=clock,
                                   sleep=sleep):
        yield res


def _iter_pairs(sequence, pipeline, *, live, speed, stats, clock, sleep):
    """``(StereoFrameResult, StereoFrame)`` per processed frame (see :func:`iter_stereo`)."""
    if getattr(sequence, "kind", None) != "stereo":
        raise TudorVisionError(f"{getattr(sequence, 'path', 'sequence')}: expected a stereo sequence, "
                               f"got kind {getattr(sequence, 'kind', None)!r}")
    st = stats if stats is not None else TrackStats(frames_total=len(sequence))
    if live:
        clk = clock or time.monotonic
        play = sequence.play(speed=speed, clock=clock, sleep=sleep)
        for played in play:
            t_recv = clk()
            res = pipeline.process(played.frame, dropped=played.dropped)
            latency = float(played.latency_s) + max(clk() - t_recv, 0.0)
            res = StereoFrameResult(index=res.index, t=res.t, detections=res.detections, spheres=res.spheres,
                                    ee=res.ee, valid=res.valid, frame=res.frame, latency_s=latency,
                                    dropped=res.dropped)
            st.record(res)
            st.skipped, st.dropped = play.skipped, play.dropped
            yield res, played.frame
        st.skipped, st.dropped = play.skipped, play.dropped
        return
    for i in range(len(sequence)):
        frame = sequence.load_or_report(i)
        if frame is None:
            st.skipped += 1
            continue
        res = pipeline.process(frame)
        st.record(res)
        yield res, frame


@dataclass(kw_only=True)
class TrackStats:
    """Counters of a tracking run.

    Attributes
    ----------
    frames_total : int
        Frames listed in the sequence.
    processed, valid : int
        Frames tracked, and those with a valid end effector.
    skipped : int
        Defective frames skipped (lenient sequences).
    dropped : int
        Frames dropped by live playback.
    wall_s : float
        Wall time of the run, seconds.
    latency_sum_s, max_latency_s : float
        Live playback latencies (frame due -> result).
    interrupted : str or None
        Why the run stopped early (``keep_partial=True``: Ctrl-C or an
        error), None when it ran to the end.
    """

    frames_total: int = 0
    processed: int = 0
    valid: int = 0
    skipped: int = 0
    dropped: int = 0
    wall_s: float = 0.0
    latency_sum_s: float = 0.0
    max_latency_s: float = float("nan")
    interrupted: str | None = None
    _n_latency: int = 0

    def record(self, res) -> None:
        """Count one processed frame.

        Parameters
        ----------
        res : StereoFrameResult
            The frame's result: ``valid`` and, from live playback, a finite
            ``latency_s`` in seconds.
        """
        self.processed += 1
        self.valid += int(bool(res.valid))
        lat = getattr(res, "latency_s", float("nan"))
        if math.isfinite(lat):
            self._n_latency += 1
            self.latency_sum_s += lat
            self.max_latency_s = lat if not math.isfinite(self.max_latency_s) else max(self.max_latency_s, lat)

    @property
    def valid_fraction(self) -> float:
        """Valid frames over processed frames (0 when none was processed)."""
        return self.valid / self.processed if self.processed else 0.0

    @property
    def fps(self) -> float:
        """Processed frames per wall-clock second."""
        return self.processed / self.wall_s if self.wall_s > 0 else float("nan")

    @property
    def mean_latency_s(self) -> float:
        """Mean live latency, NaN when not live."""
        return self.latency_sum_s / self._n_latency if self._n_latency else float("nan")

    def summary(self) -> str:
        """One line: frames, valid %, fps, and skipped/dropped/latency where they apply."""
        s = (f"{self.processed}/{self.frames_total} frames tracked, {100 * self.valid_fraction:.1f}% valid, "
             f"{self.fps:.1f} fps")
        if self.skipped:
            s += f", {self.skipped} corrupt frame(s) skipped"
        if self._n_latency:
            s += (f", {self.dropped} dropped, latency mean {1e3 * self.mean_latency_s:.1f} ms "
                  f"max {1e3 * self.max_latency_s:.1f} ms")
        return s


@dataclass(frozen=True, eq=False)
class StereoTrackResult:
    """A tracked stereo sequence.

    Attributes
    ----------
    trajectory : Trajectory
        End effector at the processed frames' timestamps (frame ``"base"`` or
        ``"left"``), rolling-shutter compensated when configured.
    triangulation : SphereTriangulation
        Sphere centres behind the trajectory.
    t : ndarray, shape (N,)
        Timestamps of the processed frames.
    index : ndarray of int, shape (N,)
        Their 0-based sequence indices.
    uv_left, uv_right : dict of str to ndarray, shape (N, 2)
        Raw centroids per sphere, NaN where not found.
    results : list of StereoFrameResult
        Per-frame results (``keep_results=True`` only, else empty).
    stats : TrackStats
    rolling_shutter : bool
        Whether the trajectory was rolling-shutter compensated.
    """

    trajectory: Trajectory
    triangulation: SphereTriangulation
    t: np.ndarray
    index: np.ndarray
    uv_left: dict
    uv_right: dict
    results: list
    stats: TrackStats
    rolling_shutter: bool


def track_stereo(sequence, calibration, color_models: ColorModelSet, *, T_base_left=None,
                 options: PipelineOptions | None = None, live: bool = False, speed: float = 1.0,
                 show_progress: bool | None = False, keep_results: bool = False,
                 on_result: Callable[[StereoFrameResult, object], None] | None = None,
                 clock=None, sleep=None, keep_partial: bool = False) -> StereoTrackResult:
    """Track the end effector through a stereo sequence.

    Parameters
    ----------
    sequence : Sequence
        Stereo sequence; open it with ``strict=False`` to skip corrupt frames.
    calibration : Calibration
        Stereo calibration.
    color_models : ColorModelSet
        Colour models for ``left`` and ``right``.
    T_base_left : array_like, shape (4, 4), optional
        Base pose of the left camera (e.g. ``calibration.transforms["T_base_left"]``);
        without it the output is in the left camera optical frame.
    options : PipelineOptions, optional
    live : bool
        Pace at the recorded rate with frame dropping (see :func:`iter_stereo`).
    speed : float
        Live playback speed factor.
    show_progress : bool or None
        Progress bar on stderr (None: when stderr is a terminal).
    keep_results : bool
        Keep the per-frame :class:`StereoFrameResult` list.
    on_result : callable, optional
        ``on_result(result, frame)`` after each processed frame (``frame`` is
        the StereoFrame; e.g. for a rerun recording).
    clock, sleep : callable, optional
        Fakes for live playback (tests).
    keep_partial : bool
        On Ctrl-C (``KeyboardInterrupt``) or an error while reading or
        tracking frames, stop and return the frames done so far, with the
        reason in ``stats.interrupted``, instead of raising.

    Returns
    -------
    StereoTrackResult

    Raises
    ------
    TudorVisionError
        Calibration or colour models unusable, images of another size than
        calibrated, a strict sequence with a corrupt frame.
    """
    from .._progress import progress

    pipe = StereoPipeline(calibration, color_models, T_base_left=T_base_left, options=options)
    stats = TrackStats(frames_total=len(sequence))
    t, idx, results = [], [], []
    uvl = {s: [] for s in pipe.spheres}
    uvr = {s: [] for s in pipe.spheres}
    t0 = time.perf_counter()
    it = _iter_pairs(sequence, pipe, live=live, speed=speed, stats=stats, clock=clock, sleep=sleep)
    try:
        for res, frame in progress(it, total=len(sequence), desc="tracking", enabled=show_progress):
            for s in pipe.spheres:
                uvl[s].append(res.uv("left", s))
                uvr[s].append(res.uv("right", s))
            t.append(res.t)
            idx.append(res.index)
            if keep_results:
                results.append(res)
            if on_result is not None:
                on_result(res, frame)
    except (KeyboardInterrupt, Exception) as exc:
        if not keep_partial:
            raise
        stats.interrupted = _stop_reason(exc)
        n = len(t)   # a frame interrupted half-way is left out
        uvl = {s: v[:n] for s, v in uvl.items()}
        uvr = {s: v[:n] for s, v in uvr.items()}
    stats.wall_s = time.perf_counter() - t0
    t = np.array(t, dtype=np.float64)
    uvl = {s: np.array(v, dtype=np.float64).reshape(-1, 2) for s, v in uvl.items()}
    uvr = {s: np.array(v, dtype=np.float64).reshape(-1, 2) for s, v in uvr.items()}
    tri = pipe.triangulate_tracks(t, uvl, uvr)
    rate = getattr(sequence, "rate_hz", None)
    max_dt = pipe.options.max_gap_frames / rate if rate else None
    traj = trajectory_from_points(t, tri.ee, frame=pipe.frame, max_dt_s=max_dt)
    return StereoTrackResult(trajectory=traj, triangulation=tri, t=t, index=np.array(idx, dtype=int),
                             uv_left=uvl, uv_right=uvr, results=results, stats=stats,
                             rolling_shutter=pipe.rolling_shutter)


# ----------------------------------------------------------------------------- mono
@dataclass(frozen=True, eq=False)
class MonoTrackResult:
    """Pixel track of one sphere in one camera.

    Attributes
    ----------
    frame : ndarray of int, shape (N,)
        0-based decode index of each processed frame.
    t : ndarray, shape (N,)
        Timestamps, seconds.
    uv : ndarray, shape (N, 2)
        Centroids (u right, v down), NaN where not found.
    valid : ndarray of bool, shape (N,)
    detections : list of SphereDetection
    stats : TrackStats
    """

    frame: np.ndarray
    t: np.ndarray
    uv: np.ndarray
    valid: np.ndarray
    detections: list
    stats: TrackStats


def _stop_reason(exc: BaseException) -> str:
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted (Ctrl-C)"
    first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return f"stopped by an error ({first})"


def track_mono(sequence, model: ColorModel, *, tracking: bool = True, params: TrackerParams | None = None,
               show_progress: bool | None = False, keep_partial: bool = False) -> MonoTrackResult:
    """Track one sphere through a single-camera sequence (video or image folder).

    Parameters
    ----------
    sequence : Sequence
        Mono sequence (``kind == "mono"``); open it with ``strict=False`` to
        skip undecodable frames.
    model : ColorModel
        The sphere's colour model.
    tracking : bool
        Window search around the prediction (True) or full frames.
    params : TrackerParams, optional
    show_progress : bool or None
        Progress bar on stderr.
    keep_partial : bool
        On Ctrl-C or an error while reading or tracking frames, stop and
        return the frames done so far (reason in ``stats.interrupted``).

    Returns
    -------
    MonoTrackResult

    Raises
    ------
    TudorVisionError
        Not a mono sequence, or frames of another size than the model's pick.
    """
    from .._progress import progress

    if getattr(sequence, "kind", None) != "mono":
        raise TudorVisionError(f"{getattr(sequence, 'path', 'sequence')}: expected a single-camera (mono) "
                               f"sequence or video, got kind {getattr(sequence, 'kind', None)!r}")
    if not isinstance(model, ColorModel):
        raise TudorVisionError(f"model: expected a ColorModel, got {type(model).__name__}")
    params = TrackerParams() if params is None else params
    trk = SphereTracker(model, params=params)
    stats = TrackStats(frames_total=len(sequence))
    idx, ts, uv, ok, dets = [], [], [], [], []
    t0 = time.perf_counter()

    def frames():
        for i in range(len(sequence)):
            f = sequence.load_or_report(i)
            if f is None:
                stats.skipped += 1
                continue
            yield f

    try:
        for f in progress(frames(), total=len(sequence), desc="tracking", enabled=show_progress):
            _track_mono_frame(f, model, trk, tracking, params, stats, (idx, ts, uv, ok, dets))
    except (KeyboardInterrupt, Exception) as exc:
        if not keep_partial:
            raise
        stats.interrupted = _stop_reason(exc)
    stats.wall_s = time.perf_counter() - t0
    return MonoTrackResult(frame=np.array(idx, dtype=int), t=np.array(ts, dtype=np.float64),
                           uv=np.array(uv, dtype=np.float64).reshape(-1, 2), valid=np.array(ok, dtype=bool),
                           detections=dets, stats=stats)


def _track_mono_frame(f, model, trk, tracking, params, stats, out) -> None:
    """Track one mono frame and append its row to the ``out`` lists (all or nothing)."""
    idx, ts, uv, ok, dets = out
    img = np.asarray(f.image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise TudorVisionError(f"frame {f.index}: image is {img.dtype} {img.shape}; colour tracking needs "
                               "8-bit BGR images")
    w, h = model.image_size
    if (w, h) != (0, 0) and (img.shape[1], img.shape[0]) != (w, h):
        raise TudorVisionError(f"frame {f.index}: image is {img.shape[1]}x{img.shape[0]}, but the colour "
                               f"model was picked on a {w}x{h} image")
    d = trk.update(img) if tracking else _detect_one(img, model, params.segment)
    idx.append(int(f.index))
    ts.append(float(f.t))
    uv.append(d.uv if d.valid else _NAN2)
    ok.append(bool(d.valid))
    dets.append(d)
    stats.processed += 1
    stats.valid += int(d.valid)


def _detect_one(img, model: ColorModel, params: SegmentParams) -> SphereDetection:
    return detect_spheres(img, {"_": model}, params=params)["_"]


_MONO_COLUMNS = ("frame", "t", "u", "v", "valid")


def write_mono_track_csv(path, result: MonoTrackResult, *, comment: str | None = None) -> Path:
    """Write a pixel track as CSV: ``frame,t,u,v,valid``.

    ``frame`` is the 0-based decode index (real videos may have a variable
    frame rate), ``t`` seconds, ``u``/``v`` pixels (u right, v down, pixel
    centres at integers), ``valid`` 0/1 with ``nan`` pixels when 0.

    Examples
    --------
    >>> import tempfile, os
    >>> r = MonoTrackResult(frame=np.array([0, 1]), t=np.array([0.0, 0.04]),
    ...                     uv=np.array([[10.5, 20.0], [np.nan, np.nan]]), valid=np.array([True, False]),
    ...                     detections=[], stats=TrackStats())
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = read_mono_track_csv(write_mono_track_csv(os.path.join(d, "m.csv"), r))
    >>> back["u"].tolist()[0], back["valid"].tolist()
    (10.5, [1, 0])
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = ["# tudorvision pixel track v1",
             "# units: frame 0-based decode index; t s; u v px (u right, v down, pixel centres at integers); "
             "valid 0/1"]
    if comment:
        lines += [f"# {c}" for c in comment.splitlines()]
    lines.append(",".join(_MONO_COLUMNS))
    for k, t, (u, v), ok in zip(result.frame, result.t, result.uv, result.valid):
        us = repr(float(u)) if ok else "nan"
        vs = repr(float(v)) if ok else "nan"
        lines.append(f"{int(k)},{float(t)!r},{us},{vs},{int(bool(ok))}")
    write_text_atomic(path, "\n".join(lines) + "\n")
    return path


def read_mono_track_csv(path) -> dict:
    """Read a pixel track written by :func:`write_mono_track_csv` as ``{column: (N,) array}``.

    Raises
    ------
    TudorVisionError
        Missing or malformed file (naming the file and line).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise TudorVisionError(f"{path}: cannot read pixel track ({exc.strerror or exc})") from None
    rows, header = [], False
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if not header:
            if tuple(c.strip() for c in line.split(",")) != _MONO_COLUMNS:
                raise TudorVisionError(f"{path}:{lineno}: expected header {','.join(_MONO_COLUMNS)}")
            header = True
            continue
        try:
            vals = [float(x) for x in line.split(",")]
        except ValueError:
            raise TudorVisionError(f"{path}:{lineno}: malformed number in {line!r}") from None
        if len(vals) != len(_MONO_COLUMNS):
            raise TudorVisionError(f"{path}:{lineno}: expected {len(_MONO_COLUMNS)} values, got {len(vals)}")
        rows.append(vals)
    if not header:
        raise TudorVisionError(f"{path}: no header line {','.join(_MONO_COLUMNS)}")
    data = np.array(rows, dtype=np.float64).reshape(-1, len(_MONO_COLUMNS))
    out = {c: data[:, k] for k, c in enumerate(_MONO_COLUMNS)}
    out["frame"] = out["frame"].astype(int)
    out["valid"] = out["valid"].astype(int)
    return out
