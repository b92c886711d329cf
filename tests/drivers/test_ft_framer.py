"""The Kunwei framer: round trips, boundary cases, and hypothesis fuzzing of corrupted streams.

The resync guarantee pinned down here ("back in sync within two clean frames"): feed any bytes
G, then clean frames F1, F2, ..., Fn (n >= 3), cut into chunks anywhere. The last n - 1 samples
the framer emits are exactly F2, ..., Fn: nothing lost, nothing in between, nothing after. If
the payloads are free of the tail pair, even F1 is recovered (the last n samples are F1..Fn).
Clean means header, tail, finite in-range values, and payloads free of the header pair 48 AA or
free of the tail pair 0D 0A. Without that condition no parser of this checksum-free protocol
can always find the boundary: a stream repeating 0D 0A 48 AA at one payload offset is a valid
frame stream at two phases.
"""

import itertools
import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.ft.wire import (
    FRAME_BYTES,
    HEADER,
    KGF_N,
    START_COMMAND,
    TAIL,
    FramerConfig,
    FtSample,
    KunweiFramer,
    encode_frame,
)

UNIT = FramerConfig(kgf_scale=1.0, max_abs_force_n=1e6, max_abs_torque_nm=1e5)
WRENCH = (1.5, -2.25, 9.75, 0.125, -0.5, 0.0625)  # exact in float32


def frames(*wrenches: tuple[float, ...], config: FramerConfig = UNIT) -> bytes:
    return b"".join(encode_frame(w, kgf_scale=config.kgf_scale) for w in wrenches)


def wrench(k: int) -> tuple[float, ...]:
    return tuple(float(k + axis) for axis in range(6))


def feed_all(framer: KunweiFramer, chunks: list[bytes]) -> list[FtSample]:
    out: list[FtSample] = []
    for t_ns, chunk in enumerate(chunks):
        out.extend(framer.feed(chunk, t_ns))
    return out


def test_frames_round_trip_in_si_units() -> None:
    framer = KunweiFramer()
    samples = framer.feed(frames(WRENCH, WRENCH, config=FramerConfig()), t_ns=42)
    assert [(s.t_ns, s.seq) for s in samples] == [(42, 0), (42, 1)]
    assert samples[0].wrench_in_sensor == pytest.approx(WRENCH, rel=1e-6)
    assert framer.feed(frames(WRENCH, config=FramerConfig()))[0].seq == 2


def test_while_hunting_a_frame_waits_for_the_next_header_to_confirm_it() -> None:
    framer = KunweiFramer(UNIT)
    assert framer.feed(frames(wrench(0))) == []
    assert [s.wrench_in_sensor for s in framer.feed(HEADER)] == [wrench(0)]
    assert framer.stats.locked


def test_device_units_are_kgf() -> None:
    raw = encode_frame((1.0,) * 6, kgf_scale=1.0)  # 1 kgf on every axis
    framer = KunweiFramer()
    (sample,) = framer.feed(raw + raw[:2])
    assert sample.force_in_sensor_n == pytest.approx((KGF_N,) * 3)
    assert sample.torque_in_sensor_nm == pytest.approx((KGF_N,) * 3)


def test_frame_layout_is_header_six_le_floats_tail() -> None:
    raw = encode_frame(WRENCH, kgf_scale=1.0)
    assert len(raw) == FRAME_BYTES == 28
    assert raw[:2] == b"\x48\xaa" and raw[26:] == b"\x0d\x0a"
    assert struct.unpack("<6f", raw[2:26]) == WRENCH


def test_byte_by_byte_feeding_gives_the_same_samples() -> None:
    stream = frames(*(wrench(k) for k in range(5)))
    whole = [s.wrench_in_sensor for s in KunweiFramer(UNIT).feed(stream)]
    bytewise = feed_all(KunweiFramer(UNIT), [bytes([b]) for b in stream])
    assert [s.wrench_in_sensor for s in bytewise] == whole == [wrench(k) for k in range(5)]


def test_locked_framer_ignores_header_and_tail_bytes_inside_floats() -> None:
    (tricky,) = struct.unpack("<f", b"\x0d\x0a\x48\xaa")  # 0D 0A 48 AA inside a float
    values = (tricky, 1.0, tricky, 2.0, tricky, 3.0)
    framer = KunweiFramer(UNIT)
    samples = framer.feed(frames(*[values] * 6))
    assert [s.wrench_in_sensor for s in samples] == [values] * 6
    assert framer.stats.resyncs == 0 and framer.stats.bytes_dropped == 0


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 2e6])
def test_non_finite_or_out_of_range_frames_are_rejected_whole_and_sync_is_kept(bad: float) -> None:
    framer = KunweiFramer(UNIT)
    framer.feed(frames(wrench(0), wrench(1)))
    samples = framer.feed(frames((0.0, 0.0, bad, 0.0, 0.0, 0.0), wrench(2)))
    assert [s.wrench_in_sensor for s in samples] == [wrench(2)]
    stats = framer.stats
    assert stats.frames_rejected == 1 and stats.resyncs == 0 and stats.locked


def test_torque_limit_applies_to_the_moments() -> None:
    framer = KunweiFramer(FramerConfig(kgf_scale=1.0, max_abs_force_n=100.0, max_abs_torque_nm=1.0))
    ok = (0.0, 0.0, 2.0, 0.0, 0.0, 0.0)
    stream = frames(ok, (0.0, 0.0, 0.0, 0.0, 0.0, 50.0), (0.0, 0.0, 50.0, 0.0, 0.0, 0.5))
    samples = framer.feed(stream)
    assert [s.wrench_in_sensor[2] for s in samples] == [2.0, 50.0]
    assert framer.stats.frames_rejected == 1


def test_garbage_is_dropped_counted_and_followed_by_resync() -> None:
    framer = KunweiFramer(UNIT)
    framer.feed(frames(wrench(0), wrench(1)))
    garbage = b"\x48\xaa\x00\x0d" + START_COMMAND + b"noise"
    samples = framer.feed(garbage + frames(wrench(2), wrench(3), wrench(4)))
    assert [s.wrench_in_sensor for s in samples] == [wrench(2), wrench(3), wrench(4)]
    stats = framer.stats
    assert stats.resyncs == 1 and stats.bytes_dropped == len(garbage) and stats.locked


def test_a_lookalike_frame_in_garbage_is_not_emitted_without_a_header_after_it() -> None:
    framer = KunweiFramer(UNIT)
    lookalike = frames((7.0,) * 6)
    samples = framer.feed(b"xx" + lookalike + b"yy" + frames(wrench(0), wrench(1)))
    assert [s.wrench_in_sensor for s in samples] == [wrench(0), wrench(1)]


def test_every_byte_is_accounted_for() -> None:
    framer = KunweiFramer(UNIT)
    framer.feed(b"junk" + frames(wrench(0), (math.nan,) * 6, wrench(1)) + b"\x48\xaa\x01" + HEADER)
    s = framer.stats
    assert s.bytes_in == FRAME_BYTES * (s.frames + s.frames_rejected) + s.bytes_dropped + (
        s.bytes_buffered
    )


def test_reset_forgets_the_boundary_but_keeps_counters() -> None:
    framer = KunweiFramer(UNIT)
    framer.feed(frames(wrench(0), wrench(1)) + HEADER)
    framer.reset()
    stats = framer.stats
    assert not stats.locked and stats.bytes_buffered == 0 and stats.frames == 2
    assert framer.feed(frames(wrench(2)) + HEADER)[0].seq == 2


def test_buffer_stays_bounded_under_headerless_garbage() -> None:
    framer = KunweiFramer(UNIT)
    for _ in range(100):
        framer.feed(bytes(range(256)).replace(HEADER, b"") * 4)
    assert framer.stats.bytes_buffered <= 1


# -- hypothesis ----------------------------------------------------------------------------------

# float32 words chosen to be adversarial: random bit patterns plus ones carrying the header or
# tail pair, or both, at every byte offset
SPECIAL_WORDS = [
    struct.unpack("<I", bytes(pattern))[0]
    for pattern in (
        b"\x48\xaa\x00\x3f",
        b"\x00\x48\xaa\x3f",
        b"\x0d\x0a\x48\xaa",
        b"\x0d\x0a\x00\x3f",
        b"\x00\x0d\x0a\x3f",
        b"\x0a\x48\xaa\x0d",
        b"\xaa\x0d\x0a\x48",
    )
]
float_words = st.one_of(st.integers(0, 2**32 - 1), st.sampled_from(SPECIAL_WORDS))


def as_float(word: int) -> float:
    return float(struct.unpack("<f", struct.pack("<I", word))[0])


def clean(word: int) -> bool:
    value = as_float(word)
    return math.isfinite(value) and abs(value) <= UNIT.max_abs_torque_nm


clean_wrenches = st.tuples(*[float_words.filter(clean).map(as_float)] * 6)


def clean_wrenches_free_of(pair: bytes) -> st.SearchStrategy[tuple[float, ...]]:
    """Clean wrenches whose frame payload does not contain ``pair``."""
    allowed = [w for w in SPECIAL_WORDS if pair not in struct.pack("<I", w)]
    words = st.one_of(st.integers(0, 2**32 - 1), st.sampled_from(allowed))
    wrenches = st.tuples(*[words.filter(clean).map(as_float)] * 6)
    return wrenches.filter(lambda w: pair not in frames(w)[2:26])  # pairs across two floats


any_wrenches = st.tuples(*[float_words.map(as_float)] * 6)


truncated_frames = st.tuples(any_wrenches, st.integers(0, FRAME_BYTES)).map(
    lambda pair: frames(pair[0])[: pair[1]]
)
garbage = st.lists(
    st.one_of(
        st.binary(max_size=40),
        st.sampled_from([HEADER, TAIL, HEADER + TAIL, b"\x48", b"\x0a\x48"]),
        truncated_frames,
        any_wrenches.map(frames),
    ),
    max_size=12,
).map(b"".join)


def cut(data: st.DataObject, stream: bytes) -> list[bytes]:
    points = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=12)))
    edges = [0, *points, len(stream)]
    return [stream[a:b] for a, b in itertools.pairwise(edges)]


@settings(max_examples=400, deadline=None)
@given(data=st.data(), pieces=st.lists(st.one_of(garbage, any_wrenches.map(frames)), max_size=8))
def test_fuzz_never_raises_and_emits_only_finite_in_range_samples(
    data: st.DataObject, pieces: list[bytes]
) -> None:
    framer = KunweiFramer(UNIT)
    stream = b"".join(pieces)
    samples = feed_all(framer, cut(data, stream))
    for sample in samples:
        assert all(math.isfinite(v) for v in sample.wrench_in_sensor)
        assert all(abs(v) <= UNIT.max_abs_force_n for v in sample.force_in_sensor_n)
        assert all(abs(v) <= UNIT.max_abs_torque_nm for v in sample.torque_in_sensor_nm)
    assert [s.seq for s in samples] == list(range(len(samples)))
    s = framer.stats
    assert s.bytes_in == len(stream)
    assert s.bytes_in == FRAME_BYTES * (s.frames + s.frames_rejected) + s.bytes_dropped + (
        s.bytes_buffered
    )


@settings(max_examples=600, deadline=None)
@given(
    data=st.data(),
    before=st.lists(clean_wrenches, max_size=3),
    junk=garbage,
    free_of=st.sampled_from([HEADER, TAIL]),
)
def test_fuzz_back_in_sync_within_two_clean_frames(
    data: st.DataObject, before: list[tuple[float, ...]], junk: bytes, free_of: bytes
) -> None:
    after = data.draw(st.lists(clean_wrenches_free_of(free_of), min_size=3, max_size=6))
    framer = KunweiFramer(UNIT)
    samples = feed_all(framer, cut(data, frames(*before) + junk + frames(*after)))
    recovered = after if free_of == TAIL else after[1:]
    tail = [s.wrench_in_sensor for s in samples[len(samples) - len(recovered) :]]
    assert tail == recovered  # F2..Fn (F1..Fn) exactly: nothing lost, between or after
