"""Sessions of the joint-control layer: the owner's lease, the replay window, challenges and rate limits.

State the server keeps per client, as small classes it drives:

* :class:`SeqWindow` - the sequence numbers seen in one session: duplicates,
  stale and replayed (outside the window, or forged far ahead) datagrams, and
  the age of a datagram relative to the fastest delivery seen;
* :class:`Session` - the lease holder: session id, address, session key and
  the time of its last valid datagram;
* :class:`SessionTable` - the owner, recently ended sessions (so their late
  datagrams can still be checked and answered ``NO_SESSION``) and the
  pending handshake challenges;
* :class:`RateLimiter` - a token bucket per source address.

Times named ``t_ctrl`` are control time (the sum of the steps given to the
core); ``now`` is ``time.monotonic()`` wall time. Sequence numbers are uint32
and wrap around.

Examples
--------
>>> w = SeqWindow()
>>> [w.classify(s, window=4) for s in (1, 3, 3, 2)]
['new', 'new', 'duplicate', 'stale']
"""
from __future__ import annotations

import collections
import ipaddress
import os
from typing import Hashable

from .keys import new_nonce

__all__ = ["DRIFT", "SeqWindow", "Session", "SessionTable", "RateLimiter", "is_loopback"]

#: Tolerated clock drift between sender and layer, s/s (1000 ppm).
DRIFT = 1e-3


class SeqWindow:
    """Sequence-number bookkeeping for one session.

    Attributes
    ----------
    newest : int or None
        Newest sequence number accepted.
    window : collections.deque
        The last accepted sequence numbers, oldest first.
    seen : set
        The same numbers, for lookups.
    last_reply : tuple of (int, bytes) or None
        Sequence number of the last command and the datagram answering it
        (sent again for a duplicate of that command).
    floor : float or None
        Lowest ``receive - send`` time seen in s, drifting up by :data:`DRIFT`.
    floor_t : float
        Receive time in s at which ``floor`` was set.
    """

    __slots__ = ("newest", "window", "seen", "last_reply", "floor", "floor_t")

    def __init__(self):
        self.newest = None
        self.window = collections.deque()
        self.seen = set()
        self.last_reply = None     # (seq, datagram)
        self.floor = None          # lowest (receive - send) time seen, drifting up slowly
        self.floor_t = 0.0

    def age(self, t_recv: float, t_sent: float) -> float:
        """Delay of this datagram beyond the fastest delivery seen from this sender.

        The sender's clock is unrelated to ours; only differences matter. The
        floor rises by :data:`DRIFT` s per s so clock drift between two PCs
        never makes fresh commands look old.

        Parameters
        ----------
        t_recv : float
            Receive time in s (the layer's monotonic clock).
        t_sent : float
            Send time in s from the datagram's header (the sender's clock).

        Returns
        -------
        float
            Extra delay in s (0 for the fastest delivery so far).
        """
        delay = t_recv - t_sent
        if self.floor is None or delay < self.floor + DRIFT * (t_recv - self.floor_t):
            self.floor, self.floor_t = delay, t_recv
        return delay - self.floor - DRIFT * (t_recv - self.floor_t)

    def classify(self, seq: int, window: int, ahead: int = 2**31 - 1) -> str:
        """Classify a sequence number and record it if it is new.

        Parameters
        ----------
        seq : int
            Sequence number of the datagram (uint32).
        window : int
            Number of recent sequence numbers remembered.
        ahead : int
            Largest accepted jump ahead of the newest number.

        Returns
        -------
        str
            ``"new"``, ``"duplicate"``, ``"stale"`` (older, inside the window)
            or ``"replayed"`` (older than the window, or more than ``ahead``
            newer).
        """
        if seq in self.seen:
            return "duplicate"
        if self.newest is not None:
            d = (seq - self.newest) & 0xFFFFFFFF
            if d == 0 or d >= 0x80000000:
                return "stale" if (self.newest - seq) & 0xFFFFFFFF < window else "replayed"
            if d > ahead:
                return "replayed"
        self.newest = seq
        self.window.append(seq)
        self.seen.add(seq)
        while len(self.window) > window:
            self.seen.discard(self.window.popleft())
        return "new"


class Session:
    """The owner's session: id, address, key, sequence window and lease.

    Parameters
    ----------
    sid : int
        Session id (uint32, never 0).
    addr : hashable
        The client's address.
    key : bytes or None
        Session key (``None`` on an unauthenticated layer).
    server_nonce : bytes
        The server nonce of the handshake that opened it.
    welcome : bytes
        The Welcome datagram, sent again for a retransmitted OpenSession.
    t_ctrl : float
        Control time in s of the opening; the lease runs from here.
    """

    __slots__ = ("sid", "addr", "key", "client", "last_seen", "server_nonce", "welcome", "end_reason")

    def __init__(self, sid: int, addr: Hashable, key: bytes | None, server_nonce: bytes, welcome: bytes,
                 t_ctrl: float):
        self.sid, self.addr, self.key = sid, addr, key
        self.client = SeqWindow()
        self.last_seen = t_ctrl
        self.server_nonce = server_nonce
        self.welcome = welcome
        self.end_reason = ""

    def lease_left(self, t_ctrl: float, lease_s: float) -> float:
        """Control time in s until the lease ends without another valid datagram (negative: ended).

        Parameters
        ----------
        t_ctrl : float
            Control time now, s.
        lease_s : float
            Lease length, s.

        Returns
        -------
        float
        """
        return lease_s - (t_ctrl - self.last_seen)

    def lease_expired(self, t_ctrl: float, lease_s: float) -> bool:
        """True when more than ``lease_s`` of control time passed since the last valid datagram.

        Parameters
        ----------
        t_ctrl : float
            Control time now, s.
        lease_s : float
            Lease length, s.

        Returns
        -------
        bool
        """
        return t_ctrl - self.last_seen > lease_s


class SessionTable:
    """The lease holder, recently ended sessions, and pending handshake challenges.

    Parameters
    ----------
    max_challenges : int
        Bound of the table of pending challenges (oldest forgotten first).
    handshake_timeout_s : float
        A challenge not answered within this wall time is forgotten.
    max_ended : int
        Number of ended sessions remembered.

    Attributes
    ----------
    owner : Session or None
        The session that holds the lease.
    ended : collections.OrderedDict
        Session id -> ended :class:`Session`, oldest first.
    """

    def __init__(self, *, max_challenges: int, handshake_timeout_s: float, max_ended: int = 16):
        self.owner: Session | None = None
        self.ended: collections.OrderedDict = collections.OrderedDict()
        self.max_challenges, self.timeout_s, self.max_ended = int(max_challenges), handshake_timeout_s, max_ended
        self._challenges: collections.OrderedDict = collections.OrderedDict()   # nonce -> (addr, c nonce, t)

    def find(self, sid: int) -> Session | None:
        """The owner's or an ended session with this id, else ``None``.

        Parameters
        ----------
        sid : int
            Session id from a datagram's header (not 0).

        Returns
        -------
        Session or None
        """
        o = self.owner
        if o is not None and sid == o.sid:
            return o
        return self.ended.get(sid)

    def owner_addr(self) -> Hashable | None:
        """The lease holder's address, or ``None`` without an owner.

        Returns
        -------
        hashable or None
        """
        o = self.owner
        return None if o is None else o.addr

    def end(self, reason: str) -> Session | None:
        """End the owner's session (if any) and remember it as ended.

        Parameters
        ----------
        reason : str
            Why it ended (sent to the client with ``NO_SESSION`` refusals).

        Returns
        -------
        Session or None
            The ended session, or ``None`` without an owner.
        """
        o = self.owner
        if o is None:
            return None
        o.end_reason = reason
        self.owner = None
        self.ended[o.sid] = o
        while len(self.ended) > self.max_ended:
            self.ended.popitem(last=False)
        return o

    def new_sid(self) -> int:
        """A random session id, never 0 and never one of the remembered ended sessions.

        Returns
        -------
        int
        """
        while True:
            sid = int.from_bytes(os.urandom(4), "big")
            if sid and sid not in self.ended:
                return sid

    def expire_challenges(self, now: float) -> None:
        """Forget challenges older than the handshake timeout.

        Parameters
        ----------
        now : float
            Wall time in s (``time.monotonic``).
        """
        ch = self._challenges
        while ch and next(iter(ch.values()))[2] < now - self.timeout_s:
            ch.popitem(last=False)

    def challenge(self, addr: Hashable, client_nonce: bytes, now: float) -> bytes:
        """Record a challenge for a Hello and return its fresh server nonce.

        Parameters
        ----------
        addr : hashable
            The client's address.
        client_nonce : bytes
            The nonce of its Hello.
        now : float
            Wall time in s.

        Returns
        -------
        bytes
            The server nonce.
        """
        nonce = new_nonce()
        self._challenges[nonce] = (addr, client_nonce, now)
        while len(self._challenges) > self.max_challenges:
            self._challenges.popitem(last=False)
        return nonce

    def take_challenge(self, server_nonce: bytes, addr: Hashable, client_nonce: bytes) -> bool:
        """Use up a pending challenge; True if it was issued to this address for this client nonce.

        Parameters
        ----------
        server_nonce : bytes
            Server nonce of the OpenSession.
        addr : hashable
            The client's address.
        client_nonce : bytes
            Client nonce of the OpenSession.

        Returns
        -------
        bool
            False for an unknown, used or expired challenge (a replay).
        """
        pending = self._challenges.pop(server_nonce, None)
        return pending is not None and pending[0] == addr and pending[1] == client_nonce


class RateLimiter:
    """Token bucket per source address, bounded table (oldest sources forgotten).

    Parameters
    ----------
    rate_hz : float
        Tokens added per second.
    burst : float
        Bucket size.
    max_sources : int
        Number of sources remembered.
    """

    def __init__(self, rate_hz: float, burst: float, max_sources: int):
        self.rate, self.burst, self.max = float(rate_hz), float(burst), int(max_sources)
        self._buckets: collections.OrderedDict = collections.OrderedDict()

    def allow(self, addr: Hashable, now: float) -> bool:
        """Take a token for a datagram from ``addr``; False if its bucket is empty.

        Parameters
        ----------
        addr : hashable
            Source address.
        now : float
            Wall time in s.

        Returns
        -------
        bool
        """
        b = self._buckets.get(addr)
        if b is None:
            if len(self._buckets) >= self.max:
                self._buckets.popitem(last=False)
            self._buckets[addr] = [self.burst - 1.0, now]
            return True
        tokens = min(self.burst, b[0] + (now - b[1]) * self.rate)
        b[1] = now
        if tokens < 1.0:
            b[0] = tokens
            return False
        b[0] = tokens - 1.0
        return True


def is_loopback(addr) -> bool:
    """True for in-process addresses and IP addresses on loopback.

    Parameters
    ----------
    addr : hashable
        A transport address: ``(host, port)`` for UDP, anything else in process.

    Returns
    -------
    bool

    Examples
    --------
    >>> is_loopback(("127.0.0.1", 5005)), is_loopback(("192.0.2.1", 5005)), is_loopback("inproc")
    (True, False, True)
    """
    if not isinstance(addr, tuple):
        return True
    try:
        return ipaddress.ip_address(addr[0]).is_loopback
    except ValueError:
        return addr[0] == "localhost"
