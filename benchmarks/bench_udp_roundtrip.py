"""Loopback round-trip latency of StateRequest -> State through the joint adapter.

Measures, in one run:

1. ``adapter/udp``   - ``JointAdapter.request_state`` over UDP on 127.0.0.1 to a
   ``JointLayerServer`` (kinematic core) running in a thread of this process,
   in the adapter's session (protocol v2, no key);
2. ``adapter/udp+hmac`` - the same with a key: every datagram carries and is
   checked against an HMAC-SHA256 tag (stdlib ``hmac``);
3. ``adapter/inproc`` - the same as 1 over the in-process transport;
4. ``peer/udp``      - a bare ``socket.sendto``/``recvfrom`` echo with the
   authenticated request and reply sizes, no protocol, echo in a thread;

and with ``--processes`` the UDP server (``tudorvision joint serve``, with
``--key-file``) and the bare echo in separate processes (no GIL sharing,
closer to the lab). Prints p50/p99 in microseconds and the overhead ratio
adapter/peer.

Run: ``.venv/bin/python benchmarks/bench_udp_roundtrip.py [--n 5000] [--processes]``
"""
from __future__ import annotations

import argparse
import os
import platform
import socket
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

from tudorvision.joint import protocol as P
from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.server import JointLayerServer, KinematicCore, ServerConfig
from tudorvision.joint.transport import InProcessTransport, UdpTransport

KEY = bytes(range(32))
REQ_SIZE = len(P.encode(P.StateRequest(), 1, 0.0, key=KEY))
REPLY_SIZE = len(P.encode(P.State(t=0.0, theta=(0, 0, 0), theta_dot=(0, 0, 0)), 1, 0.0, key=KEY))

ECHO_SRC = f"""
import socket, sys
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0))
print(s.getsockname()[1], flush=True)
reply = bytes({REPLY_SIZE}); s.settimeout(float(sys.argv[1]))
try:
    while True:
        data, addr = s.recvfrom(2048)
        s.sendto(reply, addr)
except socket.timeout:
    pass
"""


def _adapter_times(adapter, n, warmup):
    if not isinstance(adapter.open_session(timeout=2.0), P.Welcome):   # the owner: no rate limit
        raise RuntimeError("could not open a session")
    out = np.empty(n)
    for i in range(warmup + n):
        t0 = time.perf_counter()
        st = adapter.request_state(timeout=1.0)
        dt = time.perf_counter() - t0
        if st is None:
            raise RuntimeError("no answer from the server")
        if i >= warmup:
            out[i - warmup] = dt
    return out


def _peer_times(port, n, warmup):
    c = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    c.bind(("127.0.0.1", 0))
    c.settimeout(1.0)
    req = bytes(REQ_SIZE)
    out = np.empty(n)
    for i in range(warmup + n):
        t0 = time.perf_counter()
        c.sendto(req, ("127.0.0.1", port))
        data, _ = c.recvfrom(2048)
        dt = time.perf_counter() - t0
        if len(data) != REPLY_SIZE:
            raise RuntimeError("bad echo")
        if i >= warmup:
            out[i - warmup] = dt
    c.close()
    return out


def _echo_thread(stop):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(0.1)
    reply = bytes(REPLY_SIZE)

    def run():
        while not stop.is_set():
            try:
                data, addr = s.recvfrom(2048)
            except socket.timeout:
                continue
            s.sendto(reply, addr)
        s.close()
    threading.Thread(target=run, daemon=True).start()
    return s.getsockname()[1]


def _row(name, t):
    us = t * 1e6
    p50, p99 = np.percentile(us, [50, 99])
    print(f"{name:<26s} p50 {p50:8.1f} us   p99 {p99:8.1f} us   mean {us.mean():8.1f} us")
    return p50, p99


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=5000, help="timed round trips per case")
    ap.add_argument("--warmup", type=int, default=200)
    ap.add_argument("--rate", type=float, default=500.0, help="server control rate in Hz")
    ap.add_argument("--processes", action="store_true",
                    help="also run server and echo peer as separate processes")
    args = ap.parse_args(argv)
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo")
                if ln.startswith("model name")), platform.processor())
    print(f"machine: {cpu}, {platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}")
    print(f"payloads with tag: request {REQ_SIZE} B, reply {REPLY_SIZE} B (without: "
          f"{REQ_SIZE - P.TAG_SIZE} / {REPLY_SIZE - P.TAG_SIZE} B); n = {args.n}; "
          f"server rate {args.rate:g} Hz\n")
    cfg = ServerConfig(rate_hz=args.rate)
    res = {}

    end = UdpTransport.server(0)
    with JointLayerServer(end, KinematicCore(), config=cfg):
        with JointAdapter(UdpTransport.client(end.address[1])) as a:
            res["adapter/udp"] = _row("adapter/udp (thread)",
                                      _adapter_times(a, args.n, args.warmup))
    end.close()

    end = UdpTransport.server(0)
    with JointLayerServer(end, KinematicCore(), config=cfg, key=KEY):
        with JointAdapter(UdpTransport.client(end.address[1]), key=KEY) as a:
            res["adapter/udp+hmac"] = _row("adapter/udp+hmac (thread)",
                                           _adapter_times(a, args.n, args.warmup))
    end.close()

    client, end = InProcessTransport.pair()
    with JointLayerServer(end, KinematicCore(), config=cfg):
        with JointAdapter(client) as a:
            res["adapter/inproc"] = _row("adapter/inproc (thread)",
                                         _adapter_times(a, args.n, args.warmup))

    stop = threading.Event()
    port = _echo_thread(stop)
    res["peer/udp"] = _row("peer bare udp echo (thread)", _peer_times(port, args.n, args.warmup))
    stop.set()

    if args.processes:
        keydir = tempfile.TemporaryDirectory()
        keyfile = os.path.join(keydir.name, "joint.key")
        P.write_key_file(keyfile)
        srv = subprocess.Popen([sys.executable, "-m", "tudorvision.cli", "joint", "serve",
                                "--port", "0", "--duration", "300", "--rate", str(args.rate),
                                "--key-file", keyfile],
                               stdout=subprocess.PIPE, text=True)
        echo = subprocess.Popen([sys.executable, "-c", ECHO_SRC, "30"],
                                stdout=subprocess.PIPE, text=True)
        try:
            sport = int(srv.stdout.readline().rsplit(":", 1)[1])
            eport = int(echo.stdout.readline())
            with JointAdapter(UdpTransport.client(sport), key=P.read_key_file(keyfile)) as a:
                res["adapter/udp+hmac/proc"] = _row("adapter/udp+hmac (process)",
                                                    _adapter_times(a, args.n, args.warmup))
            res["peer/udp/proc"] = _row("peer bare udp echo (process)",
                                        _peer_times(eport, args.n, args.warmup))
        finally:
            srv.terminate()
            echo.terminate()
            srv.wait(5)
            echo.wait(5)
            keydir.cleanup()

    print()
    for a, b in (("adapter/udp", "peer/udp"), ("adapter/udp+hmac", "peer/udp"),
                 ("adapter/udp+hmac", "adapter/udp"), ("adapter/udp+hmac/proc", "peer/udp/proc"),
                 ("adapter/inproc", "peer/udp")):
        if a in res and b in res:
            print(f"overhead {a} / {b}: p50 x{res[a][0] / res[b][0]:.2f}, "
                  f"p99 x{res[a][1] / res[b][1]:.2f}")


if __name__ == "__main__":
    main()
