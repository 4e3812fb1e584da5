"""Live cameras and streams as sequences, through OpenCV's ``VideoCapture``.

Sources: a V4L2 device ``/dev/videoN``, an ``rtsp://`` / ``rtsps://``
stream, an ``http://`` / ``https://`` stream (MJPEG or anything FFmpeg
reads), ``udp://`` / ``tcp://``. Two sources joined by a comma
(``/dev/video0,/dev/video2`` or ``left=/dev/video0,right=/dev/video2``) are
a stereo pair, paired in software by the time each frame arrived
(:class:`StereoPairer`).

Each source is read by a background thread into a small queue; when the
consumer falls behind the oldest frames are dropped (a live camera cannot
wait) and counted. A frame that does not arrive within ``timeout_s``
ends the stream, like the end of a file; nothing reconnects. Frame times
``t`` are the wall-clock arrival times (``time.time()``, seconds).

A live sequence has no known length: :func:`tudorvision.io.open_sequence`
gives it ``max_frames`` frames (default: unbounded) and reading past the
end of the stream raises :class:`StreamEnded`.
"""
from __future__ import annotations

import collections
import queue
import re
import sys
import threading
import time

import cv2
import numpy as np

from .._checks import TudorVisionError
from ._index import ImageProblem
from ._layouts import Spec

__all__ = ["is_live_source", "split_live_sources", "LiveCapture", "StereoPairer", "pair_by_timestamp",
           "LiveFrames", "StreamEnded", "live_spec"]

_URL = re.compile(r"^(rtsps?|https?|udp|tcp|rtmp)://", re.I)
_DEVICE = re.compile(r"^/dev/video\d+$")


class StreamEnded(TudorVisionError):
    """A live source delivered no more frames (end of stream, or none within the timeout)."""


def split_live_sources(text) -> list[str]:
    """The one or two sources of a live source string (``left=``/``right=`` prefixes removed).

    Parameters
    ----------
    text : str
        E.g. ``"/dev/video0"``, ``"rtsp://cam/stream"`` or
        ``"left=/dev/video0,right=/dev/video2"``.

    Returns
    -------
    list of str
        One source (mono) or two (stereo: left, right); empty when
        ``text`` is not a live source.

    Examples
    --------
    >>> split_live_sources("left=/dev/video0,right=/dev/video2")
    ['/dev/video0', '/dev/video2']
    >>> split_live_sources("recording.bag")
    []
    """
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) == 2 and parts[1].startswith("left=") and parts[0].startswith("right="):
        parts = parts[::-1]
    parts = [re.sub(r"^(left|right|image)=", "", p) for p in parts]
    if not 1 <= len(parts) <= 2 or not all(_URL.match(p) or _DEVICE.match(p) for p in parts):
        return []
    return parts


def is_live_source(text) -> bool:
    """Whether ``text`` names a live device or stream (see :func:`split_live_sources`).

    Parameters
    ----------
    text : str or Path
        A command's sequence argument.

    Returns
    -------
    bool
    """
    return bool(split_live_sources(text))


class LiveCapture:
    """One OpenCV source read by a background thread.

    Parameters
    ----------
    source : str
        Anything ``cv2.VideoCapture`` opens (device path, URL, also a video
        file or an image pattern, which is handy for tests).
    timeout_s : float
        Longest wait for the stream to open and for each frame, seconds.
    buffer : int
        Frames kept while the consumer is busy.
    drop_old : bool
        When the buffer is full, drop the oldest frame (live cameras); with
        False the reading thread waits (files: every frame is delivered).

    Raises
    ------
    TudorVisionError
        If the source cannot be opened.

    Attributes
    ----------
    fps : float or None
        Frame rate the source reports, Hz.
    dropped : int
        Frames dropped because the consumer was too slow.
    """

    def __init__(self, source: str, *, timeout_s: float = 5.0, buffer: int = 8, drop_old: bool = True):
        self.source = str(source)
        self.timeout_s = float(timeout_s)
        ms = int(max(self.timeout_s, 0.1) * 1000)
        params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms]
        try:
            cap = cv2.VideoCapture(self.source, cv2.CAP_ANY, params)
        except cv2.error:
            cap = None
        if cap is None or not cap.isOpened():
            raise TudorVisionError(f"{self.source}: cannot open the live source (no such device, or the "
                                   "stream does not answer)")
        fps = cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if fps and np.isfinite(fps) and 0 < fps < 1000 else None
        self.dropped = 0
        self._cap = cap
        self._q: queue.Queue = queue.Queue(maxsize=max(1, int(buffer)))
        self._drop_old = bool(drop_old)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"live {self.source}", daemon=True)
        self._thread.start()

    def _put(self, item) -> None:
        while not self._stop.is_set():
            try:
                self._q.put(item, timeout=0.05)
                return
            except queue.Full:
                if self._drop_old:
                    try:
                        self._q.get_nowait()
                        self.dropped += 1
                    except queue.Empty:
                        pass

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                ok, img = self._cap.read()
                t = time.time()
                if not ok or img is None:
                    break
                self._put((t, img))
        except cv2.error:
            pass
        finally:
            self._put(None)           # end of stream
            self._cap.release()

    def get(self, timeout_s: float | None = None):
        """The next frame, waiting at most ``timeout_s`` (default the capture's timeout).

        Parameters
        ----------
        timeout_s : float, optional
            Longest wait, seconds.

        Returns
        -------
        tuple of (float, ndarray) or None
            Arrival time (``time.time()``, seconds) and the ``(H, W, 3)``
            uint8 BGR image; None when the stream ended or nothing arrived
            in time.
        """
        try:
            item = self._q.get(timeout=self.timeout_s if timeout_s is None else timeout_s)
        except queue.Empty:
            return None
        if item is None:
            self._put(None)           # stay ended for later calls
        return item

    def close(self) -> None:
        """Stop the reading thread (the capture is released by the thread itself)."""
        self._stop.set()
        self._thread.join(timeout=max(self.timeout_s, 1.0))


class StereoPairer:
    """Pair frames of two unsynchronised cameras by their timestamps.

    Frames are pushed as they arrive; a pair is formed when the oldest
    left and right frames are within ``tol_s`` of each other and neither has
    a closer partner already waiting. A frame with no partner within
    ``tol_s`` is dropped (counted in :attr:`dropped`).

    Parameters
    ----------
    tol_s : float
        Largest accepted time difference, seconds (e.g. half a frame period).

    Attributes
    ----------
    dropped : dict of str to int
        Frames dropped per side (``left``, ``right``).
    """

    def __init__(self, tol_s: float):
        if not tol_s > 0:
            raise ValueError(f"tol_s: expected a positive number of seconds, got {tol_s!r}")
        self.tol_s = float(tol_s)
        self._buf = {"left": collections.deque(), "right": collections.deque()}
        self.dropped = {"left": 0, "right": 0}

    def push(self, side: str, t: float, item=None) -> list[tuple]:
        """Add a frame and return the pairs it completes.

        Parameters
        ----------
        side : {"left", "right"}
            Which camera.
        t : float
            Its timestamp, seconds (increasing per side).
        item : object, optional
            Carried along (the image).

        Returns
        -------
        list of tuple
            ``((t_left, item_left), (t_right, item_right))`` per pair formed,
            oldest first.
        """
        self._buf[side].append((float(t), item))
        out = []
        L, R = self._buf["left"], self._buf["right"]
        while L and R:
            (tl, _), (tr, _) = L[0], R[0]
            if abs(tl - tr) > self.tol_s or (len(L) > 1 and abs(L[1][0] - tr) < abs(tl - tr)) \
                    or (len(R) > 1 and abs(R[1][0] - tl) < abs(tl - tr)):
                older = "left" if tl < tr else "right"   # the older one can only get a worse partner
                self._buf[older].popleft()
                self.dropped[older] += 1
                continue
            out.append((L.popleft(), R.popleft()))
        return out


def pair_by_timestamp(t_left, t_right, tol_s: float) -> np.ndarray:
    """Pair two arrival-time lists as :class:`StereoPairer` does on a live stream.

    The frames are pushed in order of arrival (merged by time).

    Parameters
    ----------
    t_left, t_right : array_like, shape (N,), (M,)
        Increasing arrival times, seconds.
    tol_s : float
        Largest accepted time difference, seconds.

    Returns
    -------
    ndarray, shape (K, 2), int
        Index pairs ``(i_left, i_right)`` in order.

    Examples
    --------
    >>> pair_by_timestamp([0.0, 0.1, 0.2], [0.004, 0.15, 0.203], 0.02).tolist()
    [[0, 0], [2, 2]]
    """
    pairer = StereoPairer(tol_s)
    events = sorted([(float(t), 0, i) for i, t in enumerate(t_left)]
                    + [(float(t), 1, j) for j, t in enumerate(t_right)])
    out = []
    for t, side, k in events:
        for (_, a), (_, b) in pairer.push("left" if side == 0 else "right", t, k):
            out.append((a, b))
    return np.asarray(out, dtype=np.int64).reshape(-1, 2)


class LiveFrames:
    """Frame source of live captures for :class:`~tudorvision.io.sequence.Sequence` (see :func:`live_spec`).

    Parameters
    ----------
    captures : list of LiveCapture
        One (mono) or two (stereo: left, right).
    max_frames : int, optional
        Frames to deliver (default unbounded).
    tol_s : float
        Stereo pairing tolerance, seconds.

    Attributes
    ----------
    count : int
        ``max_frames`` (``sys.maxsize`` when unbounded).
    timestamps : list of float
        Times of the frames delivered so far, seconds.
    """

    def __init__(self, captures: list, *, max_frames: int | None = None, tol_s: float = 0.02):
        self._caps = list(captures)
        self.count = int(max_frames) if max_frames is not None else sys.maxsize
        self.timestamps: list[float] = []
        self._pairer = StereoPairer(tol_s) if len(self._caps) == 2 else None
        self._pairs: collections.deque = collections.deque()
        self._recent: collections.OrderedDict = collections.OrderedDict()
        self._next = 0

    def _one(self):
        if self._pairer is None:
            item = self._caps[0].get()
            if item is None:
                raise StreamEnded(f"{self._caps[0].source}: stream ended after {self._next} frames")
            return item[0], {"image": item[1]}, None
        while not self._pairs:
            for side, cap in zip(("left", "right"), self._caps):
                item = cap.get()
                if item is None:
                    raise StreamEnded(f"{cap.source}: stream ended after {self._next} frames")
                self._pairs.extend(self._pairer.push(side, item[0], item[1]))
        (tl, left), (tr, right) = self._pairs.popleft()
        return tl, {"left": left, "right": right}, tr

    def read(self, i: int):
        """Frame ``i``: the next frames of the stream are read up to it.

        Parameters
        ----------
        i : int
            Frame index; one of the last 8 read, or a later one.

        Returns
        -------
        t_s : float
            Arrival time of the (left) image, seconds.
        images : dict of str to ndarray
            ``image`` or ``left`` and ``right``: ``(H, W, 3)`` uint8 BGR.
        t_second_s : float or None
            Arrival time of the right image (stereo).

        Raises
        ------
        ImageProblem
            Frame ``i`` has already passed.
        StreamEnded
            The stream ended, or no frame arrived within the timeout.
        """
        if i in self._recent:
            return self._recent[i]
        if i < self._next:
            raise ImageProblem(f"live frame {i} has passed (the last 8 frames are kept)")
        while self._next <= i:
            frame = self._one()
            self._recent[self._next] = frame
            self.timestamps.append(frame[0])
            self._next += 1
            if len(self._recent) > 8:
                self._recent.popitem(last=False)
        return self._recent[i]

    @property
    def dropped(self) -> int:
        """Frames dropped by the capture threads and by stereo pairing."""
        return sum(c.dropped for c in self._caps) + (sum(self._pairer.dropped.values()) if self._pairer else 0)

    def close(self) -> None:
        """Stop every capture."""
        for c in self._caps:
            c.close()


def live_spec(text: str, *, max_frames: int | None = None, timeout_s: float = 5.0,
              max_dt_s: float | None = None, drop_old: bool = True) -> Spec:
    """Open a live source as a sequence layout (the reader of :func:`tudorvision.io.open_sequence`).

    Parameters
    ----------
    text : str
        One source, or two joined by a comma (stereo), see
        :func:`split_live_sources`.
    max_frames : int, optional
        Frames to deliver (default unbounded: until the stream ends or
        Ctrl-C).
    timeout_s : float
        Longest wait to open the source and for each frame, seconds.
    max_dt_s : float, optional
        Stereo pairing tolerance, seconds (default half the reported frame
        period, or 0.02 s).
    drop_old : bool
        Drop the oldest frames when the consumer is slow (live); False
        delivers every frame (a file played as a stream).

    Returns
    -------
    Spec
        Layout ``live``, kind ``mono`` or ``stereo``, with a
        :class:`LiveFrames` source.

    Raises
    ------
    TudorVisionError
        Not a live source, or a source that cannot be opened.
    ValueError
        ``max_frames`` or ``timeout_s`` not positive.
    """
    sources = split_live_sources(text) or ([text] if text else [])
    if not sources:
        raise TudorVisionError(f"{text!r}: not a live source (/dev/videoN, rtsp://, http://)")
    if max_frames is not None and (isinstance(max_frames, bool) or int(max_frames) < 1):
        raise ValueError(f"max_frames: expected a positive integer, got {max_frames!r}")
    if not timeout_s > 0:
        raise ValueError(f"timeout_s: expected a positive number of seconds, got {timeout_s!r}")
    caps = []
    try:
        for s in sources:
            caps.append(LiveCapture(s, timeout_s=timeout_s, drop_old=drop_old))
    except BaseException:
        for c in caps:
            c.close()
        raise
    fps = caps[0].fps
    tol = float(max_dt_s) if max_dt_s is not None else (0.5 / fps if fps else 0.02)
    kind = "stereo" if len(caps) == 2 else "mono"
    streams = ("left", "right") if kind == "stereo" else ("image",)
    src = LiveFrames(caps, max_frames=max_frames, tol_s=tol)
    return Spec(path=text, layout="live", kind=kind, rate_hz=fps, streams=streams, source=src,
                description=f"live {' + '.join(sources)}", notes=[f"live source: {', '.join(sources)}"])
