"""Fault injection: adapter -> lossy proxy -> server over real UDP on 127.0.0.1.

Whatever the link does (loss, bursts, duplication, reordering, corruption,
delay), the arm stays inside its ranges and speed/acceleration limits, never
executes a corrupted command, ignores duplicates and stale commands, and
stops by itself once velocity commands cease.
"""
from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from test_joint_adapter_core import AMAX, VMAX, RigidTestCore, assert_within_limits
from tudorvision.joint import protocol as P
from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.protocol import Ack, Mode, Reason
from tudorvision.joint.proxy import FaultModel, GilbertElliott, LossyUdpProxy
from tudorvision.joint.safety import SafetyLimits, stopping_time
from tudorvision.joint.server import JointLayerServer, ServerConfig
from tudorvision.joint.transport import UdpTransport

RATE = 500.0
WATCHDOG = 0.1
BURST = GilbertElliott(p_good_to_bad=0.05, p_bad_to_good=0.3, loss_good=0.0, loss_bad=0.9)
SCENARIOS = {
    "loss30": FaultModel(loss=0.3),
    "bursts": FaultModel(burst=BURST),
    "dup_reorder_delay": FaultModel(duplicate=0.25, reorder=0.25, reorder_delay_s=0.03,
                                    delay_s=0.002, jitter_s=0.01),
    "corrupt": FaultModel(corrupt=0.25),
    "everything": FaultModel(loss=0.3, burst=BURST, duplicate=0.15, reorder=0.15,
                             reorder_delay_s=0.03, corrupt=0.15, delay_s=0.002, jitter_s=0.01),
}


def _wait(predicate, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return predicate()


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_arm_stays_safe_through_a_faulty_link(name):
    model = SCENARIOS[name]
    soft = SafetyLimits.from_params().soft_limits_rad
    core = RigidTestCore(theta0=(0.0, 1.0, soft[2, 1] - 0.6))     # joint 3 near its limit
    server_end = UdpTransport.server(0)
    server = JointLayerServer(server_end, core,
                              config=ServerConfig(rate_hz=RATE, watchdog_s=WATCHDOG)).start()
    proxy = LossyUdpProxy(server_end.address, to_server=model, to_client=model, seed=11,
                          max_duration_s=30.0).start()
    adapter = JointAdapter(UdpTransport.client(proxy.address[1]), retry_interval_s=0.03)
    rng = np.random.default_rng(5)
    try:
        assert isinstance(adapter.set_mode(Mode.VELOCITY, timeout=5.0), Ack)
        # ---- servoing: 0.5 s of velocity commands at 100 Hz, some too fast, pushing joint 3 up
        sent = {}
        for _ in range(50):
            v = rng.uniform(-1.3, 1.3, 3) * VMAX
            v[0] = 1.3 * VMAX[0]       # held: the speed clamp must act
            v[2] = abs(v[2])
            sent[adapter.send_velocity(v)] = tuple(float(x) for x in v)
            time.sleep(0.01)
        # ---- commands cease: the layer stops the arm by itself
        assert core.wait_until(lambda c: np.all(c.v == 0.0), timeout=10.0)
        # ---- catching: a setpoint through the same link, executed exactly once
        assert isinstance(adapter.set_mode(Mode.SETPOINT, timeout=5.0), Ack)
        here = adapter.request_state(timeout=5.0)
        assert here is not None and np.allclose(here.theta_dot, 0.0)
        target = np.asarray(here.theta) + [-0.2, 0.1, -0.2]
        reply = adapter.send_setpoint(target, max_speed=1.5, max_accel=6.0, timeout=5.0)
        assert isinstance(reply, Ack) and reply.code == Reason.OK
        assert adapter.wait_settled(target, tol=1e-3, timeout=10.0) is not None
        assert proxy.wait_idle(timeout=2.0)
        # the server has taken in every datagram the proxy delivered once its count settles
        to_server = proxy.stats()["to_server"]
        assert _wait(lambda: server.counters.malformed == to_server.corrupted, 3.0), \
            (server.counters, to_server)
    finally:
        server.shutdown()
        proxy.stop()
        server_end.close()
    adapter.poll()
    adapter.close()

    hist = core.history()
    counters = server.counters
    log = server.command_log()
    stats = proxy.stats()

    # never beyond a range, speed or acceleration limit
    assert_within_limits(hist)
    # no corrupted command executed: every executed velocity is bit-identical to one sent
    executed = [r for r in log if isinstance(r.msg, P.JointVelocityCommand)
                and r.code in (Reason.OK, Reason.CLAMPED_SPEED)]
    assert len(executed) >= 10
    for r in executed:
        assert r.msg.theta_dot == sent[r.seq]
    setpoints = [r for r in log if isinstance(r.msg, P.JointSetpoint)]
    assert len(setpoints) == 1 and len(core.setpoint_calls) == 1
    # duplicates and stale commands ignored: handled sequence numbers strictly increase
    seqs = [r.seq for r in log]
    assert len(set(seqs)) == len(seqs)
    assert all(P.seq_newer(b, a) for a, b in zip(seqs, seqs[1:]))
    # corrupted datagrams are counted as malformed on both ends, never anything else
    assert counters.malformed == stats["to_server"].corrupted
    assert adapter.stats().malformed == stats["to_client"].corrupted
    if model.corrupt:
        assert stats["to_server"].corrupted > 0 and stats["to_client"].corrupted > 0
    if model.duplicate:
        assert counters.duplicates > 0
    if model.reorder:
        assert counters.stale > 0
    if model.loss or model.burst:
        assert stats["to_server"].dropped > 0 and stats["to_client"].dropped > 0
    # stop after the last executed velocity command within watchdog + stopping time
    t_last = executed[-1].t_core
    moving = np.any(hist[:, 4:7] != 0.0, axis=1)
    after = hist[:, 0] > t_last
    t_rest = hist[after & ~moving, 0].min()
    window = (hist[:, 0] >= t_last) & (hist[:, 0] <= t_last + WATCHDOG + 2 / RATE)
    v_trip = np.abs(hist[window, 4:7]).max(axis=0)
    bound = WATCHDOG + stopping_time(v_trip, AMAX) + 3 / RATE
    assert t_rest - t_last <= bound, (t_rest - t_last, bound)


def _pump(proxy_addr, sink, n, chunk=60):
    """Send ``n`` numbered datagrams through the proxy to ``sink``; return the numbers received."""
    src = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    src.bind(("127.0.0.1", 0))
    got = []
    try:
        for start in range(0, n, chunk):
            for i in range(start, min(start + chunk, n)):
                src.sendto(i.to_bytes(4, "big"), proxy_addr)
            sink.settimeout(0.035)         # longer than any delay these tests configure
            for _ in range(4 * chunk):
                try:
                    data, _ = sink.recvfrom(64)
                except socket.timeout:
                    break
                got.append(int.from_bytes(data[:4], "big"))
        sink.settimeout(0.3)               # stragglers on a loaded machine
        for _ in range(n):
            try:
                got.append(int.from_bytes(sink.recvfrom(64)[0][:4], "big"))
            except socket.timeout:
                break
    finally:
        src.close()
    return got


def _run_proxy(model, seed, n=600):
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    try:
        with LossyUdpProxy(sink.getsockname(), to_server=model, seed=seed,
                           max_duration_s=20.0) as proxy:
            got = _pump(proxy.address, sink, n)
            proxy.wait_idle(1.0)
            stats = proxy.stats()["to_server"]
    finally:
        sink.close()
    return got, stats


def _burst_lengths(got, n):
    lost = np.ones(n, bool)
    lost[np.array(got, int)] = False
    runs, cur = [], 0
    for x in lost:
        if x:
            cur += 1
        elif cur:
            runs.append(cur)
            cur = 0
    return np.array(runs + ([cur] if cur else []))


def test_proxy_loss_rate_and_seed_reproducibility():
    got_a, st = _run_proxy(FaultModel(loss=0.3), seed=3)
    got_b, _ = _run_proxy(FaultModel(loss=0.3), seed=3)
    got_c, _ = _run_proxy(FaultModel(loss=0.3), seed=4)
    assert st.received == 600 and st.delivered + st.dropped == st.received
    assert 0.24 < st.dropped / st.received < 0.36
    assert sorted(got_a) == sorted(got_b) != sorted(got_c)
    assert len(set(got_a)) == len(got_a) == st.delivered


def test_proxy_bursts_are_longer_than_independent_losses():
    ge = GilbertElliott(p_good_to_bad=0.08, p_bad_to_good=0.25, loss_bad=1.0)
    got_ge, st = _run_proxy(FaultModel(burst=ge), seed=1)
    got_iid, _ = _run_proxy(FaultModel(loss=st.dropped / st.received), seed=1)
    assert _burst_lengths(got_ge, 600).mean() > 2.0 * _burst_lengths(got_iid, 600).mean()


def test_proxy_duplicates_reorders_and_corrupts():
    got, st = _run_proxy(FaultModel(duplicate=0.3, reorder=0.3, reorder_delay_s=0.02), seed=2)
    assert st.duplicated > 0 and len(got) == 600 + st.duplicated
    assert any(b < a for a, b in zip(got, got[1:]))        # some overtaken
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    good = P.encode(P.StateRequest(), seq=1, t=0.0)
    try:
        with LossyUdpProxy(sink.getsockname(), to_server=FaultModel(corrupt=1.0), seed=9) as px:
            src = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            for _ in range(50):
                src.sendto(good, px.address)
                sink.settimeout(2.0)
                data, _ = sink.recvfrom(2048)
                with pytest.raises(P.ProtocolError):
                    P.decode(data)
            src.close()
    finally:
        sink.close()


def test_proxy_stops_by_itself_and_rejects_non_loopback():
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    proxy = LossyUdpProxy(sink.getsockname(), max_duration_s=0.2).start()
    assert _wait(lambda: not proxy.running, 5.0)
    proxy.stop()
    sink.close()
    with pytest.raises(ValueError, match="loopback-only"):
        LossyUdpProxy(("10.0.0.1", 9))
    with pytest.raises(ValueError, match="loss: expected a probability"):
        FaultModel(loss=1.5)
