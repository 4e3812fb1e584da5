"""Messages of the joint protocol: enums, message dataclasses, state feedback and decoding errors.

These are the values :func:`tudorvision.joint.protocol.encode` puts on the
wire and :func:`~tudorvision.joint.protocol.decode` returns; the byte layout
lives in :mod:`tudorvision.joint.protocol`. Units are SI: radians, rad/s,
rad/s², seconds, strain in m/m.

Examples
--------
>>> JointVelocityCommand(theta_dot=[0.1, 0, -0.2]).theta_dot
(0.1, 0.0, -0.2)
>>> State(t=0.0, theta=(0, 0, 0), theta_dot=(0, 0, 0), flags=StateFlags.SETTLED).settled
True
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field

from .._checks import TudorVisionError
from .keys import check_nonce

__all__ = [
    "MsgType", "Mode", "Damping", "CollisionStrategy", "Reason", "StateFlags", "Header",
    "JointVelocityCommand", "JointSetpoint", "ModeSwitch", "PayloadUpdate", "FaultReset", "StateRequest",
    "Counters", "COUNTER_NAMES", "N_COUNTERS", "State", "Ack", "Refusal", "Hello", "Challenge",
    "OpenSession", "Welcome", "Release", "Message", "COMMAND_TYPES", "SESSION_TYPES", "ProtocolError",
    "BadMagic", "BadVersion", "BadLength", "BadChecksum", "Unauthenticated", "UnknownType", "NonFinite",
    "BadValue",
]




class MsgType(enum.IntEnum):
    """Message type byte in the header."""

    VELOCITY = 1
    SETPOINT = 2
    MODE = 3
    STATE_REQUEST = 4
    STATE = 5
    ACK = 6
    REFUSAL = 7
    PAYLOAD = 8            # added after version 1 shipped; older layers refuse it as unknown
    RESET = 9              # version 2: clear a FAULT (session owner only)
    HELLO = 10             # version 2: session handshake
    CHALLENGE = 11
    OPEN = 12
    WELCOME = 13
    RELEASE = 14


class Mode(enum.IntEnum):
    """Operating mode of the joint-control layer."""

    IDLE = 0        # holds position, refuses motion commands
    VELOCITY = 1    # joint velocity commands with watchdog (visual servoing)
    SETPOINT = 2    # point-to-point joint setpoints (catching)


class Damping(enum.IntEnum):
    """Oscillation damping law of the layer (sections 5-7)."""

    OFF = 0
    PROPORTIONAL = 1       # strain feedback at the velocity-loop input (5.2.1)
    INTEGRAL = 2           # integral feedback at position level (6.5.1)
    HALF_INTEGRATOR = 3    # shifted Pade P5,5 half-integrator (7.5.1)


class CollisionStrategy(enum.IntEnum):
    """Collision reaction strategy (section 11.2)."""

    NONE = 0
    STOP = 1
    REFLEX = 2
    INTERACTION = 3


class Reason(enum.IntEnum):
    """Reason codes carried by :class:`Ack` (codes < 10) and :class:`Refusal` (>= 10)."""

    OK = 0
    CLAMPED_RANGE = 1      # setpoint moved inside the joint range
    CLAMPED_SPEED = 2      # velocity scaled down / setpoint speed reduced to the limit
    CLAMPED_ACCEL = 3      # setpoint acceleration reduced to the limit
    OUT_OF_RANGE = 10
    OVER_SPEED = 11
    OVER_ACCEL = 12
    NON_FINITE = 13
    MALFORMED = 14
    WRONG_MODE = 15
    STALE = 16
    FAULT = 17             # the layer is in a fault stop
    UNSUPPORTED = 18       # the layer's core cannot do this (e.g. no payload model)
    NOT_OWNER = 19         # another client holds the lease (version 2)
    NO_SESSION = 20        # no session, or it ended (lease expired, released, taken over): open one
    INTERNAL = 21          # an exception inside the layer; it stopped the core (FAULT)


class StateFlags(enum.IntFlag):
    """Bits of :attr:`State.flags`."""

    NONE = 0
    WATCHDOG_STOP = 1 << 0   # velocity commands expired; controlled stop in progress/done
    CLAMPED = 1 << 1         # the last accepted command was clamped
    REFUSED = 1 << 2         # the last command was refused
    COLLISION = 1 << 3       # the core reports a detected collision
    SETTLED = 1 << 4         # the core reports the arm at rest (joints and strains)
    MOVING = 1 << 5          # some joint speed above the rest threshold
    LIMIT_BRAKE = 1 << 6     # velocity reduced to stop before a joint range limit
    FAULT = 1 << 7           # the core left its limits or raised; the layer stopped it
    OWNED = 1 << 8           # a client holds the lease (version 2)


@dataclass(frozen=True)
class Header:
    """Decoded datagram header."""

    version: int
    msg_type: MsgType
    seq: int
    t_sent: float
    payload_len: int
    session: int = 0
    authenticated: bool = False


def _floats(value, name: str, n: int) -> tuple:
    tolist = getattr(value, "tolist", None)      # numpy arrays: much faster than iterating
    if tolist is not None:
        value = tolist()
    try:
        out = tuple(map(float, value))
    except TypeError:
        raise ValueError(f"{name}: expected {n} numbers, got {value!r}") from None
    if len(out) != n:
        raise ValueError(f"{name}: expected {n} numbers, got {len(out)}")
    return out


@dataclass(frozen=True, kw_only=True)
class JointVelocityCommand:
    """Joint velocity reference, held until the watchdog expires.

    Parameters
    ----------
    theta_dot : tuple of 3 float
        Joint speeds in rad/s at the gear output (any sequence of 3 numbers).
    """

    theta_dot: tuple

    def __post_init__(self):
        object.__setattr__(self, "theta_dot", _floats(self.theta_dot, "theta_dot", 3))


@dataclass(frozen=True, kw_only=True)
class JointSetpoint:
    """Joint position setpoint in rad, shape (3,), with optional scalar limits.

    Parameters
    ----------
    theta : tuple of 3 float
        Target joint angles in rad (any sequence of 3 numbers).
    max_speed : float or None
        Speed bound of the point-to-point profile in rad/s; ``None``: the
        layer's default.
    max_accel : float or None
        Acceleration bound of the profile in rad/s²; ``None``: the layer's default.
    """

    theta: tuple
    max_speed: float | None = None
    max_accel: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "theta", _floats(self.theta, "theta", 3))
        for name in ("max_speed", "max_accel"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, float(v))


@dataclass(frozen=True, kw_only=True)
class ModeSwitch:
    """Switch mode, damping law and collision strategy; ``None`` keeps the current one.

    Parameters
    ----------
    mode : Mode or None
        Operating mode.
    damping : Damping or None
        Oscillation damping law.
    collision : CollisionStrategy or None
        Collision reaction strategy.
    """

    mode: Mode | None = None
    damping: Damping | None = None
    collision: CollisionStrategy | None = None

    def __post_init__(self):
        for name, cls in (("mode", Mode), ("damping", Damping), ("collision", CollisionStrategy)):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, cls(v))


@dataclass(frozen=True, kw_only=True)
class PayloadUpdate:
    """Tell the layer the payload at the end effector (mount, plates, caught balls), kg.

    The layer schedules its damping gains and its collision model on it; a
    layer whose core has no payload model refuses it with ``UNSUPPORTED``.

    Parameters
    ----------
    payload_kg : float
        Payload mass in kg (the layer accepts [0, 5] kg).
    """

    payload_kg: float

    def __post_init__(self):
        object.__setattr__(self, "payload_kg", float(self.payload_kg))


@dataclass(frozen=True, kw_only=True)
class FaultReset:
    """Clear the layer's ``FAULT`` flag (the session owner only; empty payload).

    A mode switch does not clear a fault: the owner must say so explicitly.
    """


@dataclass(frozen=True, kw_only=True)
class Release:
    """End the session and give the lease back (empty payload)."""


@dataclass(frozen=True, kw_only=True)
class StateRequest:
    """Ask the layer for a :class:`State` (empty payload)."""


@dataclass(frozen=True, kw_only=True)
class Hello:
    """First message of the session handshake: a fresh random client nonce (16 bytes)."""

    client_nonce: bytes

    def __post_init__(self):
        object.__setattr__(self, "client_nonce", check_nonce(self.client_nonce, "client_nonce"))


@dataclass(frozen=True, kw_only=True)
class Challenge:
    """The layer's answer to :class:`Hello`: the client nonce and a fresh server nonce."""

    client_nonce: bytes
    server_nonce: bytes

    def __post_init__(self):
        for name in ("client_nonce", "server_nonce"):
            object.__setattr__(self, name, check_nonce(getattr(self, name), name))


@dataclass(frozen=True, kw_only=True)
class OpenSession:
    """Open the session: both nonces back, and whether to take the lease over from its holder."""

    client_nonce: bytes
    server_nonce: bytes
    takeover: bool = False

    def __post_init__(self):
        for name in ("client_nonce", "server_nonce"):
            object.__setattr__(self, name, check_nonce(getattr(self, name), name))
        object.__setattr__(self, "takeover", bool(self.takeover))


@dataclass(frozen=True, kw_only=True)
class Welcome:
    """The session is open: its id (uint32, never 0) and the lease time in s of control time.

    The lease is renewed by every valid datagram of the session; it ends after
    ``lease_s`` without one, on :class:`Release` or on a takeover.
    """

    client_nonce: bytes
    session: int
    lease_s: float

    def __post_init__(self):
        object.__setattr__(self, "client_nonce", check_nonce(self.client_nonce, "client_nonce"))
        object.__setattr__(self, "session", int(self.session))
        object.__setattr__(self, "lease_s", float(self.lease_s))


@dataclass(frozen=True, kw_only=True)
class Counters:
    """Event counters of the layer since it started."""

    malformed: int = 0       # datagrams that failed to decode (incl. NaN/inf values)
    refused: int = 0         # well-formed commands refused (limits, mode, age)
    duplicates: int = 0      # commands whose sequence number was already seen
    stale: int = 0           # commands older than the newest seen, or too old in time
    watchdog_stops: int = 0  # velocity watchdog expiries
    accepted: int = 0        # commands accepted (possibly clamped)
    overruns: int = 0        # control ticks skipped because the loop fell behind
    unauthenticated: int = 0  # datagrams without a valid tag (or no session known for them)
    replayed: int = 0        # authenticated datagrams outside the session's sequence window
    rate_limited: int = 0    # datagrams dropped by the per-source rate limit, before decoding
    not_owner: int = 0       # commands refused because the sender does not hold the lease
    faults: int = 0          # fault stops (limits left, non-finite state, exceptions)


COUNTER_NAMES = ("malformed", "refused", "duplicates", "stale", "watchdog_stops", "accepted",
                  "overruns", "unauthenticated", "replayed", "rate_limited", "not_owner", "faults")
N_COUNTERS = len(COUNTER_NAMES)


@dataclass(frozen=True, kw_only=True)
class State:
    """State feedback of the joint-control layer.

    Attributes
    ----------
    t : float
        Time of the layer's core in s.
    theta, theta_dot : tuple of 3 float
        Joint angles (rad) and speeds (rad/s) at the gear output.
    strains : tuple of 4 float
        Strain gauge signals in m/m (link 2 root, link 2 mid, link 3 root, link 3 mid).
    residuals : tuple of 3 float
        Collision-detection residuals per joint (core units).
    flags : StateFlags
    mode, damping, collision : Mode, Damping, CollisionStrategy
    last_command_seq : int
        Sequence number of the last command accepted from any client (0 before any).
    request_seq : int
        Sequence number of the :class:`StateRequest` this answers (0 if unsolicited).
    counters : Counters
    tick_p50_s, tick_p99_s, tick_max_s : float
        Median, 99th percentile and largest interval in s between control
        ticks of the wall-clock loop over the last second (0 without ticks).
    """

    t: float
    theta: tuple
    theta_dot: tuple
    strains: tuple = (0.0, 0.0, 0.0, 0.0)
    residuals: tuple = (0.0, 0.0, 0.0)
    flags: StateFlags = StateFlags.NONE
    mode: Mode = Mode.IDLE
    damping: Damping = Damping.OFF
    collision: CollisionStrategy = CollisionStrategy.NONE
    last_command_seq: int = 0
    request_seq: int = 0
    counters: Counters = field(default_factory=Counters)
    tick_p50_s: float = 0.0
    tick_p99_s: float = 0.0
    tick_max_s: float = 0.0

    def __post_init__(self):
        put = object.__setattr__
        for name in ("t", "tick_p50_s", "tick_p99_s", "tick_max_s"):
            put(self, name, float(getattr(self, name)))
        for name, n in (("theta", 3), ("theta_dot", 3), ("strains", 4), ("residuals", 3)):
            put(self, name, _floats(getattr(self, name), name, n))
        if type(self.flags) is not StateFlags:
            put(self, "flags", StateFlags(int(self.flags)))
        for name, cls in (("mode", Mode), ("damping", Damping), ("collision", CollisionStrategy)):
            if type(getattr(self, name)) is not cls:
                put(self, name, cls(getattr(self, name)))

    @property
    def settled(self) -> bool:
        """True when the SETTLED flag is set."""
        return bool(self.flags & StateFlags.SETTLED)


@dataclass(frozen=True, kw_only=True)
class Ack:
    """Acceptance of a command; ``code`` tells whether it was clamped.

    Parameters
    ----------
    command_seq : int
        Sequence number of the accepted command.
    code : Reason
        ``OK`` or a ``CLAMPED_*`` code (< 10).
    text : str
        What was clamped, for humans (at most 255 bytes of UTF-8 on the wire).
    """

    command_seq: int
    code: Reason = Reason.OK
    text: str = ""

    def __post_init__(self):
        object.__setattr__(self, "code", Reason(self.code))


@dataclass(frozen=True, kw_only=True)
class Refusal:
    """Refusal of a command with a reason code and a human-readable text.

    Parameters
    ----------
    command_seq : int
        Sequence number of the refused command.
    code : Reason
        Why (a code >= 10).
    text : str
        Explanation for humans (at most 255 bytes of UTF-8 on the wire).
    """

    command_seq: int
    code: Reason
    text: str = ""

    def __post_init__(self):
        object.__setattr__(self, "code", Reason(self.code))


Message = (JointVelocityCommand | JointSetpoint | ModeSwitch | PayloadUpdate | FaultReset | Release
           | StateRequest | State | Ack | Refusal | Hello | Challenge | OpenSession | Welcome)
#: Messages that change the layer: only the session owner's are executed.
COMMAND_TYPES = (JointVelocityCommand, JointSetpoint, ModeSwitch, PayloadUpdate, FaultReset, Release)
#: Messages of the session handshake (sent with session id 0).
SESSION_TYPES = (Hello, Challenge, OpenSession, Welcome)


class ProtocolError(TudorVisionError):
    """A datagram that cannot be decoded.

    ``header`` is the decoded :class:`Header` when the header and checksum were
    valid (the sender and sequence number can be trusted), else ``None``.
    """

    reason = Reason.MALFORMED

    def __init__(self, message: str, header: Header | None = None):
        super().__init__(message)
        self.header = header


class BadMagic(ProtocolError):
    """The datagram does not start with :data:`MAGIC`."""


class BadVersion(ProtocolError):
    """Unsupported protocol version."""


class BadLength(ProtocolError):
    """Datagram shorter than a header, or payload length not matching."""


class BadChecksum(ProtocolError):
    """CRC32 mismatch (corrupted bytes)."""


class Unauthenticated(ProtocolError):
    """The HMAC-SHA256 tag is missing, wrong, or present where no key is known."""


class UnknownType(ProtocolError):
    """Unknown message type byte."""


class NonFinite(ProtocolError):
    """A float field holds NaN or an infinity."""

    reason = Reason.NON_FINITE


class BadValue(ProtocolError):
    """A field holds a value outside its domain (enum, flags, text encoding)."""
