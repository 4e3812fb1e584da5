"""Depth sensor basics shared by every layer: raw <-> metric depth and the depth-noise model.

Bottom layer: imports only :mod:`tudorvision._checks` and numpy.

Conventions
-----------
Depth images hold z along the optical axis (not the range along the ray), as
Kinect-type sensors and the TUM benchmark do. Metric depth is in metres with
``NaN`` marking invalid pixels; raw depth is ``uint16`` in ``1 / depth_scale``
metres with ``0`` marking invalid pixels (1000 raw units per metre for
millimetres, 5000 for TUM).

The Kinect noise fit of the seed (figure 2.5) is
``sigma_z(z) = 0.51 z^3 - 2.1 z^2 + 5.12 z - 2.18`` with z in metres. The
unit of sigma is not stated next to the fit; the lab reads it in
**millimetres** (BRIEF, issue 18): 1.35 mm at 1 m, 3.7 mm at 2 m, 35 mm at
5 m, as published Kinect noise studies (Khoshelham and Elberink 2012,
Nguyen et al. 2012); read in centimetres it would be 7-9 times larger than
those. :data:`KINECT_SIGMA_UNIT` names that reading (until issue 18 the lab
read it in centimetres).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from ._checks import TudorVisionError

__all__ = [
    "KINECT_SIGMA_Z_COEFFS", "KINECT_SIGMA_UNIT", "KINECT_RANGE_M", "SIGMA_UNITS_PER_M", "DEFAULT_SIGMA_FLOOR_M",
    "PLAUSIBLE_DEPTH_RANGE_M", "DepthNoiseModel", "KINECT_DEPTH_NOISE",
    "depth_m_from_raw", "raw_from_depth_m",
]

#: The seed's Kinect fit of sigma_z(z), highest power first, z in metres,
#: sigma in :data:`KINECT_SIGMA_UNIT`. The only place the polynomial is typed.
KINECT_SIGMA_Z_COEFFS = (0.51, -2.1, 5.12, -2.18)

#: Units of sigma per metre, by unit name.
SIGMA_UNITS_PER_M = {"m": 1.0, "cm": 100.0, "mm": 1000.0}

#: How the lab reads the fit's sigma: millimetres (BRIEF; centimetres before issue 18).
KINECT_SIGMA_UNIT = "mm"

#: Default lower bound of sigma, metres: below the cubic's value at the near end
#: of its range (0.25 mm at 0.6 m), so the model is the seed's fit over 0.6-6 m;
#: it only guards the depths below about 0.59 m (the cubic turns negative below 0.52 m).
DEFAULT_SIGMA_FLOOR_M = 2e-4

#: Depth range of the Kinect fit and of the simulated sensor, metres.
KINECT_RANGE_M = (0.6, 6.0)

#: Plausible median scene depth of a depth image, metres
#: (used by ``depth_m_from_raw(..., check_range=True)``).
PLAUSIBLE_DEPTH_RANGE_M = (0.1, 20.0)

_UINT16_MAX = 65535


@dataclass(frozen=True, kw_only=True)
class DepthNoiseModel:
    """Polynomial depth noise model ``sigma_z(z)``, SI units throughout.

    Parameters
    ----------
    coeffs : tuple of float
        Polynomial coefficients, highest power first (``np.polyval``);
        z in metres, sigma in metres. Default: the seed's Kinect fit read in
        :data:`KINECT_SIGMA_UNIT`, converted to metres.
    z_range_m : tuple of 2 floats
        Depth range the model was fitted on, metres (informative; evaluation
        is not clipped).
    floor_m : float
        Lower bound of the returned sigma, metres, >= 0 (the Kinect cubic
        turns negative below about 0.52 m). Default
        :data:`DEFAULT_SIGMA_FLOOR_M` (0.2 mm): the Kinect model stays above
        it inside :data:`KINECT_RANGE_M` (its minimum there is 0.25 mm at
        0.6 m, below the sensor's 1 mm output step).
    extra : dict
        Further entries read from a file and kept for writing it back
        (not compared, not used in evaluation).

    Raises
    ------
    ValueError
        Non-finite or no coefficients, a negative floor, a bad range.

    Examples
    --------
    >>> m = DepthNoiseModel()          # the seed's fit, read in mm
    >>> round(float(m.sigma_m(1.0)), 5)
    0.00135
    >>> m.sigma_m([0.3, 2.0, 5.0]).round(5).tolist()     # floored below the fit's range
    [0.0002, 0.00374, 0.03467]
    """

    coeffs: tuple = tuple(c / SIGMA_UNITS_PER_M[KINECT_SIGMA_UNIT] for c in KINECT_SIGMA_Z_COEFFS)
    z_range_m: tuple = KINECT_RANGE_M
    floor_m: float = DEFAULT_SIGMA_FLOOR_M
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        c = tuple(float(x) for x in self.coeffs)
        if not c or not all(math.isfinite(x) for x in c):
            raise ValueError(f"coeffs: expected finite polynomial coefficients, got {self.coeffs}")
        object.__setattr__(self, "coeffs", c)
        zr = tuple(float(x) for x in self.z_range_m)
        if len(zr) != 2 or not 0 <= zr[0] <= zr[1]:
            raise ValueError(f"z_range_m: expected (min, max) with 0 <= min <= max, got {self.z_range_m}")
        object.__setattr__(self, "z_range_m", zr)
        if not (math.isfinite(self.floor_m) and self.floor_m >= 0):
            raise ValueError(f"floor_m: expected a finite value >= 0, got {self.floor_m}")

    def sigma_m(self, z_m) -> np.ndarray:
        """Depth standard deviation at depth ``z_m``.

        Parameters
        ----------
        z_m : array_like, any shape
            Depth along the optical axis, metres.

        Returns
        -------
        sigma_m : ndarray, same shape as ``z_m``, float64
            Standard deviation in metres, at least ``floor_m``.

        Examples
        --------
        >>> DepthNoiseModel(coeffs=(0.01, 0.0)).sigma_m([1.0, 2.0]).tolist()   # 1 cm per metre
        [0.01, 0.02]
        """
        return np.maximum(np.polyval(self.coeffs, np.asarray(z_m, dtype=np.float64)), self.floor_m)

    def noisy_depth_m(self, depth_m, rng: np.random.Generator) -> np.ndarray:
        """Add zero-mean Gaussian noise of std ``sigma_m(depth_m)`` to a depth image.

        Draws ``rng.standard_normal(depth_m.shape)`` once, in C order.

        Parameters
        ----------
        depth_m : array_like, any shape
            True depth, metres.
        rng : numpy.random.Generator
            Source of the noise.

        Returns
        -------
        ndarray, same shape, float64
            ``depth_m + sigma_m(depth_m) * N(0, 1)``, metres.

        Examples
        --------
        >>> d = DepthNoiseModel().noisy_depth_m(np.full(10000, 2.0), np.random.default_rng(0))
        >>> abs(float(d.std()) / 0.00374 - 1) < 0.03
        True
        """
        d = np.asarray(depth_m, dtype=np.float64)
        return d + self.sigma_m(d) * rng.standard_normal(d.shape)

    def as_dict(self) -> dict:
        """Plain dict for calibration files (``sigma_z_coeffs_m``: highest power first).

        Returns
        -------
        dict
            ``sigma_z_coeffs_m``, ``z_range_m``, ``floor_m`` and a ``units`` note.

        Examples
        --------
        >>> DepthNoiseModel(coeffs=(0.01, 0.0)).as_dict()["sigma_z_coeffs_m"]
        [0.01, 0.0]
        """
        return {"sigma_z_coeffs_m": list(self.coeffs), "z_range_m": list(self.z_range_m),
                "floor_m": self.floor_m, "units": "z in m, sigma in m, highest power first"}

    @classmethod
    def from_dict(cls, doc: dict) -> "DepthNoiseModel":
        """Inverse of :meth:`as_dict`.

        Parameters
        ----------
        doc : dict
            As written by :meth:`as_dict` (e.g. read from a calibration file).

        Returns
        -------
        DepthNoiseModel

        Raises
        ------
        TudorVisionError
            A missing or invalid entry.

        Examples
        --------
        >>> DepthNoiseModel.from_dict(KINECT_DEPTH_NOISE.as_dict()) == KINECT_DEPTH_NOISE
        True
        """
        try:
            return cls(coeffs=tuple(doc["sigma_z_coeffs_m"]),
                       z_range_m=tuple(doc.get("z_range_m", KINECT_RANGE_M)),
                       floor_m=float(doc.get("floor_m", DEFAULT_SIGMA_FLOOR_M)))
        except (KeyError, TypeError) as exc:
            raise TudorVisionError(f"depth model: missing or invalid entry {exc}") from None


#: The seed's Kinect fit (sigma read in :data:`KINECT_SIGMA_UNIT`, millimetres), in metres.
KINECT_DEPTH_NOISE = DepthNoiseModel()


def _check_depth_scale(depth_scale) -> float:
    if isinstance(depth_scale, bool) or not isinstance(depth_scale, numbers.Real) \
            or not math.isfinite(depth_scale) or depth_scale <= 0:
        raise ValueError(f"depth_scale: expected a positive number of raw units per metre, got {depth_scale!r}")
    return float(depth_scale)


def depth_m_from_raw(depth_raw, depth_scale: float, *, dtype=np.float32, check_range: bool = False) -> np.ndarray:
    """Metric depth from raw depth; raw values <= 0 (invalid) become NaN.

    Parameters
    ----------
    depth_raw : array_like, any shape (usually (H, W)), integer
        Raw depth in ``1 / depth_scale`` metres; 0 marks invalid pixels.
    depth_scale : float
        Raw units per metre (1000 for millimetres, 5000 for TUM).
    dtype : numpy dtype, optional
        Output type; float32 by default (half the memory of float64, still
        below 0.5 um resolution at 6 m).
    check_range : bool, optional
        Require a valid pixel and a plausible median valid depth
        (:data:`PLAUSIBLE_DEPTH_RANGE_M`); catches a wrong ``depth_scale``.

    Returns
    -------
    depth_m : ndarray, same shape as ``depth_raw``, ``dtype``
        Depth (z) in metres, NaN where invalid.

    Raises
    ------
    ValueError
        ``depth_scale`` not a positive finite number.
    TudorVisionError
        With ``check_range``: no valid pixel, or an implausible median depth
        (the message suggests a scale that would give a plausible depth).

    Examples
    --------
    >>> depth_m_from_raw(np.array([[0, 1500]], np.uint16), 1000.0)
    array([[nan, 1.5]], dtype=float32)
    >>> depth_m_from_raw(np.array([[0, 1500]], np.uint16), 1.0, check_range=True)
    Traceback (most recent call last):
    ...
    tudorvision._checks.TudorVisionError: depth_scale=1 gives an implausible median depth of 1500 m (expected 0.1-20 m); did you mean depth_scale=1000 (median 1.50 m)?
    """
    scale = _check_depth_scale(depth_scale)
    raw = np.asarray(depth_raw)
    dtype = np.dtype(dtype)
    out = raw.astype(dtype) / dtype.type(scale)
    out[raw <= 0] = np.nan
    if check_range:
        if not np.any(np.isfinite(out)):
            raise TudorVisionError("depth_raw: depth image has no valid pixel (all zero or invalid)")
        med = float(np.nanmedian(out.astype(np.float64)))
        lo, hi = PLAUSIBLE_DEPTH_RANGE_M
        if not lo <= med <= hi:
            raw_med = med * scale
            hint = ""
            for cand in (1000.0, 5000.0, 1.0, 10000.0, 100.0):
                if lo <= raw_med / cand <= hi and cand != scale:
                    hint = f"; did you mean depth_scale={cand:g} (median {raw_med / cand:.2f} m)?"
                    break
            raise TudorVisionError(
                f"depth_scale={scale:g} gives an implausible median depth of {med:.4g} m "
                f"(expected {lo:g}-{hi:g} m){hint}")
    return out


def raw_from_depth_m(depth_m, depth_scale: float, *, out_of_range: str = "invalid") -> np.ndarray:
    """Raw uint16 depth from metres, rounded to the nearest raw unit.

    NaN, infinite and non-positive depths (invalid) become 0, as do depths
    that round to 0 raw units.

    Parameters
    ----------
    depth_m : array_like, any shape (usually (H, W))
        Depth (z) in metres; NaN or <= 0 marks invalid pixels.
    depth_scale : float
        Raw units per metre (1000 for millimetres, 5000 for TUM).
    out_of_range : {"invalid", "raise"}, optional
        A depth beyond 16 bits at this scale (``depth_m * depth_scale``
        rounds above 65535) becomes 0 like a sensor out of range
        (``"invalid"``, default) or raises (``"raise"``).

    Returns
    -------
    depth_raw : ndarray, same shape as ``depth_m``, uint16
        0 where invalid.

    Raises
    ------
    ValueError
        ``depth_scale`` not a positive finite number; an unknown
        ``out_of_range``; with ``out_of_range="raise"``, a depth that does not
        fit in 16 bits.

    Examples
    --------
    >>> raw_from_depth_m(np.array([[np.nan, 1.2345, -1.0, 70.0]]), 1000.0)
    array([[   0, 1234,    0,    0]], dtype=uint16)
    >>> raw_from_depth_m(np.array([70.0]), 1000.0, out_of_range="raise")
    Traceback (most recent call last):
    ...
    ValueError: depth_m: 70.000 m exceeds 16 bits at depth_scale=1000
    """
    scale = _check_depth_scale(depth_scale)
    if out_of_range not in ("invalid", "raise"):
        raise ValueError(f"out_of_range: expected 'invalid' or 'raise', got {out_of_range!r}")
    d = np.asarray(depth_m, dtype=np.float64) * scale
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(d) & (d >= 0.5)
        too_far = ok & (d >= _UINT16_MAX + 0.5)
    if out_of_range == "raise" and np.any(too_far):
        raise ValueError(f"depth_m: {float(np.max(d[too_far])) / scale:.3f} m exceeds 16 bits "
                         f"at depth_scale={scale:g}")
    ok &= ~too_far
    out = np.zeros(d.shape, np.uint16)
    out[ok] = np.rint(d[ok]).astype(np.uint16)
    return out
