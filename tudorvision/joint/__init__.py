"""Joint-control layer: cascade control, motion planning, and the thin adapter perception talks to.

Perception code uses :class:`JointAdapter` only (over UDP or in-process);
the layer (:class:`JointLayerServer` around a core such as the simulated
arm) owns safety, damping and collision handling.

The names below are imported on first use (PEP 562), so importing one
submodule (``tudorvision.joint.cores``) does not load scipy for the damping
filters; ``from tudorvision.joint import X`` works as usual.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:  # the same names, for type checkers and the import-layer checks
    from .adapter import AdapterStats, JointAdapter
    from .cascade import CascadeGains, JointCascade, design_cascade
    from .collision import CollisionMonitor, MomentumObserver, ReactionConfig, reaction_config
    from .strain_dynamics import StrainDynamicsModel, fit_strain_dynamics
    from .damping import DampingConfig, StrainDamper, default_damping_config
    from .metrics import damping_metrics, settling_time
    from .planner import BlendedMotion, JointMotion, OnlinePlanner, blend_replan, plan_motion
    from .protocol import (Ack, CollisionStrategy, Damping, JointSetpoint, JointVelocityCommand, Mode, ModeSwitch,
                           PayloadUpdate, ProtocolError, Reason, Refusal, State, StateFlags, StateRequest, decode,
                           encode)
    from .proxy import FaultModel, LossyUdpProxy
    from .safety import SafetyLimits, SafetyPolicy
    from .cores import CoreState, JointCore, KinematicCore, core_names, make_core, register_core
    from .server import JointLayerServer
    from .server_config import ServerConfig
    from .transport import InProcessTransport, LockstepClientTransport, Transport, TransportClosed, UdpTransport

# submodule -> the names it provides here
_PROVIDERS = {
    "adapter": ("AdapterStats", "JointAdapter"),
    "cascade": ("CascadeGains", "JointCascade", "design_cascade"),
    "collision": ("CollisionMonitor", "MomentumObserver", "ReactionConfig", "reaction_config"),
    "strain_dynamics": ("StrainDynamicsModel", "fit_strain_dynamics"),
    "damping": ("DampingConfig", "StrainDamper", "default_damping_config"),
    "metrics": ("damping_metrics", "settling_time"),
    "planner": ("JointMotion", "OnlinePlanner", "plan_motion", "BlendedMotion", "blend_replan"),
    "protocol": ("Ack", "CollisionStrategy", "Damping", "JointSetpoint", "JointVelocityCommand", "Mode", "ModeSwitch",
                 "PayloadUpdate", "ProtocolError", "Reason", "Refusal", "State", "StateFlags", "StateRequest",
                 "decode", "encode"),
    "proxy": ("FaultModel", "LossyUdpProxy"),
    "safety": ("SafetyLimits", "SafetyPolicy"),
    "cores": ("CoreState", "JointCore", "KinematicCore", "core_names", "make_core", "register_core"),
    "server": ("JointLayerServer",),
    "server_config": ("ServerConfig",),
    "transport": ("InProcessTransport", "LockstepClientTransport", "Transport", "TransportClosed", "UdpTransport"),
}

__all__ = [
    # what perception talks to
    "JointAdapter", "AdapterStats",
    # the wire protocol
    "Mode", "CollisionStrategy", "Damping", "JointSetpoint", "JointVelocityCommand", "ModeSwitch", "PayloadUpdate",
    "StateRequest", "State", "StateFlags", "Ack", "Refusal", "Reason", "ProtocolError", "encode", "decode",
    # the layer and its cores
    "JointLayerServer", "ServerConfig", "JointCore", "CoreState", "KinematicCore", "make_core", "register_core",
    "core_names", "SafetyLimits", "SafetyPolicy",
    # transports and the lossy test proxy
    "Transport", "TransportClosed", "UdpTransport", "InProcessTransport", "LockstepClientTransport",
    "LossyUdpProxy", "FaultModel",
    # control: cascade, planning, damping, collision handling
    "CascadeGains", "JointCascade", "design_cascade", "JointMotion", "OnlinePlanner", "plan_motion",
    "BlendedMotion", "blend_replan",
    "DampingConfig", "StrainDamper", "default_damping_config",
    "CollisionMonitor", "MomentumObserver", "ReactionConfig", "reaction_config", "StrainDynamicsModel",
    "fit_strain_dynamics", "damping_metrics", "settling_time",
]


__getattr__, __dir__ = lazy_exports(__name__, _PROVIDERS, globals(), __all__)
