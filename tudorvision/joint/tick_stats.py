"""Tick statistics of the server's wall-clock loop: intervals between control ticks over the last second.

:func:`tick_percentiles` is the pure summary; :class:`TickStats` keeps the
recent intervals and caches the summary so a State request stays cheap.

Examples
--------
>>> tick_percentiles([0.002, 0.001, 0.003])
(0.002, 0.003, 0.003)
>>> stats = TickStats()
>>> for now in (0.0, 0.002, 0.004, 0.007):
...     stats.record(now)
>>> [round(x, 6) for x in stats.summary(now=0.01)]
[0.002, 0.003, 0.003]
"""
from __future__ import annotations

import collections

__all__ = ["tick_percentiles", "TickStats"]


def tick_percentiles(intervals) -> tuple[float, float, float]:
    """Median, 99th percentile (nearest rank) and maximum of tick intervals.

    Parameters
    ----------
    intervals : iterable of float
        Intervals between ticks in s.

    Returns
    -------
    tuple of 3 float
        ``(p50, p99, max)`` in s; zeros without intervals.
    """
    iv = sorted(intervals)
    if not iv:
        return 0.0, 0.0, 0.0
    n = len(iv)
    return iv[(n - 1) // 2], iv[min(n - 1, int(0.99 * (n - 1) + 0.5))], iv[-1]


class TickStats:
    """The intervals between control ticks over a sliding window, with a cached summary.

    Not thread-safe: the server calls it under its lock.

    Parameters
    ----------
    window_s : float
        Length of the window in s of wall time.
    cache_s : float
        The summary is recomputed at most this often, s.
    """

    def __init__(self, window_s: float = 1.0, cache_s: float = 0.05):
        self.window_s, self.cache_s = float(window_s), float(cache_s)
        self._ticks = collections.deque()           # (t_wall, interval)
        self._last = None
        self._summary, self._summary_at = (0.0, 0.0, 0.0), None

    def restart(self) -> None:
        """Forget the last tick time (a new loop starts: no interval to the previous one)."""
        self._last = None

    def record(self, now: float) -> None:
        """Record a tick at wall time ``now``.

        Parameters
        ----------
        now : float
            Wall time in s (``time.monotonic``).
        """
        last, self._last = self._last, now
        if last is None:
            return
        self._ticks.append((now, now - last))
        while self._ticks and self._ticks[0][0] < now - self.window_s:
            self._ticks.popleft()

    def summary(self, now: float) -> tuple[float, float, float]:
        """Interval p50, p99 and maximum in s over the window (cached for ``cache_s``).

        Parameters
        ----------
        now : float
            Wall time in s.

        Returns
        -------
        tuple of 3 float
            See :func:`tick_percentiles`.
        """
        if self._summary_at is not None and now - self._summary_at < self.cache_s:
            return self._summary
        self._summary = tick_percentiles(x for _, x in self._ticks)
        self._summary_at = now
        return self._summary
