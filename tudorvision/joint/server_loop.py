"""The wall-clock loop of the joint-layer server: control ticks at a fixed rate, datagrams in between.

:class:`WallClockLoop` owns the timing only: it calls the server's tick at
the control rate (skipping ticks beyond a backlog and counting them as
overruns), reads datagrams while it waits, drops those of rate-limited
sources other than the lease holder before decoding, and hands the owner's
datagrams to the server first. What a tick or a datagram does is the
server's (:class:`~tudorvision.joint.server.JointLayerServer`).

Examples
--------
>>> from tudorvision.joint.transport import InProcessTransport
>>> _, end = InProcessTransport.pair()
>>> ticks = []
>>> loop = WallClockLoop(end, tick=ticks.append, handle=lambda data, addr: None, owner_addr=lambda: None,
...                      record_tick=lambda now: None, count=lambda **inc: None,
...                      limiter=RateLimiter(100.0, 10.0, 8), max_backlog_ticks=10, max_batch=8)
>>> loop.run(period=0.01, duration=0.055, stop=threading.Event())
>>> 3 <= len(ticks) <= 6, ticks[0]
(True, 0.01)
"""
from __future__ import annotations

import threading
import time
from typing import Callable, Hashable

from .session import RateLimiter

__all__ = ["WallClockLoop"]


class WallClockLoop:
    """Runs control ticks at a fixed wall-clock rate and handles datagrams between them.

    Parameters
    ----------
    transport : Transport
        The server's bound transport (``recv(timeout) -> (data, addr) or None``).
    tick : callable
        ``tick(dt)``: one control period of ``dt`` s.
    handle : callable
        ``handle(data, addr)``: one datagram (never raises).
    owner_addr : callable
        ``owner_addr() -> address or None``: the lease holder's address.
    record_tick : callable
        ``record_tick(now)``: called with the wall time of each tick.
    count : callable
        ``count(**increments)``: adds to the server's counters
        (``overruns``, ``rate_limited``).
    limiter : RateLimiter
        Token buckets of the sources other than the owner.
    max_backlog_ticks : int
        Ticks caught up after a stall; beyond it they are skipped (overruns).
    max_batch : int
        Datagrams read per burst before the owner's are handled first.
    """

    def __init__(self, transport, *, tick: Callable[[float], None], handle: Callable[[bytes, Hashable], None],
                 owner_addr: Callable[[], Hashable | None], record_tick: Callable[[float], None],
                 count: Callable[..., None], limiter: RateLimiter, max_backlog_ticks: int, max_batch: int):
        self.transport, self.tick, self.handle = transport, tick, handle
        self.owner_addr, self.record_tick, self.count = owner_addr, record_tick, count
        self.limiter, self.max_backlog_ticks, self.max_batch = limiter, max_backlog_ticks, max_batch

    def run(self, period: float, duration: float | None, stop: threading.Event) -> None:
        """Run until ``stop`` is set or ``duration`` s of wall time have passed.

        Parameters
        ----------
        period : float
            Control period in s.
        duration : float or None
            Wall time to run for, s; ``None``: until ``stop``.
        stop : threading.Event
            Set from another thread to end the loop.

        Raises
        ------
        OSError
            If the transport fails while ``stop`` is not set.
        """
        now = time.monotonic()
        end = None if duration is None else now + duration
        next_tick = now + period
        while not stop.is_set():
            now = time.monotonic()
            if end is not None and now >= end:
                break
            if now >= next_tick:
                behind = int((now - next_tick) / period)
                if behind > self.max_backlog_ticks:
                    next_tick += behind * period
                    self.count(overruns=behind)
                self.record_tick(now)
                self.tick(period)
                next_tick += period
                continue
            wait = next_tick - now
            if end is not None:
                wait = min(wait, max(end - now, 0.0))
            try:
                item = self.transport.recv(wait)
            except OSError:
                if stop.is_set():
                    break
                raise
            if item is not None:
                self.handle_batch(item, next_tick)

    def handle_batch(self, first, next_tick: float) -> None:
        """Read up to ``max_batch`` datagrams, drop rate-limited strangers, handle the owner's first.

        Parameters
        ----------
        first : tuple of (bytes, hashable)
            The datagram already received and its sender.
        next_tick : float
            Wall time in s of the next tick: reading stops there.
        """
        owner_items, others = [], []
        limiter, now = self.limiter, time.monotonic()
        item = first
        while item is not None:
            owner = self.owner_addr()
            if owner is not None and item[1] == owner:
                owner_items.append(item)
            elif limiter.allow(item[1], now):
                others.append(item)
            else:
                self.count(rate_limited=1)
            if len(owner_items) + len(others) >= self.max_batch or time.monotonic() >= next_tick:
                break
            try:
                item = self.transport.recv(0.0)
            except OSError:
                break
        for item in owner_items:
            self.handle(*item)
        for item in others:
            self.handle(*item)
