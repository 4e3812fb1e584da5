"""A joint-layer stand-in for the catching agent's unit tests (no plant, no layer)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np


class LayerStub:
    """Records the setpoints the agent sends; the arm stands at ``theta`` (rad), at rest."""

    def __init__(self, theta_deg=(0.0, 60.0, 60.0)):
        self.sent = []
        self.theta = np.deg2rad(np.asarray(theta_deg, float))
        outer = self

        class Adapter:
            def send_setpoint(self, theta, **kw):
                from tudorvision.joint import Ack
                outer.sent.append(np.asarray(theta, float))
                return Ack(command_seq=len(outer.sent))

            def __getattr__(self, name):
                return lambda *a, **kw: None

        self.adapter = Adapter()

    def state(self):
        from tudorvision.joint import StateFlags
        return SimpleNamespace(flags=StateFlags(0), theta=self.theta, theta_dot=np.zeros(3))
