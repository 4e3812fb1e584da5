"""Issue 14, joint layer: only the owner is obeyed, replays and forgeries change nothing,
nonsense limits are refused, and exceptions fault the layer instead of killing it.

Real UDP sockets on 127.0.0.1 (and the in-process/lockstep transports where the
case is about logic, not sockets).
"""
from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from test_joint_adapter_core import AMAX, VMAX, RigidTestCore, assert_within_limits
from tudorvision._checks import TudorVisionError
from tudorvision.joint import protocol as P
from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.protocol import Ack, Mode, Reason, Refusal, StateFlags
from tudorvision.joint.safety import SafetyLimits
from tudorvision.joint.server import JointLayerServer, ServerConfig
from tudorvision.joint.session import RateLimiter
from tudorvision.joint.transport import InProcessTransport, LockstepClientTransport, UdpTransport

KEY = bytes(range(100, 132))
LIM = SafetyLimits.from_params()


class Recording:
    """A client transport that keeps a copy of every datagram it sends (the attacker's capture)."""

    def __init__(self, inner):
        self.inner, self.sent = inner, []

    @property
    def address(self):
        return self.inner.address

    def send(self, data, addr=None):
        self.sent.append(bytes(data))
        self.inner.send(data, addr)

    def recv(self, timeout):
        return self.inner.recv(timeout)

    def close(self):
        self.inner.close()


class Stranger:
    """A raw UDP socket on loopback that is not the owner."""

    def __init__(self, port):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(2.0)
        self.dest = ("127.0.0.1", port)

    def send(self, data):
        self.sock.sendto(data, self.dest)

    def ask(self, msg, seq, *, session=0, key=None, answer_key="same"):
        """Send ``msg`` and return the decoded answer (None on silence)."""
        self.send(P.encode(msg, seq, time.monotonic(), session=session, key=key))
        try:
            data, _ = self.sock.recvfrom(2048)
        except socket.timeout:
            return None
        return P.decode(data, key=key if answer_key == "same" else answer_key)[1]

    def close(self):
        self.sock.close()


@pytest.fixture
def udp_layer(request):
    """A keyless layer on 127.0.0.1 with a rigid test core and an owner adapter."""
    opts = getattr(request, "param", {})
    key = opts.get("key")
    core = RigidTestCore()
    end = UdpTransport.server(0)
    server = JointLayerServer(end, core, key=key,
                              config=ServerConfig(rate_hz=500.0, **opts.get("config", {}))).start()
    client = Recording(UdpTransport.client(end.address[1]))
    owner = JointAdapter(client, key=key)
    yield server, core, owner, client, end.address[1]
    server.shutdown()
    owner.close()
    end.close()


def _counters(server):
    return server.counters


def _wait(predicate, timeout=3.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


# ------------------------------------------------------------------ ownership
def test_stranger_is_refused_and_changes_nothing(udp_layer):
    server, core, owner, _, port = udp_layer
    assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    sid = owner.session
    stranger = Stranger(port)
    try:
        # commands without a session
        for seq, msg in enumerate([P.ModeSwitch(mode=Mode.VELOCITY), P.PayloadUpdate(payload_kg=5.0),
                                   P.JointSetpoint(theta=(0.5, 1.0, 0.0)), P.FaultReset(), P.Release(),
                                   P.ModeSwitch(mode=Mode.IDLE)], start=1):
            r = stranger.ask(msg, seq)
            assert isinstance(r, Refusal) and r.code == Reason.NO_SESSION, r
        # the owner's session id, sent from another address
        r = stranger.ask(P.ModeSwitch(mode=Mode.VELOCITY), 50, session=sid)
        assert isinstance(r, Refusal) and r.code == Reason.NOT_OWNER
        # a full handshake without takeover: the lease is held
        other = JointAdapter(UdpTransport.client(port))
        r = other.set_mode(Mode.VELOCITY, timeout=3.0)
        assert isinstance(r, Refusal) and r.code == Reason.NOT_OWNER and "lease" in r.text
        assert other.session is None
        assert other.request_state(timeout=3.0).mode == Mode.SETPOINT      # reading is allowed
        other.close()
    finally:
        stranger.close()
    assert server.mode == Mode.SETPOINT and core.setpoint_calls == [] and core.velocity_calls == []
    assert not hasattr(core, "payload_kg")
    r = owner.send_setpoint([0.1, 1.4, 0.0], timeout=3.0)             # the owner is still obeyed
    assert isinstance(r, Ack) and owner.session == sid
    assert server.counters.not_owner >= 8


def test_takeover_stops_the_arm_and_the_old_owner_is_told(udp_layer):
    server, core, owner, _, port = udp_layer
    assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    assert isinstance(owner.send_setpoint([0.8, 1.0, 0.5], max_speed=0.5, timeout=3.0), Ack)
    assert core.wait_until(lambda c: np.any(np.abs(c.v) > 0.1), timeout=3.0)
    stops = core.stop_calls
    new = JointAdapter(UdpTransport.client(port), takeover=True)
    try:
        assert isinstance(new.open_session(timeout=3.0), P.Welcome)
        assert server.mode == Mode.IDLE and core.stop_calls > stops          # controlled stop
        assert [e.kind for e in server.events()][-3:] == ["session_end", "takeover", "session_open"]
        r = owner.send_setpoint([0.0, 1.0, 0.0], timeout=3.0)                 # reopens: lease held
        assert isinstance(r, Refusal) and r.code == Reason.NOT_OWNER
        assert isinstance(new.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
        assert isinstance(new.release(timeout=3.0), Ack) and server.owner is None
    finally:
        new.close()


def test_lease_expires_in_control_time_and_the_adapter_reopens():
    core = RigidTestCore()
    client, end = InProcessTransport.pair()
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=100.0, lease_s=0.5))
    adapter = JointAdapter(LockstepClientTransport(client, server))
    assert isinstance(adapter.set_mode(Mode.SETPOINT), Ack)
    first = adapter.session
    for _ in range(40):                                    # 0.4 s of silence: still held
        server.tick(0.01)
    assert server.owner is not None
    for _ in range(20):                                    # 0.6 s: expired
        server.tick(0.01)
    assert server.owner is None and server.events()[-1].kind == "session_end"
    assert "lease expired" in server.events()[-1].text
    r = adapter.send_setpoint([0.1, 1.4, 0.0])             # told NO_SESSION, reopens, resends
    assert isinstance(r, Ack) and adapter.session not in (None, first)
    assert adapter.stats().sessions == 2


# ------------------------------------------------------------ replay, forgery
@pytest.mark.parametrize("udp_layer", [{"key": KEY}], indirect=True)
def test_replayed_datagrams_from_a_new_socket_change_nothing(udp_layer):
    server, core, owner, client, port = udp_layer
    assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    assert isinstance(owner.send_setpoint([0.2, 1.4, 0.1], timeout=3.0), Ack)
    assert owner.wait_settled([0.2, 1.4, 0.1], timeout=10.0) is not None
    captured = list(client.sent)
    n_log, n_calls, mode = len(server.command_log()), len(core.setpoint_calls), server.mode
    before = server.counters
    time.sleep(0.3)
    stranger = Stranger(port)
    try:
        for data in captured:                               # the whole capture, 0.3 s+ later
            stranger.send(data)
        for data in captured:                               # and from the owner's own address
            client.inner.send(data)
        time.sleep(0.3)
    finally:
        stranger.close()
    after = server.counters
    assert len(server.command_log()) == n_log and len(core.setpoint_calls) == n_calls
    assert server.mode == mode and after.accepted == before.accepted
    assert after.replayed + after.not_owner + after.duplicates + after.stale > before.replayed
    assert after.replayed > before.replayed                 # the captured OpenSession, at least
    r = owner.send_setpoint([0.0, 1.3, 0.0], timeout=3.0)   # the owner goes on
    assert isinstance(r, Ack)


@pytest.mark.parametrize("udp_layer", [{"key": KEY}], indirect=True)
def test_unauthenticated_and_wrong_key_datagrams_are_dropped(udp_layer):
    server, core, owner, _, port = udp_layer
    assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    for key in (None, bytes(32)):
        with JointAdapter(UdpTransport.client(port), key=key) as intruder:
            assert intruder.request_state(timeout=0.3) is None
            assert intruder.set_mode(Mode.VELOCITY, timeout=0.3) is None
    stranger = Stranger(port)
    try:   # a datagram in the owner's session with a forged (wrong-key) tag and a huge sequence number
        stranger.send(P.encode(P.ModeSwitch(mode=Mode.VELOCITY), 2**31, time.monotonic(),
                               session=owner.session, key=bytes(32)))
        assert stranger.ask(P.StateRequest(), 1, key=KEY) is not None   # the key holder can read
    finally:
        stranger.close()
    assert _wait(lambda: server.counters.unauthenticated >= 5)
    assert server.mode == Mode.SETPOINT and core.velocity_calls == []
    assert isinstance(owner.send_setpoint([0.1, 1.3, 0.0], timeout=3.0), Ack)


def test_forged_large_sequence_number_does_not_lock_the_owner_out(udp_layer):
    server, core, owner, client, _ = udp_layer
    assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    seq = owner._seq
    for jump in (2**31 - 1, 10**6, 5000):                # spoofed from the owner's own address
        client.inner.send(owner.encode(P.JointSetpoint(theta=(0.9, 0.9, 0.9)), (seq + jump) & 0xFFFFFFFF))
    assert _wait(lambda: server.counters.replayed >= 3)
    assert core.setpoint_calls == []
    r = owner.send_setpoint([0.1, 1.3, 0.0], timeout=3.0)
    assert isinstance(r, Ack) and r.command_seq == seq


# ------------------------------------------------------ limits, NaN, faults
@pytest.mark.parametrize("speed, accel, code", [
    (5e-324, None, Reason.OVER_SPEED), (None, 5e-324, Reason.OVER_ACCEL),
    (1e-6, None, Reason.OVER_SPEED), (None, 1e-6, Reason.OVER_ACCEL),
    (1e300, None, Reason.OVER_SPEED), (None, 1e300, Reason.OVER_ACCEL),
    (-1.0, None, Reason.OVER_SPEED), (0.0, 0.0, Reason.OVER_SPEED)])
def test_tiny_and_huge_profile_limits_are_refused(udp_layer, speed, accel, code):
    server, core, owner, _, _ = udp_layer
    assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
    r = owner.send_setpoint([0.5, 1.0, 0.3], max_speed=speed, max_accel=accel, timeout=3.0)
    assert isinstance(r, Refusal) and r.code == code, r
    assert core.setpoint_calls == [] and server.counters.faults == 0
    assert isinstance(owner.send_setpoint([0.05, 1.5, 0.0], max_accel=float(LIM.min_accel_rad_s2),
                                          timeout=3.0), Ack)       # the minimum itself is fine
    for _, vlim, alim in core.setpoint_calls:                        # commanded <= limits, >= minima
        assert np.all(alim <= AMAX) and np.all(alim >= LIM.min_accel_rad_s2)
        assert np.all(vlim <= VMAX) and np.all(vlim >= LIM.min_speed_rad_s)


def test_huge_velocity_is_refused_not_clamped_and_nan_inf_never_execute(udp_layer):
    server, core, owner, client, _ = udp_layer
    assert isinstance(owner.set_mode(Mode.VELOCITY, timeout=3.0), Ack)
    seq = owner.send_velocity([0.0, 1e300, 0.0])
    assert _wait(lambda: owner.poll() >= 0 and owner.reply_for(seq) is not None)
    assert owner.reply_for(seq).code == Reason.OVER_SPEED
    for i, bad in enumerate([np.nan, np.inf, -np.inf]):
        msgs = [P.JointVelocityCommand(theta_dot=(0.0, bad, 0.0)),
                P.JointSetpoint(theta=(0.0, 1.0, 0.0), max_accel=bad), P.PayloadUpdate(payload_kg=bad)]
        for j, msg in enumerate(msgs):
            s = owner._next_seq()
            client.inner.send(owner.encode(msg, s, strict=False))
            assert _wait(lambda: owner.poll() >= 0 and owner.reply_for(s) is not None)
            assert owner.reply_for(s).code == Reason.NON_FINITE
    assert all(np.all(v == 0.0) for v in core.velocity_calls) and core.setpoint_calls == []
    assert server.counters.faults == 0 and not server.state().flags & StateFlags.FAULT
    assert_within_limits(core.history())


class ExplodingCore(RigidTestCore):
    """A core that raises on demand (the planner's 'math domain error'), or reports NaN."""

    explode_setpoint = False
    explode_step = False
    nan_state = False

    def apply_setpoint(self, theta, **kw):
        if self.explode_setpoint:
            raise ValueError("math domain error")
        super().apply_setpoint(theta, **kw)

    def step(self, dt):
        if self.explode_step:
            raise ZeroDivisionError("float division by zero")
        super().step(dt)

    def state(self):
        st = super().state()
        if self.nan_state:
            st.theta[1] = np.nan
        return st


@pytest.mark.parametrize("where", ["handler", "tick", "nan_state"])
def test_exceptions_fault_the_layer_which_keeps_serving(where):
    core = ExplodingCore()
    end = UdpTransport.server(0)
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=500.0)).start()
    owner = JointAdapter(UdpTransport.client(end.address[1]))
    try:
        assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
        stops = core.stop_calls
        if where == "handler":
            core.explode_setpoint = True
            r = owner.send_setpoint([0.1, 1.4, 0.0], timeout=3.0)
            assert isinstance(r, Refusal) and r.code == Reason.INTERNAL
        elif where == "tick":
            core.explode_step = True
        else:
            core.nan_state = True
        assert _wait(lambda: server.state().flags & StateFlags.FAULT)
        core.explode_setpoint = core.explode_step = core.nan_state = False
        st = owner.request_state(timeout=3.0)                     # still serving
        assert st.flags & StateFlags.FAULT and st.mode == Mode.IDLE and st.counters.faults == 1
        assert np.all(np.isfinite(st.theta)) and core.stop_calls > stops
        assert server._thread.is_alive() and server.events()[-1].kind == "fault"
        # a mode switch does not clear it; a stranger cannot; the owner's reset does
        assert isinstance(owner.set_mode(Mode.SETPOINT, timeout=3.0), Ack)
        r = owner.send_setpoint([0.1, 1.4, 0.0], timeout=3.0)
        assert isinstance(r, Refusal) and r.code == Reason.FAULT
        stranger = Stranger(end.address[1])
        r = stranger.ask(P.FaultReset(), 1)
        stranger.close()
        assert isinstance(r, Refusal) and r.code == Reason.NO_SESSION
        assert server.state().flags & StateFlags.FAULT
        assert isinstance(owner.reset_fault(timeout=3.0), Ack)
        assert not server.state().flags & StateFlags.FAULT
        assert isinstance(owner.send_setpoint([0.1, 1.4, 0.0], timeout=3.0), Ack)
    finally:
        server.shutdown()
        owner.close()
        end.close()


def test_optional_acceleration_monitor_faults_a_core_that_jumps():
    core = RigidTestCore()
    client, end = InProcessTransport.pair()
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=500.0, fault_accel_factor=2.0))
    adapter = JointAdapter(LockstepClientTransport(client, server))
    assert isinstance(adapter.set_mode(Mode.SETPOINT), Ack)
    assert isinstance(adapter.send_setpoint([0.3, 1.4, 0.2]), Ack)
    for _ in range(500):
        server.tick(0.002)
    assert not server.state().flags & StateFlags.FAULT          # a lawful profile never trips it
    with core._cond:
        core.alim = AMAX * 30.0                                   # a planner gone wrong
    adapter.send_setpoint([0.0, 1.5, 0.0])
    with core._cond:
        core.alim = AMAX * 30.0
    for _ in range(50):
        server.tick(0.002)
    assert server.state().flags & StateFlags.FAULT
    assert "acceleration" in server.events()[-1].text


# ----------------------------------------------------------- binding, limits
def test_keyless_layer_refuses_to_bind_beyond_loopback():
    end = UdpTransport.server(0, host="0.0.0.0")
    try:
        with pytest.raises(TudorVisionError, match="not loopback; a key is required"):
            JointLayerServer(end, RigidTestCore())
        JointLayerServer(end, RigidTestCore(), key=KEY)           # with a key it may
    finally:
        end.close()


def test_rate_limiter_allows_a_burst_then_the_rate():
    lim = RateLimiter(rate_hz=100.0, burst=10, max_sources=2)
    assert sum(lim.allow("a", 0.0) for _ in range(50)) == 10
    assert sum(lim.allow("a", 0.1) for _ in range(50)) == 10      # 0.1 s at 100/s refills 10
    assert lim.allow("b", 0.1) and lim.allow("c", 0.1)            # table bounded: "a" forgotten
    assert lim.allow("a", 0.1)
