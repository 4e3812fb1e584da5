"""Foreign calibration formats: ROS ``camera_info`` YAML and OpenCV stereo ``.yml`` files.

* ROS ``camera_info`` YAML (one file per camera, as written by
  ``camera_calibration``): ``image_width``, ``image_height``,
  ``camera_name``, ``camera_matrix``, ``distortion_model`` (``plumb_bob``),
  ``distortion_coefficients``, ``rectification_matrix``,
  ``projection_matrix``; matrices as ``{rows, cols, data}``. A stereo pair
  is two such files; :func:`load_ros_stereo` recovers ``R``, ``T`` from the
  rectification and projection matrices and :func:`save_ros_stereo` writes
  them.
* OpenCV's ``stereo_calib`` sample: ``intrinsics.yml`` (``M1``, ``D1``,
  ``M2``, ``D2``) and ``extrinsics.yml`` (``R``, ``T``, ``R1``, ``R2``,
  ``P1``, ``P2``, ``Q``), read and written with ``cv2.FileStorage``. The
  sample writes ``T`` in checkerboard units; ``m_per_unit`` converts.
  The sample stores no image size: pass ``size`` when reading unless the
  file has ``image_width`` / ``image_height`` (which :func:`save_opencv_stereo`
  adds).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError, check_array
from ._yaml import YamlContext as _Ctx
from ._yaml import dump_yaml, read_yaml
from .atomic import write_text_atomic
from .calibration import RECTIFICATION_SHAPES, Calibration, CameraModel, StereoExtrinsics

__all__ = ["CameraInfo", "load_ros_camera_info", "save_ros_camera_info", "calibration_from_ros",
           "load_ros_stereo", "save_ros_stereo", "load_opencv_stereo", "save_opencv_stereo"]


@dataclass(frozen=True, kw_only=True, eq=False)
class CameraInfo:
    """Content of one ROS ``camera_info`` file.

    Attributes
    ----------
    name : str
        ``camera_name``.
    camera : CameraModel
        Intrinsics, distortion and image size.
    R_rect : ndarray, shape (3, 3)
        ``rectification_matrix`` (identity for a monocular camera).
    P : ndarray, shape (3, 4)
        ``projection_matrix`` of the rectified image, pixels (``P[0, 3]`` is
        ``-fx' * baseline`` for the right camera of a stereo pair).
    """

    name: str
    camera: CameraModel
    R_rect: np.ndarray
    P: np.ndarray


def _ros_matrix(data, key, rows, cols, ctx):
    m = data.get(key)
    if not isinstance(m, dict) or "data" not in m:
        raise ctx.error((key,), "expected a mapping with rows, cols, data")
    r, c = m.get("rows", rows), m.get("cols", cols)
    if (r, c) != (rows, cols):
        raise ctx.error((key,), f"expected rows: {rows}, cols: {cols}, got rows: {r}, cols: {c}")
    values = m["data"]
    if not isinstance(values, list) or len(values) != rows * cols:
        n = len(values) if isinstance(values, list) else values
        raise ctx.error((key, "data"), f"expected {rows * cols} numbers, got {n}")
    return ctx.array(values, (key, "data"), (rows * cols,)).reshape(rows, cols)


def load_ros_camera_info(path) -> CameraInfo:
    """Read a ROS ``camera_info`` YAML file.

    Parameters
    ----------
    path : str or Path
        The ``camera_info`` YAML file (as written by ROS
        ``camera_calibration`` or :func:`save_ros_camera_info`).

    Returns
    -------
    CameraInfo
        Camera name, intrinsics (pixels) and distortion, rectification
        rotation and rectified projection matrix.

    Raises
    ------
    TudorVisionError
        If the file is absent, not YAML, misses keys, has a distortion model
        other than ``plumb_bob`` with 5 coefficients, or has wrong matrix
        sizes; the message names the file and line.
    """
    path = Path(path)
    data, line_of = read_yaml(path)
    ctx = _Ctx(path, line_of)
    if not isinstance(data, dict):
        raise ctx.error((), "expected a ROS camera_info mapping")
    for key in ("image_width", "image_height", "camera_matrix", "distortion_coefficients"):
        if key not in data:
            raise ctx.error((), f"missing {key!r}")
    model = data.get("distortion_model", "plumb_bob")
    if model not in ("plumb_bob", "radtan"):
        raise ctx.error(("distortion_model",), f"unsupported distortion model {model!r} "
                                               "(only plumb_bob with 5 coefficients)")
    K = _ros_matrix(data, "camera_matrix", 3, 3, ctx)
    d = data["distortion_coefficients"]
    cols = d.get("cols", 5) if isinstance(d, dict) else 5
    dist = _ros_matrix(data, "distortion_coefficients", 1, cols, ctx).ravel()
    if dist.size == 4:
        dist = np.append(dist, 0.0)
    if dist.size != 5:
        raise ctx.error(("distortion_coefficients",), f"plumb_bob needs 5 coefficients, got {dist.size}")
    R = _ros_matrix(data, "rectification_matrix", 3, 3, ctx) if "rectification_matrix" in data else np.eye(3)
    if "projection_matrix" in data:
        P = _ros_matrix(data, "projection_matrix", 3, 4, ctx)
    else:
        P = np.hstack([K, np.zeros((3, 1))])
    try:
        cam = CameraModel(K=K, dist=dist, width=data["image_width"], height=data["image_height"])
    except (ValueError, TypeError) as exc:
        raise ctx.error(("camera_matrix",), str(exc)) from None
    return CameraInfo(name=str(data.get("camera_name", path.stem)), camera=cam, R_rect=R, P=P)


def save_ros_camera_info(path, camera: CameraModel, *, name: str = "camera", R_rect=None, P=None) -> Path:
    """Write ``camera`` as a ROS ``camera_info`` YAML file.

    Parameters
    ----------
    path : str or Path
        Output file; written atomically (a failed write leaves a previous
        file intact).
    camera : CameraModel
        Intrinsics (pixels), plumb_bob distortion and image size to write;
        ``line_time_s`` and ``T_ref_cam`` have no place in the format and
        are left out.
    name : str
        ``camera_name``.
    R_rect : array_like, shape (3, 3), optional
        Rectification rotation; identity by default.
    P : array_like, shape (3, 4), optional
        Rectified projection matrix; ``[K | 0]`` by default.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``R_rect`` or ``P`` has the wrong shape or non-finite values.
    TudorVisionError
        If the file cannot be written (disk full, read-only folder).
    """
    R = np.eye(3) if R_rect is None else check_array(R_rect, "R_rect", (3, 3))
    P = np.hstack([camera.K, np.zeros((3, 1))]) if P is None else check_array(P, "P", (3, 4))

    def mat(a):
        a = np.atleast_2d(a)
        return {"rows": a.shape[0], "cols": a.shape[1], "data": [float(x) for x in a.ravel()]}

    doc = {"image_width": camera.width, "image_height": camera.height, "camera_name": name,
           "camera_matrix": mat(camera.K), "distortion_model": "plumb_bob",
           "distortion_coefficients": mat(camera.dist[None, :]), "rectification_matrix": mat(R),
           "projection_matrix": mat(P)}
    path = Path(path)
    write_text_atomic(path, dump_yaml(doc))
    return path


def calibration_from_ros(paths) -> Calibration:
    """Build a :class:`Calibration` from one ROS file per camera.

    Parameters
    ----------
    paths : mapping of str to path
        Camera name (``left``, ``rgbd``, ...) to its ``camera_info`` file.

    Returns
    -------
    Calibration
        The cameras only (intrinsics in pixels, distortion, image size); the
        files' rectification and projection matrices are not kept.

    Raises
    ------
    TudorVisionError
        If a file is absent or malformed (see :func:`load_ros_camera_info`).
    """
    return Calibration(cameras={name: load_ros_camera_info(p).camera for name, p in paths.items()})


def load_ros_stereo(left_path, right_path, *, left: str = "left", right: str = "right") -> Calibration:
    """Read a stereo pair from two ROS ``camera_info`` files, extrinsics included.

    ROS stores the pair's geometry in the rectification rotations ``R1``,
    ``R2`` and the projection matrices ``P1 = K' [I | t1]``, ``P2 = K' [I | t2]``
    (``P2[0, 3] = -fx' * baseline``): the rectified frames differ by the
    translation ``t2 - t1``, so ``x_right = R2^T (R1 x_left + t2 - t1)``.

    Parameters
    ----------
    left_path, right_path : str or Path
        The left and right ``camera_info`` files.
    left, right : str
        Camera names in the result.

    Returns
    -------
    Calibration
        Both cameras, and the stereo extrinsics with the files' rectification
        (``R1``, ``R2``, ``P1``, ``P2`` and ``Q`` derived from them) when the
        projection matrices hold a baseline; the cameras only when they do not
        (two independently calibrated cameras).

    Raises
    ------
    TudorVisionError
        A file absent or malformed, or a rectification matrix that is not a
        rotation (the message names the file).
    """
    infos = {name: load_ros_camera_info(p) for name, p in ((left, left_path), (right, right_path))}
    cams = {name: info.camera for name, info in infos.items()}
    il, ir = infos[left], infos[right]
    t1 = np.linalg.solve(il.P[:, :3], il.P[:, 3])
    t2 = np.linalg.solve(ir.P[:, :3], ir.P[:, 3])
    if not np.any(t2 - t1):
        return Calibration(cameras=cams)
    R = ir.R_rect.T @ il.R_rect
    T = ir.R_rect.T @ (t2 - t1)
    rect = {"R1": il.R_rect, "R2": ir.R_rect, "P1": il.P, "P2": ir.P}
    Q = rectified_q(il.P, ir.P)
    if Q is not None:
        rect["Q"] = Q
    try:
        stereo = StereoExtrinsics(R=R, T=T, left=left, right=right, **rect)
    except ValueError as exc:
        raise TudorVisionError(f"{right_path}: rectification_matrix: {exc}") from None
    return Calibration(cameras=cams, stereo=stereo)


def rectified_q(P1, P2):
    """OpenCV's disparity-to-depth matrix ``Q`` from the rectified projection matrices.

    Parameters
    ----------
    P1, P2 : array_like, shape (3, 4)
        Rectified projection matrices of the left and right camera (pixels;
        ``P2[0, 3]`` or ``P2[1, 3]`` is ``f' * t`` with ``t`` in metres).

    Returns
    -------
    ndarray, shape (4, 4) or None
        ``Q`` as ``cv2.stereoRectify`` builds it (horizontal or vertical
        pair), None when ``P2`` holds no baseline.
    """
    P1, P2 = np.asarray(P1, float), np.asarray(P2, float)
    idx = 0 if abs(P2[0, 3]) >= abs(P2[1, 3]) else 1
    f = P2[idx, idx]
    t = (P2[idx, 3] - P1[idx, 3]) / f
    if t == 0 or f == 0:
        return None
    return np.array([[1.0, 0, 0, -P1[0, 2]], [0, 1.0, 0, -P1[1, 2]], [0, 0, 0, P1[0, 0]],
                     [0, 0, -1.0 / t, (P1[idx, 2] - P2[idx, 2]) / t]])


def save_ros_stereo(calibration: Calibration, left_path, right_path, *, alpha: float = -1.0) -> tuple[Path, Path]:
    """Write the stereo pair of ``calibration`` as two ROS ``camera_info`` files.

    Parameters
    ----------
    calibration : Calibration
        Calibration with a stereo part. Its rectification is written when
        present; otherwise it is computed with ``cv2.stereoRectify``.
    left_path, right_path : str or Path
        Output files (``camera_name`` is the camera's name); written
        atomically.
    alpha : float
        ``cv2.stereoRectify`` free scaling when the rectification is
        computed here (-1: OpenCV's default).

    Returns
    -------
    left_path, right_path : Path
        The written files.

    Raises
    ------
    TudorVisionError
        If ``calibration`` has no stereo part, or a file cannot be written.
    """
    st = calibration.stereo
    if st is None:
        raise TudorVisionError("calibration has no stereo extrinsics to write")
    cl, cr = calibration.camera(st.left), calibration.camera(st.right)
    if all(getattr(st, n) is not None for n in ("R1", "R2", "P1", "P2")):
        R1, R2, P1, P2 = st.R1, st.R2, st.P1, st.P2
    else:
        R1, R2, P1, P2, *_ = cv2.stereoRectify(cl.K, cl.dist, cr.K, cr.dist, cl.size, st.R,
                                               st.T.reshape(3, 1), alpha=alpha)
    out = (save_ros_camera_info(left_path, cl, name=st.left, R_rect=R1, P=P1),
           save_ros_camera_info(right_path, cr, name=st.right, R_rect=R2, P=P2))
    return out


# ----------------------------------------------------------------------------- OpenCV FileStorage
_CV_LINE = re.compile(r"\((\d+)\):\s*(.*)")


def _open_storage(path: Path):
    """Open an OpenCV FileStorage for reading; errors name the file and line."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TudorVisionError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read ({exc})") from None
    if not text.strip():
        raise TudorVisionError(f"{path}: empty file")
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except Exception as exc:  # cv2.error, or SystemError wrapping it (opencv 5)
        msg = str(exc.__cause__ or exc)
        m = _CV_LINE.search(msg)
        if m:
            raise TudorVisionError(f"{path}:{m.group(1)}: malformed OpenCV YAML: "
                                   f"{m.group(2).strip().rstrip(chr(39))}") from None
        raise TudorVisionError(f"{path}: malformed OpenCV YAML ({msg.strip().splitlines()[-1]})") from None
    if not fs.isOpened():
        raise TudorVisionError(f"{path}: cannot open as OpenCV FileStorage")
    if not fs.root().isMap():   # getNode() on a sequence or scalar root raises cv2.error
        raise TudorVisionError(f"{path}: expected a mapping of OpenCV matrices (M1, D1, ...)")
    return fs


def _cv_mat(fs, path, key, shape, *, optional=False):
    node = fs.getNode(key)
    if node.empty():
        if optional:
            return None
        raise TudorVisionError(f"{path}: missing matrix {key!r}")
    # FileNode.mat() aborts the whole process on some malformed nodes (e.g. no 'cols'; found by
    # benchmarks/fuzz_files.py), so the node's structure is checked here first.
    m = node.mat() if node.isMap() and cv_matrix_node_ok(node) else None
    if m is None:
        raise TudorVisionError(f"{path}: {key} is not an OpenCV matrix (!!opencv-matrix with rows, cols, "
                               "dt and rows * cols data values)")
    m = np.asarray(m, dtype=np.float64)
    if shape == (3,) or shape == (5,):
        m = m.ravel()
        if shape == (5,) and m.size in (4, 8, 12, 14) and m.size != 5:
            if m.size > 5 and np.any(m[5:] != 0):
                raise TudorVisionError(f"{path}: {key}: only 5 distortion coefficients are supported, "
                                       f"got {m.size} with non-zero higher terms")
            m = np.append(m, np.zeros(max(0, 5 - m.size)))[:5]
    if m.shape != shape:
        raise TudorVisionError(f"{path}: {key}: expected shape {shape}, got {m.shape}")
    return m


def cv_matrix_node_ok(node) -> bool:
    """Whether an OpenCV FileNode is a well-formed ``!!opencv-matrix`` (safe for ``node.mat()``).

    Parameters
    ----------
    node : cv2.FileNode
        A map node.

    Returns
    -------
    bool
        True when ``rows`` and ``cols`` are integers in 1..10000, ``dt`` is a
        one-channel type code (``d``, ``f``, ``i``, ``u``, ``w``, ``s``,
        ``c``) and ``data`` is a sequence of ``rows * cols`` numbers.
    """
    rows, cols, dt, data = (node.getNode(k) for k in ("rows", "cols", "dt", "data"))
    if not (rows.isInt() and cols.isInt() and dt.isString() and data.isSeq()):
        return False
    r, c = int(rows.real()), int(cols.real())
    if not (1 <= r <= 10000 and 1 <= c <= 10000) or dt.string() not in ("d", "f", "i", "u", "w", "s", "c"):
        return False
    if data.size() != r * c:
        return False
    return all(data.at(i).isReal() or data.at(i).isInt() for i in range(data.size()))


def _cv_int(fs, key):
    node = fs.getNode(key)
    return None if node.empty() else int(node.real())


def load_opencv_stereo(intrinsics_path, extrinsics_path=None, *, size=None, left: str = "left",
                       right: str = "right", m_per_unit: float = 1.0) -> Calibration:
    """Read OpenCV ``stereo_calib`` files into a :class:`Calibration`.

    Parameters
    ----------
    intrinsics_path : str or Path
        ``intrinsics.yml`` with ``M1``, ``D1``, ``M2``, ``D2``.
    extrinsics_path : str or Path, optional
        ``extrinsics.yml`` with ``R``, ``T`` and optionally ``R1``, ``R2``,
        ``P1``, ``P2``, ``Q``. Without it only the cameras are returned.
    size : tuple of int, optional
        ``(width, height)`` in pixels; required unless the intrinsics file
        has ``image_width`` and ``image_height``.
    left, right : str
        Camera names in the result.
    m_per_unit : float
        Metres per unit of ``T`` in the file (the checkerboard square size
        when the sample ran with ``-s 1``).

    Returns
    -------
    Calibration

    Raises
    ------
    TudorVisionError
        Absent, malformed or incomplete files (message names the file, and
        the line for syntax errors).
    """
    ipath = Path(intrinsics_path)
    fs = _open_storage(ipath)
    M1, D1 = _cv_mat(fs, ipath, "M1", (3, 3)), _cv_mat(fs, ipath, "D1", (5,))
    M2, D2 = _cv_mat(fs, ipath, "M2", (3, 3)), _cv_mat(fs, ipath, "D2", (5,))
    w, h = _cv_int(fs, "image_width"), _cv_int(fs, "image_height")
    fs.release()
    if size is not None:
        w, h = (int(v) for v in size)
    if w is None or h is None:
        raise TudorVisionError(f"{ipath}: no image size in the file: pass size=(width, height)")
    try:
        cams = {left: CameraModel(K=M1, dist=D1, width=w, height=h),
                right: CameraModel(K=M2, dist=D2, width=w, height=h)}
    except ValueError as exc:
        raise TudorVisionError(f"{ipath}: {exc}") from None
    if extrinsics_path is None:
        return Calibration(cameras=cams)
    epath = Path(extrinsics_path)
    fs = _open_storage(epath)
    R, T = _cv_mat(fs, epath, "R", (3, 3)), _cv_mat(fs, epath, "T", (3,))
    rect = {n: _cv_mat(fs, epath, n, shp, optional=True) for n, shp in RECTIFICATION_SHAPES.items()}
    fs.release()
    s = float(m_per_unit)
    T = T * s
    if rect["P2"] is not None:
        rect["P2"] = rect["P2"].copy()
        rect["P2"][:, 3] *= s
    if rect["Q"] is not None:
        rect["Q"] = rect["Q"].copy()
        rect["Q"][3, :] /= s
    try:
        stereo = StereoExtrinsics(R=R, T=T, left=left, right=right,
                                  **{k: v for k, v in rect.items() if v is not None})
    except ValueError as exc:
        raise TudorVisionError(f"{epath}: {exc}") from None
    return Calibration(cameras=cams, stereo=stereo)


def save_opencv_stereo(calibration: Calibration, intrinsics_path, extrinsics_path, *,
                       m_per_unit: float = 1.0) -> tuple[Path, Path]:
    """Write the stereo part of ``calibration`` as OpenCV ``intrinsics.yml`` / ``extrinsics.yml``.

    ``image_width`` and ``image_height`` are added to the intrinsics file
    (the sample ignores unknown keys). ``T`` (and ``P2``, ``Q``) are written
    in units of ``m_per_unit`` metres.

    Parameters
    ----------
    calibration : Calibration
        Calibration with a stereo part. The files hold one image size for
        both cameras: the left camera's is written.
    intrinsics_path : str or Path
        Output ``intrinsics.yml`` (``M1``, ``D1``, ``M2``, ``D2``, image
        size).
    extrinsics_path : str or Path
        Output ``extrinsics.yml`` (``R``, ``T`` and the rectification
        matrices present in ``calibration``).
    m_per_unit : float
        Metres per unit of the written ``T``; 1 writes metres, the square
        size writes checkerboard squares like the sample.

    Returns
    -------
    intrinsics_path, extrinsics_path : Path
        The written files.

    Raises
    ------
    TudorVisionError
        If ``calibration`` has no stereo part, or a file cannot be written.
    """
    st = calibration.stereo
    if st is None:
        raise TudorVisionError("calibration has no stereo extrinsics to write")
    cl, cr = calibration.camera(st.left), calibration.camera(st.right)
    s = float(m_per_unit)
    out = []
    ipath, epath = Path(intrinsics_path), Path(extrinsics_path)
    entries_i = [("M1", cl.K), ("D1", cl.dist[None, :]), ("M2", cr.K), ("D2", cr.dist[None, :])]
    entries_e = [("R", st.R), ("T", st.T[:, None] / s)]
    for name in RECTIFICATION_SHAPES:
        m = getattr(st, name)
        if m is None:
            continue
        m = np.array(m)
        if name == "P2":
            m[:, 3] /= s
        if name == "Q":
            m[3, :] *= s
        entries_e.append((name, m))
    for path, entries, extra in ((ipath, entries_i, cl.size), (epath, entries_e, None)):
        fs = cv2.FileStorage("out.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
        for key, m in entries:
            fs.write(key, np.ascontiguousarray(m, dtype=np.float64))
        if extra is not None:
            fs.write("image_width", int(extra[0]))
            fs.write("image_height", int(extra[1]))
        text = fs.releaseAndGetString()
        write_text_atomic(path, text)
        out.append(path)
    return out[0], out[1]
