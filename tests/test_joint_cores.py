"""Core capabilities are declared in protocols: a payload update reaches only a PayloadAwareCore."""
import numpy as np
import pytest

from tudorvision.joint.adapter import JointAdapter
from tudorvision.joint.controlled import CascadeCore
from tudorvision.joint.cores import JointCore, KinematicCore, PayloadAwareCore, make_core
from tudorvision.joint.protocol import Ack, Reason, Refusal, StateFlags
from tudorvision.joint.server import JointLayerServer
from tudorvision.joint.transport import InProcessTransport


class NoPayloadCore:
    """A JointCore without a payload model (delegates everything else to a KinematicCore)."""

    def __init__(self):
        self.inner = KinematicCore()

    def apply_velocity(self, theta_dot):
        self.inner.apply_velocity(theta_dot)

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2):
        self.inner.apply_setpoint(theta, max_speed_rad_s=max_speed_rad_s, max_accel_rad_s2=max_accel_rad_s2)

    def stop(self):
        self.inner.stop()

    def set_modes(self, *, damping, collision):
        self.inner.set_modes(damping=damping, collision=collision)

    def step(self, dt):
        self.inner.step(dt)

    def state(self):
        return self.inner.state()


def test_capabilities_are_declared():
    assert isinstance(NoPayloadCore(), JointCore)
    assert not isinstance(NoPayloadCore(), PayloadAwareCore)
    assert isinstance(make_core("kinematic"), PayloadAwareCore)
    assert issubclass(KinematicCore, PayloadAwareCore) and issubclass(CascadeCore, PayloadAwareCore)


def _payload_reply(core, payload_kg):
    client, end = InProcessTransport.pair()
    with JointLayerServer(end, core):
        adapter = JointAdapter(client)
        try:
            return adapter.set_payload(payload_kg, timeout=3.0)
        finally:
            adapter.close()


@pytest.mark.parametrize("core, payload_kg, expected", [
    (KinematicCore(), 0.3, Reason.OK),
    (KinematicCore(), 6.0, Reason.OUT_OF_RANGE),
    (NoPayloadCore(), 0.3, Reason.UNSUPPORTED),
])
def test_payload_update_reaches_only_payload_aware_cores(core, payload_kg, expected):
    reply = _payload_reply(core, payload_kg)
    assert isinstance(reply, Ack if expected == Reason.OK else Refusal)
    assert reply.code == expected
    if expected == Reason.UNSUPPORTED:
        assert "no payload model" in reply.text
    if isinstance(core, KinematicCore):
        assert getattr(core, "payload_kg", None) == (payload_kg if expected == Reason.OK else None)


def test_core_state_flags():
    core = KinematicCore(theta0=np.zeros(3))
    assert core.state().status_flags(1e-3) == StateFlags.SETTLED
    core.apply_velocity(np.array([0.1, 0.0, 0.0]))
    core.step(0.01)
    assert core.state().status_flags(1e-3) == StateFlags.MOVING
