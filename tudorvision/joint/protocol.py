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

This module holds the byte layout (:func:`encode`, :func:`decode`,
:func:`peek`) and the sequence-number arithmetic; the message dataclasses,
enums and decoding errors live in :mod:`tudorvision.joint.messages`, key
files, tags and session keys in :mod:`tudorvision.joint.keys`. Both are
re-exported here, so ``from tudorvision.joint.protocol import State`` keeps
working.

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

import math
import struct
import zlib

from .keys import (KEY_SIZE, NONCE_SIZE, TAG_SIZE, check_key, hmac_tag, new_nonce, read_key_file, session_key,
                   verify_tag, write_key_file)
from .messages import (COMMAND_TYPES, COUNTER_NAMES, N_COUNTERS, SESSION_TYPES, Ack, BadChecksum, BadLength,
                       BadMagic, BadValue, BadVersion, Challenge, CollisionStrategy, Counters, Damping, FaultReset,
                       Header, Hello, JointSetpoint, JointVelocityCommand, Message, Mode, ModeSwitch, MsgType,
                       NonFinite, OpenSession, PayloadUpdate, ProtocolError, Reason, Refusal, Release, State,
                       StateFlags, StateRequest, Unauthenticated, UnknownType, Welcome)

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
_AUTH = 0x01                        # header flags bit: tag present
MAX_DATAGRAM = 1400                 # stays below a typical Ethernet MTU
MAX_TEXT = 255                      # bytes of UTF-8 in Ack/Refusal texts
_KEEP = 0xFF                        # "keep current" in ModeSwitch fields

# ---------------------------------------------------------------- payload codecs
_VEL = struct.Struct("!3d")
_SETP = struct.Struct("!3d2dB")
_MODE = struct.Struct("!3B")
_PAYLOAD = struct.Struct("!d")
_STATE = struct.Struct(f"!17dI3B2I{N_COUNTERS}I")
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
        counts = [getattr(c, name) for name in COUNTER_NAMES]
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
    key = check_key(key)
    mtype, payload = _pack_payload(msg, strict)
    _check_finite((t,), "t", strict)
    head = _HEADER.pack(MAGIC, VERSION, int(mtype), 0 if key is None else _AUTH, 0,
                        session & _U32, seq & _U32, float(t), len(payload), 0)
    crc = zlib.crc32(payload, zlib.crc32(head))
    body = head[:-4] + crc.to_bytes(4, "big") + payload
    if key is None:
        return body
    return body + hmac_tag(key, body)


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
                     counters=Counters(**dict(zip(COUNTER_NAMES, counts))))
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
    tudorvision.joint.messages.BadLength: datagram of 4 bytes is shorter than the 32-byte header
    """
    data = bytes(data)
    key = check_key(key)
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
        if not verify_tag(key, data[:body_len], data[body_len:]):
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
