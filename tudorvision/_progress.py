"""A dependency-free progress bar for long CLI work (writes to stderr)."""
from __future__ import annotations

import sys
import time

__all__ = ["progress"]


def progress(iterable, *, total: int | None = None, desc: str = "", enabled: bool | None = None,
             stream=None):
    """Yield from ``iterable`` while drawing a one-line progress bar on stderr.

    The bar is drawn only when ``stream`` is a terminal (or ``enabled=True``),
    so logs and tests stay clean.

    Examples
    --------
    >>> list(progress(range(3), enabled=False))
    [0, 1, 2]
    """
    stream = stream or sys.stderr
    if enabled is None:
        enabled = hasattr(stream, "isatty") and stream.isatty()
    if total is None:
        try:
            total = len(iterable)
        except TypeError:
            total = None
    if not enabled:
        yield from iterable
        return
    t0 = time.monotonic()
    last = 0.0
    n = 0
    for n, item in enumerate(iterable, 1):
        yield item
        now = time.monotonic()
        if now - last > 0.1 or (total is not None and n == total):
            last = now
            rate = n / max(now - t0, 1e-9)
            if total:
                frac = n / total
                bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
                stream.write(f"\r{desc} [{bar}] {n}/{total} {rate:6.1f}/s")
            else:
                stream.write(f"\r{desc} {n} {rate:6.1f}/s")
            stream.flush()
    stream.write("\n")
    stream.flush()
