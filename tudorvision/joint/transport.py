"""Datagram transports between the adapter and the joint-control layer.

Both transports carry the same encoded datagrams and share one interface
(:class:`Transport`), so the adapter and the server never know which one
they use:

* :class:`UdpTransport` - a real UDP socket (bound on 127.0.0.1 by default);
* :class:`InProcessTransport` - a pair of thread-safe queues, for tests and
  for running perception and the simulated layer in one process.

Examples
--------
>>> client, server = InProcessTransport.pair()
>>> client.send(b"ping")
>>> data, addr = server.recv(timeout=1.0)
>>> server.send(b"pong", addr)
>>> client.recv(timeout=1.0)[0]
b'pong'
"""
from __future__ import annotations

import itertools
import queue
import select
import socket
import threading
from typing import Hashable, Protocol

__all__ = ["Transport", "UdpTransport", "InProcessTransport", "LockstepClientTransport", "TransportClosed"]

Address = Hashable


class TransportClosed(OSError):
    """Operation on a closed transport."""


class Transport(Protocol):
    """What the adapter and the server need from a datagram transport."""

    def send(self, data: bytes, addr: Address | None = None) -> None:
        """Send one datagram to ``addr`` (``None``: the transport's fixed peer)."""

    def recv(self, timeout: float) -> tuple[bytes, Address] | None:
        """Wait at most ``timeout`` s for one datagram; ``None`` if none arrived."""

    def close(self) -> None:
        """Release the transport; later calls raise :class:`TransportClosed`."""


class UdpTransport:
    """A UDP socket with an optional fixed peer.

    Parameters
    ----------
    host : str
        Local address to bind; loopback by default.
    port : int
        Local port; 0 picks an ephemeral port.
    peer : tuple (host, port) or None
        Default destination of :meth:`send`. When given, datagrams from other
        sources are dropped and counted in ``foreign``.
    rcvbuf : int or None
        Receive buffer size to ask the kernel for, bytes (it may grant less:
        ``net.core.rmem_max``); :attr:`rcvbuf` holds what it granted.

    Use :meth:`server` and :meth:`client` to build the two ends.
    """

    #: Receive buffer a server asks for: 4 MiB, about 30 000 command datagrams of backlog.
    SERVER_RCVBUF = 4 * 1024 * 1024

    def __init__(self, *, host: str = "127.0.0.1", port: int = 0,
                 peer: tuple[str, int] | None = None, rcvbuf: int | None = None):
        if not 0 <= int(port) <= 65535:
            raise ValueError(f"port: expected 0..65535, got {port}")
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            if rcvbuf is not None:
                self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, int(rcvbuf))
            self._sock.bind((host, int(port)))
        except OSError:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self.peer = None if peer is None else (socket.gethostbyname(peer[0]), int(peer[1]))
        self.foreign = 0          # datagrams from a source other than the peer
        self.send_errors = 0      # sendto failures (e.g. ICMP errors reported late)
        self._closed = False
        self.rcvbuf = self._sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)

    @classmethod
    def server(cls, port: int = 0, host: str = "127.0.0.1") -> "UdpTransport":
        """A transport bound on ``host:port`` that answers whoever writes to it (large receive buffer)."""
        return cls(host=host, port=port, rcvbuf=cls.SERVER_RCVBUF)

    @classmethod
    def client(cls, port: int, host: str = "127.0.0.1") -> "UdpTransport":
        """A transport on an ephemeral local port that talks to ``host:port``."""
        if not 0 < int(port) <= 65535:
            raise ValueError(f"port: expected 1..65535, got {port}")
        return cls(host="127.0.0.1" if host in ("127.0.0.1", "localhost") else "0.0.0.0",
                   port=0, peer=(host, port))

    @property
    def address(self) -> tuple[str, int]:
        """Local ``(host, port)``."""
        return self._sock.getsockname()

    def fileno(self) -> int:
        return self._sock.fileno()

    def send(self, data: bytes, addr: Address | None = None) -> None:
        if self._closed:
            raise TransportClosed("send on a closed UdpTransport")
        dest = self.peer if addr is None else addr
        if dest is None:
            raise ValueError("addr: required for a transport without a peer")
        try:
            self._sock.sendto(data, dest)
        except (BlockingIOError, ConnectionRefusedError):
            self.send_errors += 1   # datagram semantics: a lost send is a lost packet

    def recv(self, timeout: float) -> tuple[bytes, Address] | None:
        if self._closed:
            raise TransportClosed("recv on a closed UdpTransport")
        while True:
            try:
                data, addr = self._sock.recvfrom(65535)
            except BlockingIOError:
                if timeout <= 0:
                    return None
                ready, _, _ = select.select([self._sock], [], [], timeout)
                if not ready:
                    return None
                timeout = 0.0    # one more non-blocking try, then give up
                continue
            except ConnectionRefusedError:
                continue         # ICMP port unreachable from an earlier send
            if self.peer is not None and addr != self.peer:
                self.foreign += 1
                continue
            return data, addr

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class InProcessTransport:
    """One end of an in-process datagram pipe; build both ends with :meth:`pair`.

    Datagrams are ``bytes`` objects passed through a :class:`queue.Queue`, in
    order and without loss. The address of the other end is ``peer_name``.
    """

    _ids = itertools.count(1)

    def __init__(self, name: str, inbox: queue.Queue, outbox: queue.Queue, peer_name: str):
        self.name = name
        self.peer_name = peer_name
        self._inbox = inbox
        self._outbox = outbox
        self._closed = threading.Event()

    @classmethod
    def pair(cls, maxsize: int = 10000) -> tuple["InProcessTransport", "InProcessTransport"]:
        """Return ``(client_end, server_end)`` connected to each other.

        ``maxsize`` bounds each direction; datagrams beyond it are dropped like
        a full socket buffer would.
        """
        n = next(cls._ids)
        a, b = queue.Queue(maxsize), queue.Queue(maxsize)
        client = cls(f"inproc-client-{n}", inbox=a, outbox=b, peer_name=f"inproc-server-{n}")
        server = cls(f"inproc-server-{n}", inbox=b, outbox=a, peer_name=f"inproc-client-{n}")
        return client, server

    @property
    def address(self) -> str:
        return self.name

    def send(self, data: bytes, addr: Address | None = None) -> None:
        if self._closed.is_set():
            raise TransportClosed("send on a closed InProcessTransport")
        if addr is not None and addr != self.peer_name:
            raise ValueError(f"addr: {addr!r} is not the peer {self.peer_name!r}")
        try:
            self._outbox.put_nowait((bytes(data), self.name))
        except queue.Full:
            pass

    def recv(self, timeout: float) -> tuple[bytes, Address] | None:
        if self._closed.is_set():
            raise TransportClosed("recv on a closed InProcessTransport")
        try:
            if timeout <= 0:
                return self._inbox.get_nowait()
            return self._inbox.get(timeout=timeout)
        except queue.Empty:
            return None

    def close(self) -> None:
        self._closed.set()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class LockstepClientTransport:
    """Client end for a layer driven in simulated time (:meth:`JointLayerServer.tick`).

    Wraps the client end of an in-process pair; every :meth:`send` lets the
    lockstep server handle the datagram at once (``server.poll()``), so a
    request's answer is already waiting when the adapter reads it and
    :meth:`recv` never blocks. With a wall-clock server thread use the plain
    :class:`InProcessTransport` instead.

    Parameters
    ----------
    inner : InProcessTransport
        Client end of :meth:`InProcessTransport.pair`.
    server : object with ``poll()``
        The :class:`~tudorvision.joint.server.JointLayerServer` on the other end.
    """

    def __init__(self, inner: InProcessTransport, server):
        self._inner, self._server = inner, server

    @property
    def address(self):
        return self._inner.address

    def send(self, data: bytes, addr: Address | None = None) -> None:
        self._inner.send(data, addr)
        self._server.poll()

    def recv(self, timeout: float) -> tuple[bytes, Address] | None:
        return self._inner.recv(0.0)

    def close(self) -> None:
        self._inner.close()
