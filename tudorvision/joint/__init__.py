"""Joint-control layer: cascade control, motion planning, and the thin adapter perception talks to.

Perception code uses :class:`JointAdapter` only (over UDP or in-process);
the layer (:class:`JointLayerServer` around a core such as the simulated
arm) owns safety, damping and collision handling.
"""
from .adapter import AdapterStats, JointAdapter
from .cascade import (CascadeGains, JointCascade, design_cascade, friction_torque, motor_gain,
                      reflected_inertia, reflected_viscous)
from .planner import JointMotion, OnlinePlanner, plan_motion, sinusoidal_transition
from .protocol import (Ack, CollisionStrategy, Damping, JointSetpoint, JointVelocityCommand, Mode, ModeSwitch,
                       ProtocolError, Reason, Refusal, State, StateFlags, StateRequest, decode, encode)
from .proxy import FaultModel, GilbertElliott, LossyUdpProxy
from .safety import (SafetyLimits, SafetyPolicy, brake_velocity, check_setpoint, check_velocity_command,
                     ramp_velocity, stopping_time, within_range)
from .server import (CoreState, JointCore, JointLayerServer, KinematicCore, ServerConfig, core_names,
                     make_core, register_core)
from .transport import InProcessTransport, LockstepClientTransport, Transport, TransportClosed, UdpTransport

__all__ = [
    "AdapterStats", "JointAdapter",
    "CascadeGains", "JointCascade", "design_cascade", "friction_torque", "motor_gain", "reflected_inertia",
    "reflected_viscous",
    "JointMotion", "OnlinePlanner", "plan_motion", "sinusoidal_transition",
    "Ack", "CollisionStrategy", "Damping", "JointSetpoint", "JointVelocityCommand", "Mode", "ModeSwitch",
    "ProtocolError", "Reason", "Refusal", "State", "StateFlags", "StateRequest", "decode", "encode",
    "FaultModel", "GilbertElliott", "LossyUdpProxy",
    "SafetyLimits", "SafetyPolicy", "brake_velocity", "check_setpoint", "check_velocity_command",
    "ramp_velocity", "stopping_time", "within_range",
    "CoreState", "JointCore", "JointLayerServer", "KinematicCore", "ServerConfig", "core_names", "make_core",
    "register_core",
    "InProcessTransport", "LockstepClientTransport", "Transport", "TransportClosed", "UdpTransport",
]
