"""The one client API perception code uses to talk to the joint-control layer.

:class:`JointAdapter` numbers and encodes commands, retransmits requests
that need an answer, matches replies to requests, and caches the last state.
It works over any :mod:`~tudorvision.joint.transport` (UDP or in-process).

Velocity commands (visual servoing) are fire-and-forget: send them at the
perception rate, and the layer stops the arm by itself when they cease.
Setpoints (catching), mode switches and state requests wait for an answer,
retransmitting every ``retry_interval_s``; a command is resent with the same
sequence number, so the layer executes it at most once.

Examples
--------
>>> from tudorvision.joint.transport import InProcessTransport
>>> from tudorvision.joint.server import JointLayerServer, make_core
>>> client, end = InProcessTransport.pair()
>>> with JointLayerServer(end, make_core("kinematic")), JointAdapter(client) as joints:
...     reply = joints.set_mode(Mode.SETPOINT, timeout=2.0)
...     reply = joints.send_setpoint([0.0, 1.5, 0.1], timeout=2.0)
...     state = joints.wait_settled([0.0, 1.5, 0.1], timeout=10.0)
>>> reply.code.name, state is not None and state.settled
('OK', True)
"""
from __future__ import annotations

import collections
import time
from dataclasses import dataclass

import numpy as np

from .._checks import check_array, check_mass
from . import protocol as P
from .protocol import Ack, CollisionStrategy, Damping, Mode, Refusal, State

__all__ = ["JointAdapter", "AdapterStats", "Mode", "Damping", "CollisionStrategy"]


@dataclass(frozen=True, kw_only=True)
class AdapterStats:
    """Counters of one adapter since it was created.

    ``rtt_s`` is the round-trip time of the last answered request (from its
    first transmission), ``None`` before any.
    """

    sent: int = 0
    received: int = 0
    malformed: int = 0
    retransmissions: int = 0
    timeouts: int = 0
    acks: int = 0
    refusals: int = 0
    states: int = 0
    rtt_s: float | None = None


class JointAdapter:
    """Client of the joint-control layer.

    Parameters
    ----------
    transport : Transport
        Client end: ``UdpTransport.client(port)`` or the client end of
        ``InProcessTransport.pair()``.
    retry_interval_s : float
        Time between retransmissions of an unanswered request.
    first_seq : int
        First sequence number (uint32).

    Notes
    -----
    Not thread-safe: use one adapter per thread.
    """

    def __init__(self, transport, *, retry_interval_s: float = 0.05, first_seq: int = 1):
        if not retry_interval_s > 0:
            raise ValueError(f"retry_interval_s: must be positive, got {retry_interval_s}")
        self.transport = transport
        self.retry_interval_s = float(retry_interval_s)
        self._seq = int(first_seq) & 0xFFFFFFFF
        self._counts = dict.fromkeys(AdapterStats.__dataclass_fields__, 0)
        self._counts["rtt_s"] = None
        self.last_state: State | None = None
        self.last_reply: Ack | Refusal | None = None
        self._replies: collections.OrderedDict = collections.OrderedDict()

    # ------------------------------------------------------------- plumbing
    def _count(self, key: str) -> None:
        self._counts[key] += 1

    def stats(self) -> AdapterStats:
        """Snapshot of the counters."""
        return AdapterStats(**self._counts)

    def _next_seq(self) -> int:
        seq = self._seq
        self._seq = P.seq_add(self._seq)
        return seq

    def _transmit(self, msg, seq: int) -> None:
        self.transport.send(P.encode(msg, seq, time.monotonic()))
        self._count("sent")

    def _receive(self, timeout: float):
        """Receive and decode one datagram; update caches. ``None`` on timeout or junk."""
        item = self.transport.recv(max(timeout, 0.0))
        if item is None:
            return None
        self._count("received")
        try:
            header, msg = P.decode(item[0])
        except P.ProtocolError:
            self._count("malformed")
            return None
        if isinstance(msg, State):
            self._count("states")
            if self.last_state is None or msg.t >= self.last_state.t:
                self.last_state = msg
        elif isinstance(msg, (Ack, Refusal)):
            self._count("acks" if isinstance(msg, Ack) else "refusals")
            self.last_reply = msg
            self._replies[msg.command_seq] = msg
            self._replies.move_to_end(msg.command_seq)
            while len(self._replies) > 1024:
                self._replies.popitem(last=False)
        return header, msg

    def reply_for(self, seq: int) -> Ack | Refusal | None:
        """The answer received so far to command ``seq`` (recent 1024 kept), else ``None``.

        Call :meth:`poll` first to take in datagrams that have arrived.
        """
        return self._replies.get(seq)

    def poll(self, max_datagrams: int = 1000) -> int:
        """Process datagrams already received (replies to velocity commands); return how many."""
        n = 0
        while n < max_datagrams and self._receive(0.0) is not None:
            n += 1
        return n

    def _request(self, msg, timeout: float, match):
        """Send ``msg`` and retransmit until ``match(seqs, reply)`` or timeout."""
        if not timeout > 0:
            raise ValueError(f"timeout: must be positive, got {timeout}")
        command = isinstance(msg, P.COMMAND_TYPES)
        seqs = {self._next_seq()}
        seq = next(iter(seqs))
        t0 = time.monotonic()
        deadline = t0 + timeout
        self._transmit(msg, seq)
        next_retry = t0 + self.retry_interval_s
        while True:
            now = time.monotonic()
            if now >= deadline:
                self._count("timeouts")
                return None
            if now >= next_retry:
                if not command:            # queries get a fresh number, commands keep theirs
                    seq = self._next_seq()
                    seqs.add(seq)
                self._transmit(msg, seq)
                self._count("retransmissions")
                next_retry = now + self.retry_interval_s
                continue
            got = self._receive(min(next_retry, deadline) - now)
            if got is not None and match(seqs, got[1]):
                self._counts["rtt_s"] = time.monotonic() - t0
                return got[1]

    @staticmethod
    def _is_reply(seqs, msg) -> bool:
        return isinstance(msg, (Ack, Refusal)) and msg.command_seq in seqs

    # ------------------------------------------------------------ commands
    def send_velocity(self, theta_dot) -> int:
        """Send a joint velocity command (rad/s, shape (3,)) without waiting.

        Returns the sequence number. The layer holds it for its watchdog time
        (default 0.1 s); send the next one before that expires.

        Raises
        ------
        ValueError
            If ``theta_dot`` is not 3 finite numbers.
        """
        v = check_array(theta_dot, "theta_dot", (3,))
        self.poll()
        seq = self._next_seq()
        self._transmit(P.JointVelocityCommand(theta_dot=v), seq)
        return seq

    def send_setpoint(self, theta, *, max_speed: float | None = None,
                      max_accel: float | None = None, timeout: float = 1.0) -> Ack | Refusal | None:
        """Send a joint setpoint (rad, shape (3,)) and wait for the layer's answer.

        ``max_speed`` (rad/s) and ``max_accel`` (rad/s²) bound the profile;
        ``None`` leaves the layer's defaults. Returns the :class:`Ack` (possibly
        with a ``CLAMPED_*`` code) or :class:`Refusal`, or ``None`` if nothing
        answered within ``timeout`` s.
        """
        th = check_array(theta, "theta", (3,))
        msg = P.JointSetpoint(theta=th, max_speed=max_speed, max_accel=max_accel)
        return self._request(msg, timeout, self._is_reply)

    def set_mode(self, mode: Mode | None = None, *, damping: Damping | None = None,
                 collision: CollisionStrategy | None = None,
                 timeout: float = 1.0) -> Ack | Refusal | None:
        """Switch mode / damping law / collision strategy (``None`` keeps the current one).

        A mode switch also clears the ``FAULT`` and ``WATCHDOG_STOP`` flags.
        Returns the answer, or ``None`` on timeout.
        """
        msg = P.ModeSwitch(mode=mode, damping=damping, collision=collision)
        return self._request(msg, timeout, self._is_reply)

    def set_payload(self, payload_kg: float, *, timeout: float = 1.0) -> Ack | Refusal | None:
        """Tell the layer the end-effector payload (kg: mount, plates, caught balls).

        The layer schedules its damping gains and collision model on it. Returns
        the answer (a :class:`Refusal` with ``UNSUPPORTED`` from a core without a
        payload model), or ``None`` on timeout.
        """
        return self._request(P.PayloadUpdate(payload_kg=check_mass(payload_kg)), timeout, self._is_reply)

    def request_state(self, timeout: float = 0.5) -> State | None:
        """Ask for the layer's state; ``None`` if no answer within ``timeout`` s."""
        return self._request(P.StateRequest(), timeout,
                             lambda seqs, m: isinstance(m, State) and m.request_seq in seqs)

    def wait_settled(self, theta, *, tol: float = np.deg2rad(0.5), timeout: float = 10.0,
                     strains: bool = True, poll_interval_s: float = 0.02) -> State | None:
        """Poll the state until the arm rests within ``tol`` rad of ``theta``.

        With ``strains=True`` the layer must report SETTLED (joints at rest and
        link strains inside the settling band); with ``strains=False`` joints
        at rest (no MOVING flag) suffice, though the links may still vibrate.
        Returns that state, or ``None`` when ``timeout`` s pass first.
        """
        target = check_array(theta, "theta", (3,))
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            st = self.request_state(timeout=min(remaining, 0.5))
            if st is not None and np.max(np.abs(np.asarray(st.theta) - target)) <= tol and (
                    st.settled if strains else not st.flags & P.StateFlags.MOVING):
                return st
            pause = min(poll_interval_s, deadline - time.monotonic())
            if pause > 0:
                time.sleep(pause)

    # ------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Close the transport."""
        self.transport.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
