"""Checkerboard stereo calibration: corner detection, intrinsics, extrinsics, rectification.

Pipeline (:func:`calibrate_stereo_from_images`):

1. :func:`find_board_corners` per image: :func:`cv2.findChessboardCorners`
   with adaptive threshold and image normalisation, retried on a 2x
   upscaled image like OpenCV's ``stereo_calib`` sample, then
   :func:`cv2.cornerSubPix` (window up to 11 px half-size, shrunk for small
   squares so it never spans a neighbouring corner). A pair is used only
   when the board is found in both images; other pairs are skipped and
   counted with the reason.
2. :func:`calibrate_stereo` on the detections: ``mode="default"``
   calibrates each camera with :func:`cv2.calibrateCamera` (5-coefficient
   plumb-bob distortion), then refines everything jointly with
   :func:`cv2.stereoCalibrate` (``CALIB_USE_INTRINSIC_GUESS``; with
   ``fix_intrinsic=True`` only R and T). ``mode="opencv-sample"`` follows
   the ``stereo_calib`` sample instead: ``initCameraMatrix2D`` then one
   ``stereoCalibrate`` with ``FIX_ASPECT_RATIO``, ``ZERO_TANGENT_DIST``,
   ``SAME_FOCAL_LENGTH``, ``USE_INTRINSIC_GUESS`` and ``FIX_K3``. (The sample
   also sets ``RATIONAL_MODEL``, leaving k6 free; the project's calibration
   format holds the 5 plumb-bob coefficients, so k4..k6 stay 0 here.)
3. :func:`cv2.stereoRectify` with ``CALIB_ZERO_DISPARITY`` and
   ``alpha = 1`` as in the sample gives R1, R2, P1, P2, Q.

Lengths are metres (``square_m``), so T comes out in metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError
from .._progress import progress
from ..io.calibration import Calibration, CameraModel, StereoExtrinsics

__all__ = ["board_object_points", "find_board_corners", "BoardDetections", "detect_board_pairs",
           "StereoCalibrationResult", "calibrate_stereo", "calibrate_stereo_from_images",
           "plot_view_errors", "parse_board"]

_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 30, 0.01)
_STEREO_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-5)


def parse_board(text: str) -> tuple[int, int]:
    """``"9x6"`` -> ``(9, 6)`` inner corners (columns, rows).

    Parameters
    ----------
    text : str
        Board size ``"COLSxROWS"`` of inner corners, case-insensitive
        (``"9x6"`` or ``"9X6"``).

    Returns
    -------
    tuple of int
        ``(columns, rows)`` of inner corners.

    Raises
    ------
    ValueError
        If ``text`` is not two integers joined by ``x``, or either is below 2.

    Examples
    --------
    >>> parse_board("9x6")
    (9, 6)
    """
    try:
        w, h = (int(x) for x in str(text).lower().split("x"))
    except ValueError:
        raise ValueError(f"board: expected COLSxROWS of inner corners like 9x6, got {text!r}") from None
    if w < 2 or h < 2:
        raise ValueError(f"board: need at least 2x2 inner corners, got {text!r}")
    return w, h


def board_object_points(board: tuple[int, int], square_m: float) -> np.ndarray:
    """Inner-corner positions of a checkerboard in its own plane.

    Parameters
    ----------
    board : tuple of int
        ``(columns, rows)`` of inner corners, e.g. ``(9, 6)``.
    square_m : float
        Square edge length in metres.

    Returns
    -------
    ndarray, shape (columns * rows, 3), float32
        ``(k * square, j * square, 0)`` for row j, column k, row-major (the
        order of :func:`cv2.findChessboardCorners`). Board frame, metres.

    Examples
    --------
    >>> board_object_points((3, 2), 0.5)[:4].tolist()
    [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.5, 0.0]]
    """
    if not square_m > 0:
        raise ValueError(f"square_m: must be positive, got {square_m}")
    cols, rows = board
    j, k = np.mgrid[0:rows, 0:cols]
    pts = np.column_stack([k.ravel() * square_m, j.ravel() * square_m, np.zeros(rows * cols)])
    return pts.astype(np.float32)


def _grey(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.dtype != np.uint8:
        img = cv2.normalize(img, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return img


def find_board_corners(image, board: tuple[int, int], *, max_scale: int = 2) -> np.ndarray | None:
    """Find the inner corners of a checkerboard with sub-pixel accuracy.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
        Grey or BGR image.
    board : tuple of int
        ``(columns, rows)`` of inner corners.
    max_scale : int
        Retry on images upscaled by 2 .. ``max_scale`` when not found.

    Returns
    -------
    corners : ndarray, shape (columns * rows, 2), float32, or None
        Pixel positions (u right, v down) in the order of
        :func:`board_object_points`; None when the board is not found.
    """
    grey = _grey(image)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    corners = None
    for scale in range(1, max(1, max_scale) + 1):
        img = grey if scale == 1 else cv2.resize(grey, None, fx=scale, fy=scale)
        found, c = cv2.findChessboardCorners(img, board, flags=flags)
        if found:
            corners = c.reshape(-1, 2) / scale
            break
    if corners is None:
        return None
    cols, rows = board
    grid = corners.reshape(rows, cols, 2)
    spacing = min(np.linalg.norm(np.diff(grid, axis=1), axis=2).min(),
                  np.linalg.norm(np.diff(grid, axis=0), axis=2).min())
    half = int(np.clip(np.floor(0.45 * spacing), 2, 11))
    refined = cv2.cornerSubPix(grey, corners.reshape(-1, 1, 2).astype(np.float32), (half, half), (-1, -1),
                               _SUBPIX_CRITERIA)
    return refined.reshape(-1, 2)


@dataclass(frozen=True, kw_only=True)
class BoardDetections:
    """Checkerboard corners found in image pairs.

    Attributes
    ----------
    names : list of str
        ``"left.png|right.png"`` for each used pair.
    corners_left, corners_right : list of ndarray, shape (M, 2)
        Corners per used pair, pixels.
    image_size : tuple of int
        ``(width, height)``.
    skipped : list of (str, str)
        ``(pair name, reason)`` for each pair left out.
    """

    names: list
    corners_left: list
    corners_right: list
    image_size: tuple
    skipped: list = field(default_factory=list)


def _read_grey(path: Path) -> np.ndarray | None:
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    return img


def detect_board_pairs(left_paths, right_paths, board: tuple[int, int], *,
                       show_progress: bool | None = None) -> BoardDetections:
    """Detect the checkerboard in image pairs, skipping pairs where it is not found in both.

    Parameters
    ----------
    left_paths, right_paths : sequence of path
        Image files, paired by position.
    board : tuple of int
        Inner corners ``(columns, rows)``.

    Returns
    -------
    BoardDetections

    Raises
    ------
    ValueError
        If the lists differ in length or are empty.
    """
    left_paths, right_paths = [Path(p) for p in left_paths], [Path(p) for p in right_paths]
    if len(left_paths) != len(right_paths):
        raise ValueError(f"right: expected {len(left_paths)} images like left, got {len(right_paths)}")
    if not left_paths:
        raise ValueError("left: no calibration images given")
    names, cl, cr, skipped = [], [], [], []
    size = None
    pairs = list(zip(left_paths, right_paths))
    for lp, rp in progress(pairs, desc="checkerboard", enabled=show_progress):
        name = f"{lp.name}|{rp.name}"
        found = []
        reason = None
        for p in (lp, rp):
            img = _read_grey(p)
            if img is None:
                reason = f"{p}: cannot read image"
                break
            s = (img.shape[1], img.shape[0])
            if size is None:
                size = s
            elif s != size:
                reason = f"{p}: image size {s[0]}x{s[1]} differs from {size[0]}x{size[1]}"
                break
            c = find_board_corners(img, board)
            if c is None:
                reason = f"{p}: checkerboard {board[0]}x{board[1]} not found"
                break
            found.append(c)
        if reason is not None:
            skipped.append((name, reason))
            continue
        names.append(name)
        cl.append(found[0])
        cr.append(found[1])
    return BoardDetections(names=names, corners_left=cl, corners_right=cr,
                           image_size=size or (0, 0), skipped=skipped)


@dataclass(frozen=True, kw_only=True)
class StereoCalibrationResult:
    """Outcome of a stereo calibration.

    Attributes
    ----------
    calibration : Calibration
        Cameras ``left`` and ``right`` and the stereo extrinsics with
        rectification (R1, R2, P1, P2, Q), metres.
    rms_px : float
        Overall RMS reprojection error of the joint stereo fit, pixels.
    rms_left_px, rms_right_px : float
        RMS of the per-camera calibrations (``mode="default"``; NaN otherwise).
    per_view_rms_px : ndarray, shape (M, 2)
        RMS reprojection error per view (columns: left, right) of the joint fit.
    epipolar_error_px : float
        Mean distance of the undistorted corners to their epipolar lines
        (both directions summed, like the ``stereo_calib`` sample).
    views : list of str
        View names, in the order of ``per_view_rms_px``.
    skipped : list of (str, str)
        Views left out and why.
    mode : str
    """

    calibration: Calibration
    rms_px: float
    rms_left_px: float
    rms_right_px: float
    per_view_rms_px: np.ndarray
    epipolar_error_px: float
    views: list
    skipped: list
    mode: str

    def summary(self) -> str:
        """A few human-readable lines.

        Returns
        -------
        str
            Multi-line report: views used and skipped, RMS reprojection and
            mean epipolar errors (pixels), and each camera's intrinsics.
        """
        cal = self.calibration
        st = cal.stereo
        lines = [f"views used: {len(self.views)}, skipped: {len(self.skipped)}",
                 f"overall RMS reprojection error: {self.rms_px:.4f} px (mode {self.mode})"]
        if np.isfinite(self.rms_left_px):
            lines.append(f"per-camera RMS: left {self.rms_left_px:.4f} px, right {self.rms_right_px:.4f} px")
        lines.append(f"mean epipolar error: {self.epipolar_error_px:.4f} px")
        for name in (st.left, st.right):
            c = cal.camera(name)
            lines.append(f"{name}: fx {c.fx:.2f} fy {c.fy:.2f} cx {c.cx:.2f} cy {c.cy:.2f} "
                         f"dist {np.array2string(c.dist, precision=4)}")
        lines.append(f"baseline: {st.baseline_m:.4f} m, T = {np.array2string(st.T, precision=4)} m")
        worst = int(np.argmax(self.per_view_rms_px.max(axis=1))) if len(self.views) else None
        if worst is not None:
            lines.append(f"worst view: {self.views[worst]} "
                         f"({self.per_view_rms_px[worst, 0]:.3f} / {self.per_view_rms_px[worst, 1]:.3f} px)")
        return "\n".join(lines)


def _epipolar_error(pl, pr, K1, D1, K2, D2, F) -> float:
    total, n = 0.0, 0
    for a, b in zip(pl, pr):
        ua = cv2.undistortPoints(a.reshape(-1, 1, 2).astype(np.float64), K1, D1, P=K1).reshape(-1, 2)
        ub = cv2.undistortPoints(b.reshape(-1, 1, 2).astype(np.float64), K2, D2, P=K2).reshape(-1, 2)
        l2 = cv2.computeCorrespondEpilines(ua.reshape(-1, 1, 2), 1, F).reshape(-1, 3)
        l1 = cv2.computeCorrespondEpilines(ub.reshape(-1, 1, 2), 2, F).reshape(-1, 3)
        total += float(np.sum(np.abs(np.sum(ub * l2[:, :2], axis=1) + l2[:, 2]))
                       + np.sum(np.abs(np.sum(ua * l1[:, :2], axis=1) + l1[:, 2])))
        n += len(a)
    return total / max(n, 1)


def calibrate_stereo(object_points, corners_left, corners_right, image_size, *, mode: str = "default",
                     fix_intrinsic: bool = False, alpha: float = 1.0, views=None, skipped=(),
                     line_time_s: float | None = None, min_views: int = 3) -> StereoCalibrationResult:
    """Calibrate a stereo pair from checkerboard corner detections.

    Parameters
    ----------
    object_points : array_like, shape (M, 3)
        Board corners in the board frame, metres (:func:`board_object_points`);
        the same for every view.
    corners_left, corners_right : sequence of array_like, shape (M, 2)
        Detected corners per view, pixels.
    image_size : tuple of int
        ``(width, height)``.
    mode : {"default", "opencv-sample"}
        See the module docstring.
    fix_intrinsic : bool
        ``mode="default"`` only: keep the per-camera intrinsics fixed in the
        stereo step.
    alpha : float
        Free scaling of :func:`cv2.stereoRectify` (1 keeps all pixels, like the
        sample; 0 crops to valid pixels; -1 is OpenCV's default).
    views : list of str, optional
        View names for the report.
    skipped : sequence of (str, str)
        Views left out upstream, carried into the result.
    line_time_s : float, optional
        Rolling-shutter row time stored with both cameras.
    min_views : int
        Fewer valid views raise :class:`TudorVisionError`.

    Returns
    -------
    StereoCalibrationResult

    Raises
    ------
    TudorVisionError
        If there are too few views.
    ValueError
        If ``mode`` is unknown or shapes are inconsistent.
    """
    if mode not in ("default", "opencv-sample"):
        raise ValueError(f"mode: expected 'default' or 'opencv-sample', got {mode!r}")
    nv = len(corners_left)
    if nv != len(corners_right):
        raise ValueError(f"corners_right: expected {nv} views like corners_left, got {len(corners_right)}")
    if nv < min_views:
        raise TudorVisionError(f"too few valid checkerboard views: {nv} (need at least {min_views}; "
                               f"{len(skipped)} skipped)")
    obj = np.asarray(object_points, dtype=np.float32).reshape(-1, 3)
    objs = [obj] * nv
    pl = [np.asarray(c, dtype=np.float32).reshape(-1, 1, 2) for c in corners_left]
    pr = [np.asarray(c, dtype=np.float32).reshape(-1, 1, 2) for c in corners_right]
    for i, (a, b) in enumerate(zip(pl, pr)):
        if len(a) != len(obj) or len(b) != len(obj):
            raise ValueError(f"corners_left[{i}]: expected {len(obj)} corners, got {len(a)} / {len(b)}")
    size = (int(image_size[0]), int(image_size[1]))
    rms_l = rms_r = float("nan")
    if mode == "default":
        rms_l, K1, D1, *_ = cv2.calibrateCamera(objs, pl, size, None, None)
        rms_r, K2, D2, *_ = cv2.calibrateCamera(objs, pr, size, None, None)
        flags = cv2.CALIB_FIX_INTRINSIC if fix_intrinsic else cv2.CALIB_USE_INTRINSIC_GUESS
    else:
        K1 = cv2.initCameraMatrix2D(objs, pl, size, 0)
        K2 = cv2.initCameraMatrix2D(objs, pr, size, 0)
        D1, D2 = np.zeros(5), np.zeros(5)
        flags = (cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_USE_INTRINSIC_GUESS
                 | cv2.CALIB_SAME_FOCAL_LENGTH | cv2.CALIB_FIX_K3)
    out = cv2.stereoCalibrateExtended(objs, pl, pr, K1, D1, K2, D2, size, None, None,
                                      flags=flags, criteria=_STEREO_CRITERIA)
    rms, K1, D1, K2, D2, R, T, E, F, _, _, per_view = out
    D1, D2 = np.asarray(D1, float).ravel()[:5], np.asarray(D2, float).ravel()[:5]
    T = np.asarray(T, float).ravel()
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(K1, D1, K2, D2, size, R, T.reshape(3, 1),
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha,
                                                newImageSize=size)
    cams = {"left": CameraModel(K=K1, dist=D1, width=size[0], height=size[1], line_time_s=line_time_s),
            "right": CameraModel(K=K2, dist=D2, width=size[0], height=size[1], line_time_s=line_time_s)}
    stereo = StereoExtrinsics(R=R, T=T, R1=R1, R2=R2, P1=P1, P2=P2, Q=Q)
    epi = _epipolar_error(pl, pr, K1, D1, K2, D2, F)
    meta = {"source": "tudorvision calib stereo", "mode": mode, "views": nv, "skipped": len(skipped),
            "rms_px": float(rms), "epipolar_error_px": float(epi)}
    calibration = Calibration(cameras=cams, stereo=stereo, metadata=meta)
    return StereoCalibrationResult(
        calibration=calibration, rms_px=float(rms), rms_left_px=float(rms_l), rms_right_px=float(rms_r),
        per_view_rms_px=np.asarray(per_view, float).reshape(nv, 2), epipolar_error_px=epi,
        views=list(views) if views is not None else [f"view{i}" for i in range(nv)],
        skipped=list(skipped), mode=mode)


def calibrate_stereo_from_images(left_paths, right_paths, board: tuple[int, int], square_m: float, *,
                                 show_progress: bool | None = None, **kwargs) -> StereoCalibrationResult:
    """Detect the board in image pairs and calibrate (see :func:`calibrate_stereo` for ``kwargs``).

    Parameters
    ----------
    left_paths, right_paths : sequence of str or Path
        Left and right image files, paired by position.
    board : tuple of int
        Inner corners ``(columns, rows)``, e.g. from :func:`parse_board`.
    square_m : float
        Square edge length in metres.
    show_progress : bool, optional
        Draw a progress bar on stderr over the pairs; ``None`` draws it only
        when stderr is a terminal.
    **kwargs
        Passed on to :func:`calibrate_stereo` (``mode``, ``fix_intrinsic``,
        ``alpha``, ``line_time_s``, ``min_views``).

    Returns
    -------
    StereoCalibrationResult
        The calibration, with the pairs that were skipped (board not found in
        both images, unreadable or differently sized images).

    Raises
    ------
    ValueError
        If the path lists differ in length or are empty, or ``square_m`` is
        not positive.
    TudorVisionError
        If fewer than ``min_views`` pairs show the board in both images.
    """
    det = detect_board_pairs(left_paths, right_paths, board, show_progress=show_progress)
    return calibrate_stereo(board_object_points(board, square_m), det.corners_left, det.corners_right,
                            det.image_size, views=det.names, skipped=det.skipped, **kwargs)


def plot_view_errors(result: StereoCalibrationResult, path) -> Path:
    """Bar plot of the per-view RMS reprojection errors (left and right) as PNG.

    matplotlib is imported here; the plot is drawn on its own
    :class:`matplotlib.figure.Figure`, so the global backend is left alone.

    Parameters
    ----------
    result : StereoCalibrationResult
        Calibration result; ``per_view_rms_px`` (shape (V, 2), pixels, left
        and right) and ``views`` are plotted.
    path : str or Path
        Output PNG; parent directories are created.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TudorVisionError
        If matplotlib is not installed.
    """
    try:
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover
        raise TudorVisionError("plotting needs matplotlib: pip install matplotlib") from None
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    err = result.per_view_rms_px
    n = len(err)
    x = np.arange(n)
    fig = Figure(figsize=(max(6.0, 0.45 * n + 2), 3.8))
    ax = fig.add_subplot()
    ax.bar(x - 0.2, err[:, 0], 0.4, label="left")
    ax.bar(x + 0.2, err[:, 1], 0.4, label="right")
    ax.axhline(result.rms_px, color="k", ls="--", lw=1, label=f"overall {result.rms_px:.3f} px")
    ax.set_xticks(x)
    ax.set_xticklabels([v.split("|")[0] for v in result.views], rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("RMS reprojection error [px]")
    ax.set_title(f"stereo calibration: {n} views, {len(result.skipped)} skipped")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
