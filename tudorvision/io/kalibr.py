"""Kalibr ``camchain.yaml``: read and write, and the equidistant-to-plumb_bob fit.

Kalibr (``kalibr_calibrate_cameras``) writes one entry per camera,
``cam0``, ``cam1``, ...::

    cam0:
      camera_model: pinhole
      intrinsics: [fu, fv, pu, pv]          # pixels
      distortion_model: radtan              # or equidistant, none
      distortion_coeffs: [k1, k2, r1, r2]   # equidistant: [k1, k2, k3, k4]
      resolution: [width, height]
      rostopic: /cam0/image_raw
    cam1:
      T_cn_cnm1: [[...], ...]               # 4x4, p_cam1 = T_cn_cnm1 @ p_cam0 (metres)
      ...

``T_cn_cnm1`` of ``cam1`` is the OpenCV stereo ``[R | T]`` (``x_right = R @
x_left + T``). The project's cameras use Brown–Conrady (plumb_bob) distortion
with five coefficients: ``radtan`` is read exactly (``k3 = 0``); an
``equidistant`` (fisheye) camera is converted by a least-squares fit of
``k1, k2, k3`` over the image (smallest worst-case difference) and the
worst pixel difference is reported; a lens too wide for the fit is refused
(about 0.01 px at 33 degrees from the axis to the image corner, but about
1 px at 57 degrees: three radial terms cannot follow a fisheye). Writing needs ``k3`` to be zero, or a
refit of ``k1, k2`` accepted with ``allow_lossy``.
"""
from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError
from ._yaml import YamlContext as _Ctx
from ._yaml import dump_yaml, read_yaml
from .atomic import write_text_atomic
from .calibration import Calibration, CameraModel, StereoExtrinsics

__all__ = ["load_kalibr_camchain", "save_kalibr_camchain", "equidistant_to_plumb_bob", "drop_k3"]

_CAM_KEY = re.compile(r"^cam(\d+)$")
_NAME = re.compile(r"^[A-Za-z0-9]+$")


# ----------------------------------------------------------------------------- distortion fits
def _minimax(A, target, iterations: int = 60) -> np.ndarray:
    """Coefficients minimising the largest residual of ``A @ x - target`` (Lawson's reweighted least squares)."""
    w = np.full(len(target), 1.0 / len(target))
    x = np.linalg.lstsq(A, target, rcond=None)[0]
    for _ in range(iterations):
        sw = np.sqrt(w)[:, None]
        x = np.linalg.lstsq(A * sw, target * sw[:, 0], rcond=None)[0]
        w = w * (np.abs(A @ x - target) + 1e-300)
        w /= w.sum()
    return x


def _corner_radius(K, width: int, height: int) -> float:
    """Largest normalised (distorted) radius over the image corners."""
    u = np.array([-0.5, width - 0.5, -0.5, width - 0.5])
    v = np.array([-0.5, -0.5, height - 0.5, height - 0.5])
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    return float(np.max(np.hypot(x, y)))


def equidistant_to_plumb_bob(K, coeffs, width: int, height: int) -> tuple[np.ndarray, float]:
    """Fit plumb_bob ``k1, k2, k3`` to an equidistant (Kannala–Brandt) lens over the image (minimax).

    The equidistant model maps the angle ``theta = atan(r)`` of an
    undistorted normalised radius ``r`` to the distorted radius ``theta (1 +
    k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`` (Kalibr's and
    ``cv2.fisheye``'s model); plumb_bob maps ``r`` to ``r (1 + k1 r^2 + k2
    r^4 + k3 r^6)``. Both are radial, so the pixel difference is the radial
    difference times the focal length.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsic matrix, pixels.
    coeffs : array_like, shape (4,)
        Equidistant ``[k1, k2, k3, k4]``.
    width, height : int
        Image size in pixels; the fit covers the radii out to the farthest
        corner.

    Returns
    -------
    dist : ndarray, shape (5,)
        ``[k1, k2, 0, 0, k3]`` (OpenCV order).
    max_err_px : float
        Worst pixel difference between the two models inside the image; inf
        when the lens sees 80 degrees or more off axis or the fitted mapping
        is not monotonic (undistortion would fail).
    """
    K = np.asarray(K, float)
    k = np.asarray(coeffs, float)

    def theta_d(theta):
        t2 = theta * theta
        return theta * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))

    rho_c = _corner_radius(K, width, height)
    hi = np.deg2rad(80.0)
    if theta_d(hi) < rho_c:
        return np.zeros(5), float("inf")
    lo = 0.0
    for _ in range(100):       # theta_d is increasing on [0, hi] for any usable lens
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if theta_d(mid) < rho_c else (lo, mid)
    r_max = float(np.tan(hi))
    r = np.linspace(0.0, r_max, 600)[1:]
    s = r / r_max
    target = theta_d(np.arctan(r)) - r
    A = np.stack([r * s ** 2, r * s ** 4, r * s ** 6], axis=1)
    a = _minimax(A, target) / np.array([r_max ** 2, r_max ** 4, r_max ** 6])
    fitted = r * (1 + a[0] * r ** 2 + a[1] * r ** 4 + a[2] * r ** 6)
    err = float(np.max(np.abs(fitted - theta_d(np.arctan(r))))) * float(max(K[0, 0], K[1, 1]))
    if np.any(np.diff(fitted) <= 0):
        err = float("inf")
    return np.array([a[0], a[1], 0.0, 0.0, a[2]]), err


def _undistorted_corner_radius(camera: CameraModel) -> float:
    u = np.array([-0.5, camera.width - 0.5, -0.5, camera.width - 0.5, camera.width / 2, -0.5])
    v = np.array([-0.5, -0.5, camera.height - 0.5, camera.height - 0.5, -0.5, camera.height / 2])
    pts = np.stack([u, v], axis=1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    xy = cv2.undistortPoints(pts, camera.K, camera.dist, R=None, P=None, criteria=crit).reshape(-1, 2)
    return float(np.max(np.hypot(xy[:, 0], xy[:, 1])))


def drop_k3(camera: CameraModel) -> tuple[CameraModel, float]:
    """The camera with ``k3 = 0`` and ``k1, k2`` refitted over the image (for 4-coefficient formats).

    Parameters
    ----------
    camera : CameraModel
        Camera with plumb_bob distortion ``[k1, k2, p1, p2, k3]``.

    Returns
    -------
    camera : CameraModel
        The same camera with ``k3 = 0`` and ``k1, k2`` fitted (smallest
        worst-case difference) to the original radial profile out to the farthest image corner
        (``p1, p2`` kept); ``camera`` itself when ``k3`` is already 0.
    max_err_px : float
        Worst pixel difference between the two inside the image (0 when
        ``k3`` was 0).
    """
    k1, k2, p1, p2, k3 = camera.dist
    if k3 == 0:
        return camera, 0.0
    r_max = max(_undistorted_corner_radius(camera), 1e-6)
    r = np.linspace(0.0, r_max, 600)[1:]
    s = r / r_max
    target = k1 * r ** 3 + k2 * r ** 5 + k3 * r ** 7
    A = np.stack([r * s ** 2, r * s ** 4], axis=1)
    sol = _minimax(A, target) / np.array([r_max ** 2, r_max ** 4])
    err = float(np.max(np.abs(A @ (sol * [r_max ** 2, r_max ** 4]) - target))) * max(camera.fx, camera.fy)
    return camera.replace(dist=[sol[0], sol[1], p1, p2, 0.0]), err


# ----------------------------------------------------------------------------- reading
def _camera(ctx, key, c, max_fit_px) -> tuple[CameraModel, str | None]:
    for req in ("intrinsics", "resolution"):
        if req not in c:
            raise ctx.error((key,), f"missing {req!r}")
    model = c.get("camera_model", "pinhole")
    if model != "pinhole":
        raise ctx.error((key, "camera_model"), f"unsupported camera model {model!r} (only pinhole)")
    fu, fv, pu, pv = ctx.array(c["intrinsics"], (key, "intrinsics"), (4,))
    w, h = ctx.array(c["resolution"], (key, "resolution"), (2,))
    K = np.array([[fu, 0.0, pu], [0.0, fv, pv], [0.0, 0.0, 1.0]])
    dmodel = c.get("distortion_model", "none")
    coeffs = c.get("distortion_coeffs", [])
    note = None
    if dmodel in ("none", None) or (dmodel == "radtan" and not coeffs):
        dist = np.zeros(5)
    elif dmodel == "radtan":
        k = ctx.array(coeffs, (key, "distortion_coeffs"), (4,))
        dist = np.array([k[0], k[1], k[2], k[3], 0.0])
    elif dmodel == "equidistant":
        k = ctx.array(coeffs, (key, "distortion_coeffs"), (4,))
        if not (w == int(w) and h == int(h) and w > 0 and h > 0):
            raise ctx.error((key, "resolution"), f"expected positive integers, got {[w, h]}")
        dist, err = equidistant_to_plumb_bob(K, k, int(w), int(h))
        if not err <= max_fit_px:
            what = "no plumb_bob fit" if not np.isfinite(err) else f"the best plumb_bob fit is off by {err:.2f} px"
            raise ctx.error((key, "distortion_model"),
                            f"equidistant (fisheye) lens: {what} inside the image (limit {max_fit_px:g} px); "
                            "tudorvision cameras use plumb_bob/radtan distortion: calibrate with pinhole-radtan")
        note = f"{key} equidistant converted to plumb_bob (max {err:.3f} px inside the image)"
    else:
        raise ctx.error((key, "distortion_model"),
                        f"unsupported distortion model {dmodel!r} (radtan, equidistant or none)")
    try:
        cam = CameraModel(K=K, dist=dist, width=w, height=h)
    except ValueError as exc:
        raise ctx.error((key,), str(exc)) from None
    return cam, note


def _names(data, keys) -> list[str]:
    if len(keys) == 2:
        return ["left", "right"]
    names = []
    for key in keys:
        topic = str(data[key].get("rostopic", "")).strip("/").split("/")[0]
        names.append(topic)
    if all(_NAME.match(n) for n in names) and len(set(names)) == len(names):
        return names
    return list(keys)


def load_kalibr_camchain(path, *, max_fit_px: float = 0.1) -> Calibration:
    """Read a Kalibr ``camchain.yaml``.

    Parameters
    ----------
    path : str or Path
        The camchain file.
    max_fit_px : float
        Largest accepted pixel difference of the plumb_bob fit to an
        equidistant lens.

    Returns
    -------
    Calibration
        The cameras (two cameras are named ``left`` and ``right``; otherwise
        by their ``rostopic``'s first part, or ``cam0``, ``cam1``, ...); the
        stereo extrinsics from ``cam1``'s ``T_cn_cnm1``; for three or more
        cameras ``T_ref_cam`` of every camera in the ``cam0`` frame;
        ``T_cam_imu`` entries as transforms ``T_<camera>_imu``. Fitted
        equidistant lenses are listed in ``metadata["converted"]``.

    Raises
    ------
    TudorVisionError
        Absent file, malformed YAML, missing or malformed keys, an
        unsupported camera or distortion model; the message names the file,
        line and key.
    """
    path = Path(path)
    data, line_of = read_yaml(path)
    ctx = _Ctx(path, line_of)
    if not isinstance(data, dict) or "cam0" not in data:
        raise ctx.error((), "expected a Kalibr camchain mapping with cam0, cam1, ...")
    keys = sorted((k for k in data if isinstance(k, str) and _CAM_KEY.match(k)), key=lambda k: int(k[3:]))
    if [int(k[3:]) for k in keys] != list(range(len(keys))):
        raise ctx.error((), f"expected cameras cam0, cam1, ... without gaps, got {', '.join(keys)}")
    for key in keys:
        if not isinstance(data[key], dict):
            raise ctx.error((key,), "expected a mapping with intrinsics, distortion_coeffs, resolution")
    names = _names(data, keys)
    cams, notes, chain, trans = {}, [], [np.eye(4)], {}
    for i, (key, name) in enumerate(zip(keys, names)):
        cam, note = _camera(ctx, key, data[key], max_fit_px)
        cams[name] = cam
        if note:
            notes.append(note)
        if i > 0:
            if "T_cn_cnm1" not in data[key]:
                raise ctx.error((key,), f"missing 'T_cn_cnm1' (the pose of {keys[i - 1]} in {key})")
            chain.append(ctx.transform(data[key]["T_cn_cnm1"], (key, "T_cn_cnm1")) @ chain[-1])
        if "T_cam_imu" in data[key]:
            trans[f"T_{name}_imu"] = ctx.transform(data[key]["T_cam_imu"], (key, "T_cam_imu"))
    stereo = None
    if len(keys) >= 2:
        T10 = chain[1]
        stereo = StereoExtrinsics(R=T10[:3, :3], T=T10[:3, 3], left=names[0], right=names[1])
    if len(keys) >= 3:
        cams = {n: c.replace(T_ref_cam=np.linalg.inv(T_c0)) for (n, c), T_c0 in zip(cams.items(), chain)}
    meta = {"converted": notes} if notes else {}
    try:
        return Calibration(cameras=cams, stereo=stereo, transforms=trans, metadata=meta)
    except ValueError as exc:
        raise ctx.error((), str(exc)) from None


# ----------------------------------------------------------------------------- writing
def save_kalibr_camchain(calibration: Calibration, path, *, allow_lossy: bool = False) -> tuple[Path, list[str]]:
    """Write ``calibration`` as a Kalibr ``camchain.yaml`` (pinhole, radtan).

    Parameters
    ----------
    calibration : Calibration
        One camera, or a stereo pair (written as ``cam0`` = left, ``cam1`` =
        right); other cameras are left out and noted.
    path : str or Path
        Output file, written atomically.
    allow_lossy : bool
        Write a camera with ``k3 != 0`` with ``k1, k2`` refitted (radtan has
        four coefficients); without it such a camera is an error unless the
        refit is exact.

    Returns
    -------
    path : Path
        The written file.
    notes : list of str
        What the format could not hold (other cameras, transforms, rolling
        shutter times) and any refit with its worst pixel difference.

    Raises
    ------
    TudorVisionError
        No camera, a camera with skew, or ``k3 != 0`` without
        ``allow_lossy``.
    """
    st = calibration.stereo
    if st is not None:
        order = [st.left, st.right]
    elif len(calibration.cameras) == 1:
        order = list(calibration.cameras)
    else:
        raise TudorVisionError("Kalibr camchain: need one camera or a stereo pair, got cameras "
                               f"{sorted(calibration.cameras)} without stereo extrinsics")
    notes = []
    doc = {}
    for i, name in enumerate(order):
        cam = calibration.camera(name)
        if cam.K[0, 1] != 0:
            raise TudorVisionError(f"Kalibr camchain: camera {name!r} has skew K[0, 1] = {cam.K[0, 1]:g}; "
                                   "Kalibr's pinhole model has none")
        fitted, err = drop_k3(cam)
        if err > 1e-9:
            msg = f"camera {name!r}: k3 = {cam.dist[4]:.6g} has no place in radtan; the best k1, k2 refit is " \
                  f"off by {err:.3f} px inside the image"
            if not allow_lossy:
                raise TudorVisionError(f"Kalibr camchain: {msg} (pass --allow-lossy to write it anyway)")
            notes.append(msg)
        c = {}
        if i == 1:
            c["T_cn_cnm1"] = st.T_right_left.tolist()
        c["cam_overlaps"] = [1 - i] if st is not None else []
        c["camera_model"] = "pinhole"
        c["distortion_coeffs"] = [float(x) for x in fitted.dist[:4]]
        c["distortion_model"] = "radtan"
        c["intrinsics"] = [cam.fx, cam.fy, cam.cx, cam.cy]
        c["resolution"] = [cam.width, cam.height]
        c["rostopic"] = f"/{name}/image_raw"
        imu = f"T_{name}_imu"
        if imu in calibration.transforms:
            c["T_cam_imu"] = calibration.transforms[imu].tolist()
        doc[f"cam{i}"] = c
        if cam.line_time_s is not None:
            notes.append(f"camera {name!r}: line_time_s not written (no place in camchain)")
    other = [n for n in calibration.cameras if n not in order]
    if other:
        notes.append(f"cameras not written: {', '.join(other)}")
    kept = {f"T_{n}_imu" for n in order}
    dropped = [n for n in calibration.transforms if n not in kept]
    if dropped:
        notes.append(f"transforms not written: {', '.join(dropped)}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, dump_yaml(doc))
    return path, notes
