"""A rerun recording (``.rrd``) of stereo tracking: images, detections and the 3D track.

Entity layout (rerun 0.41)::

    cameras/left/image          rr.EncodedImage (JPEG) of the left frame
    cameras/left/detections     rr.Points2D, one point per valid sphere (label, colour)
    cameras/right/...           the same for the right camera
    world/spheres               rr.Points3D, sphere centres of the frame
    world/ee                    rr.Points3D, end effector of the frame
    world/track                 rr.LineStrips3D, the whole trajectory (logged at the end)
    plots/speed                 rr.Scalars, |v| in m/s

Timelines: ``frame`` (sequence index) and ``time`` (seconds, the frame
timestamp). 3D entities are in metres in the trajectory's frame (base frame
z up, or left camera optical frame). rerun is imported inside the functions,
so the rest of the package works without it.

Open the file with ``rerun out.rrd``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .._checks import TudorVisionError

__all__ = ["RerunStereoLog", "log_mono_track"]

_COLORS = {"red": (230, 40, 40), "green": (40, 200, 60), "blue": (40, 90, 230), "yellow": (230, 210, 40)}


def _rerun():
    try:
        import rerun as rr
    except ImportError:  # pragma: no cover
        raise TudorVisionError("--rerun needs the rerun SDK: pip install rerun-sdk") from None
    return rr


class RerunStereoLog:
    """Write a stereo tracking run to a rerun ``.rrd`` file.

    Parameters
    ----------
    path : str or Path, optional
        Output ``.rrd`` file (parent directories are created); not used
        when ``recording`` is given.
    image_every : int
        Log the images of every n-th frame only (detections and 3D points are
        logged for every frame); 0 logs no images.
    jpeg_quality : int
        Images are stored JPEG-encoded to keep the file small.
    application_id : str
        rerun application id.
    recording : rerun.RecordingStream, optional
        Log to this stream (its sinks: a file, a live or a web viewer)
        instead of opening ``path``; :meth:`close` then only flushes it.

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> log = RerunStereoLog(os.path.join(d, "t.rrd"))
    >>> log.close()
    >>> os.path.getsize(os.path.join(d, "t.rrd")) > 0
    True
    """

    def __init__(self, path=None, *, image_every: int = 1, jpeg_quality: int = 85,
                 application_id: str = "tudorvision_stereo", recording=None):
        if int(image_every) != image_every or image_every < 0:
            raise TudorVisionError(f"image_every: expected a non-negative integer, got {image_every!r}")
        if path is None and recording is None:
            raise TudorVisionError("RerunStereoLog: give a path or a recording")
        rr = _rerun()
        self.image_every = int(image_every)
        self.jpeg_quality = int(jpeg_quality)
        self._rr = rr
        self._own = recording is None
        self.path = None if path is None else Path(path)
        if self._own:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._rec = rr.RecordingStream(application_id)
            self._rec.save(str(self.path))
        else:
            self._rec = recording
        self._n = 0

    def _time(self, index: int, t: float) -> None:
        self._rec.set_time("frame", sequence=int(index))
        self._rec.set_time("time", duration=float(t))

    def log_frame(self, result, frame=None) -> None:
        """Log one :class:`~tudorvision.stereo.pipeline.StereoFrameResult` (and its images).

        Parameters
        ----------
        result : StereoFrameResult
            One frame's output of the stereo pipeline: the 2D detections per
            camera (pixels) and the triangulated sphere and end-effector
            positions (metres), logged at its ``index`` and time ``t``.
        frame : StereoFrame, optional
            The frame's images (``left``, ``right`` BGR).
        """
        import cv2

        rr, rec = self._rr, self._rec
        self._time(result.index, result.t)
        if frame is not None and self.image_every and self._n % self.image_every == 0:
            for cam in ("left", "right"):
                ok, buf = cv2.imencode(".jpg", getattr(frame, cam), [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
                if ok:
                    rec.log(f"cameras/{cam}/image", rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"))
        for cam, dets in result.detections.items():
            names = [s for s, d in dets.items() if d.valid]
            pos = np.array([dets[s].uv for s in names], dtype=np.float64).reshape(-1, 2)
            radii = [max(dets[s].radius_px, 1.0) for s in names]
            colors = [_COLORS.get(s, (255, 255, 255)) for s in names]
            rec.log(f"cameras/{cam}/detections", rr.Points2D(pos, radii=radii, colors=colors, labels=names))
        names = [s for s, p in result.spheres.items() if np.all(np.isfinite(p))]
        pts = np.array([result.spheres[s] for s in names], dtype=np.float64).reshape(-1, 3)
        rec.log("world/spheres", rr.Points3D(pts, radii=0.035, colors=[_COLORS.get(s, (255, 255, 255))
                                                                        for s in names], labels=names))
        ee = np.asarray(result.ee, dtype=np.float64).reshape(-1, 3)
        rec.log("world/ee", rr.Points3D(ee[np.all(np.isfinite(ee), axis=1)], radii=0.01, colors=[(250, 250, 250)]))
        self._n += 1

    def log_trajectory(self, traj, index=None) -> None:
        """Log the whole trajectory as line strips (split at invalid samples) and the speed plot.

        Parameters
        ----------
        traj : Trajectory
            End-effector trajectory (seconds, metres, m/s); samples with
            ``valid`` False break the line strip.
        index : array_like of int, shape (N,), optional
            Sequence index of each sample (default 0..N-1), for the ``frame`` timeline.
        """
        rr, rec = self._rr, self._rec
        strips, cur = [], []
        for p, ok in zip(traj.p, traj.valid):
            if ok:
                cur.append(p)
            elif cur:
                strips.append(np.array(cur))
                cur = []
        if cur:
            strips.append(np.array(cur))
        strips = [s for s in strips if len(s) >= 2]
        if len(traj.t):
            self._time(0, float(traj.t[0]))
        rec.log("world/track", rr.LineStrips3D(strips, radii=0.003, colors=[(255, 200, 0)]), static=True)
        index = np.arange(len(traj.t)) if index is None else np.asarray(index, dtype=int)
        for k, t, s in zip(index, traj.t, traj.speed):
            if np.isfinite(s):
                self._time(k, t)
                rec.log("plots/speed", rr.Scalars(float(s)))

    def close(self) -> None:
        """Flush; close the file when this log opened it."""
        self._rec.flush()
        if self._own:
            self._rec.disconnect()


def log_mono_track(recording, result, *, sphere: str = "sphere", camera: str = "mono") -> None:
    """Log a single-camera pixel track: the sphere's image point per frame and its u, v plots.

    Entities: ``cameras/<camera>/<sphere>`` (rr.Points2D, pixels, u right,
    v down), ``plots/<sphere>/u_px`` and ``plots/<sphere>/v_px``
    (rr.Scalars), on the ``frame`` and ``time`` timelines; invalid frames
    clear the point.

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream to log to.
    result : MonoTrackResult
        Output of :func:`~tudorvision.stereo.tracking.track_mono`: ``frame``
        (N,) decode index, ``t`` (N,) in s, ``uv`` (N, 2) in px, ``valid`` (N,).
    sphere : str
        Sphere name (entity path and label).
    camera : str
        Camera name (entity path).

    Returns
    -------
    None
    """
    rr = _rerun()
    color = _COLORS.get(sphere, (255, 255, 255))
    index = np.asarray(getattr(result, "frame", np.arange(len(result.t))), dtype=int)
    uv = np.asarray(result.uv, dtype=np.float64).reshape(-1, 2)
    for k, t, p, ok in zip(index, result.t, uv, result.valid):
        recording.set_time("frame", sequence=int(k))
        recording.set_time("time", duration=float(t))
        if ok and np.all(np.isfinite(p)):
            recording.log(f"cameras/{camera}/{sphere}", rr.Points2D([p], radii=4, colors=[color], labels=[sphere]))
            recording.log(f"plots/{sphere}/u_px", rr.Scalars(float(p[0])))
            recording.log(f"plots/{sphere}/v_px", rr.Scalars(float(p[1])))
        else:
            recording.log(f"cameras/{camera}/{sphere}", rr.Clear(recursive=False))
