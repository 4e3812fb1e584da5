"""The catching demo's joint-control layer in simulated time (lockstep).

The demo drives the real :class:`~tudorvision.joint.server.JointLayerServer`
(its safety checks, its over-speed and range faults) and the real
:class:`~tudorvision.joint.adapter.JointAdapter` over an in-process pipe, but
the layer's control loop runs in the caller's simulated time
(:meth:`JointLayerServer.tick`) instead of a wall-clock thread: every run is
deterministic for a seed, whatever the machine's load.

Commands are answered at once: the client end hands each datagram to the
server's :meth:`~JointLayerServer.poll` as it is sent.
"""
from __future__ import annotations

import numpy as np

__all__ = ["LockstepCore", "LockstepLayer"]


class LockstepCore:
    """A :class:`~tudorvision.joint.server.JointCore` around :class:`~tudorvision.sim.arm.SimCore`.

    Forwards everything to the simulated arm; a damping mode set through the
    layer installs a :class:`~tudorvision.joint.damping.StrainDamper` on the
    plant's cascade unless the simulated core has installed one itself.

    Parameters
    ----------
    sim : SimCore
    """

    def __init__(self, sim):
        self.sim = sim

    def apply_velocity(self, theta_dot) -> None:
        self.sim.apply_velocity(theta_dot)

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2) -> None:
        self.sim.apply_setpoint(theta, max_speed_rad_s=max_speed_rad_s, max_accel_rad_s2=max_accel_rad_s2)

    def stop(self) -> None:
        self.sim.stop()

    def set_modes(self, *, damping, collision) -> None:
        from ..joint.damping import StrainDamper, default_damping_config

        self.sim.set_modes(damping=damping, collision=collision)
        law = {0: "off", 1: "proportional", 2: "integral", 3: "half_integrator"}[int(damping)]
        ctl = self.sim.controlled
        if law == "off":
            ctl.set_damper(None)
        elif getattr(ctl, "damper", None) is None:     # the plant did not install one itself
            arm = self.sim.arm
            ctl.set_damper(StrainDamper(default_damping_config(law), arm.strain, arm.config.dt))

    def step(self, dt: float) -> None:
        self.sim.step(dt)

    def state(self):
        return self.sim.state()


class _Immediate:
    """Client transport whose every send is handled by the lockstep server at once."""

    def __init__(self, inner, server):
        self._inner, self._server = inner, server

    @property
    def address(self):
        return self._inner.address

    def send(self, data, addr=None):
        self._inner.send(data, addr)
        self._server.poll()

    def recv(self, timeout):
        return self._inner.recv(0.0)

    def close(self):
        self._inner.close()


class LockstepLayer:
    """Simulated arm + joint-control layer + adapter, advanced in simulated time.

    Parameters
    ----------
    sim : SimCore
        The simulated arm (its clock starts at ``sim.arm.t``).
    rate_hz : float
        Control rate of the layer's loop (safety checks run every period).

    Attributes
    ----------
    server : JointLayerServer
    adapter : JointAdapter
    t : float
        Simulated time, s.
    """

    def __init__(self, sim, *, rate_hz: float = 500.0):
        from ..joint import InProcessTransport, JointAdapter, JointLayerServer, ServerConfig

        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz}")
        self.sim = sim
        self.core = LockstepCore(sim)
        client, end = InProcessTransport.pair()
        # simulated time: the wall-clock age of a command means nothing here
        self.server = JointLayerServer(end, self.core, config=ServerConfig(rate_hz=rate_hz, max_command_age_s=None))
        self.adapter = JointAdapter(_Immediate(client, self.server))
        self.period = 1.0 / float(rate_hz)
        self.t = float(sim.arm.t)

    def advance_to(self, t: float) -> None:
        """Run the layer (and the plant) up to simulated time ``t`` (s, on its control grid)."""
        n = int(round((float(t) - self.t) / self.period))
        for _ in range(max(n, 0)):
            self.server.tick(self.period)
            self.t += self.period

    def state(self):
        """The layer's current state message (joint angles, strains, flags)."""
        return self.server.state()

    def close(self) -> None:
        self.adapter.close()
