"""Tracking over a recording: a sequence in, an end-effector trajectory (stereo) or a pixel track (mono) out.

:func:`iter_stereo` feeds a recorded :class:`~tudorvision.io.Sequence` through
a :class:`~tudorvision.stereo.pipeline.StereoPipeline`, either as fast as
possible or paced at the recorded rate; :func:`track_stereo` collects the
results into a trajectory (re-triangulated from the whole pixel tracks with
rolling-shutter compensation); :func:`track_mono` gives one sphere's pixel
track. Defective frames are skipped, counted and named; with
``keep_partial=True`` an interrupted run returns the rows so far, flagged.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from .._checks import TudorVisionError
from ..io.atomic import write_text_atomic
from .colormodel import ColorModel, ColorModelSet
from .pipeline import PipelineOptions, StereoFrameResult, StereoPipeline
from .segment import SegmentParams, SphereDetection, detect_spheres
from .tracker2d import SphereTracker, TrackerParams
from .trajectory import Trajectory, trajectory_from_points
from .triangulate import SphereTriangulation

_NAN2 = (float("nan"), float("nan"))

__all__ = ["TrackStats", "StereoTrackResult", "iter_stereo", "track_stereo", "MonoTrackResult", "track_mono",
           "write_mono_track_csv", "read_mono_track_csv"]


def iter_stereo(sequence, pipeline: StereoPipeline, *, live: bool = False, speed: float = 1.0,
                stats: "TrackStats | None" = None, clock=None, sleep=None) -> Iterator[StereoFrameResult]:
    """Run a pipeline over a stereo sequence, yielding one result per processed frame.

    Parameters
    ----------
    sequence : Sequence
        A stereo sequence (:func:`tudorvision.io.open_sequence`); with
        ``strict=False`` defective frames are skipped and counted.
    pipeline : StereoPipeline
        Configured pipeline (calibration, colour models, output frame); its
        tracking state carries across the frames.
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
        One per processed frame, in sequence order; positions in metres in
        the pipeline's output frame (``"base"`` or ``"left"``).

    Raises
    ------
    TudorVisionError
        If ``sequence`` is not a stereo sequence, a frame of a strict
        sequence is defective, or an image is not 8-bit BGR of the
        calibrated size.
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
    checks : dict of str to int
        Stereo runs: what the pipeline's consistency checks did over the run
        (:meth:`StereoPipeline.check_counts`); empty for one camera.
    _n_latency : int
        Internal: frames with a measured live latency, the divisor of
        :attr:`mean_latency_s`; leave it at 0 when constructing.
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
    checks: dict = field(default_factory=dict)
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
        """One line: frames, valid %, fps, and skipped/dropped/latency where they apply.

        Returns
        -------
        str
            E.g. ``"120/125 frames tracked, 96.7% valid, 48.2 fps"``, with
            the corrupt frames skipped and, for live runs, the frames
            dropped and the mean and maximum latency in milliseconds; then
            the stereo checks that did something (``checks``), e.g.
            ``"; stereo checks: 3 views measured again on their luma rim"``.
        """
        s = (f"{self.processed}/{self.frames_total} frames tracked, {100 * self.valid_fraction:.1f}% valid, "
             f"{self.fps:.1f} fps")
        if self.skipped:
            s += f", {self.skipped} corrupt frame(s) skipped"
        if self._n_latency:
            s += (f", {self.dropped} dropped, latency mean {1e3 * self.mean_latency_s:.1f} ms "
                  f"max {1e3 * self.max_latency_s:.1f} ms")
        done = [f"{n} {what}" for what, n in self.checks.items() if n]
        if done:
            s += "; stereo checks: " + ", ".join(done)
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
        Tracking, triangulation and consistency options; default
        ``PipelineOptions()``.
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
    stats.checks = pipe.check_counts()
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
        Window and segmentation options; default ``TrackerParams()``.
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

    Parameters
    ----------
    path : str or Path
        Output CSV; parent directories are created. Written atomically: a
        failed write leaves a previous file intact.
    result : MonoTrackResult
        The pixel track (``frame``, ``t``, ``uv``, ``valid``).
    comment : str, optional
        Extra comment lines at the top (e.g. the command).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OSError
        If missing parent folders cannot be created.
    TudorVisionError
        If the file cannot be written (disk full, read-only folder).

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

    Parameters
    ----------
    path : str or Path
        Pixel track CSV.

    Returns
    -------
    dict of str to ndarray, shape (N,)
        ``frame`` (int, 0-based decode index), ``t`` (seconds), ``u``,
        ``v`` (pixels, u right, v down; NaN when invalid) and ``valid``
        (int, 0/1).

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
