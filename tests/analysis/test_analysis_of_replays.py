"""Analysis of hilrig.replay's own output: a recorded session replayed through its controller
measures exactly as the session itself did, and the other laws are compared against it."""

from pathlib import Path

import pytest

from hilrig.analysis import Source, SourceKind, analyze, load_session, runs_from_frame

replay = pytest.importorskip("hilrig.replay")

EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"


def test_a_replay_through_the_recorded_controller_measures_like_the_session() -> None:
    table = replay.run(replay.load_trace(EXAMPLE), replay.parse_specs(["adaptive", "fixed"]))
    replayed = analyze(Source(Path("replay.parquet"), SourceKind.REPLAY, runs_from_frame(table)))
    recorded = analyze(load_session(EXAMPLE))
    assert replayed.events == recorded.events  # same force, same time axis
    ours = {m.axis: m for m in replayed.metrics if m.run == "adaptive"}
    for m in recorded.metrics:
        again = ours[m.axis]
        assert again.max_offset == pytest.approx(m.max_offset, rel=1e-12)
        assert again.time_to_max_offset_s == pytest.approx(m.time_to_max_offset_s, abs=1e-9)
        assert again.recovery_time_s == pytest.approx(m.recovery_time_s, abs=1e-9)
    fixed = {m.axis: m.max_abs_offset for m in replayed.metrics if m.run == "fixed"}
    assert all(ours[axis].max_abs_offset > fixed[axis] for axis in ("x", "y", "z"))
