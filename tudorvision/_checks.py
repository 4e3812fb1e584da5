"""Boundary checks shared by all subpackages.

Each ``check_*`` converts to float64, validates and raises ``ValueError``
naming the argument, the expected and the actual shape.
"""
from __future__ import annotations

import numpy as np

__all__ = ["TudorVisionError", "check_array", "check_points", "check_vector", "check_transform", "check_mass"]


class TudorVisionError(ValueError):
    """A user-facing error (bad file, bad argument). The CLI prints it as one line."""


def check_array(value, name: str, shape: tuple, *, finite: bool = True) -> np.ndarray:
    """Convert ``value`` to float64 and check its shape.

    Parameters
    ----------
    value : array_like
        The input.
    name : str
        Argument name used in the error message.
    shape : tuple
        Expected shape; ``None`` entries match any length.
    finite : bool
        Also require all entries to be finite.

    Returns
    -------
    ndarray
        float64 array.

    Raises
    ------
    ValueError
        If the shape does not match or entries are not finite.

    Examples
    --------
    >>> check_array([1, 2, 3], "p", (3,)).dtype
    dtype('float64')
    """
    arr = np.asarray(value, dtype=np.float64)
    ok = arr.ndim == len(shape) and all(s is None or s == a for s, a in zip(shape, arr.shape))
    if not ok:
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return arr


def check_points(value, name: str, dim: int = 3, *, finite: bool = True) -> np.ndarray:
    """Check an ``(N, dim)`` point array (a single ``(dim,)`` point is promoted).

    Examples
    --------
    >>> check_points([0.0, 1.0, 2.0], "p_base").shape
    (1, 3)
    """
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    return check_array(arr, name, (None, dim), finite=finite)


def check_vector(value, name: str, n: int) -> np.ndarray:
    """Check a length-``n`` vector."""
    return check_array(value, name, (n,))


def check_mass(value, name: str = "payload_kg", *, max_kg: float = float("inf")) -> float:
    """Check a mass in kg: finite, in ``[0, max_kg]``; returns it as a float.

    Examples
    --------
    >>> check_mass(0.35)
    0.35
    """
    try:
        m = float(value)
    except (TypeError, ValueError):
        m = float("nan")
    if not (np.isfinite(m) and 0.0 <= m <= max_kg):
        raise ValueError(f"{name}: expected a finite mass in [0, {max_kg:g}] kg, got {value!r}")
    return m


def check_transform(value, name: str) -> np.ndarray:
    """Check a 4x4 homogeneous rigid transform (orthonormal rotation, last row 0 0 0 1).

    Examples
    --------
    >>> check_transform(np.eye(4), "T_base_cam").shape
    (4, 4)
    """
    T = check_array(value, name, (4, 4))
    R = T[:3, :3]
    if not np.allclose(T[3], [0, 0, 0, 1], atol=1e-9):
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1], got {T[3].tolist()}")
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError(f"{name}: rotation part is not a proper orthonormal matrix")
    return T
