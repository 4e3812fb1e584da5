"""Binary protocol: seeded round trips for every message, every decode error, seq arithmetic."""
import math
import struct
import zlib

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.joint import protocol as P
from tudorvision.joint.protocol import (Ack, CollisionStrategy, Counters, Damping,
                                        JointSetpoint, JointVelocityCommand, Mode, ModeSwitch,
                                        PayloadUpdate, Reason, Refusal, State, StateFlags, StateRequest,
                                        decode, encode)


def _random_message(rng, kind):
    f = lambda n, s=3.0: tuple(rng.normal(0, s, n).tolist())  # noqa: E731
    if kind is JointVelocityCommand:
        return JointVelocityCommand(theta_dot=f(3))
    if kind is JointSetpoint:
        speed = None if rng.random() < 0.3 else float(rng.uniform(0.01, 5))
        accel = None if rng.random() < 0.3 else float(rng.uniform(0.01, 9))
        return JointSetpoint(theta=f(3), max_speed=speed, max_accel=accel)
    if kind is ModeSwitch:
        pick = lambda cls: None if rng.random() < 0.25 else cls(int(rng.integers(len(cls))))  # noqa: E731
        return ModeSwitch(mode=pick(Mode), damping=pick(Damping), collision=pick(CollisionStrategy))
    if kind is PayloadUpdate:
        return PayloadUpdate(payload_kg=float(rng.uniform(0, 5)))
    if kind is StateRequest:
        return StateRequest()
    if kind is State:
        u32 = lambda: int(rng.integers(0, 2**32))  # noqa: E731
        return State(t=float(rng.uniform(0, 1e6)), theta=f(3), theta_dot=f(3),
                     strains=f(4, 4e-4), residuals=f(3), flags=StateFlags(int(rng.integers(512))),
                     tick_p50_s=float(rng.uniform(0, 0.01)), tick_p99_s=float(rng.uniform(0, 0.02)),
                     tick_max_s=float(rng.uniform(0, 0.1)),
                     mode=Mode(int(rng.integers(3))), damping=Damping(int(rng.integers(4))),
                     collision=CollisionStrategy(int(rng.integers(4))),
                     last_command_seq=u32(), request_seq=u32(),
                     counters=Counters(**{k: u32() for k in Counters.__dataclass_fields__}))
    codes_ack = [r for r in Reason if r < 10]
    codes_ref = [r for r in Reason if r >= 10]
    text = "".join(chr(int(c)) for c in rng.integers(32, 0x3000, int(rng.integers(0, 40))))
    if kind is Ack:
        return Ack(command_seq=int(rng.integers(0, 2**32)),
                   code=codes_ack[int(rng.integers(len(codes_ack)))], text=text)
    return Refusal(command_seq=int(rng.integers(0, 2**32)),
                   code=codes_ref[int(rng.integers(len(codes_ref)))], text=text)


KINDS = [JointVelocityCommand, JointSetpoint, ModeSwitch, PayloadUpdate, StateRequest, State, Ack, Refusal]



@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.__name__)
def test_round_trip_every_message(kind):
    rng = np.random.default_rng(abs(hash(kind.__name__)) % 2**32)
    for _ in range(200):
        msg = _random_message(rng, kind)
        seq = int(rng.integers(0, 2**32))
        t = float(rng.uniform(0, 1e5))
        data = encode(msg, seq=seq, t=t)
        assert len(data) <= P.MAX_DATAGRAM
        header, back = decode(data)
        assert back == msg
        assert (header.seq, header.t_sent, header.version) == (seq, t, P.VERSION)
        assert header.payload_len == len(data) - P.HEADER_SIZE
        assert type(back) is kind


def test_sequence_numbers_wrap_in_the_header():
    header, _ = decode(encode(StateRequest(), seq=2**32 + 5, t=0.0))
    assert header.seq == 5


def test_long_text_is_truncated_on_a_character_boundary():
    msg = Refusal(command_seq=1, code=Reason.OUT_OF_RANGE, text="é" * 300)
    _, back = decode(encode(msg, seq=1, t=0.0))
    assert back.text == "é" * (P.MAX_TEXT // 2)


def _valid():
    return encode(JointVelocityCommand(theta_dot=(0.1, 0.2, 0.3)), seq=9, t=1.0)


def _reseal(data: bytes) -> bytes:
    """Recompute the CRC after tampering, so a later check is the one that fires."""
    head0 = data[:P.HEADER_SIZE - 4] + b"\0\0\0\0"
    crc = zlib.crc32(data[P.HEADER_SIZE:], zlib.crc32(head0))
    return data[:P.HEADER_SIZE - 4] + crc.to_bytes(4, "big") + data[P.HEADER_SIZE:]


def _with_header(**fields) -> bytes:
    data = _valid()
    names = ["magic", "version", "mtype", "flags", "reserved", "session", "seq", "t", "plen", "crc"]
    vals = dict(zip(names, struct.unpack_from("!4sBBBBIIdII", data)))
    vals.update(fields)
    head = struct.pack("!4sBBBBIIdII", *[vals[n] for n in names])
    return head + data[P.HEADER_SIZE:]


def test_bad_magic():
    data = _reseal(_with_header(magic=b"XXXX"))
    with pytest.raises(P.BadMagic, match="bad magic"):
        decode(data)


def test_bad_version():
    data = _reseal(_with_header(version=P.VERSION + 1))
    with pytest.raises(P.BadVersion, match=f"version {P.VERSION + 1}"):
        decode(data)


def test_short_datagram():
    data = _valid()[:10]
    with pytest.raises(P.BadLength, match="shorter than the 32-byte header"):
        decode(data)


def test_length_field_mismatch():
    truncated = _valid()[:-1]
    extended = _valid() + b"\0"
    with pytest.raises(P.BadLength, match="does not match"):
        decode(truncated)
    with pytest.raises(P.BadLength, match="does not match"):
        decode(extended)


def test_payload_size_wrong_for_type():
    data = _reseal(_with_header(mtype=int(P.MsgType.SETPOINT)))
    with pytest.raises(P.BadLength, match="SETPOINT payload: expected 41 bytes") as err:
        decode(data)
    assert err.value.header is not None and err.value.header.seq == 9


def test_checksum_detects_every_single_byte_flip():
    data = _valid()
    for i in range(len(data)):
        for flip in (0x01, 0x80, 0xFF):
            bad = bytearray(data)
            bad[i] ^= flip
            with pytest.raises(P.ProtocolError):
                decode(bytes(bad))
    bad = bytearray(data)
    bad[-1] ^= 0x10
    with pytest.raises(P.BadChecksum, match="checksum mismatch"):
        decode(bytes(bad))


def test_unknown_type():
    data = _reseal(_with_header(mtype=99))
    with pytest.raises(P.UnknownType, match="unknown message type 99"):
        decode(data)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_values_refused(bad):
    data = encode(JointVelocityCommand(theta_dot=(0.0, bad, 0.0)), seq=3, t=0.0, strict=False)
    with pytest.raises(P.NonFinite, match="NaN or infinite") as err:
        decode(data)
    assert err.value.header.seq == 3 and err.value.reason == Reason.NON_FINITE
    setp = encode(JointSetpoint(theta=(0, 1, 0), max_speed=bad), seq=4, t=0.0, strict=False)
    with pytest.raises(P.NonFinite):
        decode(setp)
    mass = encode(PayloadUpdate(payload_kg=bad), seq=6, t=0.0, strict=False)
    with pytest.raises(P.NonFinite, match="payload_kg"):
        decode(mass)
    stamp = encode(StateRequest(), seq=5, t=bad, strict=False)
    with pytest.raises(P.NonFinite, match="timestamp"):
        decode(stamp)


def test_encode_refuses_non_finite_by_default():
    msg = JointVelocityCommand(theta_dot=(math.nan, 0.0, 0.0))
    with pytest.raises(P.NonFinite, match="theta_dot"):
        encode(msg, seq=1, t=0.0)


def test_bad_values():
    mode = encode(ModeSwitch(mode=Mode.IDLE), seq=1, t=0.0)
    bad_enum = mode[:P.HEADER_SIZE] + bytes([7]) + mode[P.HEADER_SIZE + 1:]
    with pytest.raises(P.BadValue, match="mode: invalid value 7"):
        decode(_reseal(bad_enum))
    setp = bytearray(encode(JointSetpoint(theta=(0, 1, 0)), seq=1, t=0.0))
    setp[-1] = 0b100
    with pytest.raises(P.BadValue, match="option bits"):
        decode(_reseal(bytes(setp)))
    ack = encode(Ack(command_seq=1, code=Reason.OK), seq=1, t=0.0)
    wrong_code = ack[:P.HEADER_SIZE + 4] + struct.pack("!H", int(Reason.OUT_OF_RANGE)) + ack[-1:]
    with pytest.raises(P.BadValue, match="not allowed"):
        decode(_reseal(wrong_code))
    text = encode(Ack(command_seq=1, code=Reason.OK, text="ab"), seq=1, t=0.0)
    not_utf8 = text[:-2] + b"\xff\xfe"
    with pytest.raises(P.BadValue, match="not UTF-8"):
        decode(_reseal(not_utf8))
    reserved = _reseal(_with_header(reserved=1))
    with pytest.raises(P.BadValue, match="reserved"):
        decode(reserved)
    flags = _reseal(_with_header(flags=0x80))
    with pytest.raises(P.BadValue, match="reserved"):
        decode(flags)


def test_version_1_datagrams_are_refused():
    old = struct.pack("!4sBBHIdII", b"TDJL", 1, 4, 0, 1, 0.0, 0, 0) + bytes(8)
    with pytest.raises(P.BadVersion, match="version 1, expected 2"):
        decode(old)


KEY = bytes(range(32))


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.__name__)
def test_authenticated_round_trip_and_every_byte_flip_is_caught(kind):
    rng = np.random.default_rng(7)
    msg = _random_message(rng, kind)
    data = encode(msg, seq=5, t=1.0, session=77, key=KEY)
    header, back = decode(data, key=KEY)
    assert back == msg and header.session == 77 and header.authenticated
    for i in range(len(data)):
        bad = bytearray(data)
        bad[i] ^= 0x01
        with pytest.raises(P.ProtocolError):
            decode(bytes(bad), key=KEY)


def test_wrong_missing_or_unexpected_tag_is_unauthenticated():
    plain = encode(StateRequest(), seq=1, t=0.0)
    tagged = encode(StateRequest(), seq=1, t=0.0, key=KEY)
    other = encode(StateRequest(), seq=1, t=0.0, key=bytes(32))
    with pytest.raises(P.Unauthenticated, match="without an authentication tag"):
        decode(plain, key=KEY)
    with pytest.raises(P.Unauthenticated, match="tag mismatch"):
        decode(other, key=KEY)
    with pytest.raises(P.Unauthenticated, match="no key"):
        decode(tagged)
    # a tag forged by recomputing the CRC after tampering still fails the HMAC
    forged = bytearray(tagged)
    forged[12:16] = (2**31).to_bytes(4, "big")            # a large sequence number
    body = bytes(forged[:-P.TAG_SIZE])
    body = _reseal(body)
    with pytest.raises(P.Unauthenticated, match="tag mismatch"):
        decode(body + bytes(forged[-P.TAG_SIZE:]), key=KEY)
    with pytest.raises(ValueError, match="key: expected at least 16 bytes"):
        encode(StateRequest(), seq=1, t=0.0, key=b"short")


def test_session_messages_round_trip_and_session_keys_differ():
    c, n = bytes(range(16)), bytes(range(16, 32))
    for msg in (P.Hello(client_nonce=c), P.Challenge(client_nonce=c, server_nonce=n),
                P.OpenSession(client_nonce=c, server_nonce=n, takeover=True),
                P.Welcome(client_nonce=c, session=9, lease_s=1.0), P.Release(), P.FaultReset()):
        assert decode(encode(msg, seq=3, t=0.0, key=KEY), key=KEY)[1] == msg
    k1 = P.session_key(KEY, c, n, 1)
    assert len({k1, P.session_key(KEY, c, n, 2), P.session_key(KEY, n, c, 1),
                P.session_key(bytes(32), c, n, 1)}) == 4
    assert P.session_key(None, c, n, 1) is None
    with pytest.raises(ValueError, match="client_nonce: expected 16 bytes"):
        P.Hello(client_nonce=b"x")
    welcome = bytearray(encode(P.Welcome(client_nonce=c, session=9, lease_s=1.0), seq=1, t=0.0))
    welcome[P.HEADER_SIZE + 16:P.HEADER_SIZE + 20] = bytes(4)     # session 0 is not a session
    with pytest.raises(P.BadValue, match="welcome"):
        decode(_reseal(bytes(welcome)))


def test_key_file_is_0600_refuses_overwrite_and_loose_permissions(tmp_path):
    import os
    path = tmp_path / "joint.key"
    key = P.write_key_file(path)
    assert os.stat(path).st_mode & 0o777 == 0o600 and len(key) == P.KEY_SIZE
    assert P.read_key_file(path) == key
    with pytest.raises(TudorVisionError, match="exists"):
        P.write_key_file(path)
    assert P.write_key_file(path, overwrite=True) != key
    assert os.stat(path).st_mode & 0o777 == 0o600
    os.chmod(path, 0o644)
    with pytest.raises(TudorVisionError, match="chmod 600"):
        P.read_key_file(path)
    bad = tmp_path / "bad.key"
    bad.write_text("not hex\n")
    os.chmod(bad, 0o600)
    with pytest.raises(TudorVisionError, match="not a key file"):
        P.read_key_file(bad)
    with pytest.raises(TudorVisionError, match="cannot read"):
        P.read_key_file(tmp_path / "missing.key")


def test_reply_text_length_mismatch():
    ack = encode(Ack(command_seq=1, code=Reason.OK, text="abc"), seq=1, t=0.0)
    bad = ack[:P.HEADER_SIZE + 6] + bytes([5]) + ack[P.HEADER_SIZE + 7:]
    with pytest.raises(P.BadLength, match="text length 5"):
        decode(_reseal(bad))


def test_message_fields_are_checked():
    with pytest.raises(ValueError, match="theta_dot: expected 3 numbers, got 2"):
        JointVelocityCommand(theta_dot=(1.0, 2.0))
    with pytest.raises(ValueError):
        ModeSwitch(mode=9)
    with pytest.raises(TypeError, match="not a protocol message"):
        encode("hello", seq=1, t=0.0)


def test_seq_newer_with_wrap():
    rng = np.random.default_rng(4)
    for _ in range(1000):
        a = int(rng.integers(0, 2**32))
        d = int(rng.integers(1, 2**31))
        b = P.seq_add(a, d)
        assert P.seq_newer(b, a) and not P.seq_newer(a, b)
    assert not P.seq_newer(7, 7)
    assert P.seq_newer(0, 2**32 - 1)
