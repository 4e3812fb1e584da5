"""Cores of the joint-control layer: the protocol the server drives, and the registry of cores by name.

A *core* is the object that actually moves the arm. The server
(:class:`tudorvision.joint.server.JointLayerServer`) drives anything that
implements :class:`JointCore`; a core that can take the payload announced by
a :class:`~tudorvision.joint.messages.PayloadUpdate` also implements
:class:`PayloadAwareCore`. :class:`KinematicCore` (a rigid integrator) is
registered as ``"kinematic"``; the simulated elastic arm is registered by the
``cli`` package as ``"sim"``, so the joint layer never imports the simulation.

Examples
--------
>>> core = make_core("kinematic")
>>> isinstance(core, JointCore), isinstance(core, PayloadAwareCore)
(True, True)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol, runtime_checkable

import numpy as np

from .._checks import TudorVisionError, check_array
from .messages import CollisionStrategy, Damping, StateFlags
from .safety import SafetyLimits, ramp_velocity

__all__ = ["CoreState", "JointCore", "PayloadAwareCore", "KinematicCore", "MAX_PAYLOAD_KG", "register_core",
           "make_core", "core_names"]

# StateFlags bits as plain ints: IntFlag arithmetic costs microseconds per operation.
_SETTLED, _MOVING, _COLLISION = int(StateFlags.SETTLED), int(StateFlags.MOVING), int(StateFlags.COLLISION)


@dataclass(frozen=True, kw_only=True, eq=False)
class CoreState:
    """What a core reports after each step.

    Attributes
    ----------
    t : float
        Core time in s (advances by the ``dt`` given to :meth:`JointCore.step`).
    theta, theta_dot : ndarray, shape (3,)
        Joint angles (rad) and speeds (rad/s) at the gear output.
    strains : ndarray, shape (4,)
        Strain gauge signals in m/m (link 2 root, mid; link 3 root, mid).
    residuals : ndarray, shape (3,)
        Collision residuals per joint.
    collision : bool
        A collision is detected now.
    settled : bool
        The arm is at rest: the current setpoint is reached (or the stop is
        complete) and strains are inside the settling band.
    """

    t: float
    theta: np.ndarray
    theta_dot: np.ndarray
    strains: np.ndarray = field(default_factory=lambda: np.zeros(4))
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(3))
    collision: bool = False
    settled: bool = False

    def status_flags(self, rest_speed_rad_s: float) -> int:
        """The :class:`~tudorvision.joint.messages.StateFlags` this state implies: SETTLED, MOVING, COLLISION.

        Parameters
        ----------
        rest_speed_rad_s : float
            A joint faster than this (rad/s) is moving.

        Returns
        -------
        int
            The flag bits as a plain int.
        """
        flags = _SETTLED if self.settled else 0
        if np.any(np.abs(self.theta_dot) > rest_speed_rad_s):
            flags |= _MOVING
        return flags | _COLLISION if self.collision else flags


@runtime_checkable
class JointCore(Protocol):
    """The minimal interface between the server and the arm's joint controller.

    The server calls these from one thread only. Per control tick in velocity
    mode it calls :meth:`apply_velocity` then :meth:`step` while a command is
    live or the reference is still ramping down; once the reference is zero
    with no live command it calls :meth:`stop` once (position hold) and then
    only :meth:`step`. In the other modes it calls :meth:`step` each tick,
    :meth:`apply_setpoint` per accepted setpoint and :meth:`stop` on entering
    IDLE, on leaving VELOCITY and on a fault. All vectors are float64 arrays
    of shape (3,), SI units; ``state().t`` should advance by the stepped ``dt``.

    Optional capabilities are declared by further protocols, never guessed
    from attributes: a core with a payload model implements
    :class:`PayloadAwareCore` as well; the server refuses a
    :class:`~tudorvision.joint.messages.PayloadUpdate` with ``UNSUPPORTED``
    for a core that does not.
    """

    def apply_velocity(self, theta_dot: np.ndarray) -> None:
        """Track this joint velocity reference from now on.

        Parameters
        ----------
        theta_dot : ndarray, shape (3,)
            Joint velocity reference in rad/s, already checked, braked and
            acceleration-limited by the server.
        """

    def apply_setpoint(self, theta: np.ndarray, *, max_speed_rad_s: np.ndarray,
                       max_accel_rad_s2: np.ndarray) -> None:
        """Start a point-to-point motion to ``theta`` within these per-joint limits.

        May be called while the arm moves (a new setpoint replaces the old one).

        Parameters
        ----------
        theta : ndarray, shape (3,)
            Target joint angles in rad, inside the joint ranges.
        max_speed_rad_s : ndarray, shape (3,)
            Per-joint speed limit of the profile in rad/s.
        max_accel_rad_s2 : ndarray, shape (3,)
            Per-joint acceleration limit of the profile in rad/s².
        """

    def stop(self) -> None:
        """Controlled stop: decelerate within the acceleration limits and hold."""

    def set_modes(self, *, damping: Damping, collision: CollisionStrategy) -> None:
        """Select the damping law and the collision reaction strategy.

        Parameters
        ----------
        damping : Damping
            Oscillation damping law.
        collision : CollisionStrategy
            Collision reaction strategy.
        """

    def step(self, dt: float) -> None:
        """Advance the arm by ``dt`` (the core may sub-step, e.g. at 2 kHz).

        Parameters
        ----------
        dt : float
            Control period in s.
        """

    def state(self) -> CoreState:
        """Current state after the last :meth:`step`."""


@runtime_checkable
class PayloadAwareCore(Protocol):
    """The capability of a core with a payload model: it takes the payload mass at the end effector.

    The server checks ``isinstance(core, PayloadAwareCore)`` when a
    :class:`~tudorvision.joint.messages.PayloadUpdate` arrives: it calls
    :meth:`set_payload` with the checked mass (in [0, :data:`MAX_PAYLOAD_KG`]
    kg) if the core implements it, and refuses the update with
    ``Reason.UNSUPPORTED`` otherwise. :class:`KinematicCore` and
    :class:`tudorvision.joint.controlled.CascadeCore` implement it.
    """

    def set_payload(self, payload_kg: float) -> None:
        """Take the payload at the end effector (mount, plates, caught balls).

        Parameters
        ----------
        payload_kg : float
            Payload mass in kg, in [0, :data:`MAX_PAYLOAD_KG`].
        """


class KinematicCore:
    """Rigid joint integrator: a stand-in core without elasticity.

    Velocity references are followed exactly; setpoints with a time-optimal
    bang-bang profile per joint; :meth:`stop` decelerates at the acceleration
    limit. Strains and residuals stay zero. Used by ``tudorvision joint serve
    --core kinematic`` until the simulated elastic arm is registered.

    Parameters
    ----------
    theta0 : array_like, shape (3,), optional
        Initial joint angles in rad (default: the vertical posture [0, 90°, 0]).
    limits : SafetyLimits, optional
        Acceleration limits for stops (default: the robot parameters).
    substep_s : float
        Integration step in s.

    Examples
    --------
    >>> core = KinematicCore(theta0=[0.0, 0.0, 0.0])
    >>> core.apply_velocity(np.array([0.1, 0.0, 0.0])); core.step(1.0)
    >>> round(float(core.state().theta[0]), 6)
    0.1
    """

    def __init__(self, theta0=None, *, limits: SafetyLimits | None = None,
                 substep_s: float = 1e-3):
        self._limits = limits or SafetyLimits.from_params()
        self._theta = (np.array([0.0, np.pi / 2, 0.0]) if theta0 is None
                       else check_array(theta0, "theta0", (3,)).copy())
        self._v = np.zeros(3)
        self._t = 0.0
        self._h = float(substep_s)
        self._mode = "stop"
        self._v_cmd = np.zeros(3)
        self._target = self._theta.copy()
        self._vmax = self._limits.max_speed_rad_s
        self._amax = self._limits.max_accel_rad_s2
        self.damping, self.collision = Damping.OFF, CollisionStrategy.NONE

    def apply_velocity(self, theta_dot):
        """Follow this joint velocity exactly from the next step on.

        Parameters
        ----------
        theta_dot : array_like, shape (3,)
            Joint velocity in rad/s.
        """
        self._mode, self._v_cmd = "velocity", np.asarray(theta_dot, dtype=float).copy()

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2):
        """Move to ``theta`` with a time-optimal bang-bang profile per joint.

        Parameters
        ----------
        theta : array_like, shape (3,)
            Target joint angles in rad.
        max_speed_rad_s : array_like, shape (3,)
            Per-joint speed limit in rad/s.
        max_accel_rad_s2 : array_like, shape (3,)
            Per-joint acceleration limit in rad/s².
        """
        self._mode, self._target = "setpoint", np.asarray(theta, dtype=float).copy()
        self._vmax = np.asarray(max_speed_rad_s, dtype=float)
        self._amax = np.asarray(max_accel_rad_s2, dtype=float)

    def stop(self):
        """Decelerate at the acceleration limits and hold."""
        self._mode, self._amax = "stop", self._limits.max_accel_rad_s2

    def set_modes(self, *, damping, collision):
        """Record the damping law and collision strategy (a rigid integrator uses neither).

        Parameters
        ----------
        damping : Damping
            Oscillation damping law.
        collision : CollisionStrategy
            Collision reaction strategy.
        """
        self.damping, self.collision = Damping(damping), CollisionStrategy(collision)

    def set_payload(self, payload_kg: float) -> None:
        """Record the payload (a rigid integrator has no use for it).

        Parameters
        ----------
        payload_kg : float
            Payload mass in kg.
        """
        self.payload_kg = float(payload_kg)

    def step(self, dt):
        """Integrate the joints over ``dt`` in sub-steps of at most about ``substep_s``.

        Parameters
        ----------
        dt : float
            Duration in s.
        """
        n = max(1, int(round(dt / self._h)))
        h = dt / n
        for _ in range(n):
            if self._mode == "velocity":
                self._v = self._v_cmd.copy()
            else:
                if self._mode == "setpoint":
                    e = self._target - self._theta
                    want = np.sign(e) * np.minimum.reduce(
                        [self._vmax, np.sqrt(2 * self._amax * np.abs(e)), np.abs(e) / h])
                else:
                    want = np.zeros(3)
                self._v = ramp_velocity(self._v, want, self._amax, h)
            self._theta = self._theta + self._v * h
            self._t += h

    def state(self) -> CoreState:
        """The current joint state.

        Returns
        -------
        CoreState
            Angles and speeds; strains and residuals are zero; settled when at
            rest (and the setpoint is reached) outside velocity mode.
        """
        at_rest = bool(np.all(np.abs(self._v) < 1e-6))
        reached = (self._mode != "setpoint"
                   or bool(np.all(np.abs(self._target - self._theta) < 1e-6)))
        return CoreState(t=self._t, theta=self._theta.copy(), theta_dot=self._v.copy(),
                         settled=at_rest and reached and self._mode != "velocity")


#: Largest payload a :class:`tudorvision.joint.protocol.PayloadUpdate` may announce, kg.
MAX_PAYLOAD_KG = 5.0

_CORES: dict[str, Callable[..., JointCore]] = {}


def register_core(name: str, factory: Callable[..., JointCore]) -> None:
    """Make a core available to :func:`make_core` and ``tudorvision joint serve --core``.

    Parameters
    ----------
    name : str
        Name of the core (replaces an earlier registration of that name).
    factory : callable
        ``factory(**options) -> JointCore``.
    """
    _CORES[name] = factory


def core_names() -> list[str]:
    """Names accepted by :func:`make_core`.

    Returns
    -------
    list of str
        Registered core names, sorted.
    """
    return sorted(_CORES)


def make_core(name: str, **options) -> JointCore:
    """Build a registered core by name: ``"kinematic"`` or ``"sim"`` (the elastic arm).

    Parameters
    ----------
    name : str
        A name from :func:`core_names`.
    **options
        Keyword arguments for the core's factory.

    Returns
    -------
    JointCore
        The new core.

    Raises
    ------
    TudorVisionError
        If no core of that name is registered.
    """
    try:
        factory = _CORES[name]
    except KeyError:
        raise TudorVisionError(f"core: unknown core {name!r}; available: "
                               f"{', '.join(core_names())}") from None
    return factory(**options)


register_core("kinematic", KinematicCore)
