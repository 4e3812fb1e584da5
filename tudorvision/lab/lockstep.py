"""The catching demo's joint-control layer in simulated time (lockstep).

The demo drives the real :class:`~tudorvision.joint.server.JointLayerServer`
(its safety checks, its over-speed and range faults) and the real
:class:`~tudorvision.joint.adapter.JointAdapter` over an in-process pipe, but
the layer's control loop runs in the caller's simulated time
(:meth:`JointLayerServer.tick`) instead of a wall-clock thread: every run is
deterministic for a seed, whatever the machine's load.

Commands are answered at once: the client end
(:class:`~tudorvision.joint.transport.LockstepClientTransport`) hands each
datagram to the server's :meth:`~JointLayerServer.poll` as it is sent.
"""
from __future__ import annotations

__all__ = ["LockstepLayer"]


class LockstepLayer:
    """Simulated arm + joint-control layer + adapter, advanced in simulated time.

    Parameters
    ----------
    sim : SimCore
        The simulated arm (its clock starts at ``sim.arm.t``).
    rate_hz : float
        Control rate of the layer's loop (safety checks run every period), Hz.

    Raises
    ------
    ValueError
        If ``rate_hz`` is not positive.

    Attributes
    ----------
    server : JointLayerServer
    adapter : JointAdapter
    t : float
        Simulated time, s.
    """

    def __init__(self, sim, *, rate_hz: float = 500.0):
        from ..joint import (InProcessTransport, JointAdapter, JointLayerServer, LockstepClientTransport,
                             ServerConfig)

        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz}")
        self.sim = sim
        self.core = sim       # SimCore installs the damper and collision monitor the layer switches on
        client, end = InProcessTransport.pair()
        # simulated time: the wall-clock age of a command means nothing here
        self.server = JointLayerServer(end, self.core, config=ServerConfig(rate_hz=rate_hz, max_command_age_s=None))
        self.adapter = JointAdapter(LockstepClientTransport(client, self.server))
        self.period = 1.0 / float(rate_hz)
        self.t = float(sim.arm.t)

    def advance_to(self, t: float) -> None:
        """Run the layer (and the plant) up to simulated time ``t`` (s, on its control grid).

        Parameters
        ----------
        t : float
            Target simulated time, seconds; rounded to whole control periods
            from the current time (no step when ``t`` is not ahead).
        """
        n = int(round((float(t) - self.t) / self.period))
        for _ in range(max(n, 0)):
            self.server.tick(self.period)
            self.t += self.period

    def state(self):
        """The layer's current state message (joint angles, strains, flags).

        Returns
        -------
        tudorvision.joint.protocol.State
            The state feedback message (angles in rad, strains in m/m,
            status flags) the server would send now.
        """
        return self.server.state()

    def close(self) -> None:
        """Close the adapter (and its in-process transport)."""
        self.adapter.close()
