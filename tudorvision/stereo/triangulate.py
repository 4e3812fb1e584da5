"""Stereo triangulation of the tracking spheres, with rolling-shutter compensation.

Conventions
-----------
- Pixels: ``uv`` rows ``(u, v)``, u right, v down, OpenCV origin (centre of
  the top-left pixel). A missing detection is a NaN row.
- Camera optical frames: x right, y down, z forward. Stereo extrinsics follow
  OpenCV: ``x_right = R @ x_left + T`` (``T`` in metres).
- Triangulated points are in the **left** camera's optical frame unless a
  ``T_base_left`` (``p_base = T_base_left @ p_left``) is given.
- A point is triangulated only when it is seen in both cameras; a point
  missing in either camera gives a NaN row and ``valid = False``: never a 3D
  point from a single view.

Two triangulation routes are offered (section 2.4 of the seed triangulates
after rectification, Hartley and Zisserman p. 318):

``"normalized"``
    undistort each camera's pixels to normalised coordinates and triangulate
    with ``P_left = [I | 0]``, ``P_right = [R | T]``;
``"rectified"``
    undistort *and* rectify (``R1, P1, R2, P2`` from ``cv2.stereoRectify``),
    triangulate with ``P1, P2`` and rotate back with ``R1^T``.

Both use :func:`cv2.triangulatePoints` on float64 ``2 x N`` arrays and divide
by w. :func:`triangulate_dlt` is an independent pure-numpy linear
triangulation used as the test oracle.

Rolling shutter: :mod:`.rolling_shutter` (its functions are re-exported here);
:func:`triangulate_spheres` applies it when given per-camera timestamps.
"""
from __future__ import annotations

import weakref
from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from .._checks import check_array, check_points
from ..geometry import transform_points
from .rolling_shutter import compensate_rolling_shutter, rolling_shutter_times

__all__ = [
    "undistort_points", "projection_matrices", "triangulate_points", "triangulate_dlt",
    "triangulate_stereo", "StereoRig", "SphereTriangulation", "triangulate_spheres",
    "rolling_shutter_times", "compensate_rolling_shutter",
]


# OpenCV's default (5 iterations) leaves up to ~0.01 px at the corners of a
# wide-angle image (k1 = -0.2); iterate to convergence instead (~3x the cost).
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10)


_P_IDENTITY = np.hstack([np.eye(3), np.zeros((3, 1))])

# StereoRig memoises the undistortion of calls with at most _MEMO_POINTS points, up to _MEMO_SIZE per camera
_MEMO_POINTS = 8
_MEMO_SIZE = 4096


def _uv(value, name: str) -> np.ndarray:
    return check_points(value, name, dim=2, finite=False)


def _valid_rows(*arrays) -> np.ndarray:
    ok = np.ones(len(arrays[0]), bool)
    for a in arrays:
        ok &= np.all(np.isfinite(a), axis=1)
    return ok


def undistort_points(uv, K, dist, *, R=None, P=None) -> np.ndarray:
    """Remove lens distortion from pixel positions (NaN rows pass through).

    Parameters
    ----------
    uv : array_like, shape (N, 2)
        Distorted pixel positions (u right, v down).
    K : array_like, shape (3, 3)
        Camera matrix, pixels.
    dist : array_like, shape (5,) or (K,)
        OpenCV distortion coefficients.
    R : array_like, shape (3, 3), optional
        Rectifying rotation applied after undistortion.
    P : array_like, shape (3, 3) or (3, 4), optional
        New projection matrix. Without it the result is in normalised image
        coordinates (x/z, y/z); with ``P = K`` it is in ideal pixels.

    Returns
    -------
    ndarray, shape (N, 2)
        Undistorted points. The iterative inversion runs to convergence
        (1e-10 in normalised units) rather than OpenCV's default 5 steps.

    Examples
    --------
    >>> K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    >>> undistort_points([[320.0, 240.0], [np.nan, np.nan], [820.0, 240.0]], K, np.zeros(5))
    array([[ 0.,  0.],
           [nan, nan],
           [ 1.,  0.]])
    """
    pts = _uv(uv, "uv")
    K = check_array(K, "K", (3, 3))
    d = np.asarray(dist, dtype=np.float64).ravel()
    if R is not None:
        R = check_array(R, "R", (3, 3))
    if P is not None:
        P = np.asarray(P, dtype=np.float64)
        if P.shape not in ((3, 3), (3, 4)):
            raise ValueError(f"P: expected shape (3, 3) or (3, 4), got {P.shape}")
    return _undistort(pts, K, d, R=R, P=P)


def _undistort(pts, K, d, *, R=None, P=None) -> np.ndarray:
    """Core of :func:`undistort_points` on checked arrays."""
    out = np.full_like(pts, np.nan)
    ok = _valid_rows(pts)
    if ok.any():
        kw = {"criteria": _UNDISTORT_CRITERIA}
        if R is not None:
            kw["R"] = R
        if P is not None:
            kw["P"] = P
        und = cv2.undistortPoints(np.ascontiguousarray(pts[ok]).reshape(-1, 1, 2), K, d, **kw)
        out[ok] = und.reshape(-1, 2)
    return out


def projection_matrices(K_left, K_right, R, T) -> tuple[np.ndarray, np.ndarray]:
    """Pixel projection matrices of a stereo pair, reference = left camera frame.

    Parameters
    ----------
    K_left, K_right : array_like, shape (3, 3)
        Camera matrices (pixels).
    R : array_like, shape (3, 3)
        Rotation, ``x_right = R @ x_left + T``.
    T : array_like, shape (3,)
        Translation in metres.

    Returns
    -------
    P_left, P_right : ndarray, shape (3, 4)
        ``K_left [I | 0]`` and ``K_right [R | T]``; pass ``np.eye(3)`` as both
        K for normalised coordinates.

    Examples
    --------
    >>> P1, P2 = projection_matrices(np.eye(3), np.eye(3), np.eye(3), [-0.1, 0, 0])
    >>> P2[:, 3].tolist()
    [-0.1, 0.0, 0.0]
    """
    Kl = check_array(K_left, "K_left", (3, 3))
    Kr = check_array(K_right, "K_right", (3, 3))
    R = check_array(R, "R", (3, 3))
    T = check_array(T, "T", (3,))
    return Kl @ np.hstack([np.eye(3), np.zeros((3, 1))]), Kr @ np.hstack([R, T[:, None]])


def triangulate_points(uv_left, uv_right, P_left, P_right) -> np.ndarray:
    """Linear triangulation with :func:`cv2.triangulatePoints` (float64, 2 x N, divide by w).

    Parameters
    ----------
    uv_left, uv_right : array_like, shape (N, 2)
        Corresponding *undistorted* image points in the coordinates that
        ``P_left`` / ``P_right`` project to. NaN rows mark missing points.
    P_left, P_right : array_like, shape (3, 4)
        Projection matrices sharing one reference frame.

    Returns
    -------
    points : ndarray, shape (N, 3)
        Points in the reference frame of the P matrices; NaN where either
        view is missing or the point is at infinity.

    Raises
    ------
    ValueError
        If the shapes do not match.

    Examples
    --------
    >>> P1, P2 = projection_matrices(np.eye(3), np.eye(3), np.eye(3), [-0.2, 0, 0])
    >>> triangulate_points([[0.1, 0.05]], [[0.0, 0.05]], P1, P2).round(9).tolist()
    [[0.2, 0.1, 2.0]]
    """
    a, b, P1, P2 = _checked_pair(uv_left, uv_right, P_left, P_right)
    return _triangulate_cv2(a, b, P1, P2)


def _checked_pair(uv_left, uv_right, P_left, P_right):
    """Boundary checks shared by the triangulation functions."""
    a = _uv(uv_left, "uv_left")
    b = _uv(uv_right, "uv_right")
    if a.shape != b.shape:
        raise ValueError(f"uv_right: expected shape {a.shape} like uv_left, got {b.shape}")
    return a, b, check_array(P_left, "P_left", (3, 4)), check_array(P_right, "P_right", (3, 4))


def _triangulate_cv2(a, b, P1, P2) -> np.ndarray:
    """Core of :func:`triangulate_points` on checked float64 arrays."""
    out = np.full((len(a), 3), np.nan)
    ok = _valid_rows(a, b)
    if ok.any():
        out[ok] = _dlt_finite(a[ok], b[ok], P1, P2)
    return out


def _dlt_finite(a, b, P1, P2) -> np.ndarray:
    """:func:`cv2.triangulatePoints` of finite rows (N, 2) each, divided by w; NaN at infinity."""
    X = cv2.triangulatePoints(P1, P2, np.ascontiguousarray(a.T), np.ascontiguousarray(b.T))
    w = X[3]
    at_infinity = np.abs(w) < 1e-300
    return (X[:3] / (np.where(at_infinity, np.nan, w) if at_infinity.any() else w)).T


def triangulate_dlt(uv_left, uv_right, P_left, P_right) -> np.ndarray:
    """Pure-numpy linear (DLT) triangulation, the independent oracle.

    For each point the homogeneous X minimising ``|A X|`` subject to
    ``|X| = 1``, with ``A = [u P3 - P1; v P3 - P2]`` stacked for both views,
    is the last right singular vector of A (Hartley and Zisserman, section
    12.2). This is the same algebraic estimator as
    :func:`cv2.triangulatePoints`, computed independently (batched
    ``numpy.linalg.svd``), so the two agree to rounding on noisy data.

    Parameters
    ----------
    uv_left, uv_right : array_like, shape (N, 2)
        Corresponding undistorted image points; NaN rows are missing.
    P_left, P_right : array_like, shape (3, 4)
        Projection matrices.

    Returns
    -------
    points : ndarray, shape (N, 3)
        NaN where either view is missing.

    Examples
    --------
    >>> P1, P2 = projection_matrices(np.eye(3), np.eye(3), np.eye(3), [-0.2, 0, 0])
    >>> triangulate_dlt([[0.1, 0.05]], [[0.0, 0.05]], P1, P2).round(9).tolist()
    [[0.2, 0.1, 2.0]]
    """
    a, b, P1, P2 = _checked_pair(uv_left, uv_right, P_left, P_right)
    out = np.full((len(a), 3), np.nan)
    ok = _valid_rows(a, b)
    if not ok.any():
        return out
    a, b = a[ok], b[ok]
    A = np.stack([a[:, :1] * P1[2] - P1[0], a[:, 1:] * P1[2] - P1[1],
                  b[:, :1] * P2[2] - P2[0], b[:, 1:] * P2[2] - P2[1]], axis=1)
    _, _, vt = np.linalg.svd(A)
    X = vt[:, -1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        out[ok] = X[:, :3] / X[:, 3:]
    return out


def _rig(calibration):
    """(left CameraModel, right CameraModel, StereoExtrinsics) from a Calibration."""
    stereo = getattr(calibration, "stereo", None)
    if stereo is None:
        raise ValueError("calibration: has no stereo extrinsics (run 'tudorvision calib stereo')")
    return calibration.camera(stereo.left), calibration.camera(stereo.right), stereo


_RECTIFY_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _rectification(left, right, stereo):
    """(R1, R2, P1, P2): stored ones, else computed once per extrinsics object."""
    if stereo.has_rectification:
        return stereo.R1, stereo.R2, stereo.P1, stereo.P2
    key = (left.K.tobytes(), left.dist.tobytes(), right.K.tobytes(), right.dist.tobytes())
    hit = _RECTIFY_CACHE.get(stereo)
    if hit is not None and hit[0] == key:
        return hit[1]
    R1, R2, P1, P2, *_ = cv2.stereoRectify(left.K, left.dist, right.K, right.dist,
                                           (left.width, left.height), stereo.R,
                                           stereo.T.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY,
                                           alpha=-1)
    _RECTIFY_CACHE[stereo] = (key, (R1, R2, P1, P2))
    return R1, R2, P1, P2


def triangulate_stereo(uv_left, uv_right, calibration, *, method: str = "normalized") -> np.ndarray:
    """Triangulate raw (distorted) pixel detections of a calibrated stereo pair.

    Parameters
    ----------
    uv_left, uv_right : array_like, shape (N, 2)
        Raw pixel positions in the left and right image; NaN rows are missing.
    calibration : tudorvision.io.calibration.Calibration
        Must contain the two cameras and ``stereo`` extrinsics.
    method : {"normalized", "rectified"}
        Triangulation route (see the module docstring).

    Returns
    -------
    points_left : ndarray, shape (N, 3)
        Metres, left camera optical frame; NaN where either view is missing.

    Raises
    ------
    ValueError
        If ``method`` is unknown, the calibration has no stereo part, or the
        shapes differ.
    """
    left, right, stereo = _rig(calibration)
    a = _uv(uv_left, "uv_left")
    b = _uv(uv_right, "uv_right")
    if a.shape != b.shape:
        raise ValueError(f"uv_right: expected shape {a.shape} like uv_left, got {b.shape}")
    return _triangulate_rig(a, b, left, right, stereo, method)


def _triangulate_rig(a, b, left, right, stereo, method) -> np.ndarray:
    """Core of :func:`triangulate_stereo` on checked (N, 2) arrays; validated models."""
    if method == "normalized":
        na = _undistort(a, left.K, left.dist)
        nb = _undistort(b, right.K, right.dist)
        P2 = np.hstack([stereo.R, stereo.T[:, None]])
        return _triangulate_cv2(na, nb, _P_IDENTITY, P2)
    if method == "rectified":
        R1, R2, P1, P2 = _rectification(left, right, stereo)
        ra = _undistort(a, left.K, left.dist, R=R1, P=P1)
        rb = _undistort(b, right.K, right.dist, R=R2, P=P2)
        points_rect = _triangulate_cv2(ra, rb, np.asarray(P1, float), np.asarray(P2, float))
        return points_rect @ np.asarray(R1)   # p_left = R1^T p_rect, as rows
    raise ValueError(f"method: expected 'normalized' or 'rectified', got {method!r}")


class StereoRig:
    """A calibrated stereo pair checked once, for many small calls: epipolar distances and triangulation.

    The tracking pipeline's per-frame path (a few points per call); same results as :func:`triangulate_stereo`.

    Parameters
    ----------
    calibration : tudorvision.io.calibration.Calibration
        Two cameras and ``stereo`` extrinsics.
    method : {"normalized", "rectified"}
        Triangulation route (see the module docstring).

    Examples
    --------
    >>> from tudorvision.io import Calibration, CameraModel, StereoExtrinsics
    >>> cam = CameraModel(K=[[500, 0, 320], [0, 500, 240], [0, 0, 1]], width=640, height=480)
    >>> cal = Calibration(cameras={"left": cam, "right": cam}, stereo=StereoExtrinsics(R=np.eye(3), T=[-0.1, 0, 0]))
    >>> rig = StereoRig(cal)
    >>> (rig.triangulate([[345.0, 240.0]], [[320.0, 240.0]]).round(9) + 0.0).tolist()
    [[0.1, 0.0, 2.0]]
    >>> rig.epipolar_px([[345.0, 240.0]], [[320.0, 243.0]]).round(9).tolist()
    [3.0]
    """

    def __init__(self, calibration, method: str = "normalized"):
        self.left, self.right, self.stereo = _rig(calibration)
        if method not in ("normalized", "rectified"):
            raise ValueError(f"method: expected 'normalized' or 'rectified', got {method!r}")
        self.method = method
        tx, ty, tz = self.stereo.T
        self.E = np.array([[0.0, -tz, ty], [tz, 0.0, -tx], [-ty, tx, 0.0]]) @ self.stereo.R   # x_r^T E x_l = 0
        self.f_left_px, self.f_right_px = (0.5 * (c.fx + c.fy) for c in (self.left, self.right))
        self._P2 = np.hstack([self.stereo.R, self.stereo.T[:, None]])
        self._dist = (np.asarray(self.left.dist, np.float64).ravel(), np.asarray(self.right.dist, np.float64).ravel())
        self._memo = ({}, {})     # raw pixel (u, v) -> normalised (x, y), per camera (see _undistorted)

    def _pairs(self, uv_left, uv_right):
        a, b = (np.asarray(v, dtype=np.float64).reshape(-1, 2) for v in (uv_left, uv_right))
        if a.shape != b.shape:
            raise ValueError(f"uv_right: expected shape {a.shape} like uv_left, got {b.shape}")
        return a, b, np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)

    def normalised(self, uv_left, uv_right) -> tuple:
        """Undistorted normalised coordinates ``(x_left, x_right)``, each (N, 2), of finite raw pixels (N, 2)."""
        a, b, _ = self._pairs(uv_left, uv_right)
        return self._undistorted(a, 0), self._undistorted(b, 1)

    def _undistorted(self, uv, cam: int) -> np.ndarray:
        """Normalised coordinates (n, 2) of raw pixels ``uv`` (n, 2) of camera ``cam`` (0 left, 1 right).

        Calls of a few points (a frame's centres, checked, triangulated and
        triangulated again) are memoised by value: each centre is undistorted once.
        """
        few = len(uv) <= _MEMO_POINTS
        if few:
            memo = self._memo[cam]
            try:
                return np.array([memo[tuple(p)] for p in uv.tolist()], dtype=np.float64).reshape(-1, 2)
            except KeyError:        # not seen yet (or the memo was just cleared)
                pass
        cam_model = self.left if cam == 0 else self.right
        x = cv2.undistortPoints(np.ascontiguousarray(uv).reshape(-1, 1, 2), cam_model.K, self._dist[cam],
                                criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)
        if few:
            self.remember(uv, x, cam)
        return x

    def remember(self, uv, x, cam: int) -> None:
        """Record that raw pixels ``uv`` (n, 2) of camera ``cam`` (0 left, 1 right) undistort to ``x`` (n, 2).

        For points made by distorting ``x`` (e.g. centres moved in normalised
        coordinates): later calls then use ``x`` itself.
        """
        memo = self._memo[cam]
        if len(memo) > _MEMO_SIZE:
            memo.clear()
        memo.update(zip((tuple(p) for p in np.asarray(uv, np.float64).reshape(-1, 2).tolist()),
                        np.asarray(x, np.float64).reshape(-1, 2).tolist()))

    def epipolar_px(self, uv_left, uv_right) -> np.ndarray:
        """Distance (N,) of each right point from the epipolar line of its left point, raw pixels (N, 2) in.

        In the undistorted right image, in pixels of its mean focal length; NaN rows give NaN.
        """
        a, b, ok = self._pairs(uv_left, uv_right)
        out = np.full(len(a), np.nan)
        if ok.any():
            out[ok] = self.epipolar_px_normalised(*self.normalised(a[ok], b[ok]))
        return out

    def epipolar_px_normalised(self, x_left, x_right) -> np.ndarray:
        """:meth:`epipolar_px` of undistorted normalised coordinates (N, 2) each."""
        lines = x_left @ self.E[:, :2].T + self.E[:, 2]             # E @ (x, y, 1) per left point
        num = np.abs(lines[:, 0] * x_right[:, 0] + lines[:, 1] * x_right[:, 1] + lines[:, 2])
        return self.f_right_px * num / np.hypot(lines[:, 0], lines[:, 1])

    def triangulate(self, uv_left, uv_right) -> np.ndarray:
        """Points in the left camera frame, metres, shape (N, 3), from raw pixels (N, 2); NaN rows missing."""
        a, b, ok = self._pairs(uv_left, uv_right)
        if self.method != "normalized":
            return _triangulate_rig(a, b, self.left, self.right, self.stereo, self.method)
        out = np.full((len(a), 3), np.nan)
        if ok.any():
            out[ok] = _dlt_finite(*self.normalised(a[ok], b[ok]), _P_IDENTITY, self._P2)
        return out


@dataclass(frozen=True, kw_only=True)
class SphereTriangulation:
    """Triangulated tracking spheres and the end effector.

    Attributes
    ----------
    spheres : dict of str to ndarray, shape (N, 3)
        Sphere centres in metres, frame ``frame``; NaN rows where missing.
    sphere_valid : dict of str to ndarray of bool, shape (N,)
        True where the sphere was seen in both cameras.
    ee : ndarray, shape (N, 3)
        End effector, the midpoint of the sphere centres; NaN unless every
        sphere is valid.
    ee_valid : ndarray of bool, shape (N,)
    frame : str
        ``"left"`` (left camera optical frame: x right, y down, z forward) or
        ``"base"`` (robot base frame, z up).
    """

    spheres: dict
    sphere_valid: dict
    ee: np.ndarray
    ee_valid: np.ndarray
    frame: str


def triangulate_spheres(uv_left: Mapping, uv_right: Mapping, calibration, *, T_base_left=None,
                        method: str = "normalized", t_left=None, t_right=None,
                        t_target=None) -> SphereTriangulation:
    """Triangulate every tracking sphere and the end-effector midpoint.

    Parameters
    ----------
    uv_left, uv_right : mapping of str to array_like, shape (N, 2)
        Raw pixel centroids per sphere name (e.g. ``"red"``, ``"green"``),
        NaN rows where the sphere was not found. Both mappings need the same
        names.
    calibration : tudorvision.io.calibration.Calibration
        Stereo calibration.
    T_base_left : array_like, shape (4, 4), optional
        Robot base pose of the left camera; the output is then in the base frame.
    method : {"normalized", "rectified"}
        Triangulation route.
    t_left, t_right : array_like, shape (N,), optional
        Frame timestamps (seconds) of each camera. When both are given and
        the camera models have ``line_time_s``, every track is moved to the
        times ``t_target`` (default ``t_left``) with
        :func:`compensate_rolling_shutter` before triangulation.
    t_target : array_like, shape (N,), optional
        Common time of each output sample.

    Returns
    -------
    SphereTriangulation

    Raises
    ------
    ValueError
        If the sphere names differ, shapes differ, or arguments are invalid.
    """
    if set(uv_left) != set(uv_right) or not uv_left:
        raise ValueError(f"uv_right: expected the same non-empty sphere names as uv_left "
                         f"({sorted(uv_left)}), got {sorted(uv_right)}")
    left, right, stereo = _rig(calibration)
    if method not in ("normalized", "rectified"):
        raise ValueError(f"method: expected 'normalized' or 'rectified', got {method!r}")
    rs = t_left is not None and t_right is not None and \
        bool(left.line_time_s) and bool(right.line_time_s)
    names = list(uv_left)
    ua, ub = [], []
    for name in names:
        a = _uv(uv_left[name], f"uv_left[{name!r}]")
        b = _uv(uv_right[name], f"uv_right[{name!r}]")
        if a.shape != b.shape or (ua and a.shape != ua[0].shape):
            raise ValueError(f"uv_right[{name!r}]: expected shape {ua[0].shape if ua else a.shape} "
                             f"like the other tracks, got {a.shape} / {b.shape}")
        if rs:
            tt = t_left if t_target is None else t_target
            a, _ = compensate_rolling_shutter(t_left, a, left.line_time_s, t_target=tt)
            b, _ = compensate_rolling_shutter(t_right, b, right.line_time_s, t_target=tt)
        ua.append(a)
        ub.append(b)
    n = len(ua[0])
    # all spheres in one call: per-frame use is dominated by call overhead
    p_all = _triangulate_rig(np.concatenate(ua), np.concatenate(ub), left, right, stereo, method)
    if T_base_left is not None:
        p_all = transform_points(T_base_left, p_all)
    spheres, valid = {}, {}
    for i, name in enumerate(names):
        spheres[name] = p_all[i * n:(i + 1) * n]
        valid[name] = np.all(np.isfinite(spheres[name]), axis=1)
    stack = np.stack(list(spheres.values()))
    ee_valid = np.all(np.stack(list(valid.values())), axis=0)
    ee = np.full(stack.shape[1:], np.nan)
    ee[ee_valid] = stack[:, ee_valid].mean(axis=0)
    return SphereTriangulation(spheres=spheres, sphere_valid=valid, ee=ee, ee_valid=ee_valid,
                               frame="base" if T_base_left is not None else "left")
