"""Results on disk: Parquet round trip with the runs' metadata, MCAP read by the official tools."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from replay_helpers import EXAMPLE, trace

from hilrig.errors import OutputError
from hilrig.replay import INPUT_KEY, RUNS_KEY, ReplayError, load_trace, outputs, parse_specs, run
from hilrig.replay.outputs import load_results, topic_names, write_mcap, write_parquet


@pytest.fixture(scope="module")
def example_table() -> pd.DataFrame:
    source = load_trace(EXAMPLE)
    return run(source, parse_specs(["adaptive", "fixed"], sweeps=["fixed.k_d=250,350"]))


def test_parquet_round_trip_keeps_every_value_type_and_the_runs(
    example_table: pd.DataFrame, tmp_path: Path
) -> None:
    path = write_parquet(example_table, tmp_path / "results.parquet")
    table, runs = load_results(path)
    # float32 in the file (test_replay_parquet.py checks each value's rounding)
    pd.testing.assert_frame_equal(table, example_table, rtol=2.0**-24, atol=2.0**-150)
    assert runs == example_table.attrs[RUNS_KEY]
    assert table.attrs[INPUT_KEY]["source"] == f"{EXAMPLE}:/controller/state"
    assert runs["fixed.k_d=350"]["params"]["k_d"][:3] == [350.0, 350.0, 350.0]
    schema = pq.read_schema(path)
    assert str(schema.field("run").type) == "dictionary<values=string, indices=int8, ordered=0>"
    assert json.loads(schema.metadata[b"hilrig.runs"]) == runs


def test_parquet_never_overwrites_and_load_refuses_other_tables(
    example_table: pd.DataFrame, tmp_path: Path
) -> None:
    path = tmp_path / "results.parquet"
    path.write_bytes(b"")
    with pytest.raises(OutputError) as caught:
        write_parquet(example_table, path)
    assert str(caught.value) == f"{path}: already exists; refusing to overwrite it"
    assert path.read_bytes() == b""
    other = tmp_path / "other.parquet"
    pd.DataFrame({"x": [1.0]}).to_parquet(other)
    with pytest.raises(ReplayError) as caught:
        load_results(other)
    assert str(caught.value) == f"{other}: not a hilrig replay result (no hilrig.runs metadata)"


def test_mcap_output_is_read_by_mcap_and_mcap_ros2_on_the_recordings_clock(
    example_table: pd.DataFrame, tmp_path: Path
) -> None:
    source = load_trace(EXAMPLE)
    path = write_mcap(
        example_table, tmp_path / "replay.mcap", session=source.session, t0_ns=source.t0_ns
    )
    messages: dict[str, list[tuple[int, object]]] = {}
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages():
            messages.setdefault(channel.topic, []).append((message.log_time, decoded))
        attachments = {a.name: a.data for a in reader.iter_attachments()}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert set(messages) == {
        "/replay/adaptive/state",
        "/replay/fixed_k_d_250/state",
        "/replay/fixed_k_d_350/state",
    }
    rows = example_table[example_table["run"] == "fixed.k_d=250"]
    log_times, decoded = zip(*messages["/replay/fixed_k_d_250/state"], strict=True)
    recorded = np.asarray(source.t0_ns) + np.round(source.t_s * 1e9).astype(np.int64)
    np.testing.assert_array_equal(log_times, recorded)  # the recording's own tick times
    last = decoded[-1]
    assert last.controller == "fixed" and list(last.axis_names) == list(source.axis_names)
    for quantity, field in (
        ("offset", "offset"),
        ("velocity", "offset_rate"),
        ("damping", "damping"),
        ("zeta", "zeta"),
    ):
        expected = [rows[f"{quantity}_{a}"].to_numpy()[-1] for a in source.axis_names]
        assert list(getattr(last, field)) == expected
    assert list(last.contact_state) == [
        rows[f"contact_{a}"].to_numpy()[-1] for a in source.axis_names
    ]
    about = json.loads(attachments["replay.json"])
    assert about["topics"]["fixed.k_d=250"] == "/replay/fixed_k_d_250/state"
    assert about[RUNS_KEY] == example_table.attrs[RUNS_KEY]
    assert metadata["session"]["subject_id"] == "S001"


def test_a_table_input_is_written_on_its_own_time_axis(tmp_path: Path) -> None:
    table = run(trace(ticks=20, axes=("x", "y", "z")), parse_specs(["fixed"]))
    path = write_mcap(table, tmp_path / "table.mcap")
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        times = [m.log_time for _, _, m, _ in reader.iter_decoded_messages()]
        session = next(m.metadata for m in reader.iter_metadata() if m.name == "session")
    assert times == [round(n * 0.002 * 1e9) for n in range(20)]
    assert session["subject_id"] == "X00"
    assert re.fullmatch(r"[0-9A-HJKMNP-TV-Z]{26}", session["session_id"])  # a new session id


def test_topic_names_are_ros_names_and_unique() -> None:
    topics = topic_names(["adaptive.a1=1.5", "adaptive.a1=1_5", "2fast"])
    assert topics == {
        "adaptive.a1=1.5": "/replay/adaptive_a1_1_5/state",
        "adaptive.a1=1_5": "/replay/adaptive_a1_1_5_2/state",
        "2fast": "/replay/run_2fast/state",
    }


def test_a_failed_write_leaves_nothing_behind(
    example_table: pd.DataFrame, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def failing(writer: object, table: object, **kwargs: object) -> None:
        raise OSError("disk full")  # in the writer's thread, after the file was opened

    monkeypatch.setattr(outputs.pq.ParquetWriter, "write_table", failing)
    path = tmp_path / "results.parquet"
    with pytest.raises(ReplayError) as caught:
        write_parquet(example_table, path)
    assert str(caught.value) == f"{path}: cannot write Parquet: disk full"
    assert list(tmp_path.iterdir()) == []
