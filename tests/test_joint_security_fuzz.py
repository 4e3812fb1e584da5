"""Property tests (hypothesis) for the protocol decoder and the layer's datagram handler.

Whatever bytes arrive, :func:`decode` returns a message or raises a
:class:`ProtocolError` - nothing else - and the server never faults or moves
on them. ``benchmarks/fuzz_protocol.py`` runs the same properties for 10^5+ cases.
"""
from __future__ import annotations

import struct
import zlib

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given, settings, strategies as st  # noqa: E402

from test_joint_adapter_core import RigidTestCore  # noqa: E402
from tudorvision.joint import protocol as P  # noqa: E402
from tudorvision.joint.server import JointLayerServer, ServerConfig  # noqa: E402
from tudorvision.joint.transport import InProcessTransport  # noqa: E402

KEY = bytes(range(32))
FAST = settings(max_examples=300, deadline=None)
finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
u32 = st.integers(0, 2**32 - 1)


def _sealed(mtype: int, payload: bytes, *, seq=1, session=0, flags=0, reserved=0, t=0.0,
            version=P.VERSION) -> bytes:
    """A datagram with a correct length and CRC around arbitrary payload bytes (reaches the payload decoders)."""
    head = struct.pack("!4sBBBBIIdII", P.MAGIC, version, mtype, flags, reserved, session, seq, t,
                       len(payload), 0)
    crc = zlib.crc32(payload, zlib.crc32(head))
    return head[:-4] + crc.to_bytes(4, "big") + payload


def _decodes_or_protocol_error(data: bytes, key=None):
    try:
        header, msg = P.decode(data, key=key)
    except P.ProtocolError:
        return None
    assert isinstance(header, P.Header)
    return msg


@FAST
@given(st.binary(max_size=1500))
def test_arbitrary_bytes_only_raise_protocol_errors(data):
    _decodes_or_protocol_error(data)
    assert _decodes_or_protocol_error(data, key=KEY) is None or len(data) >= P.HEADER_SIZE + P.TAG_SIZE


@FAST
@given(st.integers(0, 255), st.binary(max_size=400), u32, u32, st.integers(0, 3), st.integers(0, 3),
       st.floats(width=64))
def test_sealed_random_payloads_only_raise_protocol_errors(mtype, payload, seq, session, flags, reserved, t):
    msg = _decodes_or_protocol_error(_sealed(mtype, payload, seq=seq, session=session, flags=flags & 0x2,
                                             reserved=reserved, t=t))
    if msg is not None:                     # what decodes re-encodes to the same message
        assert P.decode(P.encode(msg, seq, t if t == t else 0.0))[1] == msg


@FAST
@given(st.sampled_from(sorted(P._SIZES)), st.data())
def test_right_sized_random_payloads_only_raise_protocol_errors(mtype, data):
    payload = data.draw(st.binary(min_size=P._SIZES[mtype], max_size=P._SIZES[mtype]))
    _decodes_or_protocol_error(_sealed(int(mtype), payload))


messages = st.one_of(
    st.builds(P.JointVelocityCommand, theta_dot=st.tuples(finite, finite, finite)),
    st.builds(P.JointSetpoint, theta=st.tuples(finite, finite, finite),
              max_speed=st.none() | finite, max_accel=st.none() | finite),
    st.builds(P.ModeSwitch, mode=st.none() | st.sampled_from(P.Mode),
              damping=st.none() | st.sampled_from(P.Damping),
              collision=st.none() | st.sampled_from(P.CollisionStrategy)),
    st.builds(P.PayloadUpdate, payload_kg=finite),
    st.builds(P.StateRequest), st.builds(P.FaultReset), st.builds(P.Release),
    st.builds(P.Ack, command_seq=u32, code=st.sampled_from([r for r in P.Reason if r < 10]),
              text=st.text(max_size=80)),
    st.builds(P.Refusal, command_seq=u32, code=st.sampled_from([r for r in P.Reason if r >= 10]),
              text=st.text(max_size=80)),
    st.builds(P.Hello, client_nonce=st.binary(min_size=16, max_size=16)),
    st.builds(P.OpenSession, client_nonce=st.binary(min_size=16, max_size=16),
              server_nonce=st.binary(min_size=16, max_size=16), takeover=st.booleans()),
)


@FAST
@given(messages, u32, u32, finite, st.booleans())
def test_round_trip(msg, seq, session, t, keyed):
    key = KEY if keyed else None
    header, back = P.decode(P.encode(msg, seq, t, session=session, key=key), key=key)
    if isinstance(msg, (P.Ack, P.Refusal)):
        assert back.text == P._text_bytes(msg.text).decode("utf-8")
        back = type(msg)(command_seq=back.command_seq, code=back.code, text=msg.text)
    assert back == msg and (header.seq, header.session, header.authenticated) == (seq, session, keyed)


@FAST
@given(messages, st.data())
def test_tampered_authenticated_datagrams_are_refused(msg, draw):
    data = bytearray(P.encode(msg, 5, 1.0, session=3, key=KEY))
    flips = draw.draw(st.dictionaries(st.integers(0, len(data) - 1), st.integers(1, 255),
                                      min_size=1, max_size=4))
    for i, x in flips.items():
        data[i] ^= x
    with pytest.raises(P.ProtocolError):
        P.decode(bytes(data), key=KEY)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=200),
                          st.tuples(st.integers(1, 14), st.binary(max_size=64), u32, u32).map(
                              lambda a: _sealed(a[0], a[1], seq=a[2], session=a[3]))),
                max_size=20))
def test_the_server_survives_any_datagrams_without_moving(datagrams):
    core = RigidTestCore()
    client, end = InProcessTransport.pair()
    server = JointLayerServer(end, core, config=ServerConfig(rate_hz=100.0))
    for data in datagrams:
        client.send(data)
    server.tick(0.01)
    assert server.counters.faults == 0 and server.owner is None
    assert core.setpoint_calls == [] and core.velocity_calls == []
