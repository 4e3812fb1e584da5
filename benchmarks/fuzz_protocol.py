"""Fuzz the joint protocol decoder (and the layer's datagram handler) and report crashes.

A *crash* is any exception other than :class:`~tudorvision.joint.protocol.ProtocolError`
from :func:`~tudorvision.joint.protocol.decode`, a decoded message that does
not re-encode to itself, a tampered authenticated datagram that decodes, or
a datagram that makes the server fault or move. Cases, drawn from a seeded
``random.Random``:

* ``random``   - random bytes (0..1500);
* ``mutated``  - valid datagrams of every message type with 1-4 byte flips,
  truncation or trailing bytes (unkeyed and keyed);
* ``sealed``   - a correct header, length and CRC around random payload bytes
  of the right size for the type (reaches every payload decoder);
* ``server``   - batches of the above handed to a ``JointLayerServer`` (no session).

Run: ``.venv/bin/python benchmarks/fuzz_protocol.py [--cases 100000] [--seed 0]``;
exit status 1 when any crash was found (the first few are printed).
"""
from __future__ import annotations

import argparse
import os
import platform
import random
import struct
import sys
import time
import traceback
import zlib

from tudorvision.joint import protocol as P
from tudorvision.joint.server import CoreState, JointLayerServer, KinematicCore, ServerConfig
from tudorvision.joint.transport import InProcessTransport

KEY = bytes(range(32))


def _valid_messages(r: random.Random):
    f = lambda: r.uniform(-10, 10)  # noqa: E731
    return [
        P.JointVelocityCommand(theta_dot=(f(), f(), f())),
        P.JointSetpoint(theta=(f(), f(), f()), max_speed=r.choice([None, f()]), max_accel=r.choice([None, f()])),
        P.ModeSwitch(mode=r.choice([None, *P.Mode]), damping=r.choice([None, *P.Damping])),
        P.PayloadUpdate(payload_kg=f()), P.StateRequest(), P.FaultReset(), P.Release(),
        P.State(t=f(), theta=(f(), f(), f()), theta_dot=(f(), f(), f()), flags=r.randrange(512)),
        P.Ack(command_seq=r.randrange(2**32), text="ok"),
        P.Refusal(command_seq=r.randrange(2**32), code=P.Reason.FAULT, text="no"),
        P.Hello(client_nonce=r.randbytes(16)),
        P.Challenge(client_nonce=r.randbytes(16), server_nonce=r.randbytes(16)),
        P.OpenSession(client_nonce=r.randbytes(16), server_nonce=r.randbytes(16), takeover=r.random() < 0.5),
        P.Welcome(client_nonce=r.randbytes(16), session=r.randrange(1, 2**32), lease_s=r.uniform(0.1, 5)),
    ]


def _sealed(r: random.Random) -> bytes:
    mtype = r.choice(list(P._SIZES)) if r.random() < 0.9 else r.randrange(256)
    size = P._SIZES.get(mtype, r.randrange(64))
    payload = r.randbytes(size)
    head = struct.pack("!4sBBBBIIdII", P.MAGIC, P.VERSION, int(mtype), 0, 0, r.randrange(2**32),
                       r.randrange(2**32), r.uniform(-1e6, 1e6), len(payload), 0)
    crc = zlib.crc32(payload, zlib.crc32(head))
    return head[:-4] + crc.to_bytes(4, "big") + payload


def _mutate(r: random.Random, data: bytes) -> bytes:
    b = bytearray(data)
    kind = r.random()
    if kind < 0.7:
        for i in r.sample(range(len(b)), min(len(b), r.randint(1, 4))):
            b[i] ^= r.randrange(1, 256)
    elif kind < 0.85:
        del b[r.randrange(len(b)):]
    else:
        b += r.randbytes(r.randint(1, 16))
    return bytes(b)


def _check_decode(data: bytes, key, *, tampered: bool) -> str | None:
    """None if fine, else a description of the crash."""
    try:
        header, msg = P.decode(data, key=key)
    except P.ProtocolError:
        return None
    except Exception:  # noqa: BLE001 - that is what we count
        return f"decode raised: {traceback.format_exc(limit=3)}"
    if tampered and key is not None:
        return "tampered authenticated datagram decoded"
    try:
        again = P.decode(P.encode(msg, header.seq, header.t_sent, session=header.session, key=key), key=key)[1]
    except Exception:  # noqa: BLE001
        return f"re-encode raised: {traceback.format_exc(limit=3)}"
    if again != msg:
        return f"round trip changed {msg!r} into {again!r}"
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=100_000, help="decoder cases (default 1e5)")
    ap.add_argument("--server-batches", type=int, default=2000, help="batches of 20 for the server")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    r = random.Random(args.seed)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    crashes, counts = [], {"random": 0, "mutated": 0, "sealed": 0, "server": 0}
    outcomes = {"decoded": 0, "refused": 0}
    t0 = time.perf_counter()
    for i in range(args.cases):
        pick = i % 3
        key = KEY if r.random() < 0.5 else None
        if pick == 0:
            data, tampered, kind = r.randbytes(r.randrange(1500)), False, "random"
        elif pick == 1:
            msg = r.choice(_valid_messages(r))
            good = P.encode(msg, r.randrange(2**32), r.uniform(0, 1e5), key=key)
            data, tampered, kind = _mutate(r, good), True, "mutated"
        else:
            data, tampered, kind = _sealed(r), False, "sealed"
            key = None
        counts[kind] += 1
        err = _check_decode(data, key, tampered=tampered)
        if err is not None:
            crashes.append((kind, data.hex(), err))
        else:
            try:
                P.decode(data, key=key)
                outcomes["decoded"] += 1
            except P.ProtocolError:
                outcomes["refused"] += 1
    t_dec = time.perf_counter() - t0

    core = KinematicCore()
    client, end = InProcessTransport.pair(maxsize=100_000)
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=100.0))
    theta0 = core.state().theta.copy()
    t0 = time.perf_counter()
    for _ in range(args.server_batches):
        for _ in range(20):
            choice = r.random()
            if choice < 0.4:
                data = _sealed(r)
            elif choice < 0.8:
                data = _mutate(r, P.encode(r.choice(_valid_messages(r)), r.randrange(2**32), 0.0))
            else:
                data = r.randbytes(r.randrange(200))
            client.send(data)
            counts["server"] += 1
        server.tick(0.01)
        while client.recv(0.0) is not None:
            pass
    t_srv = time.perf_counter() - t0
    st: CoreState = core.state()
    c = server.counters
    if c.faults or server.owner is not None or (st.theta != theta0).any():
        crashes.append(("server", "", f"faults {c.faults}, owner {server.owner}, moved {st.theta - theta0}"))

    total = sum(counts.values())
    print(f"cases: {total} ({', '.join(f'{k} {v}' for k, v in counts.items())}); seed {args.seed}")
    print(f"decoder: {args.cases} cases in {t_dec:.1f} s ({args.cases / t_dec:,.0f}/s): "
          f"{outcomes['decoded']} decoded, {outcomes['refused']} refused as ProtocolError")
    print(f"server: {counts['server']} datagrams in {t_srv:.1f} s: malformed {c.malformed}, "
          f"not_owner {c.not_owner}, unauthenticated {c.unauthenticated}, replayed {c.replayed}, "
          f"faults {c.faults}")
    print(f"crashes: {len(crashes)}")
    for kind, hexdata, err in crashes[:5]:
        print(f"  [{kind}] {hexdata[:120]}\n    {err}")
    return 1 if crashes else 0


if __name__ == "__main__":
    sys.exit(main())
