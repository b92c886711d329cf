"""The ARCS wire modules, pure: framing in any chunks and with garbage, login text, hello; and
the emulated controller's enums against pyaubo-sdk's own."""

import itertools
import json

import cbor2
import pyaubo_sdk as aubo
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.emulator.arcs import RobotMode, SafetyMode, ServoCode
from hilrig.emulator.arcs.wire import (
    FrameDecoder,
    Login,
    login_text,
    login_token,
    parse_login,
    rpc_frame,
    rtde_frame,
    rtde_hello,
)

# tokens pyaubo-sdk 0.24.1 sent for these passwords (user "aubo"), as captured on the wire
OBSERVED_TOKENS = {
    "123456": "3353545435353664345433434443435463466335333566235443434253142434333426365553",
    "": "3353545435353664345443435463466335333566235443434253142434333426365553",
    "wrong": "335354543535366434546465543435463466335333566235443434253142434333426365553",
}

bodies = st.lists(st.binary(max_size=300), max_size=12)


def split(stream: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({min(cut, len(stream)) for cut in cuts})
    edges = [0, *points, len(stream)]
    return [stream[a:b] for a, b in itertools.pairwise(edges)]


@settings(max_examples=200, deadline=None)
@given(bodies, st.lists(st.integers(min_value=0, max_value=5000), max_size=30), st.booleans())
def test_any_split_of_a_stream_decodes_to_its_bodies(
    messages: list[bytes], cuts: list[int], rtde: bool
) -> None:
    frame, decoder = (rtde_frame, FrameDecoder.rtde()) if rtde else (rpc_frame, FrameDecoder.rpc())
    stream = b"".join(frame(body) for body in messages)
    decoded = [body for chunk in split(stream, cuts) for body in decoder.feed(chunk)]
    assert decoded == messages
    assert decoder.garbage_bytes == 0 and decoder.buffered == 0


# garbage without the magic's first byte cannot be mistaken for a frame's start
garbage = st.binary(max_size=50).map(lambda data: data.replace(b"S", b"s"))


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(garbage, st.binary(max_size=100)), max_size=8),
    st.lists(st.integers(0, 2000)),
)
def test_garbage_between_frames_is_skipped_and_counted(
    pieces: list[tuple[bytes, bytes]], cuts: list[int]
) -> None:
    decoder = FrameDecoder.rpc()
    stream = b"".join(junk + rpc_frame(body) for junk, body in pieces)
    decoded = [body for chunk in split(stream, cuts) for body in decoder.feed(chunk)]
    assert decoded == [body for _, body in pieces]
    assert decoder.garbage_bytes == sum(len(junk) for junk, _ in pieces)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400), st.lists(st.integers(0, 400)), st.booleans())
def test_any_bytes_never_raise(data: bytes, cuts: list[int], rtde: bool) -> None:
    decoder = FrameDecoder.rtde() if rtde else FrameDecoder.rpc()
    for chunk in split(data, cuts):
        decoder.feed(chunk)
    assert decoder.garbage_bytes + decoder.buffered <= len(data)


def test_a_length_over_the_limit_is_garbage_and_the_next_frame_is_found() -> None:
    decoder = FrameDecoder.rpc()
    bogus = b"SOF\x01" + (1 << 30).to_bytes(4, "big")
    assert decoder.feed(bogus + rpc_frame(b"{}")) == [b"{}"]
    assert decoder.garbage_bytes == len(bogus)


def test_login_token_is_the_clients() -> None:
    for password, token in OBSERVED_TOKENS.items():
        assert login_token(password) == token
    body = login_text("aubo", "123456")
    assert parse_login(body) == Login("aubo", OBSERVED_TOKENS["123456"], "0.24.0")
    assert parse_login(b"__login__\naubo\n") is None
    assert parse_login(b'{"id":"1"}') is None


def test_rtde_hello_types() -> None:
    hello = rtde_hello({"R1_actual_q": 1006}, {})
    assert hello.endswith(b"\n\n")
    parsed = json.loads(hello)
    assert parsed == {"protocol": "1", "version": 1, "input": {}, "output": {"R1_actual_q": 1006}}
    # a sample as pushed: chanel first, then the values in the topic's order
    assert cbor2.loads(rtde_frame(cbor2.dumps([0, 1.5, "Running"]))[6:]) == [0, 1.5, "Running"]


def test_enums_are_pyaubo_sdks() -> None:
    assert {m.name: m.value for m in RobotMode} == {
        name: int(value) for name, value in aubo.RobotModeType.__members__.items()
    }
    assert {m.name: m.value for m in SafetyMode} == {
        name: int(value) for name, value in aubo.SafetyModeType.__members__.items()
    }
    codes = aubo.AuboErrorCodes.__members__
    expected = {
        ServoCode.SAFETY_NOT_NORMAL: int(codes["AUBO_BAD_STATE"]),
        ServoCode.NOT_RUNNING: -int(codes["AUBO_BAD_STATE"]),
        ServoCode.INVALID_ARGUMENT: -int(codes["AUBO_INVL_ARGUMENT"]),
        ServoCode.NOT_SERVO_MODE: -int(codes["AUBO_REQUEST_IGNORE"]),
    }
    assert all(int(code) == value for code, value in expected.items())
