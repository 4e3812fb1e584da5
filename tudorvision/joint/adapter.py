"""The one client API perception code uses to talk to the joint-control layer.

:class:`JointAdapter` numbers and encodes commands, retransmits requests
that need an answer, matches replies to requests, and caches the last state.
It works over any :mod:`~tudorvision.joint.transport` (UDP or in-process).

Velocity commands (visual servoing) are fire-and-forget: send them at the
perception rate, and the layer stops the arm by itself when they cease.
Setpoints (catching), mode switches and state requests wait for an answer,
retransmitting every ``retry_interval_s``; a command is resent with the same
sequence number, so the layer executes it at most once.

The layer obeys one client at a time, the holder of its lease. The adapter
opens that session by itself before its first command (handshake with a
fresh nonce, see :mod:`~tudorvision.joint.protocol`) and opens a new one
when the layer says the old one ended (lease expired after a silence);
:meth:`JointAdapter.open_session` does it explicitly, with ``takeover`` to
take the lease from another client. With a ``key`` every datagram carries an
HMAC-SHA256 tag and only tagged answers are believed. State requests need no
session. :meth:`close` releases the lease.

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

_NO_ANSWER = object()     # the handshake got no answer at all


@dataclass(frozen=True, kw_only=True)
class AdapterStats:
    """Counters of one adapter since it was created.

    ``rtt_s`` is the round-trip time of the last answered request (from its
    first transmission), ``None`` before any.
    """

    sent: int = 0
    received: int = 0
    malformed: int = 0
    unauthenticated: int = 0
    sessions: int = 0
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
    key : bytes, optional
        The layer's key (:func:`~tudorvision.joint.protocol.read_key_file`);
        required when the layer has one.
    takeover : bool
        Sessions the adapter opens by itself take the lease over from another
        holder (the layer stops the arm and goes IDLE first).
    auto_session : bool
        Open a session before the first command and after the layer ended one.
    session_timeout_s : float
        Time allowed for the handshake when the adapter opens a session by itself.

    Notes
    -----
    Not thread-safe: use one adapter per thread.
    """

    def __init__(self, transport, *, retry_interval_s: float = 0.05, first_seq: int = 1,
                 key: bytes | None = None, takeover: bool = False, auto_session: bool = True,
                 session_timeout_s: float = 1.0):
        if not retry_interval_s > 0:
            raise ValueError(f"retry_interval_s: must be positive, got {retry_interval_s}")
        if not session_timeout_s > 0:
            raise ValueError(f"session_timeout_s: must be positive, got {session_timeout_s}")
        self.transport = transport
        self.retry_interval_s = float(retry_interval_s)
        self._seq = int(first_seq) & 0xFFFFFFFF
        self._counts = dict.fromkeys(AdapterStats.__dataclass_fields__, 0)
        self._counts["rtt_s"] = None
        self.last_state: State | None = None
        self.last_reply: Ack | Refusal | None = None
        self._replies: collections.OrderedDict = collections.OrderedDict()
        self._key = None if key is None else bytes(key)
        self.takeover = bool(takeover)
        self.auto_session = bool(auto_session)
        self.session_timeout_s = float(session_timeout_s)
        self._session: int | None = None
        self._keys: collections.OrderedDict = collections.OrderedDict()   # session id -> key
        self.lease_s: float | None = None
        self._next_open = 0.0            # no automatic handshake before this time (velocity path)

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

    @property
    def session(self) -> int | None:
        """Id of the session this adapter holds (as far as it knows), else ``None``."""
        return self._session

    def encode(self, msg, seq: int, *, t: float | None = None, strict: bool = True) -> bytes:
        """Encode ``msg`` as this adapter would send it now (its session and key).

        For tests and tools that need raw datagrams (duplicates, stale, NaN).
        Commands and state requests go in the current session; the handshake
        outside any.
        """
        sid = 0
        if self._session is not None and isinstance(msg, (*P.COMMAND_TYPES, P.StateRequest)):
            sid = self._session
        key = self._key if sid == 0 else self._keys[sid]
        return P.encode(msg, seq, time.monotonic() if t is None else t, strict=strict,
                        session=sid, key=key)

    def _transmit(self, msg, seq: int) -> None:
        self.transport.send(self.encode(msg, seq))
        self._count("sent")

    def _receive(self, timeout: float):
        """Receive and decode one datagram; update caches. ``None`` on timeout or junk."""
        item = self.transport.recv(max(timeout, 0.0))
        if item is None:
            return None
        self._count("received")
        try:
            sid, _, _ = P.peek(item[0])
            if sid and self._key is not None and sid not in self._keys:
                raise P.Unauthenticated(f"no key for session {sid}")
            header, msg = P.decode(item[0], key=self._keys.get(sid) if sid else self._key)
        except P.Unauthenticated:
            self._count("unauthenticated")
            return None
        except P.ProtocolError:
            self._count("malformed")
            return None
        if (isinstance(msg, Refusal) and msg.code == P.Reason.NO_SESSION
                and header.session in (0, self._session) and self._session is not None):
            self._session = None          # the layer ended our session (lease expired ...)
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

    # ------------------------------------------------------------- session
    def open_session(self, *, takeover: bool | None = None,
                     timeout: float = 1.0) -> P.Welcome | Refusal | None:
        """Open a session (take the lease) with a fresh nonce.

        Parameters
        ----------
        takeover : bool, optional
            Take the lease from another holder (default: the adapter's ``takeover``).
        timeout : float
            Seconds for the whole handshake.

        Returns
        -------
        Welcome, Refusal or None
            The layer's :class:`~tudorvision.joint.protocol.Welcome`; a
            :class:`Refusal` with ``NOT_OWNER`` while another client holds the
            lease; ``None`` when nothing (authentic) answered in time.
        """
        if not timeout > 0:
            raise ValueError(f"timeout: must be positive, got {timeout}")
        deadline = time.monotonic() + timeout
        self._session = None
        nonce = P.new_nonce()
        chal = self._request(P.Hello(client_nonce=nonce), timeout,
                             lambda seqs, m: isinstance(m, P.Challenge) and m.client_nonce == nonce)
        remaining = deadline - time.monotonic()
        if chal is None or remaining <= 0:
            return None
        take = self.takeover if takeover is None else bool(takeover)
        reply = self._request(
            P.OpenSession(client_nonce=nonce, server_nonce=chal.server_nonce, takeover=take), remaining,
            lambda seqs, m: ((isinstance(m, P.Welcome) and m.client_nonce == nonce)
                             or (isinstance(m, Refusal) and m.command_seq in seqs)))
        if isinstance(reply, P.Welcome):
            self._keys[reply.session] = P.session_key(self._key, nonce, chal.server_nonce, reply.session)
            while len(self._keys) > 8:
                self._keys.popitem(last=False)
            self._session = reply.session
            self.lease_s = reply.lease_s
            self._count("sessions")
        return reply

    def _ensure_session(self, timeout: float):
        """Open a session if auto_session and none is held; a Refusal/None when that failed."""
        if self._session is not None or not self.auto_session:
            return None
        got = self.open_session(timeout=min(timeout, self.session_timeout_s))
        return None if isinstance(got, P.Welcome) else (got or _NO_ANSWER)

    def _command(self, msg, timeout: float):
        """Send a command in the session (opened or reopened as needed) and wait for its answer."""
        if not timeout > 0:
            raise ValueError(f"timeout: must be positive, got {timeout}")
        deadline = time.monotonic() + timeout
        failed = self._ensure_session(timeout)
        if failed is not None:
            return None if failed is _NO_ANSWER else failed
        reply = self._request(msg, max(deadline - time.monotonic(), 1e-3), self._is_reply)
        if (isinstance(reply, Refusal) and reply.code == P.Reason.NO_SESSION and self.auto_session
                and deadline - time.monotonic() > 0):
            self._session = None
            failed = self._ensure_session(deadline - time.monotonic())
            if failed is not None:
                return None if failed is _NO_ANSWER else failed
            reply = self._request(msg, max(deadline - time.monotonic(), 1e-3), self._is_reply)
        return reply

    def release(self, *, timeout: float = 0.5) -> Ack | Refusal | None:
        """End the session and give the lease back; ``None`` when none is held or no answer came."""
        if self._session is None:
            return None
        reply = self._request(P.Release(), timeout, self._is_reply)
        self._session = None
        return reply

    def reset_fault(self, *, timeout: float = 1.0) -> Ack | Refusal | None:
        """Clear the layer's FAULT (the lease holder only): the only way to clear it.

        A mode switch does not. Returns the answer, or ``None`` on timeout.
        """
        return self._command(P.FaultReset(), timeout)

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
        if self._session is None and self.auto_session and time.monotonic() >= self._next_open:
            if not isinstance(self.open_session(timeout=self.session_timeout_s), P.Welcome):
                self._next_open = time.monotonic() + self.session_timeout_s   # no handshake per frame
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
        return self._command(msg, timeout)

    def set_mode(self, mode: Mode | None = None, *, damping: Damping | None = None,
                 collision: CollisionStrategy | None = None,
                 timeout: float = 1.0) -> Ack | Refusal | None:
        """Switch mode / damping law / collision strategy (``None`` keeps the current one).

        A mode switch clears the ``WATCHDOG_STOP`` flag, never ``FAULT`` (see
        :meth:`reset_fault`). Returns the answer, or ``None`` on timeout.
        """
        msg = P.ModeSwitch(mode=mode, damping=damping, collision=collision)
        return self._command(msg, timeout)

    def set_payload(self, payload_kg: float, *, timeout: float = 1.0) -> Ack | Refusal | None:
        """Tell the layer the end-effector payload (kg: mount, plates, caught balls).

        The layer schedules its damping gains and collision model on it. Returns
        the answer (a :class:`Refusal` with ``UNSUPPORTED`` from a core without a
        payload model), or ``None`` on timeout.
        """
        return self._command(P.PayloadUpdate(payload_kg=check_mass(payload_kg)), timeout)

    def request_state(self, timeout: float = 0.5) -> State | None:
        """Ask for the layer's state; ``None`` if no answer within ``timeout`` s.

        Needs no session; inside one it also renews the lease.
        """
        deadline = time.monotonic() + timeout
        got = self._request(P.StateRequest(), timeout,
                            lambda seqs, m: (isinstance(m, State) and m.request_seq in seqs)
                            or (isinstance(m, Refusal) and m.command_seq in seqs))
        if isinstance(got, Refusal):           # our session ended: ask outside it
            self._session = None
            remaining = deadline - time.monotonic()
            got = None if remaining <= 0 else self._request(
                P.StateRequest(), remaining, lambda seqs, m: isinstance(m, State) and m.request_seq in seqs)
        return got

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
        """Release the lease (one datagram, no wait) and close the transport."""
        if self._session is not None:
            try:
                self._transmit(P.Release(), self._next_seq())
            except OSError:
                pass
            self._session = None
        self.transport.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
