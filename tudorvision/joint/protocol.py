"""Binary UDP protocol between perception and the joint-control layer.

Every datagram is a fixed 32-byte header, a message payload and, when the
layer has a key, a 32-byte HMAC-SHA256 tag; all big-endian (network order):

========  =======  ==========================================================
offset    format   field
========  =======  ==========================================================
0         4s       magic ``b"TDJL"``
4         B        protocol version (:data:`VERSION`)
5         B        message type (:class:`MsgType`)
6         B        flags: bit 0 set = an HMAC-SHA256 tag follows the payload
7         B        reserved, must be 0
8         I        session id (0: no session - handshake and state requests)
12        I        sequence number (uint32, wraps; per sender and session)
16        d        sender timestamp in seconds (``time.monotonic`` of the sender)
24        I        payload length in bytes (without the tag)
28        I        CRC32 (``zlib.crc32``) over the header with this field zeroed,
                   followed by the payload
32        ...      payload
32 + n    32s      optional tag: ``HMAC-SHA256(key, header + payload)``
========  =======  ==========================================================

Datagrams outside a session (session id 0) are tagged with the long-term key
of the key file; datagrams in a session with the session key derived from it
and the two nonces of the handshake (:func:`session_key`), so a datagram of
one session is never valid in another. The session handshake::

    client                               layer
    Hello(client_nonce)          ->
                                 <-      Challenge(client_nonce, server_nonce)
    OpenSession(both nonces)     ->      (a fresh server nonce: replays fail)
                                 <-      Welcome(client_nonce, session, lease_s)

Units are SI: radians, rad/s, rad/s², seconds, strain in m/m. All floats are
float64 and must be finite; :func:`decode` refuses NaN and infinities.

Version 2 added the session id, the tag, the session messages, the fault
reset and the tick statistics of :class:`State`; version 1 datagrams are
refused (:class:`BadVersion`).

Examples
--------
>>> data = encode(JointVelocityCommand(theta_dot=(0.1, 0.0, -0.2)), seq=7, t=1.5)
>>> header, msg = decode(data)
>>> header.seq, header.msg_type.name, msg.theta_dot
(7, 'VELOCITY', (0.1, 0.0, -0.2))
>>> key = bytes(32)
>>> header, msg = decode(encode(StateRequest(), seq=1, t=0.0, key=key), key=key)
>>> header.authenticated
True
"""
from __future__ import annotations

import enum
import hmac
import math
import os
import struct
import zlib
from dataclasses import dataclass, field

from .._checks import TudorVisionError

__all__ = [
    "MAGIC", "VERSION", "HEADER_SIZE", "TAG_SIZE", "NONCE_SIZE", "KEY_SIZE", "MAX_DATAGRAM", "MsgType",
    "Mode", "Damping", "CollisionStrategy", "Reason", "StateFlags", "Header", "JointVelocityCommand",
    "JointSetpoint", "ModeSwitch", "PayloadUpdate", "FaultReset", "StateRequest", "Counters", "State",
    "Ack", "Refusal", "Hello", "Challenge", "OpenSession", "Welcome", "Release",
    "Message", "COMMAND_TYPES", "SESSION_TYPES", "ProtocolError", "BadMagic", "BadVersion", "BadLength",
    "BadChecksum", "Unauthenticated", "UnknownType", "NonFinite", "BadValue", "encode", "decode", "peek",
    "session_key", "new_nonce", "write_key_file", "read_key_file", "seq_newer", "seq_add",
]

MAGIC = b"TDJL"
VERSION = 2
_HEADER = struct.Struct("!4sBBBBIIdII")
HEADER_SIZE = _HEADER.size          # 32 bytes
TAG_SIZE = 32                       # HMAC-SHA256
NONCE_SIZE = 16
KEY_SIZE = 32                       # bytes of a key file's key
_AUTH = 0x01                        # header flags bit: tag present
MAX_DATAGRAM = 1400                 # stays below a typical Ethernet MTU
MAX_TEXT = 255                      # bytes of UTF-8 in Ack/Refusal texts
_KEEP = 0xFF                        # "keep current" in ModeSwitch fields


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
    """Joint velocity reference in rad/s, shape (3,), held until the watchdog expires."""

    theta_dot: tuple

    def __post_init__(self):
        object.__setattr__(self, "theta_dot", _floats(self.theta_dot, "theta_dot", 3))


@dataclass(frozen=True, kw_only=True)
class JointSetpoint:
    """Joint position setpoint in rad, shape (3,), with optional scalar limits.

    ``max_speed`` (rad/s) and ``max_accel`` (rad/s²) bound the point-to-point
    profile; ``None`` lets the layer choose its defaults.
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
    """Switch mode, damping law and collision strategy; ``None`` keeps the current one."""

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

    The layer schedules its damping gains and its collision model on it.
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


def _nonce(value, name: str) -> bytes:
    value = bytes(value)
    if len(value) != NONCE_SIZE:
        raise ValueError(f"{name}: expected {NONCE_SIZE} bytes, got {len(value)}")
    return value


@dataclass(frozen=True, kw_only=True)
class Hello:
    """First message of the session handshake: a fresh random client nonce (16 bytes)."""

    client_nonce: bytes

    def __post_init__(self):
        object.__setattr__(self, "client_nonce", _nonce(self.client_nonce, "client_nonce"))


@dataclass(frozen=True, kw_only=True)
class Challenge:
    """The layer's answer to :class:`Hello`: the client nonce and a fresh server nonce."""

    client_nonce: bytes
    server_nonce: bytes

    def __post_init__(self):
        for name in ("client_nonce", "server_nonce"):
            object.__setattr__(self, name, _nonce(getattr(self, name), name))


@dataclass(frozen=True, kw_only=True)
class OpenSession:
    """Open the session: both nonces back, and whether to take the lease over from its holder."""

    client_nonce: bytes
    server_nonce: bytes
    takeover: bool = False

    def __post_init__(self):
        for name in ("client_nonce", "server_nonce"):
            object.__setattr__(self, name, _nonce(getattr(self, name), name))
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
        object.__setattr__(self, "client_nonce", _nonce(self.client_nonce, "client_nonce"))
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


_COUNTER_NAMES = ("malformed", "refused", "duplicates", "stale", "watchdog_stops", "accepted",
                  "overruns", "unauthenticated", "replayed", "rate_limited", "not_owner", "faults")
_N_COUNTERS = len(_COUNTER_NAMES)


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
    """Acceptance of command ``command_seq``; ``code`` tells whether it was clamped."""

    command_seq: int
    code: Reason = Reason.OK
    text: str = ""

    def __post_init__(self):
        object.__setattr__(self, "code", Reason(self.code))


@dataclass(frozen=True, kw_only=True)
class Refusal:
    """Refusal of command ``command_seq`` with a reason code and a human-readable text."""

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


# ---------------------------------------------------------------- payload codecs
_VEL = struct.Struct("!3d")
_SETP = struct.Struct("!3d2dB")
_MODE = struct.Struct("!3B")
_PAYLOAD = struct.Struct("!d")
_STATE = struct.Struct(f"!17dI3B2I{_N_COUNTERS}I")
_REPLY = struct.Struct("!IHB")
_HELLO = struct.Struct(f"!{NONCE_SIZE}s")
_CHALLENGE = struct.Struct(f"!{NONCE_SIZE}s{NONCE_SIZE}s")
_OPEN = struct.Struct(f"!{NONCE_SIZE}s{NONCE_SIZE}sB")
_WELCOME = struct.Struct(f"!{NONCE_SIZE}sId")
_U32 = 0xFFFFFFFF
_ALL_FLAGS = int(sum(f.value for f in StateFlags))
_SIZES = {MsgType.VELOCITY: _VEL.size, MsgType.SETPOINT: _SETP.size, MsgType.MODE: _MODE.size,
          MsgType.STATE_REQUEST: 0, MsgType.STATE: _STATE.size, MsgType.PAYLOAD: _PAYLOAD.size,
          MsgType.RESET: 0, MsgType.RELEASE: 0, MsgType.HELLO: _HELLO.size,
          MsgType.CHALLENGE: _CHALLENGE.size, MsgType.OPEN: _OPEN.size, MsgType.WELCOME: _WELCOME.size}
_EMPTY = {FaultReset: MsgType.RESET, Release: MsgType.RELEASE, StateRequest: MsgType.STATE_REQUEST}


def _check_finite(values, what: str, strict: bool) -> None:
    if strict and not all(map(math.isfinite, values)):
        raise NonFinite(f"{what}: NaN or infinite value")


def _text_bytes(text: str) -> bytes:
    raw = text.encode("utf-8")[:MAX_TEXT]
    return raw.decode("utf-8", errors="ignore").encode("utf-8")


def _pack_payload(msg, strict: bool) -> tuple[MsgType, bytes]:
    kind = type(msg)
    if kind in _EMPTY:
        return _EMPTY[kind], b""
    if kind is JointVelocityCommand:
        _check_finite(msg.theta_dot, "theta_dot", strict)
        return MsgType.VELOCITY, _VEL.pack(*msg.theta_dot)
    if kind is JointSetpoint:
        bits = (msg.max_speed is not None) | ((msg.max_accel is not None) << 1)
        speed = 0.0 if msg.max_speed is None else msg.max_speed
        accel = 0.0 if msg.max_accel is None else msg.max_accel
        _check_finite((*msg.theta, speed, accel), "setpoint", strict)
        return MsgType.SETPOINT, _SETP.pack(*msg.theta, speed, accel, bits)
    if kind is ModeSwitch:
        vals = [_KEEP if v is None else int(v) for v in (msg.mode, msg.damping, msg.collision)]
        return MsgType.MODE, _MODE.pack(*vals)
    if kind is PayloadUpdate:
        _check_finite((msg.payload_kg,), "payload_kg", strict)
        return MsgType.PAYLOAD, _PAYLOAD.pack(msg.payload_kg)
    if kind is State:
        floats = (msg.t, *msg.theta, *msg.theta_dot, *msg.strains, *msg.residuals,
                  msg.tick_p50_s, msg.tick_p99_s, msg.tick_max_s)
        _check_finite(floats, "state", strict)
        c = msg.counters
        counts = [getattr(c, name) for name in _COUNTER_NAMES]
        return MsgType.STATE, _STATE.pack(
            *floats, int(msg.flags), int(msg.mode), int(msg.damping), int(msg.collision),
            msg.last_command_seq & _U32, msg.request_seq & _U32, *(n & _U32 for n in counts))
    if kind is Ack or kind is Refusal:
        text = _text_bytes(msg.text)
        mtype = MsgType.ACK if kind is Ack else MsgType.REFUSAL
        return mtype, _REPLY.pack(msg.command_seq & _U32, int(msg.code), len(text)) + text
    if kind is Hello:
        return MsgType.HELLO, _HELLO.pack(msg.client_nonce)
    if kind is Challenge:
        return MsgType.CHALLENGE, _CHALLENGE.pack(msg.client_nonce, msg.server_nonce)
    if kind is OpenSession:
        return MsgType.OPEN, _OPEN.pack(msg.client_nonce, msg.server_nonce, int(msg.takeover))
    if kind is Welcome:
        _check_finite((msg.lease_s,), "lease_s", strict)
        return MsgType.WELCOME, _WELCOME.pack(msg.client_nonce, msg.session & _U32, msg.lease_s)
    raise TypeError(f"msg: not a protocol message: {kind.__name__}")


def _check_key(key, name: str = "key") -> bytes | None:
    if key is None:
        return None
    if not isinstance(key, (bytes, bytearray)) or len(key) < 16:
        raise ValueError(f"{name}: expected at least 16 bytes, got {key!r:.40}")
    return bytes(key)


def encode(msg: Message, seq: int, t: float, *, strict: bool = True, session: int = 0,
           key: bytes | None = None) -> bytes:
    """Encode a message into one datagram.

    Parameters
    ----------
    msg : Message
        One of the message dataclasses of this module.
    seq : int
        Sequence number; taken modulo 2**32.
    t : float
        Sender timestamp in s (monotonic clock).
    strict : bool
        Refuse NaN/inf values (default). ``False`` lets fault-injection tests
        build datagrams that the receiver must refuse.
    session : int
        Session id (uint32) the datagram belongs to; 0 outside a session.
    key : bytes or None
        Append an HMAC-SHA256 tag with this key (the long-term key outside a
        session, the :func:`session_key` inside one); ``None``: no tag.

    Returns
    -------
    bytes

    Raises
    ------
    NonFinite
        If ``strict`` and a float field is not finite.
    TypeError
        If ``msg`` is not a protocol message.
    ValueError
        If ``key`` is shorter than 16 bytes.

    Examples
    --------
    >>> len(encode(StateRequest(), seq=1, t=0.0)) == HEADER_SIZE
    True
    >>> len(encode(StateRequest(), seq=1, t=0.0, key=bytes(32))) == HEADER_SIZE + TAG_SIZE
    True
    """
    key = _check_key(key)
    mtype, payload = _pack_payload(msg, strict)
    _check_finite((t,), "t", strict)
    head = _HEADER.pack(MAGIC, VERSION, int(mtype), 0 if key is None else _AUTH, 0,
                        session & _U32, seq & _U32, float(t), len(payload), 0)
    crc = zlib.crc32(payload, zlib.crc32(head))
    body = head[:-4] + crc.to_bytes(4, "big") + payload
    if key is None:
        return body
    return body + hmac.digest(key, body, "sha256")


def _enum(cls, value: int, what: str, header: Header, keep: bool = False):
    if keep and value == _KEEP:
        return None
    try:
        return cls(value)
    except ValueError:
        raise BadValue(f"{what}: invalid value {value}", header) from None


def _unpack_payload(header: Header, payload: bytes):
    mtype = header.msg_type
    want = _SIZES.get(mtype)
    if want is not None and len(payload) != want:
        raise BadLength(f"{mtype.name} payload: expected {want} bytes, got {len(payload)}", header)

    def finite(values, what):
        if not all(map(math.isfinite, values)):
            raise NonFinite(f"{what}: NaN or infinite value", header)

    if mtype == MsgType.VELOCITY:
        vals = _VEL.unpack(payload)
        finite(vals, "theta_dot")
        return JointVelocityCommand(theta_dot=vals)
    if mtype == MsgType.SETPOINT:
        *theta, speed, accel, bits = _SETP.unpack(payload)
        finite((*theta, speed, accel), "setpoint")
        if bits & ~0b11 or (not bits & 1 and speed != 0.0) or (not bits & 2 and accel != 0.0):
            raise BadValue(f"setpoint: inconsistent option bits {bits:#x}", header)
        return JointSetpoint(theta=theta, max_speed=speed if bits & 1 else None,
                             max_accel=accel if bits & 2 else None)
    if mtype == MsgType.MODE:
        m, d, c = _MODE.unpack(payload)
        return ModeSwitch(mode=_enum(Mode, m, "mode", header, keep=True),
                          damping=_enum(Damping, d, "damping", header, keep=True),
                          collision=_enum(CollisionStrategy, c, "collision", header, keep=True))
    if mtype == MsgType.PAYLOAD:
        (mass,) = _PAYLOAD.unpack(payload)
        finite((mass,), "payload_kg")
        return PayloadUpdate(payload_kg=mass)
    if mtype == MsgType.STATE_REQUEST:
        return StateRequest()
    if mtype == MsgType.RESET:
        return FaultReset()
    if mtype == MsgType.RELEASE:
        return Release()
    if mtype == MsgType.HELLO:
        return Hello(client_nonce=_HELLO.unpack(payload)[0])
    if mtype == MsgType.CHALLENGE:
        c, n = _CHALLENGE.unpack(payload)
        return Challenge(client_nonce=c, server_nonce=n)
    if mtype == MsgType.OPEN:
        c, n, take = _OPEN.unpack(payload)
        if take > 1:
            raise BadValue(f"open: takeover byte {take}, expected 0 or 1", header)
        return OpenSession(client_nonce=c, server_nonce=n, takeover=bool(take))
    if mtype == MsgType.WELCOME:
        c, sid, lease = _WELCOME.unpack(payload)
        finite((lease,), "lease_s")
        if sid == 0 or not lease > 0:
            raise BadValue(f"welcome: session {sid}, lease {lease:g} s", header)
        return Welcome(client_nonce=c, session=sid, lease_s=lease)
    if mtype == MsgType.STATE:
        vals = _STATE.unpack(payload)
        floats, rest = vals[:17], vals[17:]
        finite(floats, "state")
        flags, m, d, c, last_seq, req_seq, *counts = rest
        if flags & ~_ALL_FLAGS:
            raise BadValue(f"state flags: unknown bits {flags:#x}", header)
        return State(t=floats[0], theta=floats[1:4], theta_dot=floats[4:7],
                     strains=floats[7:11], residuals=floats[11:14], tick_p50_s=floats[14],
                     tick_p99_s=floats[15], tick_max_s=floats[16], flags=StateFlags(flags),
                     mode=_enum(Mode, m, "mode", header),
                     damping=_enum(Damping, d, "damping", header),
                     collision=_enum(CollisionStrategy, c, "collision", header),
                     last_command_seq=last_seq, request_seq=req_seq,
                     counters=Counters(**dict(zip(_COUNTER_NAMES, counts))))
    # ACK / REFUSAL
    if len(payload) < _REPLY.size:
        raise BadLength(f"{mtype.name} payload: expected at least {_REPLY.size} bytes, "
                        f"got {len(payload)}", header)
    cseq, code, n = _REPLY.unpack_from(payload)
    if len(payload) != _REPLY.size + n:
        raise BadLength(f"{mtype.name} payload: text length {n} does not match "
                        f"{len(payload) - _REPLY.size} bytes", header)
    try:
        text = payload[_REPLY.size:].decode("utf-8")
    except UnicodeDecodeError:
        raise BadValue(f"{mtype.name}: text is not UTF-8", header) from None
    reason = _enum(Reason, code, "reason code", header)
    if (mtype == MsgType.ACK) != (reason < 10):
        raise BadValue(f"{mtype.name}: reason code {reason.name} not allowed", header)
    cls = Ack if mtype == MsgType.ACK else Refusal
    return cls(command_seq=cseq, code=reason, text=text)


def peek(data: bytes) -> tuple[int, int, int]:
    """Session id, sequence number and type byte of a datagram, without any check but the header's size and magic.

    Cheap enough to run on every datagram before choosing the key to check it
    with; nothing it returns can be trusted before :func:`decode` succeeds.

    Raises
    ------
    BadLength, BadMagic, BadVersion

    Examples
    --------
    >>> peek(encode(StateRequest(), seq=9, t=0.0, session=5))
    (5, 9, 4)
    """
    if len(data) < HEADER_SIZE:
        raise BadLength(f"datagram of {len(data)} bytes is shorter than the "
                        f"{HEADER_SIZE}-byte header")
    if data[:4] != MAGIC:
        raise BadMagic(f"bad magic {bytes(data[:4])!r}, expected {MAGIC!r}")
    if data[4] != VERSION:
        raise BadVersion(f"unsupported protocol version {data[4]}, expected {VERSION}")
    return int.from_bytes(data[8:12], "big"), int.from_bytes(data[12:16], "big"), data[5]


def decode(data: bytes, *, key: bytes | None = None) -> tuple[Header, Message]:
    """Decode one datagram.

    Parameters
    ----------
    data : bytes
        The datagram.
    key : bytes or None
        With a key the datagram must carry a valid HMAC-SHA256 tag made with
        it; without one it must carry no tag.

    Returns
    -------
    header : Header
    msg : Message

    Raises
    ------
    BadLength
        Shorter than a header, payload length mismatch, or payload size wrong for the type.
    BadMagic, BadVersion, BadChecksum, Unauthenticated, UnknownType
        As named (checked in that order, after the length of the header). No
        header is attached to these: nothing in the datagram can be trusted.
    NonFinite
        A float field is NaN or infinite (``err.header`` is set).
    BadValue
        An enum, flag or text field is out of its domain (``err.header`` is set).

    Examples
    --------
    >>> decode(b"junk")
    Traceback (most recent call last):
    ...
    tudorvision.joint.protocol.BadLength: datagram of 4 bytes is shorter than the 32-byte header
    """
    data = bytes(data)
    key = _check_key(key)
    if len(data) < HEADER_SIZE:
        raise BadLength(f"datagram of {len(data)} bytes is shorter than the "
                        f"{HEADER_SIZE}-byte header")
    magic, version, mtype, flags, reserved, session, seq, t_sent, plen, crc = _HEADER.unpack_from(data)
    if magic != MAGIC:
        raise BadMagic(f"bad magic {magic!r}, expected {MAGIC!r}")
    if version != VERSION:
        raise BadVersion(f"unsupported protocol version {version}, expected {VERSION}")
    tagged = bool(flags & _AUTH)
    body_len = len(data) - (TAG_SIZE if tagged else 0)
    if plen != body_len - HEADER_SIZE:
        raise BadLength(f"payload length field {plen} does not match "
                        f"{body_len - HEADER_SIZE} bytes received")
    head0 = data[:HEADER_SIZE - 4] + b"\0\0\0\0"
    if zlib.crc32(data[HEADER_SIZE:body_len], zlib.crc32(head0)) != crc:
        raise BadChecksum("checksum mismatch (corrupted datagram)")
    if key is not None:
        if not tagged:
            raise Unauthenticated("datagram without an authentication tag")
        if not hmac.compare_digest(hmac.digest(key, data[:body_len], "sha256"), data[body_len:]):
            raise Unauthenticated("authentication tag mismatch")
    elif tagged:
        raise Unauthenticated("authenticated datagram, but no key to check it")
    try:
        msg_type = MsgType(mtype)
    except ValueError:
        raise UnknownType(f"unknown message type {mtype}") from None
    header = Header(version=version, msg_type=msg_type, seq=seq, t_sent=t_sent, payload_len=plen,
                    session=session, authenticated=tagged)
    if reserved != 0 or flags & ~_AUTH:
        raise BadValue(f"reserved header fields are {flags:#x}/{reserved}, expected 0", header)
    if not math.isfinite(t_sent):
        raise NonFinite("sender timestamp: NaN or infinite value", header)
    return header, _unpack_payload(header, data[HEADER_SIZE:body_len])


def new_nonce() -> bytes:
    """A fresh random nonce (``os.urandom``, 16 bytes)."""
    return os.urandom(NONCE_SIZE)


def session_key(key: bytes | None, client_nonce: bytes, server_nonce: bytes, session: int) -> bytes | None:
    """The key of one session: ``HMAC-SHA256(key, b"TDJL session" + nonces + session id)``.

    ``None`` without a long-term key (unauthenticated layer).

    Examples
    --------
    >>> k = session_key(bytes(32), bytes(16), bytes(range(16)), 7)
    >>> len(k), k == session_key(bytes(32), bytes(16), bytes(range(16)), 8)
    (32, False)
    """
    key = _check_key(key)
    if key is None:
        return None
    info = b"TDJL session" + _nonce(client_nonce, "client_nonce") + _nonce(server_nonce, "server_nonce")
    return hmac.digest(key, info + (session & _U32).to_bytes(4, "big"), "sha256")


def write_key_file(path, *, overwrite: bool = False) -> bytes:
    """Write a fresh random key (:data:`KEY_SIZE` bytes from ``os.urandom``) as one hex line.

    The file is created with permissions 0600 (owner read/write only); an
    existing file is refused unless ``overwrite`` (then it is replaced
    atomically by a new 0600 file).

    Returns
    -------
    bytes
        The key.

    Raises
    ------
    TudorVisionError
        If the file exists (without ``overwrite``) or cannot be written.
    """
    path = os.fspath(path)
    key = os.urandom(KEY_SIZE)
    target = path + ".tmp" if overwrite else path
    try:
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise TudorVisionError(f"{target}: exists; refusing to overwrite a key file") from None
    except OSError as err:
        raise TudorVisionError(f"{target}: cannot create the key file: {err.strerror}") from None
    try:
        os.fchmod(fd, 0o600)
        os.write(fd, key.hex().encode("ascii") + b"\n")
        os.fsync(fd)
    except OSError as err:
        os.close(fd)
        os.unlink(target)
        raise TudorVisionError(f"{target}: cannot write the key file: {err.strerror}") from None
    os.close(fd)
    if overwrite:
        os.replace(target, path)
    return key


def read_key_file(path) -> bytes:
    """Read a key written by :func:`write_key_file` (hex, at least 16 bytes).

    Raises
    ------
    TudorVisionError
        If the file is missing, readable by group or others (like ssh, the
        key is refused: ``chmod 600`` it), or does not hold a hex key.
    """
    path = os.fspath(path)
    try:
        st = os.stat(path)
        with open(path, "rb") as fh:
            raw = fh.read(4096)
    except OSError as err:
        raise TudorVisionError(f"{path}: cannot read the key file: {err.strerror}") from None
    if st.st_mode & 0o077:
        raise TudorVisionError(f"{path}: key file permissions {st.st_mode & 0o777:03o} let others "
                               f"read it; chmod 600 it")
    try:
        key = bytes.fromhex(raw.decode("ascii").strip())
    except (UnicodeDecodeError, ValueError):
        key = b""
    if len(key) < 16:
        raise TudorVisionError(f"{path}: not a key file (expected one line of at least 32 hex digits)")
    return key


def seq_add(seq: int, n: int = 1) -> int:
    """Add ``n`` to a uint32 sequence number with wrap-around.

    Examples
    --------
    >>> seq_add(2**32 - 1)
    0
    """
    return (seq + n) & _U32


def seq_newer(a: int, b: int) -> bool:
    """True if uint32 sequence number ``a`` is newer than ``b`` (serial arithmetic, RFC 1982).

    Examples
    --------
    >>> seq_newer(5, 3), seq_newer(3, 5), seq_newer(2, 2**32 - 3)
    (True, False, True)
    """
    d = (a - b) & _U32
    return 0 < d < 0x80000000
