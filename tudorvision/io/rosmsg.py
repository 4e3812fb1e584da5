"""ROS message contents as arrays and camera models: ``sensor_msgs/Image``, ``CompressedImage``, ``CameraInfo``.

Works on messages deserialised by ``rosbags`` (ROS 1 or ROS 2 field names);
used by :mod:`tudorvision.io.bags`.
"""
from __future__ import annotations

import cv2
import numpy as np

from ._index import ImageProblem
from .calibration import CameraModel, StereoExtrinsics

__all__ = ["decode_image", "camera_from_info", "stereo_from_infos"]


def decode_image(msg) -> np.ndarray:
    """Pixels of a deserialised ``sensor_msgs/Image`` or ``CompressedImage``.

    Parameters
    ----------
    msg : object
        The message from ``rosbags`` (attributes ``encoding``, ``height``,
        ``width``, ``step``, ``is_bigendian``, ``data``; or ``format``,
        ``data``).

    Returns
    -------
    ndarray
        ``(H, W, 3)`` uint8 BGR, ``(H, W)`` uint8 grey, ``(H, W)`` uint16
        (``mono16`` / ``16UC1``) or ``(H, W)`` float32 (``32FC1``), in the
        message's units.

    Raises
    ------
    ImageProblem
        Unsupported encoding, or data too short or undecodable.
    """
    data = np.frombuffer(memoryview(np.ascontiguousarray(msg.data, dtype=np.uint8)), dtype=np.uint8)
    if hasattr(msg, "format"):
        fmt = str(msg.format).lower()
        if "compresseddepth" in fmt:       # 12-byte config header before the PNG
            if "32fc1" in fmt:
                raise ImageProblem(f"format {msg.format!r}: quantised 32FC1 compressedDepth is not supported "
                                   "(record 16UC1, or raw 32FC1)")
            start = data.tobytes().find(b"\x89PNG")
            data = data[start:] if start >= 0 else data[:0]
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
        if img is None:
            raise ImageProblem(f"cannot decode compressed image (format {msg.format!r})")
        if img.ndim == 3 and img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
        if "rgb8" in fmt and "bgr8" not in fmt and img.ndim == 3:
            img = np.ascontiguousarray(img[:, :, ::-1])
        return img
    enc, h, w, step = str(msg.encoding).lower(), int(msg.height), int(msg.width), int(msg.step)
    layouts = {"rgb8": ("u1", 3), "bgr8": ("u1", 3), "8uc3": ("u1", 3), "rgba8": ("u1", 4), "bgra8": ("u1", 4),
               "8uc4": ("u1", 4), "mono8": ("u1", 1), "8uc1": ("u1", 1), "mono16": ("u2", 1),
               "16uc1": ("u2", 1), "32fc1": ("f4", 1)}
    if enc not in layouts:
        raise ImageProblem(f"unsupported image encoding {msg.encoding!r} (supported: {', '.join(layouts)})")
    typ, ch = layouts[enc]
    dt = np.dtype(typ).newbyteorder(">" if msg.is_bigendian else "<")
    row = w * ch * dt.itemsize
    if h <= 0 or w <= 0 or step < row or data.size < step * h:
        raise ImageProblem(f"image data of {data.size} bytes does not hold {w}x{h} {msg.encoding} "
                           f"(step {step})")
    rows = data[:step * h].reshape(h, step)[:, :row]
    img = np.ascontiguousarray(rows).view(dt).reshape((h, w, ch) if ch > 1 else (h, w))
    img = img.astype(dt.newbyteorder("="), copy=False)
    if ch == 4:
        img = img[:, :, :3]
    if enc.startswith("rgb"):
        img = img[:, :, ::-1]
    img = np.ascontiguousarray(img)      # one copy at most: the message's buffer is read-only
    return img if img.flags.writeable else img.copy()


def _field(msg, name):
    return getattr(msg, name) if hasattr(msg, name) else getattr(msg, name.upper())


def camera_from_info(msg) -> tuple[CameraModel, np.ndarray, np.ndarray]:
    """Camera model from a deserialised ``sensor_msgs/CameraInfo`` (ROS 1 or ROS 2 field names).

    Parameters
    ----------
    msg : object
        The message (``width``, ``height``, ``distortion_model``, ``k``/``K``,
        ``d``/``D``, ``r``/``R``, ``p``/``P``).

    Returns
    -------
    camera : CameraModel
        Intrinsics (pixels), plumb_bob distortion and image size.
    R_rect : ndarray, shape (3, 3)
        Rectification rotation.
    P : ndarray, shape (3, 4)
        Rectified projection matrix, pixels (``P[0, 3] = -fx' * baseline_m``
        for the right camera).

    Raises
    ------
    ValueError
        Uncalibrated (zero) ``K``, or a distortion model this project cannot
        represent (non-zero coefficients beyond the five of plumb_bob).
    """
    K = np.asarray(_field(msg, "k"), dtype=np.float64).reshape(3, 3)
    d = np.asarray(_field(msg, "d"), dtype=np.float64).ravel()
    model = str(msg.distortion_model or "plumb_bob")
    if model not in ("plumb_bob", "rational_polynomial", "radtan", "") or np.any(d[5:] != 0):
        raise ValueError(f"distortion model {model!r} with {d.size} coefficients cannot be represented "
                         "(plumb_bob, 5 coefficients)")
    dist = np.zeros(5)
    dist[:min(5, d.size)] = d[:5]
    cam = CameraModel(K=K, dist=dist, width=int(msg.width), height=int(msg.height))
    R = np.asarray(_field(msg, "r"), dtype=np.float64).reshape(3, 3)
    P = np.asarray(_field(msg, "p"), dtype=np.float64).reshape(3, 4)
    if not np.any(R):
        R = np.eye(3)
    return cam, R, P


def stereo_from_infos(left, right) -> StereoExtrinsics | None:
    """Stereo extrinsics from the left and right ``(camera, R_rect, P)`` of :func:`camera_from_info`.

    ROS rectification: ``R1 @ x_left`` and ``R2 @ x_right`` are parallel
    frames, offset along x by ``Tx = P2[0, 3] / P2[0, 0]``, so
    ``R = R2.T @ R1`` and ``T = R2.T @ (Tx, 0, 0)`` (OpenCV convention,
    ``x_right = R @ x_left + T``).

    Parameters
    ----------
    left, right : tuple
        ``(CameraModel, R_rect (3, 3), P (3, 4))`` of each camera.

    Returns
    -------
    StereoExtrinsics or None
        None when ``P2[0, 3]`` is zero (no baseline recorded).
    """
    (_, R1, P1), (_, R2, P2) = left, right
    if P2[0, 0] == 0 or P2[0, 3] == 0:                   # no baseline recorded
        return None
    tx = P2[0, 3] / P2[0, 0]
    f, cx, cy, cx2 = P1[0, 0], P1[0, 2], P1[1, 2], P2[0, 2]
    Q = np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f], [0, 0, -1 / tx, (cx - cx2) / tx]])
    return StereoExtrinsics(R=R2.T @ R1, T=R2.T @ np.array([tx, 0.0, 0.0]), R1=R1, R2=R2, P1=P1, P2=P2, Q=Q)
