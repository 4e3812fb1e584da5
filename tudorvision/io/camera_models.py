"""The parts of a calibration: camera intrinsics, stereo extrinsics, the depth-noise polynomial.

:class:`~tudorvision.io.calibration.Calibration` holds them and reads and
writes the project's calibration file.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .._checks import check_array, check_transform

__all__ = ["CameraModel", "StereoExtrinsics", "DepthModel", "RECTIFICATION_SHAPES", "UNITS_TO_M"]

UNITS_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}
#: Optional rectification matrices of :class:`StereoExtrinsics` and their shapes, in field order.
RECTIFICATION_SHAPES = MappingProxyType({"R1": (3, 3), "R2": (3, 3), "P1": (3, 4), "P2": (3, 4), "Q": (4, 4)})


def frozen_array(a: np.ndarray) -> np.ndarray:
    """A read-only float64 copy of ``a`` (calibration parts are immutable)."""
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


def optional_allclose(a, b, atol) -> bool:
    """``np.allclose`` for optional arrays: both None, or both given and close within ``atol``."""
    if a is None or b is None:
        return a is None and b is None
    return np.shape(a) == np.shape(b) and bool(np.allclose(a, b, atol=atol, rtol=0))


# ----------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True, kw_only=True, eq=False)
class CameraModel:
    """Pinhole camera with Brown–Conrady (OpenCV plumb_bob) distortion.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsic matrix in pixels (u right, v down, origin at the centre of
        the top-left pixel as in OpenCV).
    dist : array_like, shape (5,)
        ``[k1, k2, p1, p2, k3]``.
    width, height : int
        Image size in pixels.
    line_time_s : float, optional
        Rolling-shutter time between consecutive rows in seconds.
    T_ref_cam : array_like, shape (4, 4), optional
        Camera pose in a rig reference frame, ``p_ref = T_ref_cam @ p_cam``.

    Examples
    --------
    >>> cam = CameraModel(K=[[500, 0, 320], [0, 500, 240], [0, 0, 1]], width=640, height=480)
    >>> cam.fx, cam.cx
    (500.0, 320.0)
    """

    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    width: int
    height: int
    line_time_s: float | None = None
    T_ref_cam: np.ndarray | None = None

    def __post_init__(self):
        K = check_array(self.K, "K", (3, 3))
        if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
            raise ValueError(f"K: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, "
                             f"got {K.tolist()}")
        object.__setattr__(self, "K", frozen_array(K))
        object.__setattr__(self, "dist", frozen_array(check_array(self.dist, "dist", (5,))))
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or int(v) <= 0:
                raise ValueError(f"{name}: expected a positive integer, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.line_time_s is not None:
            lt = float(self.line_time_s)
            if not math.isfinite(lt) or lt < 0:
                raise ValueError(f"line_time_s: expected a non-negative number, got {lt}")
            object.__setattr__(self, "line_time_s", lt)
        if self.T_ref_cam is not None:
            object.__setattr__(self, "T_ref_cam", frozen_array(check_transform(self.T_ref_cam, "T_ref_cam")))

    fx = property(lambda self: float(self.K[0, 0]), doc="Focal length along u, pixels.")
    fy = property(lambda self: float(self.K[1, 1]), doc="Focal length along v, pixels.")
    cx = property(lambda self: float(self.K[0, 2]), doc="Principal point u, pixels.")
    cy = property(lambda self: float(self.K[1, 2]), doc="Principal point v, pixels.")
    size = property(lambda self: (self.width, self.height), doc="``(width, height)`` in pixels.")

    def replace(self, **changes) -> "CameraModel":
        """A copy with some fields changed.

        Parameters
        ----------
        **changes
            New values of fields (``K``, ``dist``, ``width``, ``height``,
            ``line_time_s``, ``T_ref_cam``), in the units of the class
            (pixels, seconds, metres).

        Returns
        -------
        CameraModel
            The copy, validated like a new camera.

        Raises
        ------
        TypeError
            If a name is not a field.
        ValueError
            If a new value is invalid.

        Examples
        --------
        >>> cam = CameraModel(K=[[500, 0, 320], [0, 500, 240], [0, 0, 1]], width=640, height=480)
        >>> cam.replace(width=320).size
        (320, 480)
        """
        return dataclasses.replace(self, **changes)

    def allclose(self, other: "CameraModel", atol: float = 1e-9) -> bool:
        """Field-wise comparison with absolute tolerance.

        Parameters
        ----------
        other : CameraModel
            Camera to compare with; any other type compares unequal.
        atol : float
            Absolute tolerance on every number (pixels for ``K``, seconds for
            ``line_time_s``, metres for the translation of ``T_ref_cam``).

        Returns
        -------
        bool
            True when the image sizes are equal and ``K``, ``dist``,
            ``line_time_s`` and ``T_ref_cam`` agree within ``atol`` (optional
            fields must be both absent or both present).
        """
        return (isinstance(other, CameraModel) and self.size == other.size
                and optional_allclose(self.K, other.K, atol) and optional_allclose(self.dist, other.dist, atol)
                and optional_allclose(self.line_time_s, other.line_time_s, atol)
                and optional_allclose(self.T_ref_cam, other.T_ref_cam, atol))


@dataclass(frozen=True, kw_only=True, eq=False)
class StereoExtrinsics:
    """Stereo pair geometry, OpenCV convention ``x_right = R @ x_left + T``.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Rotation from the left to the right camera frame.
    T : array_like, shape (3,)
        Translation in metres (the left camera centre in the right frame).
    left, right : str
        Names of the two cameras in :attr:`Calibration.cameras`.
    R1, R2 : array_like, shape (3, 3), optional
        Rectifying rotations (``cv2.stereoRectify``).
    P1, P2 : array_like, shape (3, 4), optional
        Rectified projection matrices; ``P2[0, 3] = fx' * Tx`` in pixel·metres.
    Q : array_like, shape (4, 4), optional
        Disparity-to-depth matrix, metres.
    """

    R: np.ndarray
    T: np.ndarray
    left: str = "left"
    right: str = "right"
    R1: np.ndarray | None = None
    R2: np.ndarray | None = None
    P1: np.ndarray | None = None
    P2: np.ndarray | None = None
    Q: np.ndarray | None = None

    def __post_init__(self):
        R = check_array(self.R, "R", (3, 3))
        T4 = np.eye(4)
        T4[:3, :3] = R
        check_transform(T4, "R")
        object.__setattr__(self, "R", frozen_array(R))
        object.__setattr__(self, "T", frozen_array(check_array(self.T, "T", (3,))))
        for name, shape in RECTIFICATION_SHAPES.items():
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, frozen_array(check_array(v, name, shape)))

    @property
    def baseline_m(self) -> float:
        """Distance between the camera centres in metres."""
        return float(np.linalg.norm(self.T))

    @property
    def T_right_left(self) -> np.ndarray:
        """4x4 transform with ``p_right = T_right_left @ p_left``."""
        T = np.eye(4)
        T[:3, :3] = self.R
        T[:3, 3] = self.T
        return T

    @property
    def has_rectification(self) -> bool:
        return all(getattr(self, n) is not None for n in RECTIFICATION_SHAPES)

    def allclose(self, other: "StereoExtrinsics", atol: float = 1e-9) -> bool:
        """Compare the geometry with absolute tolerance.

        Parameters
        ----------
        other : StereoExtrinsics
            Extrinsics to compare with; any other type compares unequal.
        atol : float
            Absolute tolerance on every number (metres for ``T``).

        Returns
        -------
        bool
            True when the camera names are equal and ``R``, ``T`` and the
            rectification matrices agree within ``atol`` (each optional
            matrix both absent or both present).
        """
        return (isinstance(other, StereoExtrinsics) and (self.left, self.right) == (other.left, other.right)
                and all(optional_allclose(getattr(self, n), getattr(other, n), atol)
                        for n in ("R", "T", *RECTIFICATION_SHAPES)))


@dataclass(frozen=True, kw_only=True, eq=False)
class DepthModel:
    """Depth noise model ``sigma_z(z)`` as a polynomial (highest power first).

    Parameters
    ----------
    sigma_z_poly : array_like, shape (K,)
        Coefficients for ``np.polyval`` with z in ``z_unit`` giving sigma in
        ``sigma_unit``.
    z_unit, sigma_unit : str
        ``"m"``, ``"cm"`` or ``"mm"``.
    valid_range_m : tuple of float, optional
        Usable depth range in metres.

    Examples
    --------
    >>> dm = DepthModel(sigma_z_poly=[0.51, -2.1, 5.12, -2.18], sigma_unit="cm")
    >>> round(float(dm.sigma_m(2.0)), 4)
    0.0374
    """

    sigma_z_poly: np.ndarray
    z_unit: str = "m"
    sigma_unit: str = "m"
    valid_range_m: tuple[float, float] | None = None

    def __post_init__(self):
        object.__setattr__(self, "sigma_z_poly",
                           frozen_array(check_array(self.sigma_z_poly, "sigma_z_poly", (None,))))
        for name in ("z_unit", "sigma_unit"):
            if getattr(self, name) not in UNITS_TO_M:
                raise ValueError(f"{name}: expected one of {sorted(UNITS_TO_M)}, "
                                 f"got {getattr(self, name)!r}")
        if self.valid_range_m is not None:
            lo, hi = check_array(self.valid_range_m, "valid_range_m", (2,))
            if not 0 <= lo < hi:
                raise ValueError(f"valid_range_m: expected 0 <= min < max, got {[lo, hi]}")
            object.__setattr__(self, "valid_range_m", (float(lo), float(hi)))

    def sigma_m(self, z_m):
        """Depth standard deviation in metres at depth ``z_m`` (metres, any shape).

        Parameters
        ----------
        z_m : float or array_like
            Depth (z along the optical axis), metres, any shape.

        Returns
        -------
        float or ndarray
            Standard deviation of the depth in metres, same shape as ``z_m``;
            the polynomial is evaluated outside ``valid_range_m`` as well.
        """
        z = np.asarray(z_m, dtype=np.float64) / UNITS_TO_M[self.z_unit]
        return np.polyval(self.sigma_z_poly, z) * UNITS_TO_M[self.sigma_unit]

    def noise_model(self, *, default_range_m=(0.6, 6.0)):
        """The same polynomial in SI units as the package's noise model.

        Parameters
        ----------
        default_range_m : (float, float)
            Fitted depth range to use when the file gives none, metres.

        Returns
        -------
        tudorvision.sensors.DepthNoiseModel
            Coefficients converted to z and sigma in metres.

        Examples
        --------
        >>> dm = DepthModel(sigma_z_poly=[0.51, -2.1, 5.12, -2.18], sigma_unit="cm")
        >>> round(float(dm.noise_model().sigma_m(2.0)), 4)
        0.0374
        """
        from ..sensors import DepthNoiseModel

        zu, su = UNITS_TO_M[self.z_unit], UNITS_TO_M[self.sigma_unit]
        deg = len(self.sigma_z_poly) - 1
        coeffs = tuple(float(c) * su / zu ** (deg - i) for i, c in enumerate(self.sigma_z_poly))
        rng = tuple(self.valid_range_m) if self.valid_range_m is not None else tuple(default_range_m)
        return DepthNoiseModel(coeffs=coeffs, z_range_m=rng)

    def allclose(self, other: "DepthModel", atol: float = 1e-9) -> bool:
        """Compare the noise model with absolute tolerance.

        Parameters
        ----------
        other : DepthModel
            Model to compare with; any other type compares unequal.
        atol : float
            Absolute tolerance on the coefficients and the range (metres).

        Returns
        -------
        bool
            True when the units are equal and the coefficients and
            ``valid_range_m`` agree within ``atol``. The same curve written
            in other units compares unequal.
        """
        return (isinstance(other, DepthModel) and (self.z_unit, self.sigma_unit) == (other.z_unit, other.sigma_unit)
                and optional_allclose(self.sigma_z_poly, other.sigma_z_poly, atol)
                and optional_allclose(self.valid_range_m, other.valid_range_m, atol))
