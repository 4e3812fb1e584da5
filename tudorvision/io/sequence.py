"""Recorded sequences: a lazy, timestamped reader for stereo, RGB-D and mono recordings.

Sequence directory format (``kind`` stereo | rgbd | mono)::

    myseq/
      sequence.yaml      kind, rate_hz, streams, depth_scale, size, calibration, ...
      left.txt           stereo: "timestamp path" per line, '#' comments
      right.txt
      rgb.txt            rgbd: colour (8-bit BGR PNG/JPEG)
      depth.txt          rgbd: depth (16-bit PNG, raw units; metres = raw / depth_scale, 0 = invalid)
      image.txt          mono (or ``video: clip.mp4`` in sequence.yaml)
      joints.txt         optional: "timestamp theta1 theta2 theta3" in radians
      calibration.yaml   optional (see :mod:`tudorvision.io.calibration`)
      groundtruth/*.csv  optional: '#' comments, one header line of column names, CSV rows

``sequence.yaml`` keys: ``kind``; ``rate_hz`` (nominal frame rate, Hz);
``streams`` (list, e.g. ``[left, right, joints]``); ``depth_scale`` (raw
depth units per metre, required for rgbd: 1000 for mm, 5000 for TUM);
``size`` (``[width, height]`` for every image stream, or a mapping stream ->
``[w, h]``); ``calibration`` (path relative to the sequence); ``groundtruth``
(list of files relative to the sequence); ``description`` (free text);
``sync_tolerance_s`` (pairing tolerance of the two image streams, default a
quarter frame period). Other keys are kept in :attr:`Sequence.meta`.

:func:`open_sequence` also opens, read-only:

* a TUM RGB-D benchmark directory (``rgb.txt`` + ``depth.txt``, depth scale
  5000, colour and depth associated by nearest timestamp within 0.02 s);
* a video file (mono; frame ``index`` is the 0-based decode index, ``t``
  from ``CAP_PROP_POS_MSEC``, falling back to index / fps);
* ``color/N.png`` + ``depth/N.pgm`` folders (Kinect, default depth scale
  1000) and ``N.png`` + ``N_depth.png`` folders (default 5000); frames in the
  order of N at ``rate_hz`` (default 30 Hz);
* ``left/`` + ``right/`` image folders (stereo) and ``rgb/`` + ``depth/``
  folders (rgbd, default depth scale 1000), paired by the number in the
  file names, at ``rate_hz`` (default 30 Hz);
* a plain folder of images (mono);
* a ROS 1 ``.bag``, a ROS 2 bag folder or an ``.mcap`` file
  (:mod:`tudorvision.io.bags`; image topics chosen with ``topics=``);
* a live device or stream, ``/dev/videoN``, ``rtsp://``, ``http://``
  (:mod:`tudorvision.io.live`; ``"DEV1,DEV2"`` for a stereo pair).

For folder layouts a sidecar ``sequence.yaml`` with ``layout:`` (``tum``,
``kinect_folders``, ``numbered_pairs``, ``image_folder``, ``stereo_folders``,
``rgbd_folders``), optionally ``kind`` (which must agree with the layout),
and any of ``rate_hz``, ``depth_scale``, ``calibration``, ``intrinsics``
(``{fx, fy, cx, cy}``), ``size`` supplies what the folder lacks; keyword
arguments of :func:`open_sequence` override both.

Depth convention: :attr:`RGBDFrame.depth_m` is float32 metres with **NaN for
invalid pixels** (raw value 0), so means and fits cannot silently include
zeros; :attr:`RGBDFrame.depth_raw` keeps the uint16 values.

Strict reading (default): the first defect raises :class:`~tudorvision._checks.TudorVisionError`
naming the file and line (bad or out-of-order index lines, absent files, undecodable images, sizes
that differ from ``size``). Lenient (``strict=False``): defective index lines are left out, defective
images skipped while iterating, each recorded in :attr:`Sequence.report`; ``seq[i]`` always raises.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError, check_array
from ._imageheader import DEFAULT_MAX_PIXELS
from ._index import ImageProblem, Problem, parse_table, read_columns, read_image
from ._layouts import (FRAME_STREAMS, VIDEO_SUFFIXES, Record, Spec, apply_sidecar, detect_layout,
                       parse_sequence_yaml, positive_entry, sidecar_layout, spec_image_folder, spec_kinect_folders,
                       spec_numbered_pairs, spec_paired_folders, spec_tudorvision, spec_tum)
from ._video import VideoSource
from .bags import bag_spec, is_bag
from .calibration import Calibration, CameraModel, load_calibration
from .live import is_live_source, live_spec
from .frames import (JointLog, MonoFrame, RGBDFrame, StereoFrame, depth_m_from_raw,
                     raw_from_depth_m)

__all__ = ["StereoFrame", "RGBDFrame", "MonoFrame", "JointLog", "Sequence", "open_sequence", "load_joint_log",
           "depth_m_from_raw", "raw_from_depth_m", "Problem"]


# ----------------------------------------------------------------------------- the reader
class Sequence:
    """A lazily loaded recording; build it with :func:`open_sequence`.

    Frames are decoded only when indexed or iterated. ``len(seq)`` is the
    number of frames listed; iterating yields :class:`StereoFrame`,
    :class:`RGBDFrame` or :class:`MonoFrame` according to :attr:`kind`.

    Parameters
    ----------
    spec : Spec
        The parsed layout (paths, timestamps, streams, problems found while
        indexing), as built by :func:`open_sequence`.
    strict : bool
        Raise on the first defect (True) or skip and report (False).
    calibration : Calibration, optional
        Replaces the calibration file of the sequence; intrinsics from the
        layout (or the ``K`` of :func:`open_sequence`) are still added to it
        as a camera.
    max_pixels : int or None
        Images whose header declares more pixels are defective (not
        decoded); ``None`` for no limit.
    max_frames : int or None
        Only the first ``max_frames`` frames of the source.

    Raises
    ------
    TudorVisionError
        In strict mode, if indexing found a defect (a bad index line).

    Attributes
    ----------
    path : Path or str
        The directory, video file or bag (a live source: its string).
    layout : str
        ``tudorvision``, ``tum``, ``kinect_folders``, ``numbered_pairs``,
        ``image_folder``, ``stereo_folders``, ``rgbd_folders``, ``video``,
        ``rosbag1``, ``rosbag2``, ``mcap`` or ``live``.
    kind : str
        ``stereo``, ``rgbd`` or ``mono``.
    rate_hz : float or None
        Nominal frame rate.
    depth_scale : float or None
        Raw depth units per metre (rgbd).
    size : dict or None
        Expected ``(width, height)`` per image stream.
    streams : tuple of str
        Streams present (image streams and e.g. ``joints``).
    strict : bool
        Raise on the first defect (True) or skip and report (False).
    max_pixels : int or None
        Images whose header declares more pixels are defective (not decoded).
    report : list of Problem
        Defects found so far (lenient mode): index lines left out at open,
        frames skipped while iterating.
    notes : list of str
        Non-defects worth knowing (e.g. TUM frames without a partner).
    """

    def __init__(self, spec: Spec, *, strict: bool = True, calibration: Calibration | None = None,
                 max_pixels: int | None = DEFAULT_MAX_PIXELS, max_frames: int | None = None):
        self._spec = spec
        self._max_frames = max_frames
        self.path = spec.path
        self.layout = spec.layout
        self.kind = spec.kind
        self.rate_hz = spec.rate_hz
        self.depth_scale = spec.depth_scale
        self.size = spec.size
        self.streams = spec.streams
        self.description = spec.description
        self.meta = spec.meta
        self.strict = bool(strict)
        self.max_pixels = max_pixels
        self._first_size: dict = {}   # stream -> (w, h) of the first frame read, when size is not declared
        self.notes = list(spec.notes)
        self.report: list[Problem] = []
        self._seen: set = set()
        self._calibration = calibration
        self._calibration_done = False
        self._video = VideoSource(spec.video) if spec.video is not None else None
        self._source = spec.source       # bag or live stream: count, timestamps, read(i), close()
        if self._video is not None and self.rate_hz is None:
            self.rate_hz = self._video.fps
        for p in spec.problems:
            if self.strict:
                self.close()
                raise p.error()
            self.record_problem(p)

    # -------------------------------------------------------------- basics
    def __repr__(self) -> str:
        return (f"Sequence({str(self.path)!r}, layout={self.layout!r}, kind={self.kind!r}, "
                f"frames={len(self)}, rate_hz={self.rate_hz})")

    def __len__(self) -> int:
        if self._video is not None:
            n = self._video.count
        elif self._source is not None:
            n = self._source.count
        else:
            n = len(self._spec.records)
        return n if self._max_frames is None else min(n, self._max_frames)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        """Release the video capture, bag reader or live stream, if any."""
        if self._video is not None:
            self._video.close()
        if self._source is not None:
            self._source.close()

    @property
    def timestamps(self) -> np.ndarray:
        """(N,) frame timestamps in seconds (videos: index / fps)."""
        if self._video is not None:
            return np.array([self._video.nominal_t(i) for i in range(len(self))])
        if self._source is not None:     # live streams: the frames captured so far
            return np.asarray(self._source.timestamps, dtype=np.float64)[:len(self)]
        return np.array([r.t for r in self._spec.records[:len(self)]], dtype=np.float64)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last frame, seconds."""
        ts = self.timestamps
        return float(ts[-1] - ts[0]) if ts.size else 0.0

    def record_problem(self, problem: Problem) -> None:
        """Add a defect to :attr:`report`, once (a repeated ``where`` and ``reason`` is ignored).

        Parameters
        ----------
        problem : Problem
            The defect found (lenient mode).
        """
        key = (problem.where, problem.reason)
        if key not in self._seen:
            self._seen.add(key)
            self.report.append(problem)

    @property
    def joints_path(self) -> Path | None:
        """Path of the joint log (``joints.txt``), or None when the sequence has none."""
        return self._spec.joints_path

    # -------------------------------------------------------------- frames
    def __getitem__(self, index: int):
        """Frame ``index`` (negative counts from the end).

        Raises
        ------
        IndexError
            Index out of range.
        TudorVisionError
            The frame is defective (in both modes).
        """
        n = len(self)
        if not isinstance(index, (int, np.integer)):
            raise TypeError(f"frame index must be an integer, got {type(index).__name__}")
        i = int(index) + n if index < 0 else int(index)
        if not 0 <= i < n:
            raise IndexError(f"frame {index} out of range for {n} frames")
        try:
            return self._load(i)
        except _FrameProblem as fp:
            raise fp.problem.error() from None

    def __iter__(self):
        for i in range(len(self)):
            frame = self.load_or_report(i)
            if frame is not None:
                yield frame

    def load_or_report(self, i: int):
        """Frame ``i``, or ``None`` after recording the defect (lenient); strict mode raises.

        Parameters
        ----------
        i : int
            Frame index, ``0 <= i < len(self)`` (no negative indices).

        Returns
        -------
        StereoFrame or RGBDFrame or MonoFrame or None
            The decoded frame (timestamp in seconds, depth in metres);
            ``None`` when it is defective in lenient mode, the defect then
            being in :attr:`report`.

        Raises
        ------
        TudorVisionError
            In strict mode, if the frame is defective (unreadable,
            oversized, or of the wrong image size).
        """
        try:
            return self._load(i)
        except _FrameProblem as fp:
            if self.strict:
                raise fp.problem.error() from None
            self.record_problem(fp.problem)
            return None

    def _check_size(self, img, stream, where, i):
        label = "image" if stream == "image" else f"{stream} image"
        if self.size and stream in self.size:
            w, h = self.size[stream]
            if img.shape[1] != w or img.shape[0] != h:
                raise _FrameProblem(Problem(where, f"{label} is {img.shape[1]}x{img.shape[0]}, "
                                                   f"expected {w}x{h} (size)", i))
        else:   # no declared size: every frame must match the first one read (a rotated phone JPEG does not)
            w, h = self._first_size.setdefault(stream, (img.shape[1], img.shape[0]))
            if img.shape[1] != w or img.shape[0] != h:
                raise _FrameProblem(Problem(where, f"{label} is {img.shape[1]}x{img.shape[0]}, "
                                                   f"expected {w}x{h} like the first frame", i))

    def _load(self, i: int):
        if self._video is not None:
            try:
                img, t = self._video.read(i)
            except ImageProblem as exc:
                raise _FrameProblem(Problem(f"{self._video.path} frame {i}", str(exc), i)) from None
            self._check_size(img, "image", f"{self._video.path} frame {i}", i)
            return MonoFrame(t=t, index=i, image=img)
        imgs, where, t_second = {}, {}, None
        if self._source is not None:     # decoded by the source; its errors name the file and message
            try:
                t, imgs, t_second = self._source.read(i)
            except ImageProblem as exc:
                raise _FrameProblem(Problem(f"{self.path} frame {i}", str(exc), i)) from None
            where = {s: f"{self.path} frame {i} ({s})" for s in imgs}
            for s, img in imgs.items():
                self._check_size(img, s, where[s], i)
        else:
            rec: Record = self._spec.records[i]
            t = rec.t
            for slot in rec.slots:
                w = slot.where if slot.where == str(slot.path) else f"{slot.where} ({slot.path.name})"
                try:
                    img = read_image(slot.path, depth=slot.stream == "depth", max_pixels=self.max_pixels)
                except ImageProblem as exc:
                    raise _FrameProblem(Problem(w, str(exc), i)) from None
                self._check_size(img, slot.stream, w, i)
                imgs[slot.stream], where[slot.stream] = img, w
                t_second = slot.t
        if self.kind == "stereo":
            return StereoFrame(t=t, index=i, left=imgs["left"], right=imgs["right"])
        if self.kind == "mono":
            return MonoFrame(t=t, index=i, image=imgs["image"])
        rgb, raw = imgs["rgb"], imgs["depth"]
        if rgb.ndim == 2:
            rgb = cv2.cvtColor(rgb, cv2.COLOR_GRAY2BGR)
        if rgb.shape[:2] != raw.shape:
            raise _FrameProblem(Problem(where["rgb"], f"colour {rgb.shape[1]}x{rgb.shape[0]} and depth "
                                                      f"{raw.shape[1]}x{raw.shape[0]} sizes differ", i))
        return RGBDFrame(t=t, index=i, rgb=rgb, depth_raw=raw,
                         depth_m=depth_m_from_raw(raw, self.depth_scale), t_depth=t_second)

    # -------------------------------------------------------------- side data
    @property
    def calibration(self) -> Calibration | None:
        """The sequence's calibration (loaded on first use), or ``None``."""
        if not self._calibration_done:
            spec = self._spec
            if self._calibration is None and spec.calibration_path is not None:
                self._calibration = load_calibration(spec.calibration_path)
            if spec.intrinsics is not None:
                cam = self._camera_from_intrinsics(spec.intrinsics)
                base = self._calibration or Calibration()
                self._calibration = base.with_updates(cameras={_camera_name(self.kind): cam})
            self._calibration_done = True
        return self._calibration

    def _camera_from_intrinsics(self, K) -> CameraModel:
        stream = FRAME_STREAMS[self.kind][0]
        if self.size and stream in self.size:
            w, h = self.size[stream]
        elif self._video is not None:
            w, h = self._video.size
        elif self._source is not None and len(self):
            h, w = getattr(self[0], FRAME_STREAMS[self.kind][0]).shape[:2]
        elif len(self):
            try:
                shape = read_image(self._spec.records[0].slots[0].path).shape
            except ImageProblem as exc:
                raise TudorVisionError(f"{self._spec.records[0].slots[0].path}: {exc}") from None
            w, h = shape[1], shape[0]
        else:
            raise TudorVisionError(f"{self.path}: no frames to take the image size from; pass size=")
        return CameraModel(K=K, width=w, height=h)

    def joints(self) -> JointLog:
        """The joint log (``joints.txt``).

        Returns
        -------
        JointLog
            Timestamps (seconds) and joint angles (radians); in lenient mode
            without the malformed lines, which go to :attr:`report`.

        Raises
        ------
        TudorVisionError
            No joint log, or (strict) a malformed or out-of-order line.
        """
        path = self._spec.joints_path
        if path is None:
            raise TudorVisionError(f"{self.path}: no joints.txt in this sequence")
        problems: list[Problem] = []
        log = load_joint_log(path, strict=self.strict, report=problems)
        for p in problems:
            self.record_problem(p)
        return log

    @property
    def groundtruth_names(self) -> list[str]:
        """Names accepted by :meth:`groundtruth`."""
        return sorted(self._spec.groundtruth)

    def groundtruth(self, name: str) -> dict[str, np.ndarray]:
        """Ground-truth table ``name`` as ``{column: (N,) array}``.

        Trackers never need this; it is for evaluation.

        Parameters
        ----------
        name : str
            One of :attr:`groundtruth_names`.

        Returns
        -------
        dict of str to ndarray, shape (N,)
            One float64 array per column, in file order, in the units the
            file states (the project's writer uses SI units).

        Raises
        ------
        TudorVisionError
            If the sequence has no table ``name``, or the file is unreadable
            or malformed.
        """
        try:
            path, cols = self._spec.groundtruth[name]
        except KeyError:
            raise TudorVisionError(f"{self.path}: no ground truth {name!r} "
                                   f"(have {self.groundtruth_names})") from None
        return read_columns(path, cols)

    def play(self, *, speed: float = 1.0, clock=None, sleep=None):
        """Play back at the recorded rate, dropping frames the consumer is too slow for.

        See :class:`tudorvision.io.playback.Playback`.

        Parameters
        ----------
        speed : float
            Playback speed factor (2.0: twice as fast as recorded).
        clock : callable, optional
            Time source in seconds; default ``time.monotonic``.
        sleep : callable, optional
            Sleep function taking seconds; default ``time.sleep``.

        Returns
        -------
        Playback
            Iterator over :class:`~tudorvision.io.playback.Played` items
            paced to wall time.

        Raises
        ------
        ValueError
            If ``speed`` is not a positive number.
        """
        from .playback import Playback
        return Playback(self, speed=speed, clock=clock, sleep=sleep)


def load_joint_log(path, *, strict: bool = True, report: list | None = None) -> JointLog:
    """Read a joint log file (``timestamp theta1 theta2 theta3`` per line, radians, ``#`` comments).

    Parameters
    ----------
    path : str or Path
        E.g. a sequence's ``joints.txt``.
    strict : bool
        Raise on the first malformed or out-of-order line; otherwise leave
        such lines out.
    report : list, optional
        Receives a :class:`Problem` per line left out (lenient mode).

    Returns
    -------
    JointLog

    Raises
    ------
    TudorVisionError
        Unreadable file, or (strict) a bad line, naming ``file:line``.
    """
    rows, _, problems = parse_table(Path(path), 4)
    if problems and strict:
        raise problems[0].error()
    if report is not None:
        report.extend(problems)
    return JointLog(t=rows[:, 0].copy(), theta_rad=rows[:, 1:].copy())


class _FrameProblem(Exception):
    def __init__(self, problem: Problem):
        super().__init__(str(problem))
        self.problem = problem


def _camera_name(kind: str) -> str:
    return {"rgbd": "rgbd", "mono": "camera", "stereo": "left"}[kind]


# ----------------------------------------------------------------------------- opening
def open_sequence(path, *, strict: bool = True, rate_hz: float | None = None,
                  depth_scale: float | None = None, K=None, calibration=None, size=None,
                  max_dt_s: float | None = None, allow_outside: bool = False,
                  max_pixels: int | None = DEFAULT_MAX_PIXELS, topics=None,
                  max_frames: int | None = None, timeout_s: float = 5.0) -> Sequence:
    """Open a recorded sequence (directory, sequence.yaml, video file, ROS bag, live stream).

    Parameters
    ----------
    path : str or Path
        Sequence directory (any layout in the module docstring), its
        ``sequence.yaml``, a video file, a ROS 1 ``.bag``, a ROS 2 bag
        folder, an ``.mcap`` file, or a live source (``/dev/videoN``,
        ``rtsp://...``, ``http://...``; two joined by a comma for stereo).
    strict : bool
        Raise on the first defect (default) or skip and report.
    rate_hz : float, optional
        Frame rate; sets the timestamps of folder layouts that have none
        (default 30 Hz) and overrides the nominal rate elsewhere.
    depth_scale : float, optional
        Raw depth units per metre, overriding the file's / layout's value.
    K : array_like, shape (3, 3), optional
        Intrinsics of the (first) camera, added to :attr:`Sequence.calibration`
        as camera ``rgbd`` (rgbd) or ``camera`` (mono) with zero distortion.
    calibration : Calibration or path, optional
        Replaces the sequence's calibration.
    size : tuple of int, optional
        Expected ``(width, height)`` of every image stream.
    max_dt_s : float, optional
        Pairing tolerance of the two image streams (TUM: 0.02 s).
    allow_outside : bool
        Follow index lines naming absolute paths or paths outside the
        sequence folder (``../x.png``); by default each such line is a
        defect naming the index file and line.
    max_pixels : int or None
        Largest image accepted, checked from the file header before
        decoding (default 100 megapixels); None: no limit.
    topics : str or dict, optional
        Bags: the image topics, ``"left=/a,right=/b"``, ``"rgb=/c,depth=/d"``
        or ``"image=/e"`` (or the same as a dict); found automatically when
        unambiguous. Live stereo: ``"left=DEV1,right=DEV2"`` as the path.
    max_frames : int, optional
        Only the first ``max_frames`` frames (live sources: stop after this
        many; default: until the stream ends, fails to deliver a frame
        within ``timeout_s``, or Ctrl-C).
    timeout_s : float
        Live sources: longest wait for a frame, seconds.

    Returns
    -------
    Sequence

    Raises
    ------
    TudorVisionError
        Not a sequence, malformed sequence.yaml (file and line), missing
        index files, or (strict) any defective index line.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> from tudorvision.io import SequenceWriter
    >>> d = tempfile.mkdtemp()
    >>> with SequenceWriter(d, kind="mono", rate_hz=10.0, image_ext=".png") as w:
    ...     w.add_mono(0.0, np.zeros((4, 6), np.uint8))
    ...     w.add_mono(0.1, np.ones((4, 6), np.uint8))
    >>> seq = open_sequence(d)
    >>> len(seq), seq.kind, [round(f.t, 2) for f in seq]
    (2, 'mono', [0.0, 0.1])
    """
    for name, v in (("rate_hz", rate_hz), ("depth_scale", depth_scale)):
        if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
            raise ValueError(f"{name}: expected a positive number, got {v!r}")
    if max_pixels is not None and (isinstance(max_pixels, bool) or not isinstance(max_pixels, (int, np.integer))
                                   or max_pixels < 1):
        raise ValueError(f"max_pixels: expected a positive integer or None, got {max_pixels!r}")
    text, live = str(path), is_live_source(path)
    path = Path(path)
    if not live and not path.exists():
        raise TudorVisionError(f"{path}: no such file or directory")
    if path.is_file() and path.name in ("sequence.yaml", "metadata.yaml"):   # a rosbag2 folder's metadata
        path = path.parent
    if live:
        spec = live_spec(text, max_frames=max_frames, timeout_s=timeout_s, max_dt_s=max_dt_s)
    elif is_bag(path):
        spec = bag_spec(path, topics=topics, max_dt_s=max_dt_s, depth_scale=depth_scale)
    elif path.is_file():
        if path.suffix.lower() not in VIDEO_SUFFIXES:
            raise TudorVisionError(f"{path}: not a sequence directory or a video file "
                                   f"({', '.join(sorted(VIDEO_SUFFIXES))})")
        spec = Spec(path=path, layout="video", kind="mono", rate_hz=None, streams=("image",), video=path)
        data, line_of = {}, None
    else:
        layout = detect_layout(path)
        data, line_of = ({}, None)
        if layout == "tudorvision":
            data, line_of = parse_sequence_yaml(path / "sequence.yaml")
            layout = sidecar_layout(path, data, line_of)
        side_rate = None
        if layout != "tudorvision":
            side_rate = positive_entry(data, "rate_hz", path / "sequence.yaml", line_of, required=False)
        folder_rate = float(rate_hz or side_rate or 30.0)
        if layout == "tudorvision":
            spec = spec_tudorvision(path, data, line_of, max_dt_s=max_dt_s, allow_outside=allow_outside)
        elif layout == "tum":
            spec = spec_tum(path, max_dt_s=max_dt_s, allow_outside=allow_outside)
        elif layout == "kinect_folders":
            spec = spec_kinect_folders(path, rate_hz=folder_rate)
            spec.depth_scale = 1000.0
        elif layout == "numbered_pairs":
            spec = spec_numbered_pairs(path, rate_hz=folder_rate)
            spec.depth_scale = 5000.0
        elif layout in ("stereo_folders", "rgbd_folders"):
            spec = spec_paired_folders(path, kind=layout.split("_")[0], rate_hz=folder_rate)
        else:
            spec = spec_image_folder(path, rate_hz=folder_rate)
        if spec.joints_path is None and (path / "joints.txt").is_file():
            spec.joints_path = path / "joints.txt"      # found wherever present, in every layout
        if layout != "tudorvision":
            apply_sidecar(spec, data, line_of, path / "sequence.yaml")
            if side_rate is not None:
                spec.rate_hz = side_rate
            if spec.kind == "rgbd" and depth_scale is None and "depth_scale" not in data \
                    and layout != "tum":
                spec.notes.append(f"depth_scale not given: assuming {spec.depth_scale:g} units per metre "
                                  f"for layout {layout}")
    if rate_hz is not None:
        spec.rate_hz = float(rate_hz)
    if depth_scale is not None:
        spec.depth_scale = float(depth_scale)
    if size is not None:
        w, h = (int(v) for v in size)
        spec.size = {s: (w, h) for s in FRAME_STREAMS[spec.kind]}
    if K is not None:
        if spec.kind == "stereo":
            raise ValueError("K: stereo sequences take a calibration file, not a single K")
        spec.intrinsics = check_array(K, "K", (3, 3))
    cal = spec.calibration
    if calibration is not None:
        cal = calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
        spec.calibration_path = None
    if max_frames is not None and (isinstance(max_frames, bool) or not max_frames >= 1):
        raise ValueError(f"max_frames: expected a positive integer or None, got {max_frames!r}")
    return Sequence(spec, strict=strict, calibration=cal, max_pixels=max_pixels,
                    max_frames=None if live else max_frames)
