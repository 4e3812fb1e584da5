"""Joint-control layer: cascade control, motion planning, and the thin adapter perception talks to.

Perception code uses :class:`JointAdapter` only (over UDP or in-process);
the layer (:class:`JointLayerServer` around a core such as the simulated
arm) owns safety, damping and collision handling.
"""
from .adapter import AdapterStats, JointAdapter
from .collision import (N_PARAMS, STRATEGIES, STRATEGY_OF_CODE, Admittance, CollisionMonitor, FitReport,
                        MomentumObserver, ReactionConfig, StrainDynamicsModel, aprbs, derivatives, fit_report,
                        fit_strain_dynamics, isolate, reaction_config, regressor, regressor_payload,
                        root_torque_per_strain, thresholds_from_residuals)
from .damping import (DEFAULT_GAINS, GAUGE_OF_JOINT, LAWS, ONE_WAY_GAINS, PAYLOAD_SCHEDULE, TWO_WAY_GAINS,
                      DampingConfig, SosFilter, StaticStrainFilter, StrainDamper, default_damping_config,
                      half_integrator_sos, highpass_response, moving_average_fir, pade_p55, payload_gain_factor,
                      proportional_feedback, static_strain_fir)
from .metrics import (ANGLE_BAND_RAD, METRIC_NAMES, STRAIN_BAND, damping_metrics, goodness_of_fit, iate, iats,
                      max_abs, normalise_metrics, nrmse, settling_time, spectral_amplitude)
from .cascade import CascadeGains, JointCascade, design_cascade
from .planner import JointMotion, OnlinePlanner, plan_motion, sinusoidal_transition
from .protocol import (Ack, CollisionStrategy, Damping, JointSetpoint, JointVelocityCommand, Mode, ModeSwitch,
                       PayloadUpdate, ProtocolError, Reason, Refusal, State, StateFlags, StateRequest, decode, encode)
from .proxy import FaultModel, GilbertElliott, LossyUdpProxy
from .safety import (SafetyLimits, SafetyPolicy, brake_velocity, check_setpoint, check_velocity_command,
                     ramp_velocity, stopping_time, within_range)
from .server import (CoreState, JointCore, JointLayerServer, KinematicCore, ServerConfig, core_names,
                     make_core, register_core)
from .transport import InProcessTransport, LockstepClientTransport, Transport, TransportClosed, UdpTransport

__all__ = [
    "AdapterStats", "JointAdapter",
    "N_PARAMS", "STRATEGIES", "STRATEGY_OF_CODE", "Admittance", "CollisionMonitor", "FitReport", "MomentumObserver",
    "ReactionConfig", "StrainDynamicsModel", "aprbs", "derivatives", "fit_report", "fit_strain_dynamics", "isolate",
    "reaction_config", "regressor", "regressor_payload", "root_torque_per_strain", "thresholds_from_residuals",
    "DEFAULT_GAINS", "GAUGE_OF_JOINT", "LAWS", "ONE_WAY_GAINS", "PAYLOAD_SCHEDULE", "TWO_WAY_GAINS", "DampingConfig", "SosFilter",
    "StaticStrainFilter", "StrainDamper", "default_damping_config", "half_integrator_sos", "highpass_response",
    "moving_average_fir", "pade_p55", "payload_gain_factor", "proportional_feedback", "static_strain_fir",
    "ANGLE_BAND_RAD", "METRIC_NAMES", "STRAIN_BAND", "damping_metrics", "goodness_of_fit", "iate", "iats", "max_abs",
    "normalise_metrics", "nrmse", "settling_time", "spectral_amplitude",
    "CascadeGains", "JointCascade", "design_cascade",
    "JointMotion", "OnlinePlanner", "plan_motion", "sinusoidal_transition",
    "Ack", "CollisionStrategy", "Damping", "JointSetpoint", "JointVelocityCommand", "Mode", "ModeSwitch",
    "PayloadUpdate", "ProtocolError", "Reason", "Refusal", "State", "StateFlags", "StateRequest", "decode", "encode",
    "FaultModel", "GilbertElliott", "LossyUdpProxy",
    "SafetyLimits", "SafetyPolicy", "brake_velocity", "check_setpoint", "check_velocity_command",
    "ramp_velocity", "stopping_time", "within_range",
    "CoreState", "JointCore", "JointLayerServer", "KinematicCore", "ServerConfig", "core_names", "make_core",
    "register_core",
    "InProcessTransport", "LockstepClientTransport", "Transport", "TransportClosed", "UdpTransport",
]
