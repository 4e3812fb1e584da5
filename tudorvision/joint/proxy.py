"""A lossy loopback UDP proxy for fault-injection tests of the joint protocol.

:class:`LossyUdpProxy` listens on 127.0.0.1, forwards datagrams from clients
to an upstream server and the answers back, and on the way applies a
:class:`FaultModel` per direction: independent loss, Gilbert-Elliott burst
loss, duplication, reordering (holding a datagram back so later ones
overtake it), byte corruption (one flipped byte, truncation or trailing
garbage: all detectable by the protocol's length and CRC32 checks), and
fixed plus random delay. Each direction draws from its own generator seeded
from ``seed``, so a seed reproduces the fault pattern of a direction for the
same sequence of datagrams.

The proxy runs in a daemon thread and stops by itself after
``max_duration_s`` or ``max_packets``.

Examples
--------
>>> import socket
>>> echo = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); echo.bind(("127.0.0.1", 0))
>>> with LossyUdpProxy(echo.getsockname(), seed=1, max_duration_s=5.0) as proxy:
...     c = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
...     c.sendto(b"hello", proxy.address)
...     data, via = echo.recvfrom(100)
5
>>> data, proxy.stats()["to_server"].delivered
(b'hello', 1)
>>> c.close(); echo.close()
"""
from __future__ import annotations

import heapq
import itertools
import random
import select
import socket
import threading
import time
from dataclasses import dataclass

__all__ = ["GilbertElliott", "FaultModel", "ProxyStats", "LossyUdpProxy"]


def _check_prob(obj, *names):
    for name in names:
        p = getattr(obj, name)
        if not 0.0 <= p <= 1.0:
            raise ValueError(f"{name}: expected a probability in [0, 1], got {p}")


@dataclass(frozen=True, kw_only=True)
class GilbertElliott:
    """Two-state burst-loss channel, stepped once per datagram.

    In the good state datagrams are lost with ``loss_good``, in the bad state
    with ``loss_bad``; the state flips good->bad with ``p_good_to_bad`` and
    bad->good with ``p_bad_to_good``. Mean burst length is ``1 / p_bad_to_good``.
    """

    p_good_to_bad: float
    p_bad_to_good: float
    loss_good: float = 0.0
    loss_bad: float = 1.0

    def __post_init__(self):
        _check_prob(self, "p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad")


@dataclass(frozen=True, kw_only=True)
class FaultModel:
    """Faults applied to one direction of the proxy. Probabilities per datagram; times in s."""

    loss: float = 0.0
    burst: GilbertElliott | None = None
    duplicate: float = 0.0
    reorder: float = 0.0
    reorder_delay_s: float = 0.03
    corrupt: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0

    def __post_init__(self):
        _check_prob(self, "loss", "duplicate", "reorder", "corrupt")
        for name in ("reorder_delay_s", "delay_s", "jitter_s"):
            if not 0.0 <= getattr(self, name) <= 10.0:
                raise ValueError(f"{name}: expected 0..10 s, got {getattr(self, name)}")


@dataclass(frozen=True, kw_only=True)
class ProxyStats:
    """Per-direction counts. ``corrupted`` counts delivered corrupted datagrams."""

    received: int = 0
    dropped: int = 0
    delivered: int = 0
    duplicated: int = 0
    corrupted: int = 0
    reordered: int = 0


class _Direction:
    def __init__(self, model: FaultModel, rng: random.Random):
        self.model = model
        self.rng = rng
        self.bad = False
        self.counts = dict.fromkeys(ProxyStats.__dataclass_fields__, 0)


class LossyUdpProxy:
    """Forward UDP between clients and ``upstream`` with injected faults.

    Parameters
    ----------
    upstream : tuple (host, port)
        The server; must be on loopback.
    to_server, to_client : FaultModel
        Faults for each direction.
    seed : int
        Seed of the proxy's own random generator.
    port : int
        Listening port on 127.0.0.1 (0: ephemeral); see :attr:`address`.
    max_duration_s, max_packets : float, int
        The proxy thread ends by itself after this time or this many datagrams.
    max_clients, max_pending : int
        Bounds on client sessions and on datagrams held back for delay.
    """

    def __init__(self, upstream: tuple[str, int], *, to_server: FaultModel = FaultModel(),
                 to_client: FaultModel = FaultModel(), seed: int = 0, port: int = 0,
                 max_duration_s: float = 60.0, max_packets: int = 200_000,
                 max_clients: int = 16, max_pending: int = 10_000):
        host = upstream[0]
        if host not in ("127.0.0.1", "localhost"):
            raise ValueError(f"upstream: the proxy is loopback-only, got host {host!r}")
        self.upstream = ("127.0.0.1", int(upstream[1]))
        self._dirs = {"to_server": _Direction(to_server, random.Random(2 * int(seed))),
                      "to_client": _Direction(to_client, random.Random(2 * int(seed) + 1))}
        self.max_duration_s = float(max_duration_s)
        self.max_packets = int(max_packets)
        self.max_clients = int(max_clients)
        self.max_pending = int(max_pending)
        self._listen = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._listen.bind(("127.0.0.1", int(port)))
        self._listen.setblocking(False)
        self._up_by_client: dict = {}     # client addr -> upstream socket
        self._client_by_up: dict = {}     # upstream socket -> client addr
        self._pending: list = []          # heap of (due, n, sock, data, dest, direction)
        self._tie = itertools.count()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self._n_packets = 0

    @property
    def address(self) -> tuple[str, int]:
        """``(host, port)`` clients send to."""
        return self._listen.getsockname()

    def stats(self) -> dict[str, ProxyStats]:
        """Counts per direction: ``{"to_server": ProxyStats, "to_client": ProxyStats}``."""
        with self._lock:
            return {k: ProxyStats(**d.counts) for k, d in self._dirs.items()}

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> "LossyUdpProxy":
        if self.running:
            raise RuntimeError("proxy already running")
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="lossy-udp-proxy", daemon=True)
        self._thread.start()
        return self

    def wait_idle(self, timeout: float = 2.0) -> bool:
        """Wait until no delayed datagram is pending; False on timeout."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if not self._pending:
                    return True
            time.sleep(0.005)
        return False

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the thread (pending datagrams are discarded) and close the sockets."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        for s in [self._listen, *self._client_by_up]:
            s.close()
        self._up_by_client.clear()
        self._client_by_up.clear()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    # ---------------------------------------------------------------- faults
    @staticmethod
    def _corrupt(data: bytes, r: random.Random) -> bytes:
        kind = r.random()
        if kind < 0.6 or len(data) < 2:
            b = bytearray(data)
            i = r.randrange(len(b))
            b[i] ^= r.randrange(1, 256)
            return bytes(b)
        if kind < 0.8:
            return data[:r.randrange(len(data))]
        return data + bytes(r.randrange(256) for _ in range(r.randrange(1, 9)))

    def _admit(self, direction: str, data: bytes, sock, dest, now: float) -> None:
        d = self._dirs[direction]
        m, r = d.model, d.rng
        with self._lock:
            d.counts["received"] += 1
            lost = r.random() < m.loss
            if m.burst is not None:
                flip = m.burst.p_bad_to_good if d.bad else m.burst.p_good_to_bad
                if r.random() < flip:
                    d.bad = not d.bad
                lost |= r.random() < (m.burst.loss_bad if d.bad else m.burst.loss_good)
            if lost or len(self._pending) >= self.max_pending:
                d.counts["dropped"] += 1
                return
            corrupted = r.random() < m.corrupt
            if corrupted:
                data = self._corrupt(data, r)
            copies = 2 if r.random() < m.duplicate else 1
            d.counts["duplicated"] += copies - 1
            for _ in range(copies):
                due = now + m.delay_s + (r.random() * m.jitter_s if m.jitter_s else 0.0)
                if r.random() < m.reorder:
                    due += m.reorder_delay_s
                    d.counts["reordered"] += 1
                heapq.heappush(self._pending, (due, next(self._tie), sock, data, dest, direction,
                                               corrupted))

    def _release(self, now: float) -> None:
        while True:
            with self._lock:
                if not self._pending or self._pending[0][0] > now:
                    return
                _, _, sock, data, dest, direction, corrupted = heapq.heappop(self._pending)
                d = self._dirs[direction]
                d.counts["delivered"] += 1
                d.counts["corrupted"] += int(corrupted)
            try:
                sock.sendto(data, dest)
            except OSError:
                pass

    def _upstream_for(self, client):
        s = self._up_by_client.get(client)
        if s is None:
            if len(self._up_by_client) >= self.max_clients:
                return None
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind(("127.0.0.1", 0))
            s.setblocking(False)
            self._up_by_client[client] = s
            self._client_by_up[s] = client
        return s

    def _run(self) -> None:
        end = time.monotonic() + self.max_duration_s
        while not self._stop.is_set() and self._n_packets < self.max_packets:
            now = time.monotonic()
            if now >= end:
                break
            with self._lock:
                due = self._pending[0][0] if self._pending else now + 0.01
            wait = min(max(due - now, 0.0), 0.01)
            socks = [self._listen, *self._client_by_up]
            try:
                ready, _, _ = select.select(socks, [], [], wait)
            except (OSError, ValueError):
                break
            now = time.monotonic()
            for s in ready:
                for _ in range(256):
                    try:
                        data, src = s.recvfrom(65535)
                    except (BlockingIOError, ConnectionRefusedError):
                        break
                    except OSError:
                        return
                    self._n_packets += 1
                    if s is self._listen:
                        up = self._upstream_for(src)
                        if up is not None:
                            self._admit("to_server", data, up, self.upstream, now)
                    else:
                        self._admit("to_client", data, self._listen, self._client_by_up[s], now)
            self._release(time.monotonic())
