"""Argument parsing shared by the CLI's commands."""
from __future__ import annotations

import math

from .._checks import TudorVisionError

__all__ = ["parse_floats"]


def parse_floats(text: str, name: str, n: int | None = None, example: str = "") -> list[float]:
    """Comma-separated numbers of option ``name``; a one-line error on anything else.

    Parameters
    ----------
    text : str
        The option's value, e.g. ``"0,45,-45"``.
    name : str
        The option, as the user typed it (``"--at"``), named in the error.
    n : int, optional
        How many numbers are expected.
    example : str, optional
        A valid value quoted in the error.

    Returns
    -------
    list of float

    Raises
    ------
    TudorVisionError
        If a part is not a finite number or the count is not ``n``.

    Examples
    --------
    >>> parse_floats("0.001, 0.003", "--servo-time-constants-s", 2)
    [0.001, 0.003]
    >>> parse_floats("0,45,nan", "--from", 3)
    Traceback (most recent call last):
    ...
    tudorvision._checks.TudorVisionError: --from: expected 3 finite numbers, got '0,45,nan'
    """
    like = f" like {example}" if example else ""
    count = "" if n is None else f"{n} "
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise TudorVisionError(f"{name}: expected {count}comma-separated numbers{like}, got {text!r}") from None
    if n is not None and len(vals) != n:
        raise TudorVisionError(f"{name}: expected {count}comma-separated numbers{like}, got {text!r}")
    if not all(math.isfinite(v) for v in vals):
        raise TudorVisionError(f"{name}: expected {count}finite numbers, got {text!r}")
    return vals
