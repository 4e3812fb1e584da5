"""The joint layer driven in simulated time: ``JointLayerServer.tick`` / ``poll``
with ``LockstepClientTransport`` (no wall-clock thread, deterministic)."""
from __future__ import annotations

import numpy as np
import pytest
from test_joint_adapter_core import RigidTestCore, assert_within_limits

from tudorvision.joint import (Ack, InProcessTransport, JointAdapter, JointLayerServer, LockstepClientTransport,
                               Mode, Refusal)
from tudorvision.joint.server import ServerConfig

DT = 1.0 / 500.0


def _lockstep(core, **cfg):
    client_end, server_end = InProcessTransport.pair()
    server = JointLayerServer(server_end, core, config=ServerConfig(rate_hz=1.0 / DT, **cfg))
    adapter = JointAdapter(LockstepClientTransport(client_end, server))
    return server, adapter


def test_setpoint_reaches_target_in_simulated_time_only():
    core = RigidTestCore()
    server, adapter = _lockstep(core)
    assert isinstance(adapter.set_mode(Mode.SETPOINT), Ack)
    target = np.array([0.3, 1.2, -0.4])
    reply = adapter.send_setpoint(target)
    assert isinstance(reply, Ack)
    # nothing moves until the caller advances the clock
    assert core.t == 0.0 and np.allclose(core.theta, [0.0, np.pi / 2, 0.0])
    for _ in range(int(5.0 / DT)):
        server.tick(DT)
    st = adapter.request_state()
    assert st is not None and st.settled
    np.testing.assert_allclose(st.theta, target, atol=1e-5)
    assert st.t == pytest.approx(5.0, abs=1e-9)
    assert_within_limits(core.history())


def test_velocity_watchdog_counts_simulated_time():
    core = RigidTestCore()
    server, adapter = _lockstep(core)
    adapter.set_mode(Mode.VELOCITY)
    adapter.send_velocity([0.0, 0.2, 0.0])
    for _ in range(int(0.05 / DT)):     # well inside the 100 ms watchdog
        server.tick(DT)
    assert core.v[1] > 0.0
    for _ in range(int(1.0 / DT)):      # no fresh command: the layer must stop the arm
        server.tick(DT)
    assert np.all(core.v == 0.0)
    assert server.counters.watchdog_stops == 1


def test_idle_layer_refuses_a_setpoint_and_tick_rejects_bad_dt():
    core = RigidTestCore()
    server, adapter = _lockstep(core)
    assert isinstance(adapter.send_setpoint([0.0, 1.0, 0.0]), Refusal)   # initial mode is IDLE
    assert server.poll() == 0                                             # nothing left waiting
    with pytest.raises(ValueError, match="dt"):
        server.tick(0.0)
