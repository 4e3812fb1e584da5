"""ROS bags as sequences: ROS 1 ``.bag``, ROS 2 bag folders (sqlite3 or mcap) and bare ``.mcap`` files.

Read with the `rosbags <https://gitlab.com/ternaris/rosbags>`_ library (no
ROS installation needed). Image topics are ``sensor_msgs/Image`` (``rgb8``,
``bgr8``, ``rgba8``, ``bgra8``, ``mono8``, ``mono16``, ``16UC1``, ``32FC1``)
or ``sensor_msgs/CompressedImage`` (JPEG, PNG, ``compressedDepth`` PNG).
Depth in ``16UC1`` / ``mono16`` is millimetres (REP 118) and is kept raw
(depth scale 1000); ``32FC1`` is metres and is stored as millimetres
(NaN, inf and values <= 0 become 0 = invalid). ``mono16`` colour images are
reduced to 8 bits (the high byte).

Frame times are the messages' ``header.stamp`` (the log time when the stamp
is zero). Two image streams (``left``/``right`` or ``rgb``/``depth``) are
paired by nearest stamp within half the median frame period (``max_dt_s``
overrides); messages without a partner are counted in the notes.
``sensor_msgs/CameraInfo`` topics next to the image topics become the
sequence's calibration: cameras ``left``/``right`` (with the stereo
extrinsics from the rectification and projection matrices), ``rgbd`` or
``camera``.

The bag is scanned once when opened (only the header stamps are parsed);
frames are decoded on demand by one forward-streaming reader per stream.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._index import ImageProblem, associate
from ._layouts import FRAME_STREAMS, Spec
from .calibration import Calibration
from .frames import raw_from_depth_m
from .rosmsg import camera_from_info, decode_image, stereo_from_infos

__all__ = ["BagTopic", "is_bag", "bag_topics", "parse_topics", "choose_topics", "decode_image", "camera_from_info",
           "stereo_from_infos", "bag_spec", "BagFrames", "IMAGE_TYPES", "INFO_TYPE"]

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")   #: read as image streams
INFO_TYPE = "sensor_msgs/msg/CameraInfo"                                   #: read as calibration
_STREAM_KEYS = ("left", "right", "rgb", "depth", "image")


@dataclass(frozen=True)
class BagTopic:
    """One topic of a bag.

    Attributes
    ----------
    name : str
        Topic name, e.g. ``/camera/color/image_raw``.
    msgtype : str
        Message type, e.g. ``sensor_msgs/msg/Image``.
    count : int
        Number of messages.
    """

    name: str
    msgtype: str
    count: int


def is_bag(path) -> bool:
    """Whether ``path`` looks like a bag: a ``.bag`` or ``.mcap`` file, or a folder with ``metadata.yaml``.

    Parameters
    ----------
    path : str or Path
        Candidate file or folder.

    Returns
    -------
    bool
        True for a ROS 1 bag file, an mcap file, or a ROS 2 bag folder
        (``metadata.yaml``, or ``.db3`` / ``.mcap`` files without a
        ``sequence.yaml``).
    """
    p = Path(path)
    if p.is_file():
        return p.suffix.lower() in (".bag", ".mcap")
    if p.is_dir() and not (p / "sequence.yaml").is_file():
        return (p / "metadata.yaml").is_file() or any(p.glob("*.db3")) or any(p.glob("*.mcap"))
    return False


def _why(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _open_reader(path: Path):
    """An open ``rosbags`` AnyReader; every failure becomes one line naming the bag."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    try:
        reader = AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:   # the library raises many types for damaged files
        raise TudorVisionError(f"{path}: cannot read bag ({_why(exc)})") from None
    return reader


def _close(reader) -> None:
    try:
        reader.close()
    except Exception:    # already closed, or broken by an earlier error: nothing left to release
        pass


def bag_topics(path) -> list[BagTopic]:
    """All topics of a bag with their types and message counts.

    Parameters
    ----------
    path : str or Path
        ROS 1 ``.bag``, ROS 2 bag folder or ``.mcap`` file.

    Returns
    -------
    list of BagTopic
        Sorted by topic name.

    Raises
    ------
    TudorVisionError
        If the bag is absent, truncated or corrupt (one line naming it).
    """
    reader = _open_reader(Path(path))
    try:
        return [BagTopic(name, info.msgtype or "?", int(info.msgcount))
                for name, info in sorted(reader.topics.items())]
    finally:
        _close(reader)


def parse_topics(text) -> dict[str, str]:
    """Parse a ``--topics`` value: ``left=/a,right=/b``, ``rgb=/c,depth=/d`` or ``image=/e``.

    Keys ``left_info=``, ``right_info=``, ``rgb_info=``, ``image_info=``
    name the ``CameraInfo`` topic of a stream when it is not found next to
    the image topic.

    Parameters
    ----------
    text : str or dict or None
        The option's value (a dict is checked and returned).

    Returns
    -------
    dict of str to str
        Stream name to topic; empty for None.

    Raises
    ------
    TudorVisionError
        Malformed item or unknown stream name.

    Examples
    --------
    >>> parse_topics("left=/cam0/image_raw, right=/cam1/image_raw")
    {'left': '/cam0/image_raw', 'right': '/cam1/image_raw'}
    """
    if text is None:
        return {}
    items = dict(text).items() if isinstance(text, dict) else \
        [tuple(p.split("=", 1)) if "=" in p else (p, "") for p in str(text).split(",") if p.strip()]
    out = {}
    allowed = _STREAM_KEYS + tuple(f"{k}_info" for k in _STREAM_KEYS)
    for key, topic in items:
        key, topic = str(key).strip(), str(topic).strip()
        if key not in allowed or not topic:
            raise TudorVisionError(f"--topics: expected STREAM=TOPIC items with STREAM one of "
                                   f"{', '.join(_STREAM_KEYS)} (or STREAM_info), got {key + '=' + topic!r}")
        out[key] = topic
    return out


def _kind_of(streams) -> str | None:
    return next((k for k, names in FRAME_STREAMS.items() if set(names) == set(streams)), None)


def _info_for(topic: str, infos: list[str]) -> str | None:
    """The CameraInfo topic sharing the longest namespace with image ``topic`` (unique best, or None)."""
    parts = [p for p in topic.split("/") if p]
    if parts and parts[-1] in ("compressed", "compressedDepth"):
        parts = parts[:-1]
    ns = parts[:-1]

    def shared(info):
        ip = [p for p in info.split("/") if p][:-1]
        n = 0
        while n < min(len(ip), len(ns)) and ip[n] == ns[n]:
            n += 1
        return n if n == len(ip) else 0      # the info's namespace must contain the image topic

    scored = sorted(((shared(i), i) for i in infos), reverse=True)
    if not scored or scored[0][0] == 0 or (len(scored) > 1 and scored[1][0] == scored[0][0]):
        return None
    return scored[0][1]


def choose_topics(topics: list[BagTopic], requested=None, *, where: str = "bag"
                  ) -> tuple[str, dict[str, str], dict[str, str]]:
    """Pick the image topics (and their CameraInfo topics) of a bag.

    Parameters
    ----------
    topics : list of BagTopic
        The bag's topics (:func:`bag_topics`).
    requested : str or dict, optional
        ``--topics`` value (see :func:`parse_topics`); by default the topics
        are found when unambiguous: one image topic (mono), one plus one
        whose name contains ``depth`` (rgbd; of several depth topics the one
        containing ``aligned`` is taken), or two whose names contain
        ``left`` and ``right`` (stereo). ``X/compressed`` is ignored when
        the raw topic ``X`` is present.
    where : str
        Name of the bag for messages.

    Returns
    -------
    kind : str
        ``stereo``, ``rgbd`` or ``mono``.
    streams : dict of str to str
        Stream (``left``, ``rgb``, ``image``, ...) to image topic.
    infos : dict of str to str
        Stream to its CameraInfo topic, where one was found.

    Raises
    ------
    TudorVisionError
        No image topic, an ambiguous choice (one line listing the
        candidates), or a requested topic that is absent or not an image.
    """
    by_name = {t.name: t for t in topics}
    images = [t.name for t in topics if t.msgtype in IMAGE_TYPES]
    infos = [t.name for t in topics if t.msgtype == INFO_TYPE]
    req = parse_topics(requested)
    streams = {k: v for k, v in req.items() if not k.endswith("_info")}
    if streams:
        kind = _kind_of(streams)
        if kind is None:
            raise TudorVisionError(f"--topics: give left= and right=, rgb= and depth=, or image=; got "
                                   f"{', '.join(streams)}")
        for k, t in list(streams.items()) + [(k, t) for k, t in req.items() if k.endswith("_info")]:
            want = INFO_TYPE if k.endswith("_info") else "an image"
            ok = t in by_name and (by_name[t].msgtype == INFO_TYPE if k.endswith("_info") else t in images)
            if not ok:
                have = f"type {by_name[t].msgtype}" if t in by_name else "not in the bag"
                raise TudorVisionError(f"--topics: {k}={t}: expected {want} topic, {have} "
                                       f"(image topics: {', '.join(images) or 'none'})")
    else:
        if not images:
            raise TudorVisionError(f"{where}: no image topics (sensor_msgs/Image or CompressedImage); topics: "
                                   f"{', '.join(f'{t.name} ({t.msgtype})' for t in topics) or 'none'}")
        cands = [t for t in images if not (t.rsplit("/", 1)[0] in images and t.rsplit("/", 1)[-1]
                                           in ("compressed", "compressedDepth"))]
        depth = [t for t in cands if "depth" in t.lower()]
        aligned = [t for t in depth if "aligned" in t.lower()]   # e.g. RealSense aligned_depth_to_color
        depth = aligned if len(aligned) == 1 else depth
        colour = [t for t in cands if "depth" not in t.lower()]
        left = [t for t in colour if "left" in t.lower()]
        right = [t for t in colour if "right" in t.lower()]
        if len(colour) == 1 and len(depth) == 1:
            streams = {"rgb": colour[0], "depth": depth[0]}
        elif not depth and len(colour) == 2 and len(left) == 1 and len(right) == 1 and left != right:
            streams = {"left": left[0], "right": right[0]}
        elif len(cands) == 1:
            streams = {"image": cands[0]}
        else:
            raise TudorVisionError(f"{where}: cannot choose the image topics ({', '.join(cands)}); pass --topics "
                                   "left=/a,right=/b or rgb=/c,depth=/d or image=/e")
        kind = _kind_of(streams)
    found = {}
    for s, t in streams.items():
        info = req.get(f"{s}_info") or _info_for(t, infos)
        if info is not None and s != "depth":
            found[s] = info
    return kind, streams, found


def _stamp(raw, is2: bool) -> float | None:
    """``header.stamp`` in seconds, read straight from the serialised bytes (None if too short)."""
    try:
        if is2:
            order = "<" if raw[1] == 1 else ">"
            sec, nsec = struct.unpack_from(order + "iI", raw, 4)
        else:
            sec, nsec = struct.unpack_from("<II", raw, 4)
    except (struct.error, IndexError):
        return None
    return sec + nsec * 1e-9


class _Cursor:
    """Reads the chosen topics forward with one reader, keeping read-ahead messages a later frame needs.

    Messages are numbered ``g`` in the order of the scan at open; a request
    behind the read position (random access) restarts at its log time.
    """

    def __init__(self, path: Path, logtimes_ns: np.ndarray, topics: list, needed: set, reader=None):
        self.path, self.logtimes_ns, self.topics, self.needed = path, logtimes_ns, topics, needed
        self.reader, self.gen, self.pos, self.cache = reader, None, -1, {}
        self.conns = [c for c in reader.connections if c.topic in set(topics)] if reader is not None else []

    def get(self, g: int):
        try:
            if g in self.cache:
                conn, raw = self.cache.pop(g)
                return self.reader.deserialize(raw, conn.msgtype)
            if self.reader is None:
                self.reader = _open_reader(self.path)
                self.conns = [c for c in self.reader.connections if c.topic in set(self.topics)]
            if self.gen is None or self.pos > g:
                t = int(self.logtimes_ns[g])
                self.gen = self.reader.messages(connections=self.conns, start=t)
                self.pos = int(np.searchsorted(self.logtimes_ns, t))
            while True:
                conn, _, raw = next(self.gen)
                k, self.pos = self.pos, self.pos + 1
                if conn.topic != self.topics[k]:
                    raise ValueError(f"message order differs from the scan at open ({conn.topic})")
                if k == g:
                    return self.reader.deserialize(raw, conn.msgtype)
                if k in self.needed:             # passed over (e.g. a right image logged first)
                    self.cache[k] = (conn, raw)
                    if len(self.cache) > 64:
                        self.cache.pop(min(self.cache))
        except Exception as exc:   # truncated chunk, corrupt message, vanished file
            self.gen = None
            why = "message missing" if isinstance(exc, StopIteration) else _why(exc)
            raise ImageProblem(f"cannot read message {g} ({self.topics[g]}) ({why})") from None

    def close(self):
        self.gen, reader, self.reader = None, self.reader, None
        self.cache.clear()
        if reader is not None:
            _close(reader)


class BagFrames:
    """Frame source of a bag for :class:`~tudorvision.io.sequence.Sequence` (built by :func:`bag_spec`).

    Parameters
    ----------
    path : Path
        The bag.
    streams : dict of str to str
        Stream to image topic.
    logtimes_ns : ndarray, shape (M,), int64
        Log time of every message of the image topics, in bag order.
    msg_topics : list of str, length M
        Topic of every such message.
    frames : list of tuple
        ``(t_s, {stream: message number into logtimes_ns}, t_second_s)`` per frame.
    depth_scale : float
        Raw depth units per metre for ``32FC1`` depth.
    reader : rosbags AnyReader, optional
        An open reader of the bag to use (and close); default: opened on the
        first read.

    Attributes
    ----------
    count : int
        Number of frames.
    timestamps : ndarray, shape (count,)
        Frame times, seconds (``header.stamp`` of the first stream).
    """

    def __init__(self, path: Path, streams: dict, logtimes_ns: np.ndarray, msg_topics: list, frames: list,
                 depth_scale: float, reader=None):
        self.path = Path(path)
        self.streams = dict(streams)
        self._frames = frames
        self.depth_scale = float(depth_scale)
        needed = {g for f in frames for g in f[1].values()}
        self._cursor = _Cursor(self.path, np.asarray(logtimes_ns, dtype=np.int64), list(msg_topics), needed,
                               reader)
        self.count = len(frames)
        self.timestamps = np.array([f[0] for f in frames], dtype=np.float64)

    def read(self, i: int):
        """Frame ``i`` decoded.

        Parameters
        ----------
        i : int
            Frame index, ``0 <= i < count``.

        Returns
        -------
        t_s : float
            Frame time, seconds.
        images : dict of str to ndarray
            Per stream: ``(H, W, 3)`` uint8 BGR or ``(H, W)`` uint8 grey;
            depth ``(H, W)`` uint16 raw units.
        t_second_s : float or None
            Time of the second stream's message, seconds.

        Raises
        ------
        ImageProblem
            Unreadable message, unsupported encoding or undecodable data.
        """
        t, ks, t2 = self._frames[i]
        out = {}
        for s, k in ks.items():
            img = decode_image(self._cursor.get(k))
            if s == "depth":
                if img.dtype == np.float32:
                    img = raw_from_depth_m(img, self.depth_scale)
                elif img.dtype != np.uint16 or img.ndim != 2:
                    raise ImageProblem(f"depth message {k} of {self.streams[s]} is {img.dtype} with shape "
                                       f"{img.shape}; expected 16UC1/mono16 (mm) or 32FC1 (m)")
            elif img.dtype == np.uint16:
                img = (img >> 8).astype(np.uint8)
            elif img.dtype != np.uint8:
                raise ImageProblem(f"message {k} of {self.streams[s]} has {img.dtype} pixels; expected an "
                                   "8-bit colour or grey image")
            out[s] = img
        return t, out, t2

    def close(self) -> None:
        """Close the reader."""
        self._cursor.close()


def _increasing(t: np.ndarray) -> np.ndarray:
    """Indices of the entries that are later than every earlier one."""
    keep, last = [], -np.inf
    for i, v in enumerate(t):
        if v > last:
            keep.append(i)
            last = v
    return np.asarray(keep, dtype=np.int64)


def _calibration(kind, infos, msgs, path, notes) -> Calibration | None:
    names = {"left": "left", "right": "right", "rgb": "rgbd", "image": "camera"}
    models = {}
    for s, msg in msgs.items():
        try:
            models[s] = camera_from_info(msg)
        except ValueError as exc:
            notes.append(f"CameraInfo {infos[s]} not used: {exc}")
    if not models:
        return None
    stereo = None
    if kind == "stereo" and len(models) == 2:
        stereo = stereo_from_infos(models["left"], models["right"])
        if stereo is None:
            notes.append("stereo extrinsics not in the CameraInfo (P[0, 3] of the right camera is 0)")
    return Calibration(cameras={names[s]: m[0] for s, m in models.items()}, stereo=stereo,
                       metadata={"source": f"CameraInfo in {path.name}: "
                                           + ", ".join(infos[s] for s in models)})


def bag_spec(path, *, topics=None, max_dt_s: float | None = None, depth_scale: float | None = None) -> Spec:
    """Open a bag as a sequence layout (the reader of :func:`tudorvision.io.open_sequence` for bags).

    Parameters
    ----------
    path : str or Path
        ROS 1 ``.bag``, ROS 2 bag folder or ``.mcap`` file.
    topics : str or dict, optional
        Image topics (:func:`parse_topics`); found automatically when
        unambiguous (:func:`choose_topics`).
    max_dt_s : float, optional
        Pairing tolerance of two image streams, seconds (default half the
        median frame period of the first stream).
    depth_scale : float, optional
        Raw depth units per metre (default 1000: ``16UC1`` millimetres;
        ``32FC1`` metres are converted with it).

    Returns
    -------
    Spec
        Layout ``rosbag1``, ``rosbag2`` or ``mcap`` with a :class:`BagFrames`
        source and the CameraInfo calibration, if any.

    Raises
    ------
    TudorVisionError
        Unreadable, truncated or corrupt bag (one line naming it), no or
        ambiguous image topics, or no frames.
    """
    path = Path(path)
    reader, done = _open_reader(path), False
    try:
        tops = [BagTopic(n, i.msgtype or "?", int(i.msgcount)) for n, i in sorted(reader.topics.items())]
        kind, streams, infos = choose_topics(tops, topics, where=str(path))
        topic_stream = {t: s for s, t in streams.items()}
        stamps, gidx, logt, msg_topics = {s: [] for s in streams}, {s: [] for s in streams}, [], []
        conns = [c for c in reader.connections if c.topic in topic_stream]
        for conn, ts, raw in reader.messages(connections=conns):
            s = topic_stream[conn.topic]
            st = _stamp(raw, reader.is2)
            gidx[s].append(len(logt))
            logt.append(ts)
            msg_topics.append(conn.topic)
            stamps[s].append(st if st else ts * 1e-9)
        msgs = {}
        for s, t in infos.items():
            for conn, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic == t]):
                msgs[s] = reader.deserialize(raw, conn.msgtype)
                break
        done = bool(logt)
    except TudorVisionError:
        raise
    except Exception as exc:   # the library raises many types for damaged files
        raise TudorVisionError(f"{path}: cannot read bag ({_why(exc)})") from None
    finally:
        if not done:
            _close(reader)
    notes = [f"topics: {', '.join(f'{s}={t}' for s, t in streams.items())}"]
    names = list(streams)
    t = {s: np.asarray(stamps[s], dtype=np.float64) for s in names}
    keep = {s: np.asarray(gidx[s], dtype=np.int64)[_increasing(t[s])] for s in names}
    t = {s: np.asarray(stamps[s], dtype=np.float64)[_increasing(t[s])] for s in names}
    for s in names:
        if len(keep[s]) < len(stamps[s]):
            notes.append(f"{len(stamps[s]) - len(keep[s])} {streams[s]} message(s) left out: stamp not after "
                         "the previous one")
    ta = t[names[0]]
    period = float(np.median(np.diff(ta))) if ta.size > 1 else None
    if len(names) == 1:
        frames = [(float(ta[j]), {names[0]: int(k)}, None) for j, k in enumerate(keep[names[0]])]
    else:
        tb = t[names[1]]
        tol = float(max_dt_s) if max_dt_s is not None else (0.5 * period if period else 0.02)
        pairs = associate(ta, tb, tol)
        frames = [(float(ta[i]), {names[0]: int(keep[names[0]][i]), names[1]: int(keep[names[1]][j])},
                   float(tb[j])) for i, j in pairs]
        if len(pairs) < max(ta.size, tb.size):
            notes.append(f"{ta.size - len(pairs)} {names[0]} and {tb.size - len(pairs)} {names[1]} message(s) "
                         f"without a partner within {tol:.4g} s left out")
    scale = float(depth_scale) if depth_scale is not None else 1000.0
    try:
        if not frames:
            raise TudorVisionError(f"{path}: no frames on {', '.join(streams.values())}")
        cal = _calibration(kind, infos, msgs, path, notes)
    except BaseException:
        _close(reader)
        raise
    layout = {".bag": "rosbag1", ".mcap": "mcap"}.get(path.suffix.lower() if path.is_file() else "", "rosbag2")
    src = BagFrames(path, streams, np.asarray(logt, dtype=np.int64), msg_topics, frames, scale, reader)
    return Spec(path=path, layout=layout, kind=kind, rate_hz=1.0 / period if period else None,
                depth_scale=scale if kind == "rgbd" else None,
                streams=tuple(names), source=src, calibration=cal, notes=notes,
                description=f"ROS bag {path.name}", meta={"topics": dict(streams)})
