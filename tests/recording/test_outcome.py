"""The ``outcome`` record: the loop's end figures, written last, read by the official reader,
``inspect`` and ``hilrig info``; damaged or absent, said so in one line."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from fuzz_helpers import hilrig
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from recording_helpers import samples, session_info

from hilrig.errors import RecordingError
from hilrig.recording import SessionOutcome, SessionWriter, default_channels, inspect, recover

OUTCOME = SessionOutcome(
    ticks=20_000,
    hold_ticks=12,
    fallback_ticks=3,
    missed_deadlines=150,
    merged_frames=40,
    recorder_drops=0,
    ended_by="",
    lateness_p50_us=120.0,
    lateness_p99_us=634.0,
    compute_p50_us=33.0,
    compute_p99_us=91.0,
    sensor_to_command_p50_us=118.0,
    sensor_to_command_p99_us=float("nan"),
)


def written(path: Path, outcome: SessionOutcome | None) -> Path:
    with SessionWriter(path, session_info(), channels=default_channels()) as writer:
        for topic, sample in samples(50):
            writer.write(topic, sample)
        writer.close(None if outcome is None else outcome.to_metadata())
    return path


def same(a: SessionOutcome, b: SessionOutcome) -> bool:
    """Equal, NaN equal to NaN."""
    return all(
        (x == y) or (isinstance(x, float) and math.isnan(x) and math.isnan(y))
        for x, y in zip(a.to_metadata().values(), b.to_metadata().values(), strict=True)
    )


def test_the_outcome_is_the_last_metadata_record_and_reads_back(tmp_path: Path) -> None:
    path = written(tmp_path / "s.mcap", OUTCOME)
    with open(path, "rb") as f:
        records = list(make_reader(f, validate_crcs=True).iter_metadata())
    assert [m.name for m in records][-1] == "outcome"
    assert records[-1].metadata["hold_ticks"] == "12"
    assert records[-1].metadata["sensor_to_command_p99_us"] == "nan"
    described = inspect(path)
    assert described.complete and described.outcome_problem is None
    assert described.outcome is not None and same(described.outcome, OUTCOME)
    recover(path, tmp_path / "copy.mcap")  # a recovered copy keeps it
    copied = inspect(tmp_path / "copy.mcap").outcome
    assert copied is not None and same(copied, OUTCOME)


def test_info_prints_the_loop_s_end_figures(tmp_path: Path) -> None:
    info = hilrig("info", str(written(tmp_path / "s.mcap", OUTCOME)))
    assert info.exit_code == 0
    lines = info.stdout.splitlines()
    assert (
        "loop: 20,000 ticks, 12 hold ticks, 3 fallback ticks, 150 missed deadlines (0.75 %),"
        " 0 recorder drops" in lines
    )
    assert (
        "loop timing: lateness p50/p99 120/634 us, compute per tick 33/91 us,"
        " sensor-to-command 118/nan us" in lines
    )


def test_a_file_without_outcome_says_the_figures_are_unknown(tmp_path: Path) -> None:
    info = hilrig("info", str(written(tmp_path / "s.mcap", None)))
    assert info.exit_code == 0
    assert (
        "hold ticks unknown: no outcome record: the session did not end cleanly, or an older"
        " hilrig wrote it" in info.stdout
    )


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"hold_ticks": "many"}, "metadata record 'outcome': hold_ticks 'many' is not a number"),
        ({"ticks": "-1"}, "metadata record 'outcome': ticks '-1' is not >= 0"),
        ({"ticks": None}, "metadata record 'outcome': no ticks"),
    ],
)
def test_a_bad_outcome_value_is_named_in_one_line(
    values: dict[str, str | None], message: str
) -> None:
    record = OUTCOME.to_metadata()
    for key, value in values.items():
        if value is None:
            del record[key]
        else:
            record[key] = value
    with pytest.raises(RecordingError) as caught:
        SessionOutcome.from_metadata(record)
    assert str(caught.value) == message


counts = st.integers(0, 2**40)
times = st.floats(0, 1e7, allow_nan=False) | st.just(float("nan"))


@settings(max_examples=200, deadline=None)
@given(
    st.tuples(counts, counts, counts, counts, counts, counts),
    st.text(max_size=80),
    st.tuples(times, times, times, times, times, times),
)
def test_any_outcome_survives_its_text_form_to_0_1_us(
    numbers: tuple[int, ...], ended_by: str, timing: tuple[float, ...]
) -> None:
    outcome = SessionOutcome(*numbers, ended_by, *timing)  # type: ignore[arg-type]
    back = SessionOutcome.from_metadata(outcome.to_metadata())
    assert back.to_metadata() == outcome.to_metadata()
    for f in ("lateness_p50_us", "compute_p99_us", "sensor_to_command_p99_us"):
        x, y = getattr(outcome, f), getattr(back, f)
        assert (math.isnan(x) and math.isnan(y)) or abs(x - y) <= 0.05 + 1e-9 * x
