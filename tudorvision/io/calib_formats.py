"""One loader for every calibration format, one writer per format, and the stereo sanity check.

:func:`load_any_calibration` reads what a ``--calib`` option names:

=============  ==============================================================  ===========================
format         what to pass                                                    read by
=============  ==============================================================  ===========================
tudorvision    ``calib.yaml`` (``format: tudorvision-calibration``)            :func:`load_calibration`
ros            ``cam.yaml`` (one camera), ``left.yaml,right.yaml`` or a        :func:`load_ros_stereo`
               folder holding ``left.yaml`` and ``right.yaml``
opencv         ``intrinsics.yml,extrinsics.yml`` (either order), a folder      :func:`load_opencv_stereo`
               holding both, ``intrinsics.yml`` alone (cameras only), or one
               camera's ``camera_matrix`` file (OpenCV ``calibration`` sample)
kalibr         ``camchain.yaml``, or a folder holding one ``camchain*.yaml``   :func:`load_kalibr_camchain`
=============  ==============================================================  ===========================

The format is recognised from the content, not the file name, and
:attr:`LoadedCalibration.summary` says which was read.
:func:`save_calibration_as` writes any of them and lists what the target
format has no place for. :func:`swapped_stereo_reason` recognises a stereo
calibration whose left and right cameras are exchanged.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ._yaml import read_yaml
from .atomic import write_text_atomic
from .calibration import Calibration, CameraModel, load_calibration, save_calibration
from .formats import (load_opencv_stereo, load_ros_camera_info, load_ros_stereo, save_opencv_stereo,
                      save_ros_camera_info, save_ros_stereo)
from .kalibr import load_kalibr_camchain, save_kalibr_camchain

__all__ = ["CALIBRATION_FORMATS", "LoadedCalibration", "detect_calibration_format", "load_any_calibration",
           "save_calibration_as", "swapped_stereo_reason"]

#: Formats :func:`save_calibration_as` writes and :func:`load_any_calibration` reads.
CALIBRATION_FORMATS = ("tudorvision", "ros", "opencv", "kalibr")
_LABELS = {"tudorvision": "tudorvision YAML", "ros": "ROS camera_info", "opencv": "OpenCV FileStorage",
           "kalibr": "Kalibr camchain"}
_OPENCV_DIR = (("intrinsics.yml", "extrinsics.yml"), ("intrinsics.yaml", "extrinsics.yaml"),
               ("intrinsics.xml", "extrinsics.xml"))


@dataclass(frozen=True)
class LoadedCalibration:
    """A calibration and where it came from.

    Parameters
    ----------
    calibration : Calibration
        What was read, SI units.
    format : str
        One of :data:`CALIBRATION_FORMATS`.
    paths : tuple of Path
        The files read.
    notes : tuple of str
        Conversions made on reading (e.g. a fitted fisheye lens).
    """

    calibration: Calibration
    format: str
    paths: tuple
    notes: tuple = field(default_factory=tuple)

    @property
    def summary(self) -> str:
        """One line: format, files, cameras and baseline, e.g. ``Kalibr camchain.yaml (2 cameras, ...)``."""
        cal = self.calibration
        files = ",".join(p.name for p in self.paths)
        parts = [f"{len(cal.cameras)} camera{'s' if len(cal.cameras) != 1 else ''}: {', '.join(cal.cameras)}"]
        if cal.stereo is not None:
            parts.append(f"baseline {cal.stereo.baseline_m:.4g} m")
        elif len(cal.cameras) == 2:
            parts.append("no stereo extrinsics")
        if cal.transforms:
            parts.append(", ".join(cal.transforms))
        parts.extend(self.notes)
        return f"{_LABELS[self.format]} {files} ({'; '.join(parts)})"


# ----------------------------------------------------------------------------- detection
def _opencv_text(text: str) -> bool:
    head = text.lstrip()[:200]
    return "!!opencv-matrix" in text or head.startswith("%YAML:") or head.startswith("<?xml") \
        or "<opencv_storage>" in head


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TudorVisionError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise TudorVisionError(f"{path}: is a folder") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read as a calibration file ({exc})") from None


def _opencv_role(path: Path, text: str) -> str:
    """``intrinsics``, ``extrinsics``, ``both`` or ``camera`` for an OpenCV FileStorage file."""
    import cv2

    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        root = fs.root()
        names = set(root.keys()) if root.isMap() else set()
        fs.release()
    except Exception:   # malformed: let the reader report the line
        return "intrinsics"
    has_i, has_e = "M1" in names, "R" in names and "T" in names
    if has_i and has_e:
        return "both"
    if has_e:
        return "extrinsics"
    if "camera_matrix" in names and not has_i:
        return "camera"
    return "intrinsics"


def detect_calibration_format(path) -> str:
    """The format of one calibration file, recognised from its content.

    Parameters
    ----------
    path : str or Path
        A file.

    Returns
    -------
    str
        ``tudorvision``, ``ros``, ``opencv`` or ``kalibr``.

    Raises
    ------
    TudorVisionError
        Absent or unreadable file, malformed YAML (file and line), or a
        mapping of none of the formats (the message lists its top-level
        keys).
    """
    path = Path(path)
    text = _read_text(path)
    if not text.strip():
        raise TudorVisionError(f"{path}: empty file")
    if _opencv_text(text):
        return "opencv"
    data, line_of = read_yaml(path)
    if isinstance(data, dict):
        if "cam0" in data:
            return "kalibr"
        if "camera_matrix" in data or "image_width" in data:
            return "ros"
        if "format" in data or "cameras" in data:
            return "tudorvision"
        keys = ", ".join(str(k) for k in list(data)[:6]) or "none"
        raise TudorVisionError(f"{path}:{line_of(()) or 1}: not a calibration this loader knows (tudorvision "
                               "YAML, ROS camera_info, OpenCV intrinsics/extrinsics.yml, Kalibr camchain.yaml); "
                               f"top-level keys: {keys}")
    raise TudorVisionError(f"{path}:1: not a calibration file: expected a mapping, got "
                           f"{type(data).__name__}")


def _single_ros_name(path: Path, name: str) -> str:
    name = name.strip()
    return name if name and name.replace("_", "").replace("-", "").isalnum() else path.stem


def _load_opencv_camera(path: Path, size) -> Calibration:
    import cv2

    from .formats import cv_matrix_node_ok

    fs = cv2.FileStorage(_read_text(path), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    try:
        mats = {}
        for key, shape in (("camera_matrix", (3, 3)), ("distortion_coefficients", None)):
            node = fs.getNode(key)
            if node.empty() or not (node.isMap() and cv_matrix_node_ok(node)):
                raise TudorVisionError(f"{path}: {key} is missing or not an OpenCV matrix")
            mats[key] = np.asarray(node.mat(), dtype=np.float64)
        w, h = (fs.getNode(k) for k in ("image_width", "image_height"))
        wh = (int(w.real()), int(h.real())) if w.isInt() and h.isInt() else size
    finally:
        fs.release()
    if wh is None:
        raise TudorVisionError(f"{path}: no image_width/image_height in the file (give the image size)")
    d = mats["distortion_coefficients"].ravel()
    if d.size not in (4, 5) and not (d.size > 5 and not np.any(d[5:])):
        raise TudorVisionError(f"{path}: distortion_coefficients: only plumb_bob (k1, k2, p1, p2[, k3]) "
                               f"is supported, got {d.size} values")
    d = np.append(d, np.zeros(5))[:5]
    try:
        cam = CameraModel(K=mats["camera_matrix"], dist=d, width=wh[0], height=wh[1])
    except ValueError as exc:
        raise TudorVisionError(f"{path}: {exc}") from None
    return Calibration(cameras={"camera": cam})


def _load_opencv(paths: list[Path], size, m_per_unit) -> Calibration:
    roles = {p: _opencv_role(p, _read_text(p)) for p in paths}
    if len(paths) == 1:
        p = paths[0]
        if roles[p] == "camera":
            return _load_opencv_camera(p, size)
        if roles[p] == "extrinsics":
            raise TudorVisionError(f"{p}: extrinsics alone hold no cameras: give intrinsics.yml,extrinsics.yml "
                                   "or the folder holding both")
        return load_opencv_stereo(p, p if roles[p] == "both" else None, size=size, m_per_unit=m_per_unit)
    a, b = paths
    if roles[a] == "extrinsics" and roles[b] != "extrinsics":
        a, b = b, a
    if roles[b] != "extrinsics":
        raise TudorVisionError(f"{b}: expected OpenCV extrinsics (R, T) next to the intrinsics {a.name}")
    return load_opencv_stereo(a, b, size=size, m_per_unit=m_per_unit)


def _in_folder(folder: Path) -> tuple[str, list[Path]]:
    for names in _OPENCV_DIR:
        if all((folder / n).is_file() for n in names):
            return "opencv", [folder / n for n in names]
    if (folder / "left.yaml").is_file() and (folder / "right.yaml").is_file():
        return "ros", [folder / "left.yaml", folder / "right.yaml"]
    chains = sorted(folder.glob("camchain*.yaml"))
    if len(chains) == 1:
        return "kalibr", chains
    if (folder / "calibration.yaml").is_file():
        return "tudorvision", [folder / "calibration.yaml"]
    raise TudorVisionError(f"{folder}: no calibration in the folder (looked for intrinsics.yml + extrinsics.yml, "
                           "left.yaml + right.yaml, one camchain*.yaml, calibration.yaml)")


def load_any_calibration(spec, *, size=None, m_per_unit: float = 1.0) -> LoadedCalibration:
    """Read a calibration in any supported format (see the module docstring).

    Parameters
    ----------
    spec : str or Path
        A file, two files joined by a comma (``left.yaml,right.yaml`` or
        ``intrinsics.yml,extrinsics.yml``), or a folder holding a pair.
    size : tuple of int, optional
        ``(width, height)`` in pixels for OpenCV files that store no image
        size (the ``stereo_calib`` sample's).
    m_per_unit : float
        Metres per unit of an OpenCV extrinsics ``T`` (the square size when
        the sample ran with ``-s 1``).

    Returns
    -------
    LoadedCalibration
        The calibration, its format and the files read.

    Raises
    ------
    TudorVisionError
        A missing file or folder, a format not recognised, two files of
        different formats, or malformed content; one line naming the file
        (and the line and key where the reader knows them).
    """
    try:
        return _load_any(spec, size, m_per_unit)
    except TudorVisionError as exc:
        msg = str(exc)
        if "pass size=(width, height)" not in msg:
            raise
        raise TudorVisionError(msg.replace("pass size=(width, height)", "add image_width and image_height to "
                                           "it, or give the size (calib convert --size WxH)")) from None


def _load_any(spec, size, m_per_unit) -> LoadedCalibration:
    text = str(spec)
    p = Path(text)
    if "," in text and not p.exists():
        paths = [Path(s.strip()) for s in text.split(",") if s.strip()]
        if len(paths) != 2:
            raise TudorVisionError(f"{text}: expected two files joined by a comma (left.yaml,right.yaml or "
                                   "intrinsics.yml,extrinsics.yml)")
        fmts = [detect_calibration_format(q) for q in paths]
        if fmts == ["ros", "ros"]:
            return LoadedCalibration(load_ros_stereo(*paths), "ros", tuple(paths))
        if fmts == ["opencv", "opencv"]:
            return LoadedCalibration(_load_opencv(paths, size, m_per_unit), "opencv", tuple(paths))
        raise TudorVisionError(f"{text}: two files must be ROS camera_info left,right or OpenCV "
                               f"intrinsics,extrinsics; got {_LABELS[fmts[0]]} and {_LABELS[fmts[1]]}")
    if p.is_dir():
        fmt, paths = _in_folder(p)
        if fmt == "ros":
            return LoadedCalibration(load_ros_stereo(*paths), fmt, tuple(paths))
        if fmt == "opencv":
            return LoadedCalibration(_load_opencv(paths, size, m_per_unit), fmt, tuple(paths))
        p = paths[0]
    elif not p.exists():
        raise TudorVisionError(f"{p}: calibration file not found")
    fmt = detect_calibration_format(p)
    if fmt == "tudorvision":
        cal = load_calibration(p)
    elif fmt == "ros":
        info = load_ros_camera_info(p)
        cal = Calibration(cameras={_single_ros_name(p, info.name): info.camera})
    elif fmt == "opencv":
        cal = _load_opencv([p], size, m_per_unit)
    else:
        cal = load_kalibr_camchain(p)
        return LoadedCalibration(cal, fmt, (p,), tuple(cal.metadata.get("converted", ())))
    return LoadedCalibration(cal, fmt, (p,))


# ----------------------------------------------------------------------------- writing
def _pair(out: Path, names: tuple[str, str]) -> tuple[Path, Path]:
    text = str(out)
    if "," in text:
        a, b = (s.strip() for s in text.split(",", 1))
        return Path(a), Path(b)
    return out / names[0], out / names[1]


def _dropped(cal: Calibration, fmt: str, written: list[str]) -> list[str]:
    notes = []
    label = _LABELS[fmt]
    other = [n for n in cal.cameras if n not in written]
    if other:
        notes.append(f"{label} has no place for cameras {', '.join(other)}: not written")
    for what, names in (("line_time_s", [n for n in written if cal.cameras[n].line_time_s is not None]),
                        ("T_ref_cam", [n for n in written if cal.cameras[n].T_ref_cam is not None])):
        if names:
            notes.append(f"{label} has no place for {what} ({', '.join(names)}): not written")
    if cal.transforms:
        notes.append(f"{label} has no place for transforms {', '.join(cal.transforms)}: not written")
    for what in ("depth_model", "circle_rmse_m"):
        if getattr(cal, what) is not None:
            notes.append(f"{label} has no place for {what}: not written")
    return notes


def save_calibration_as(calibration: Calibration, fmt: str, out, *, allow_lossy: bool = False,
                        m_per_unit: float = 1.0) -> tuple[list[Path], list[str]]:
    """Write ``calibration`` in format ``fmt``; every file atomically.

    Parameters
    ----------
    calibration : Calibration
        What to write (SI units).
    fmt : str
        ``tudorvision`` (one file), ``ros`` (one file for one camera; for a
        stereo pair a folder getting ``left.yaml`` and ``right.yaml``, or
        ``L.yaml,R.yaml``), ``opencv`` (a folder getting ``intrinsics.yml``
        and ``extrinsics.yml``, or ``I.yml,E.yml``; one camera without
        stereo: one ``camera_matrix`` file) or ``kalibr`` (one file).
    out : str or Path
        Output file, folder or comma-joined pair (see ``fmt``).
    allow_lossy : bool
        Kalibr: refit ``k1, k2`` for a camera with ``k3 != 0`` instead of
        refusing.
    m_per_unit : float
        OpenCV: metres per unit of the written ``T``.

    Returns
    -------
    paths : list of Path
        Files written.
    notes : list of str
        What the format has no place for (left out), and lossy conversions.

    Raises
    ------
    TudorVisionError
        An unknown format, content the format cannot hold (no stereo pair
        for a two-file format, a camera with skew for Kalibr, different image
        sizes for OpenCV), or a file that cannot be written.
    """
    if fmt not in CALIBRATION_FORMATS:
        raise TudorVisionError(f"format {fmt!r}: expected one of {', '.join(CALIBRATION_FORMATS)}")
    out = Path(out)
    cal, st = calibration, calibration.stereo
    if fmt == "tudorvision":
        return [save_calibration(cal, out)], []
    if fmt == "kalibr":
        path, notes = save_kalibr_camchain(cal, out, allow_lossy=allow_lossy)
        written = [st.left, st.right] if st is not None else list(cal.cameras)
        extra = [n for n in _dropped(cal, fmt, written) if any(w in n for w in ("T_ref_cam", "depth_model",
                                                                                 "circle_rmse_m"))]
        return [path], notes + extra
    if st is None:
        if len(cal.cameras) != 1:
            raise TudorVisionError(f"{_LABELS[fmt]}: need one camera or a stereo pair, got cameras "
                                   f"{sorted(cal.cameras)} without stereo extrinsics")
        name, cam = next(iter(cal.cameras.items()))
        if fmt == "ros":
            path = save_ros_camera_info(out, cam, name=name)
        else:
            path = _save_opencv_camera(out, cam)
        return [path], _dropped(cal, fmt, [name])
    if fmt == "ros":
        a, b = _pair(out, ("left.yaml", "right.yaml"))
        for q in (a, b):
            q.parent.mkdir(parents=True, exist_ok=True)
        return list(save_ros_stereo(cal, a, b)), _dropped(cal, fmt, [st.left, st.right])
    if cal.camera(st.left).size != cal.camera(st.right).size:
        raise TudorVisionError(f"{_LABELS[fmt]}: stereo_calib files hold one image size; the cameras have "
                               f"{cal.camera(st.left).size} and {cal.camera(st.right).size}")
    a, b = _pair(out, ("intrinsics.yml", "extrinsics.yml"))
    for q in (a, b):
        q.parent.mkdir(parents=True, exist_ok=True)
    return list(save_opencv_stereo(cal, a, b, m_per_unit=m_per_unit)), _dropped(cal, fmt, [st.left, st.right])


def _save_opencv_camera(path: Path, cam: CameraModel) -> Path:
    import cv2

    fs = cv2.FileStorage("out.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", int(cam.width))
    fs.write("image_height", int(cam.height))
    fs.write("camera_matrix", np.ascontiguousarray(cam.K))
    fs.write("distortion_coefficients", np.ascontiguousarray(cam.dist[:, None]))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, fs.releaseAndGetString())
    return path


# ----------------------------------------------------------------------------- sanity
def swapped_stereo_reason(calibration: Calibration) -> str | None:
    """Why a stereo calibration looks like its left and right cameras are exchanged, or None.

    With ``x_right = R @ x_left + T``, ``T`` is the left camera centre in the
    right camera frame: on a left/right rig it lies to the left (``T_x < 0``),
    and the right camera centre ``-R^T T`` lies to the right in the left
    frame. Both signs flipped, with the horizontal part of the baseline
    dominating (not a vertical rig), means the images were given the other
    way round.

    Parameters
    ----------
    calibration : Calibration
        Any calibration; one without stereo extrinsics gives None.

    Returns
    -------
    str or None
        One line starting ``left and right look swapped:`` with ``T_x`` and
        the likely cause, or None when the geometry is a left/right pair.
    """
    st = calibration.stereo
    if st is None:
        return None
    T = st.T
    c_right = -st.R.T @ T
    horizontal = abs(T[0]) >= 0.5 * float(np.hypot(T[0], T[1]))
    if not (T[0] > 0 and c_right[0] < 0 and horizontal):
        return None
    return (f"left and right look swapped: T_x = {T[0]:+.4g} m (the left camera centre lies to the right of the "
            "right camera; a left/right rig has T_x < 0): the images given as left are likely the right "
            "camera's (exchange --left/--right, the left/ and right/ folders or the device numbers)")
