"""Live-rate playback of a recorded sequence, dropping frames a slow consumer cannot take.

Frame ``i`` is due at wall time ``start + (t_i - t_0) / speed``. When the
consumer asks for the next frame, the newest frame already due is delivered
and the older undelivered ones are dropped (never decoded); if no frame is
due yet, playback sleeps until the next one is. This is how a live camera
behaves: a tracker that is too slow sees fewer, but current, frames.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

__all__ = ["Playback", "Played"]


@dataclass(frozen=True, eq=False)
class Played:
    """One delivered frame.

    Attributes
    ----------
    frame : StereoFrame or RGBDFrame or MonoFrame
    latency_s : float
        Wall time between the frame being due and being delivered, seconds
        (includes the decode time).
    dropped : int
        Frames dropped just before this one.
    """

    frame: object
    latency_s: float
    dropped: int


class Playback:
    """Iterator over :class:`Played` items paced to wall time.

    Parameters
    ----------
    sequence : Sequence
        Opened recording; its ``timestamps`` (seconds) set the pace, and
        frames are decoded only when delivered (defective frames of a
        lenient sequence are skipped).
    speed : float
        Playback speed factor (2.0: twice as fast as recorded).
    clock, sleep : callable, optional
        Time source (seconds) and sleep function; default
        ``time.monotonic`` / ``time.sleep`` (inject fakes in tests).

    Attributes
    ----------
    delivered, dropped, skipped : int
        Frames delivered, dropped for being late, and skipped as defective
        (lenient sequences; the defects are in ``sequence.report``).
    max_latency_s : float
        Largest delivery latency so far.

    Raises
    ------
    ValueError
        If ``speed`` is not a positive number.
    """

    def __init__(self, sequence, *, speed: float = 1.0, clock=None, sleep=None):
        if not (isinstance(speed, (int, float)) and speed > 0):
            raise ValueError(f"speed: expected a positive number, got {speed!r}")
        self.sequence = sequence
        self.speed = float(speed)
        self._clock = clock or time.monotonic
        self._sleep = sleep or time.sleep
        self._ts = np.asarray(sequence.timestamps, dtype=np.float64)
        self.delivered = 0
        self.dropped = 0
        self.skipped = 0
        self.max_latency_s = 0.0
        self._latency_sum = 0.0

    @property
    def mean_latency_s(self) -> float:
        return self._latency_sum / self.delivered if self.delivered else 0.0

    def stats(self) -> dict:
        """Counters as a dict (delivered, dropped, skipped, latencies).

        Returns
        -------
        dict
            ``delivered``, ``dropped``, ``skipped`` (int, frames so far) and
            ``mean_latency_s``, ``max_latency_s`` (float, seconds; 0 before
            the first delivery).
        """
        return {"delivered": self.delivered, "dropped": self.dropped, "skipped": self.skipped,
                "mean_latency_s": self.mean_latency_s, "max_latency_s": self.max_latency_s}

    def __iter__(self):
        n = self._ts.size
        if n == 0:
            return
        start = self._clock()
        due = start + (self._ts - self._ts[0]) / self.speed
        i = 0
        pending_drop = 0
        while i < n:
            now = self._clock()
            if now < due[i]:
                self._sleep(due[i] - now)
                now = self._clock()
            # newest frame already due; the older ones are dropped unseen
            j = int(np.searchsorted(due, now, side="right")) - 1
            if j > i:
                pending_drop += j - i
                self.dropped += j - i
                i = j
            frame = self.sequence.load_or_report(i)
            if frame is None:
                self.skipped += 1
                i += 1
                continue
            latency = max(self._clock() - due[i], 0.0)
            self.delivered += 1
            self.max_latency_s = max(self.max_latency_s, latency)
            self._latency_sum += latency
            item = Played(frame=frame, latency_s=latency, dropped=pending_drop)
            pending_drop = 0
            i += 1
            yield item
