"""Recognise a sequence on disk and list its frames (no image is decoded here).

Each ``spec_*`` function returns a :class:`Spec`: the sequence's metadata and
one :class:`Record` per frame (or a video path), plus the problems found in
the index files. :class:`tudorvision.io.sequence.Sequence` turns it into a
lazy reader.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._index import Problem, associate, parse_index
from ._yaml import read_yaml

KINDS = ("stereo", "rgbd", "mono")
FRAME_STREAMS = {"stereo": ("left", "right"), "rgbd": ("rgb", "depth"), "mono": ("image",)}
VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".mpg", ".mpeg", ".m4v", ".wmv"}
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".bmp", ".tif", ".tiff"}
LAYOUTS = ("tudorvision", "tum", "kinect_folders", "numbered_pairs", "image_folder", "stereo_folders",
           "rgbd_folders", "video")
#: Kind of each folder layout (the sidecar's ``kind`` must agree).
LAYOUT_KIND = {"tum": "rgbd", "kinect_folders": "rgbd", "numbered_pairs": "rgbd", "image_folder": "mono",
               "stereo_folders": "stereo", "rgbd_folders": "rgbd"}
#: Marker file of a recording that has not completed (written first, removed by a successful close).
INCOMPLETE_MARKER = "INCOMPLETE"


@dataclass(frozen=True)
class Slot:
    """One image of a frame: its stream, file and the index line that named it."""

    stream: str
    path: Path
    where: str
    t: float


@dataclass(frozen=True)
class Record:
    """One frame before loading: timestamp (s) and one slot per image stream."""

    t: float
    slots: tuple[Slot, ...]


@dataclass
class Spec:
    path: Path
    layout: str
    kind: str
    rate_hz: float | None
    depth_scale: float | None = None
    size: dict | None = None                 # stream -> (w, h)
    streams: tuple[str, ...] = ()
    records: list[Record] | None = None
    video: Path | None = None
    calibration_path: Path | None = None
    intrinsics: np.ndarray | None = None
    description: str = ""
    groundtruth: dict = field(default_factory=dict)   # name -> (path, column names or None)
    joints_path: Path | None = None
    problems: list[Problem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    source: object = None                    # frame source of a bag or a live stream (count, read, close)
    calibration: object = None               # Calibration found in the source itself (bag CameraInfo)


def _err(path, line_of, keys, msg):
    line = line_of(keys) if line_of else None
    where = f"{path}:{line}" if line else str(path)
    return TudorVisionError(f"{where}: {'.'.join(map(str, keys))}: {msg}")


def positive_entry(meta, key, path, line_of, *, required):
    """``meta[key]`` as a positive float, None when absent and not ``required``.

    ``path`` and ``line_of`` (from :func:`~tudorvision.io._yaml.read_yaml`)
    locate the entry in the error message.
    """
    if key not in meta or meta[key] is None:
        if required:
            raise TudorVisionError(f"{path}: missing {key!r}")
        return None
    v = meta[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise _err(path, line_of, (key,), f"expected a positive number, got {v!r}")
    return float(v)


def parse_size(value, streams, path, line_of):
    """The ``size`` entry: ``[width, height]`` for every stream in ``streams``, or ``{stream: [w, h]}``.

    Returns ``{stream: (width, height)}`` in pixels, or None when ``value`` is None.
    """
    def pair(v, keys):
        if (not isinstance(v, (list, tuple)) or len(v) != 2
                or not all(isinstance(x, int) and not isinstance(x, bool) and x > 0 for x in v)):
            raise _err(path, line_of, keys, f"expected [width, height] in pixels, got {v!r}")
        return (int(v[0]), int(v[1]))

    if value is None:
        return None
    if isinstance(value, dict):
        return {str(k): pair(v, ("size", k)) for k, v in value.items()}
    wh = pair(value, ("size",))
    return {s: wh for s in streams}


def parse_sequence_yaml(yaml_path: Path) -> tuple[dict, object]:
    data, line_of = read_yaml(yaml_path)
    if not isinstance(data, dict):
        raise TudorVisionError(f"{yaml_path}:1: expected a mapping (kind, rate_hz, streams, ...)")
    return data, line_of


def spec_tudorvision(root: Path, data: dict, line_of, *, max_dt_s=None, allow_outside: bool = False) -> Spec:
    """Our own directory format (see :mod:`tudorvision.io.sequence`)."""
    ypath = root / "sequence.yaml"
    kind = data.get("kind")
    if kind not in KINDS:
        raise _err(ypath, line_of, ("kind",), f"expected one of {', '.join(KINDS)}, got {kind!r}")
    rate = positive_entry(data, "rate_hz", ypath, line_of, required=True)
    depth_scale = positive_entry(data, "depth_scale", ypath, line_of, required=kind == "rgbd")
    streams = data.get("streams", list(FRAME_STREAMS[kind]))
    if not isinstance(streams, list) or not all(isinstance(s, str) for s in streams):
        raise _err(ypath, line_of, ("streams",), f"expected a list of stream names, got {streams!r}")
    desc = data.get("description", "") or ""
    spec = Spec(path=root, layout="tudorvision", kind=kind, rate_hz=rate, depth_scale=depth_scale,
                streams=tuple(streams), description=str(desc), meta=dict(data))
    if data.get("incomplete") or (root / INCOMPLETE_MARKER).is_file():
        why = data.get("interrupted") or f"{INCOMPLETE_MARKER} marker present"
        spec.problems.append(Problem(str(ypath), f"recording is incomplete ({why})"))
    frame_streams = FRAME_STREAMS[kind]
    spec.size = parse_size(data.get("size"), frame_streams, ypath, line_of)
    cal = data.get("calibration")
    if cal is not None:
        if not isinstance(cal, str):
            raise _err(ypath, line_of, ("calibration",), f"expected a path, got {cal!r}")
        spec.calibration_path = (root / cal)
    gts = data.get("groundtruth") or []
    if not isinstance(gts, list) or not all(isinstance(g, str) for g in gts):
        raise _err(ypath, line_of, ("groundtruth",), f"expected a list of file names, got {gts!r}")
    for g in gts:
        spec.groundtruth[Path(g).stem] = (root / g, None)
    if (root / "joints.txt").is_file():
        spec.joints_path = root / "joints.txt"
    if kind == "mono" and data.get("video") is not None:
        video = data["video"]
        if not isinstance(video, str):
            raise _err(ypath, line_of, ("video",), f"expected a path, got {video!r}")
        spec.video = root / video
        if not spec.video.is_file():
            raise _err(ypath, line_of, ("video",), f"video file {video!r} does not exist")
        return spec
    tol = max_dt_s if max_dt_s is not None else float(data.get("sync_tolerance_s", 0.25 / rate))
    spec.records = _records_from_indices(root, frame_streams, tol, spec, strict_pairs=True,
                                         allow_outside=allow_outside)
    return spec


def _records_from_indices(root: Path, streams, tol, spec: Spec, *, strict_pairs: bool,
                          allow_outside: bool = False) -> list[Record]:
    entries = {}
    for s in streams:
        idx = root / f"{s}.txt"
        if not idx.is_file():
            raise TudorVisionError(f"{idx}: index file for stream {s!r} not found")
        e, probs = parse_index(idx, allow_outside=allow_outside)
        entries[s] = e
        spec.problems.extend(probs)
    first = entries[streams[0]]
    if len(streams) == 1:
        return [Record(e.t, (Slot(streams[0], e.path, e.where, e.t),)) for e in first]
    second = entries[streams[1]]
    pairs = associate(np.array([e.t for e in first]), np.array([e.t for e in second]), tol)
    used_a = set(pairs[:, 0].tolist())
    used_b = set(pairs[:, 1].tolist())
    lost_a = [e for i, e in enumerate(first) if i not in used_a]
    lost_b = [e for i, e in enumerate(second) if i not in used_b]
    if strict_pairs:
        for e, other in [(e, streams[1]) for e in lost_a] + [(e, streams[0]) for e in lost_b]:
            spec.problems.append(Problem(e.where, f"no {other} image within {tol:.4g} s of t={e.t!r}"))
    elif lost_a or lost_b:
        spec.notes.append(f"{len(lost_a)} {streams[0]} and {len(lost_b)} {streams[1]} entries without a "
                          f"partner within {tol:.4g} s were left out")
    out = []
    for i, j in pairs:
        a, b = first[i], second[j]
        out.append(Record(a.t, (Slot(streams[0], a.path, a.where, a.t), Slot(streams[1], b.path, b.where, b.t))))
    return out


def spec_tum(root: Path, *, max_dt_s=None, allow_outside: bool = False) -> Spec:
    """A TUM RGB-D benchmark directory: rgb.txt + depth.txt (+ groundtruth.txt)."""
    spec = Spec(path=root, layout="tum", kind="rgbd", rate_hz=None, depth_scale=5000.0,
                streams=("rgb", "depth"))
    tol = 0.02 if max_dt_s is None else float(max_dt_s)
    spec.records = _records_from_indices(root, ("rgb", "depth"), tol, spec, strict_pairs=False,
                                         allow_outside=allow_outside)
    if len(spec.records) > 1:
        spec.rate_hz = float(1.0 / np.median(np.diff([r.t for r in spec.records])))
    gt = root / "groundtruth.txt"
    if gt.is_file():
        spec.groundtruth["groundtruth"] = (gt, ["t", "tx", "ty", "tz", "qx", "qy", "qz", "qw"])
    if (root / "accelerometer.txt").is_file():
        spec.groundtruth["accelerometer"] = (root / "accelerometer.txt", ["t", "ax", "ay", "az"])
    return spec


def _numbered(folder: Path, pattern: re.Pattern) -> dict[int, Path]:
    out = {}
    for p in folder.iterdir():
        m = pattern.match(p.name)
        if m and p.is_file():
            out[int(m.group(1))] = p
    return out


def _paired_records(spec: Spec, colour: dict, depth: dict, rate_hz: float) -> list[Record]:
    records = []
    keys = sorted(set(colour) | set(depth))
    k = 0
    for n in keys:
        c, d = colour.get(n), depth.get(n)
        if c is None or d is None:
            have = c or d
            spec.problems.append(Problem(str(have), f"frame {n} has no "
                                                    f"{'depth' if d is None else 'colour'} image"))
            continue
        t = k / rate_hz
        records.append(Record(t, (Slot("rgb", c, str(c), t), Slot("depth", d, str(d), t))))
        k += 1
    return records


def spec_kinect_folders(root: Path, *, rate_hz: float) -> Spec:
    """``color/N.png`` + ``depth/N.pgm`` (slambook-style), optional ``pose.txt``."""
    spec = Spec(path=root, layout="kinect_folders", kind="rgbd", rate_hz=rate_hz,
                streams=("rgb", "depth"))
    colour = _numbered(root / "color", re.compile(r"^(\d+)\.(?:png|jpg|jpeg|ppm)$", re.I))
    depth = _numbered(root / "depth", re.compile(r"^(\d+)\.(?:pgm|png)$", re.I))
    spec.records = _paired_records(spec, colour, depth, rate_hz)
    pose = root / "pose.txt"
    if pose.is_file():
        spec.groundtruth["pose"] = (pose, ["tx", "ty", "tz", "qx", "qy", "qz", "qw"])
    return spec


def spec_numbered_pairs(root: Path, *, rate_hz: float) -> Spec:
    """``N.png`` colour + ``N_depth.png`` depth in one folder."""
    spec = Spec(path=root, layout="numbered_pairs", kind="rgbd", rate_hz=rate_hz,
                streams=("rgb", "depth"))
    colour = _numbered(root, re.compile(r"^(\d+)\.(?:png|jpg|jpeg)$", re.I))
    depth = _numbered(root, re.compile(r"^(\d+)_depth\.png$", re.I))
    spec.records = _paired_records(spec, colour, depth, rate_hz)
    return spec


def _natural_key(p: Path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def spec_image_folder(root: Path, *, rate_hz: float) -> Spec:
    """A folder of images played in natural name order as a mono sequence."""
    files = sorted((p for p in root.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()),
                   key=_natural_key)
    spec = Spec(path=root, layout="image_folder", kind="mono", rate_hz=rate_hz, streams=("image",))
    spec.records = [Record(k / rate_hz, (Slot("image", p, str(p), k / rate_hz),)) for k, p in enumerate(files)]
    return spec


def _keyed(folder: Path, depth: bool = False) -> dict:
    """Image files of ``folder`` by pairing key: the last number in the name, else the stem."""
    suffixes = {".png", ".pgm"} if depth else IMAGE_SUFFIXES
    files = sorted((p for p in folder.iterdir() if p.suffix.lower() in suffixes and p.is_file()), key=_natural_key)
    out = {}
    for p in files:
        nums = re.findall(r"\d+", p.stem)
        out.setdefault(int(nums[-1]) if nums else p.stem, p)
    return out


def spec_paired_folders(root: Path, *, kind: str, rate_hz: float) -> Spec:
    """``left/`` + ``right/`` (stereo) or ``rgb/`` + ``depth/`` (rgbd) image folders.

    Files pair by the last number in their names (``left/000001.png`` with
    ``right/000001.png`` or ``right/img1.png``); when no key is shared and
    both folders hold as many images, by natural name order. Frame k is at
    ``k / rate_hz``.
    """
    a_name, b_name = FRAME_STREAMS[kind]
    a, b = _keyed(root / a_name), _keyed(root / b_name, depth=kind == "rgbd")
    spec = Spec(path=root, layout=f"{kind}_folders", kind=kind, rate_hz=rate_hz, streams=(a_name, b_name),
                depth_scale=1000.0 if kind == "rgbd" else None)
    if a and len(a) == len(b) and not set(a) & set(b):
        a, b = dict(enumerate(a.values())), dict(enumerate(b.values()))
    records, k = [], 0
    for key in sorted(set(a) | set(b), key=lambda x: (isinstance(x, str), x)):
        pa, pb = a.get(key), b.get(key)
        if pa is None or pb is None:
            spec.problems.append(Problem(str(pa or pb), f"no {b_name if pb is None else a_name} image "
                                                        f"with the same number"))
            continue
        t = k / rate_hz
        records.append(Record(t, (Slot(a_name, pa, str(pa), t), Slot(b_name, pb, str(pb), t))))
        k += 1
    spec.records = records
    return spec


def apply_sidecar(spec: Spec, data: dict, line_of, ypath: Path) -> None:
    """Sidecar ``sequence.yaml`` of a folder layout: depth scale, calibration, intrinsics, size, description."""
    if not data:
        return
    ds = positive_entry(data, "depth_scale", ypath, line_of, required=False)
    if ds is not None:
        spec.depth_scale = ds
    if data.get("calibration") is not None:
        spec.calibration_path = ypath.parent / str(data["calibration"])
    spec.size = parse_size(data.get("size"), FRAME_STREAMS[spec.kind], ypath, line_of) or spec.size
    intr = data.get("intrinsics")
    if intr is not None:
        if not isinstance(intr, dict) or not all(k in intr for k in ("fx", "fy", "cx", "cy")):
            raise TudorVisionError(f"{ypath}:{line_of(('intrinsics',))}: intrinsics: expected "
                                   "{fx, fy, cx, cy} in pixels")
        try:
            fx, fy, cx, cy = (float(intr[k]) for k in ("fx", "fy", "cx", "cy"))
        except (TypeError, ValueError):
            raise TudorVisionError(f"{ypath}:{line_of(('intrinsics',))}: intrinsics: values must be "
                                   "numbers") from None
        spec.intrinsics = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    spec.description = str(data.get("description", "") or "")
    spec.meta = dict(data)


def sidecar_layout(root: Path, data: dict, line_of) -> str:
    """The folder layout a sidecar ``sequence.yaml`` names, checked against its ``kind``.

    ``layout: image_folder`` with ``kind: stereo`` (or ``rgbd``) means the
    plain ``left/`` + ``right/`` (``rgb/`` + ``depth/``) folders when they
    exist; otherwise the contradiction is an error naming the line.
    """
    ypath = root / "sequence.yaml"
    layout = data.get("layout", "tudorvision")
    if layout not in LAYOUTS or layout == "video":
        raise TudorVisionError(f"{ypath}:{line_of(('layout',))}: layout: expected one of "
                               f"{', '.join(x for x in LAYOUTS if x != 'video')}, got {layout!r}")
    kind = data.get("kind")
    if layout == "tudorvision" or kind is None or kind == LAYOUT_KIND[layout]:
        return layout
    folders = FRAME_STREAMS.get(kind, ())
    if layout == "image_folder" and kind in ("stereo", "rgbd") and all((root / f).is_dir() for f in folders):
        return f"{kind}_folders"
    hint = f"; for plain {' + '.join(f + '/' for f in folders)} folders use layout: {kind}_folders" \
        if kind in ("stereo", "rgbd") else ""
    raise TudorVisionError(f"{ypath}:{line_of(('kind',))}: kind: {kind!r} contradicts layout {layout!r} "
                           f"(a {LAYOUT_KIND[layout]} layout){hint}")


def detect_layout(root: Path) -> str:
    """Name of the layout of directory ``root`` (see :data:`LAYOUTS`)."""
    if (root / "sequence.yaml").is_file():
        return "tudorvision"
    if (root / INCOMPLETE_MARKER).is_file():
        raise TudorVisionError(f"{root}: recording is incomplete ({INCOMPLETE_MARKER} marker, no sequence.yaml)")
    if (root / "rgb.txt").is_file() and (root / "depth.txt").is_file():
        return "tum"
    if (root / "color").is_dir() and (root / "depth").is_dir():
        return "kinect_folders"
    if (root / "left").is_dir() and (root / "right").is_dir():
        return "stereo_folders"
    if (root / "rgb").is_dir() and (root / "depth").is_dir():
        return "rgbd_folders"
    names = [p.name for p in root.iterdir()]
    if any(re.match(r"^\d+_depth\.png$", n, re.I) for n in names):
        return "numbered_pairs"
    if any(Path(n).suffix.lower() in IMAGE_SUFFIXES for n in names):
        return "image_folder"
    raise TudorVisionError(
        f"{root}: not a recognised sequence (expected sequence.yaml, a TUM rgb.txt + depth.txt, "
        "color/ + depth/ folders, left/ + right/ or rgb/ + depth/ folders, N.png + N_depth.png pairs, a folder "
        "of images, a ROS bag, a rosbag2 folder or .mcap file)")
