"""Adapter <-> server, the same test bodies over real UDP on 127.0.0.1 and in-process."""
from __future__ import annotations

import time

import numpy as np
import pytest

from test_joint_adapter_core import AMAX, LIMITS, VMAX, RigidTestCore, assert_within_limits
from tudorvision.joint import protocol as P
from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.protocol import Ack, Mode, Reason, Refusal, StateFlags
from tudorvision.joint.safety import SafetyLimits, stopping_time
from tudorvision.joint.server import JointLayerServer, ServerConfig
from tudorvision.joint.transport import InProcessTransport, UdpTransport

RATE = 500.0
WATCHDOG = 0.1


class Link:
    """A running server with a test core, an adapter, and raw access to the client end."""

    def __init__(self, kind, core, config):
        if kind == "udp":
            self.server_end = UdpTransport.server(0)
            self.client_end = UdpTransport.client(self.server_end.address[1])
        else:
            self.client_end, self.server_end = InProcessTransport.pair()
        self.core = core
        self.server = JointLayerServer(self.server_end, core, config=config).start()
        self.adapter = JointAdapter(self.client_end, retry_interval_s=0.05)

    def raw(self, msg, seq, *, strict=True, t=None):
        """Send ``msg`` with this sequence number in the adapter's session."""
        self.client_end.send(self.adapter.encode(msg, seq, t=t, strict=strict))

    def reply_to(self, seq, timeout=3.0):
        """Wait for the Ack/Refusal of command ``seq`` (bounded)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.adapter.poll()
            if self.adapter.reply_for(seq) is not None:
                return self.adapter.reply_for(seq)
            time.sleep(0.005)
        return None

    def close(self):
        self.server.shutdown()
        self.adapter.close()
        self.server_end.close()


def _make(request, theta0=(0.0, np.pi / 2, 0.0), **cfg):
    kind = request.node.callspec.params["kind"]
    link = Link(kind, RigidTestCore(theta0),
                ServerConfig(rate_hz=RATE, watchdog_s=WATCHDOG, **cfg))
    request.addfinalizer(link.close)
    return link


KINDS = pytest.mark.parametrize("kind", ["udp", "inproc"])


@KINDS
def test_state_request_answers_with_core_state(request, kind):
    link = _make(request, theta0=(0.1, 1.2, -0.3))
    st = link.adapter.request_state(timeout=3.0)
    assert st is not None
    assert np.allclose(st.theta, [0.1, 1.2, -0.3]) and st.mode == Mode.IDLE
    assert st.settled and st.strains == (1e-6,) * 4
    assert link.adapter.last_state == st
    assert link.adapter.stats().states >= 1 and link.adapter.stats().rtt_s > 0


@KINDS
def test_setpoint_moves_within_limits_and_settles(request, kind):
    link = _make(request)
    r = link.adapter.set_mode(Mode.SETPOINT, timeout=3.0)       # opens the session first
    assert isinstance(r, Ack) and r.code == Reason.OK and link.adapter.session is not None
    target = np.array([0.3, 1.3, 0.4])
    reply = link.adapter.send_setpoint(target, max_speed=1.0, timeout=3.0)
    assert isinstance(reply, Ack) and reply.code == Reason.OK
    st = link.adapter.wait_settled(target, tol=1e-3, timeout=10.0)
    assert st is not None and np.allclose(st.theta, target, atol=1e-3)
    assert st.last_command_seq == reply.command_seq
    hist = link.core.history()
    assert np.abs(hist[:, 4:7]).max() <= 1.0 + 1e-9
    assert_within_limits(hist)
    assert len(link.core.setpoint_calls) == 1
    _, vlim, alim = link.core.setpoint_calls[0]
    assert np.allclose(vlim, 1.0) and np.allclose(alim, np.deg2rad(200.0))


@KINDS
def test_velocity_commands_then_watchdog_stop(request, kind):
    link = _make(request)
    assert isinstance(link.adapter.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    v_cmd = np.array([0.4, -0.3, 0.5])
    for _ in range(15):                       # 0.3 s of servoing at 50 Hz
        link.adapter.send_velocity(v_cmd)
        time.sleep(0.02)
    last_seq = link.adapter.send_velocity(v_cmd)
    # commands cease: the layer must bring the arm to rest by itself
    assert link.core.wait_until(lambda c: c.t > 0.5 and np.all(c.v == 0.0), timeout=10.0)
    log = [r for r in link.server.command_log() if r.seq == last_seq]
    assert len(log) == 1 and log[0].code == Reason.OK
    hist = link.core.history()
    moving = np.any(hist[:, 4:7] != 0.0, axis=1)
    t_accept = log[0].t_core
    t_rest = hist[(hist[:, 0] > t_accept) & ~moving, 0].min()
    bound = WATCHDOG + stopping_time(v_cmd, AMAX) + 3 / RATE
    assert t_rest - t_accept <= bound, (t_rest - t_accept, bound)
    # without the watchdog the arm would still be moving at the commanded speed
    assert np.allclose(hist[moving, 4:7].max(axis=0)[[0, 2]], v_cmd[[0, 2]])
    assert_within_limits(hist)
    st = link.adapter.request_state(timeout=3.0)
    assert st.flags & StateFlags.WATCHDOG_STOP and st.counters.watchdog_stops == 1
    assert not st.flags & StateFlags.MOVING


@KINDS
def test_refusals_and_clamping(request, kind):
    link = _make(request)
    a = link.adapter
    seq = a.send_velocity([0.1, 0.0, 0.0])                      # layer is IDLE
    r = link.reply_to(seq)
    assert isinstance(r, Refusal) and r.code == Reason.WRONG_MODE and "VELOCITY" in r.text
    assert isinstance(a.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    r = a.send_setpoint([0.0, np.deg2rad(200.0), 0.0], timeout=3.0)
    assert isinstance(r, Refusal) and r.code == Reason.OUT_OF_RANGE
    r = a.send_setpoint([0.0, 1.5, 0.0], max_speed=15.0, timeout=3.0)
    assert isinstance(r, Ack) and r.code == Reason.CLAMPED_SPEED
    assert np.allclose(link.core.setpoint_calls[-1][1], VMAX)
    assert isinstance(a.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    seq = a.send_velocity([0.0, 0.0, 10.0])                     # 10 rad/s: too fast
    r = link.reply_to(seq)
    assert isinstance(r, Ack) and r.code == Reason.CLAMPED_SPEED
    for _ in range(100):                                      # keep it alive until at speed
        if link.core.wait_until(lambda c: c.v[2] >= VMAX[2] - 1e-9, timeout=0.02):
            break
        a.send_velocity([0.0, 0.0, 10.0])
    assert link.core.v[2] == pytest.approx(VMAX[2])
    st = a.request_state(timeout=3.0)
    assert st.flags & StateFlags.CLAMPED
    assert st.counters.refused == 2 and st.counters.accepted >= 4
    assert_within_limits(link.core.history())


@KINDS
def test_nan_and_malformed_never_execute(request, kind):
    link = _make(request)
    assert isinstance(link.adapter.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    link.raw(P.JointVelocityCommand(theta_dot=(0.0, np.nan, 0.0)), seq=100, strict=False)
    r = link.reply_to(100)
    assert isinstance(r, Refusal) and r.code == Reason.NON_FINITE
    good = link.adapter.encode(P.JointVelocityCommand(theta_dot=(0.5, 0.0, 0.0)), 101)
    link.client_end.send(good[:-3])                                 # truncated
    link.client_end.send(good[:20] + bytes([good[20] ^ 0x40]) + good[21:])   # flipped bit
    link.client_end.send(b"\x00" * 64)                              # garbage
    with pytest.raises(ValueError, match="theta_dot: contains NaN"):
        link.adapter.send_velocity([np.nan, 0.0, 0.0])              # refused at the edge
    st = link.adapter.request_state(timeout=3.0)
    assert st.counters.malformed == 4 and st.counters.accepted == 1
    assert all(np.all(np.isfinite(v)) for v in link.core.velocity_calls)
    assert all(np.all(v == 0.0) for v in link.core.velocity_calls)   # nothing was executed
    with pytest.raises(ValueError, match="theta: expected shape"):
        link.adapter.send_setpoint([0.0, 1.0])


@KINDS
def test_duplicates_and_stale_are_ignored(request, kind):
    link = _make(request)
    assert isinstance(link.adapter.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    sp = lambda q: P.JointSetpoint(theta=(q, 1.5, 0.0))  # noqa: E731
    link.raw(sp(0.2), seq=500)
    first = link.reply_to(500)
    n_acks = link.adapter.stats().acks
    link.raw(sp(0.2), seq=500)                        # duplicate: same reply, not executed again
    deadline = time.monotonic() + 3.0
    while link.adapter.stats().acks == n_acks and time.monotonic() < deadline:
        link.adapter.poll()
        time.sleep(0.005)
    again = link.adapter.last_reply
    link.raw(sp(0.9), seq=499)                        # stale: older than 500
    link.raw(sp(0.3), seq=501)
    assert isinstance(first, Ack) and again == first
    assert isinstance(link.reply_to(501), Ack)
    st = link.adapter.request_state(timeout=3.0)
    assert (st.counters.duplicates, st.counters.stale) == (1, 1)
    targets = [float(c[0][0]) for c in link.core.setpoint_calls]
    assert targets == [0.2, 0.3]
    assert st.last_command_seq == 501


@KINDS
def test_sequence_numbers_wrap(request, kind):
    link = _make(request)
    assert link.adapter.open_session(timeout=3.0) is not None
    link.adapter._seq = 2**32 - 3
    assert isinstance(link.adapter.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    seqs = [link.adapter.send_velocity([0.01 * i, 0.0, 0.0]) for i in range(1, 6)]
    assert seqs[1:3] == [2**32 - 1, 0]
    for s in seqs:
        assert isinstance(link.reply_to(s), Ack)
    st = link.adapter.request_state(timeout=3.0)
    assert st.counters.stale == 0 and st.counters.accepted == 6


@KINDS
def test_old_command_in_time_is_stale(request, kind):
    link = _make(request)
    assert isinstance(link.adapter.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    link.raw(P.JointVelocityCommand(theta_dot=(0.3, 0, 0)), seq=50,
             t=time.monotonic() - 1.0)                  # sent "1 s ago": too old to execute
    r = link.reply_to(50)
    assert isinstance(r, Refusal) and r.code == Reason.STALE
    assert all(np.all(v == 0.0) for v in link.core.velocity_calls)


@KINDS
def test_velocity_toward_a_joint_limit_brakes_before_it(request, kind):
    soft = SafetyLimits.from_params().soft_limits_rad
    link = _make(request, theta0=(0.0, 1.0, soft[2, 1] - 1.5))
    assert isinstance(link.adapter.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    for _ in range(60):                                # 1.2 s pushing into the upper limit
        link.adapter.send_velocity([0.0, 0.0, VMAX[2]])
        time.sleep(0.02)
    assert link.core.wait_until(lambda c: np.all(c.v == 0.0), timeout=10.0)
    hist = link.core.history()
    assert_within_limits(hist)
    assert hist[:, 3].max() <= soft[2, 1] + 1e-12
    assert hist[:, 3].max() >= soft[2, 1] - np.deg2rad(2.0)   # it did get there
    assert hist[:, 6].max() == pytest.approx(VMAX[2])


@KINDS
def test_core_fault_stops_and_refuses_until_reset(request, kind):
    link = _make(request)
    assert isinstance(link.adapter.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    with link.core._cond:
        link.core.theta = np.array([0.0, LIMITS[1, 0] - 0.1, 0.0])   # a broken core
    assert link.core.wait_until(lambda c: c.stop_calls >= 2, timeout=5.0)
    r = link.adapter.send_setpoint([0.0, 1.0, 0.0], timeout=3.0)
    assert isinstance(r, Refusal) and r.code in (Reason.FAULT, Reason.WRONG_MODE)
    st = link.adapter.request_state(timeout=3.0)
    assert st.flags & StateFlags.FAULT and st.mode == Mode.IDLE
    # a mode switch no longer clears the fault; only the owner's explicit reset does
    assert isinstance(link.adapter.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    r = link.adapter.send_setpoint([0.0, 1.1, 0.0], timeout=3.0)
    assert isinstance(r, Refusal) and r.code == Reason.FAULT
    assert link.adapter.request_state(timeout=3.0).flags & StateFlags.FAULT
    # outside its range but at rest, a reset fault sticks and a setpoint brings the arm back
    assert isinstance(link.adapter.reset_fault(timeout=3.0), Ack)
    assert isinstance(link.adapter.send_setpoint([0.0, 1.1, 0.0], timeout=3.0), Ack)
    assert link.core.wait_until(lambda c: abs(c.theta[1] - 1.1) < 1e-4, timeout=10.0)
    st = link.adapter.request_state(timeout=3.0)
    assert not st.flags & StateFlags.FAULT and st.mode == Mode.SETPOINT
    hist = link.core.history()
    back = hist[hist[:, 2] < LIMITS[1, 0] - np.deg2rad(1.0)]
    assert back.size and np.all(back[:, 5] >= 0.0)          # it only ever moved back toward the range


@KINDS
def test_core_moving_further_out_of_range_faults_again(request, kind):
    link = _make(request)
    assert isinstance(link.adapter.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    with link.core._cond:
        link.core.theta = np.array([0.0, LIMITS[1, 0] - 0.1, 0.0])   # a broken core
    assert link.core.wait_until(lambda c: c.stop_calls >= 2, timeout=5.0)
    assert isinstance(link.adapter.reset_fault(timeout=3.0), Ack)               # clears; at rest it sticks
    assert isinstance(link.adapter.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    st = link.adapter.request_state(timeout=3.0)
    assert not st.flags & StateFlags.FAULT and st.mode == Mode.SETPOINT
    with link.core._cond:
        link.core.mode, link.core.v_cmd = "velocity", np.array([0.0, -0.2, 0.0])   # drifting further out
    assert link.core.wait_until(lambda c: c.stop_calls >= 3, timeout=5.0)
    st = link.adapter.request_state(timeout=3.0)
    assert st.flags & StateFlags.FAULT and st.mode == Mode.IDLE


def test_request_state_times_out_without_server():
    client, _server_end = InProcessTransport.pair()
    with JointAdapter(client, retry_interval_s=0.02) as adapter:
        assert adapter.request_state(timeout=0.1) is None
        assert adapter.set_mode(Mode.IDLE, timeout=0.1) is None
        stats = adapter.stats()
    assert stats.timeouts == 2 and stats.retransmissions >= 4 and stats.received == 0


def test_command_age_tolerates_clock_offset_and_drift():
    from tudorvision.joint.session import SeqWindow
    c = SeqWindow()
    ages = []
    for k in range(20000):                    # 100 Hz for 200 s; sender clock 500 ppm slow
        t_recv = 1000.0 + 0.01 * k
        t_sent = -5e4 + 0.01 * k * (1 - 5e-4)   # unrelated epoch
        ages.append(c.age(t_recv + 0.0002 * (k % 7), t_sent))
    assert max(ages) < 0.005
    late = c.age(1000.0 + 0.01 * 20000 + 0.3, -5e4 + 0.01 * 20000 * (1 - 5e-4))
    assert late == pytest.approx(0.3, abs=0.01)


def test_transports_filter_foreign_senders_and_refuse_after_close():
    import socket

    from tudorvision.joint.transport import TransportClosed
    server = UdpTransport.server(0)
    client = UdpTransport.client(server.address[1])
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        client.send(b"hello")
        data, addr = server.recv(2.0)
        assert data == b"hello" and addr == client.address
        stranger.sendto(b"spoof", client.address)          # not from the peer: dropped
        server.send(b"answer", addr)
        assert client.recv(2.0)[0] == b"answer"
        assert client.recv(0.05) is None and client.foreign == 1
        with pytest.raises(ValueError, match="addr: required"):
            server.send(b"x")
    finally:
        stranger.close()
        server.close()
        client.close()
    with pytest.raises(TransportClosed):
        client.send(b"late")
    a, b = InProcessTransport.pair()
    with pytest.raises(ValueError, match="is not the peer"):
        b.send(b"x", "somebody-else")
    a.close()
    with pytest.raises(TransportClosed):
        a.recv(0.0)
    with pytest.raises(ValueError, match="port: expected 1..65535"):
        UdpTransport.client(0)
