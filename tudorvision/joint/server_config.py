"""Options of the joint-layer server, and the records it keeps of commands and events.

:class:`ServerConfig` is what :class:`~tudorvision.joint.server.JointLayerServer`
takes; :class:`CommandRecord` and :class:`ServerEvent` are the entries of its
:meth:`~tudorvision.joint.server.JointLayerServer.command_log` and
:meth:`~tudorvision.joint.server.JointLayerServer.events`.

Examples
--------
>>> ServerConfig(rate_hz=250.0).watchdog_s
0.1
>>> ServerConfig(lease_s=0.0)
Traceback (most recent call last):
...
ValueError: lease_s: must be positive and finite, got 0.0
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Hashable

import numpy as np

from .messages import Mode, Reason
from .safety import SafetyPolicy

__all__ = ["ServerConfig", "CommandRecord", "ServerEvent"]


@dataclass(frozen=True, kw_only=True)
class ServerConfig:
    """Options of :class:`JointLayerServer`.

    Attributes
    ----------
    rate_hz : float
        Control rate of the server loop (the core may sub-step faster).
    watchdog_s : float
        Lifetime of a velocity command in control time (the sum of the steps
        given to the core: wall time unless the loop falls behind).
    max_command_age_s : float or None
        Motion commands that arrive later than this relative to the fastest
        delivery seen from their sender are ignored as stale (None: off).
    initial_mode : Mode
    policy : SafetyPolicy
    rest_speed_rad_s : float
        Joint speed below which the arm is not ``MOVING``.
    fault_speed_factor, fault_range_tol_rad : float
        A core state faster than factor x speed limit is a fault; so is a
        joint that goes further than the tolerance outside its range, or is
        outside and moving further out (outside and at rest or moving back,
        it may be brought back after the fault is reset).
    fault_accel_factor : float or None
        With a number, a joint speed change faster than this times the
        acceleration limit (over ``accel_window_s``) is a fault too; off by
        default because an elastic arm's measured joint speed may ring above
        the commanded acceleration.
    accel_window_s : float
        Window of that acceleration estimate.
    max_clients, seq_window, log_size, max_backlog_ticks : int
        Bounds of the per-client tables, the duplicate window, the command log
        and of catch-up ticks after a stall (beyond it ticks are skipped and
        counted as overruns).
    lease_s : float
        The owner's lease in control time: it ends after this long without a
        valid datagram of its session.
    allow_takeover : bool
        Let a client open a session with ``takeover`` while another holds the
        lease (the layer stops the arm and goes IDLE first).
    seq_ahead : int
        Largest jump of the sequence number within a session; a datagram
        further ahead is dropped as forged and never moves the window.
    source_rate_hz, source_burst : float
        Token bucket per source address other than the owner's, applied
        before decoding (wall-clock loop only).
    max_sources : int
        Bound of the rate limiter's table of sources.
    handshake_timeout_s : float
        A challenge not answered within this wall time is forgotten.
    max_batch : int
        Datagrams read per burst before the owner's are handled first.
    """

    rate_hz: float = 500.0
    watchdog_s: float = 0.1
    max_command_age_s: float | None = 0.25
    initial_mode: Mode = Mode.IDLE
    policy: SafetyPolicy = SafetyPolicy()
    rest_speed_rad_s: float = 1e-3
    fault_speed_factor: float = 1.05
    fault_range_tol_rad: float = np.deg2rad(1.0)
    fault_accel_factor: float | None = None
    accel_window_s: float = 0.02
    max_clients: int = 64
    seq_window: int = 256
    log_size: int = 4096
    max_backlog_ticks: int = 10
    lease_s: float = 1.0
    allow_takeover: bool = True
    seq_ahead: int = 4096
    source_rate_hz: float = 1000.0
    source_burst: float = 200.0
    max_sources: int = 1024
    handshake_timeout_s: float = 2.0
    max_batch: int = 64

    def __post_init__(self):
        for name in ("rate_hz", "watchdog_s", "lease_s", "source_rate_hz", "source_burst",
                     "handshake_timeout_s", "accel_window_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be positive and finite, got {v}")
        if self.fault_accel_factor is not None and not self.fault_accel_factor >= 1.0:
            raise ValueError(f"fault_accel_factor: expected None or >= 1, got {self.fault_accel_factor}")
        for name in ("max_clients", "seq_window", "log_size", "seq_ahead", "max_sources", "max_batch"):
            if not int(getattr(self, name)) >= 1:
                raise ValueError(f"{name}: must be >= 1, got {getattr(self, name)}")


@dataclass(frozen=True)
class CommandRecord:
    """One handled command: times, sender, sequence number, message, outcome code and session."""

    t_wall: float
    t_core: float
    client: Hashable
    seq: int
    msg: object
    code: Reason
    session: int = 0


@dataclass(frozen=True)
class ServerEvent:
    """Something the layer did on its own: ``kind`` is one of ``session_open``,
    ``session_end``, ``takeover``, ``fault``, ``fault_reset``, ``watchdog_stop``."""

    t_wall: float
    t_core: float
    kind: str
    text: str = ""
