"""Issue 14, joint layer under load and loss of its client, on real loopback UDP sockets.

* a stranger floods 10 000 datagrams/s for ~1.5 s while the owner servos at 50 Hz:
  no spurious watchdog stop, every owner command accepted, tick p99 inside half the watchdog;
* the owning client process is killed (SIGKILL) while the arm moves: the
  watchdog starts the controlled stop within 100 ms of its last command.

Both are bounded (subprocesses with timeouts, loops with deadlines).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np

from test_joint_adapter_core import AMAX, RigidTestCore
from tudorvision.joint import protocol as P
from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.protocol import Ack, Mode, Reason
from tudorvision.joint.safety import stopping_time
from tudorvision.joint.server import JointLayerServer, ServerConfig
from tudorvision.joint.transport import UdpTransport

RATE = 500.0
WATCHDOG = 0.1
FLOOD_S = 1.5
FLOOD_HZ = 10_000

FLOODER = r"""
import socket, sys, time
port, rate, duration = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
data = bytes.fromhex(sys.argv[4])
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0))
print("ready", flush=True)
t0 = time.monotonic(); sent = 0
while True:
    now = time.monotonic() - t0
    if now >= duration:
        break
    due = int(now * rate) - sent
    for _ in range(min(due, 200)):
        s.sendto(data, ("127.0.0.1", port)); sent += 1
    time.sleep(0.0005)
print(sent, flush=True)
"""

CLIENT = r"""
import sys, time
from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.protocol import Mode
from tudorvision.joint.transport import UdpTransport
a = JointAdapter(UdpTransport.client(int(sys.argv[1])))
assert a.set_mode(Mode.VELOCITY, timeout=3.0) is not None
t0 = time.monotonic()
said = False
while time.monotonic() - t0 < 20.0:          # bounded even if never killed
    a.send_velocity([0.3, 0.0, 0.0])
    if not said and time.monotonic() - t0 > 0.3:
        print("moving", flush=True); said = True
    time.sleep(0.01)
"""


def _env():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}


def test_flood_from_a_stranger_neither_stops_nor_starves_the_owner():
    core = RigidTestCore()
    end = UdpTransport.server(0)
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=RATE, watchdog_s=WATCHDOG)).start()
    owner = JointAdapter(UdpTransport.client(end.address[1]))
    junk = P.encode(P.JointVelocityCommand(theta_dot=(1.0, 1.0, 1.0)), 1, 0.0)   # a stranger's command
    flood = subprocess.Popen([sys.executable, "-c", FLOODER, str(end.address[1]), str(FLOOD_HZ),
                              str(FLOOD_S), junk.hex()], stdout=subprocess.PIPE, text=True)
    try:
        assert isinstance(owner.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
        assert flood.stdout.readline().strip() == "ready"
        t0 = time.monotonic()
        seqs = []
        while time.monotonic() - t0 < FLOOD_S - 0.2:            # owner servoing at 50 Hz
            seqs.append(owner.send_velocity([0.02, 0.0, 0.0]))
            time.sleep(0.02)
        st = owner.request_state(timeout=1.0)                    # during the flood
        sent = int(flood.communicate(timeout=10.0)[0].split()[-1])
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline and any(owner.reply_for(s) is None for s in seqs):
            owner.poll()
            time.sleep(0.01)
    finally:
        if flood.poll() is None:
            flood.kill()
            flood.wait(5)
        server.shutdown()
        owner.close()
        end.close()
    c = st.counters
    print(f"\nflood: {sent} datagrams in {FLOOD_S} s; rate_limited {c.rate_limited}, "
          f"not_owner {c.not_owner}; tick p50 {st.tick_p50_s * 1e3:.2f} ms, "
          f"p99 {st.tick_p99_s * 1e3:.2f} ms, max {st.tick_max_s * 1e3:.2f} ms")
    assert sent > 0.8 * FLOOD_HZ * FLOOD_S
    assert c.watchdog_stops == 0 and c.faults == 0                 # no spurious stop
    assert c.rate_limited > 0.5 * sent * (FLOOD_S - 0.3) / FLOOD_S   # dropped before decoding
    replies = [owner.reply_for(s) for s in seqs]
    assert all(r is not None and r.code == Reason.OK for r in replies), \
        sum(r is None for r in replies)
    # not starved: the loop keeps ticking well inside its watchdog. The tick's p99 itself is load-dependent
    # (2.1 ms alone, 11.7 ms once under `pytest -n 2` on two cores), so its figure is reported, not asserted
    assert st.tick_p50_s > 0 and st.tick_p99_s < 0.5 * WATCHDOG, st.tick_p99_s
    assert core.velocity_calls and all(np.allclose(v[1:], 0.0) for v in core.velocity_calls)


def test_killed_client_gets_a_controlled_stop_within_100_ms():
    core = RigidTestCore()
    end = UdpTransport.server(0)
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=RATE, watchdog_s=WATCHDOG)).start()
    proc = subprocess.Popen([sys.executable, "-c", CLIENT, str(end.address[1])],
                            stdout=subprocess.PIPE, text=True, env=_env())
    try:
        assert proc.stdout.readline().strip() == "moving"
        assert core.wait_until(lambda c: c.v[0] >= 0.3 - 1e-9, timeout=3.0)
        proc.send_signal(signal.SIGKILL)
        proc.wait(5)
        t_kill = time.monotonic()
        assert core.wait_until(lambda c: np.all(c.v == 0.0), timeout=3.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        server.shutdown()
        end.close()
    last = server.command_log()[-1]
    stop = next(e for e in server.events() if e.kind == "watchdog_stop")
    hist = core.history()
    t_rest = hist[(hist[:, 0] > stop.t_core) & np.all(hist[:, 4:7] == 0.0, axis=1), 0].min()
    print(f"\nkilled client: watchdog stop {1e3 * (stop.t_wall - last.t_wall):.1f} ms (wall) / "
          f"{1e3 * (stop.t_core - last.t_core):.1f} ms (control time) after its last command, "
          f"{1e3 * (stop.t_wall - t_kill):.1f} ms after the kill returned; at rest "
          f"{1e3 * (t_rest - stop.t_core):.1f} ms later")
    assert stop.t_core - last.t_core <= WATCHDOG + 2.0 / RATE + 1e-9
    # wall clock: the thread's scheduling on a loaded two-core CI machine adds to it (30 ms measured alone); the
    # control-time bound above is the layer's own promise
    assert stop.t_wall - last.t_wall <= WATCHDOG + 0.1
    assert t_rest - stop.t_core <= stopping_time([0.3, 0, 0], AMAX) + 2.0 / RATE
