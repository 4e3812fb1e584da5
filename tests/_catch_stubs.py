"""A joint-layer stand-in for the catching agent's unit tests (no plant, no layer)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np


class LayerStub:
    """Records the setpoints and payloads (kg) the agent sends; the arm stands at ``theta`` (rad), at rest."""

    def __init__(self, theta_deg=(0.0, 60.0, 60.0)):
        self.sent = []
        self.payloads = []                     # every set_payload, kg
        self.profiles = []                     # (max_speed, max_accel) of each setpoint
        self.theta = np.deg2rad(np.asarray(theta_deg, float))
        outer = self

        class Adapter:
            def send_setpoint(self, theta, **kw):
                from tudorvision.joint import Ack
                outer.sent.append(np.asarray(theta, float))
                outer.profiles.append((kw.get("max_speed"), kw.get("max_accel")))
                return Ack(command_seq=len(outer.sent))

            def set_payload(self, kg):
                outer.payloads.append(kg)

            def __getattr__(self, name):
                return lambda *a, **kw: None

        self.adapter = Adapter()

    def state(self):
        from tudorvision.joint import StateFlags
        return SimpleNamespace(flags=StateFlags(0), theta=self.theta, theta_dot=np.zeros(3))


def identity_ik_agent(layer, monkeypatch, ready_deg, **options):
    """A :class:`CatchAgent` on ``layer`` whose net targets are its joint setpoints (identity IK, no net pull).

    ``ready_deg``: the ready "point" (joint angles, deg); ``options``: further :class:`DemoOptions` fields.
    """
    import tudorvision.lab.catch.agent as agent_mod
    from tudorvision.lab.catch.options import DemoOptions
    from tudorvision.robot import load_robot_params

    monkeypatch.setattr(agent_mod, "net_target", lambda p, *a, **k: np.asarray(p, float))

    def ik(p, payload, near=None, elbow=None):
        return np.asarray(p, float)          # the "target" is the joint setpoint itself

    ik.theta1_rad = 0.0
    o = DemoOptions(ready_point_base=tuple(np.deg2rad(np.asarray(ready_deg, float))), **options)
    return agent_mod.CatchAgent(layer, ik, None, None, None, np.eye(4), options=o, params=load_robot_params(),
                                payload_range_kg=(0.0, 0.4))
