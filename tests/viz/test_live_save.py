"""The live view's ``.rrd`` (``hilrig record --view-save``): never over an existing file, written
beside it under a temporary name and moved into place whole at the end, nothing left over."""

from __future__ import annotations

from pathlib import Path

import pytest
from rrd_helpers import Rrd

from hilrig.errors import OutputError
from hilrig.viz import paths
from hilrig.viz.live import LiveView, check_sink
from hilrig.viz.sinks import Sink, SinkKind


def live_view(path: Path) -> LiveView:
    return LiveView(
        Sink(SinkKind.SAVE, path=path), session_id="saved", controller="fixed", source="s.mcap"
    )


def test_an_existing_file_is_refused_before_the_live_view_starts(tmp_path: Path) -> None:
    kept = tmp_path / "kept.rrd"
    kept.write_bytes(b"a view someone keeps")
    with pytest.raises(OutputError) as caught:
        check_sink(Sink(SinkKind.SAVE, path=kept))
    assert str(caught.value) == f"{kept}: already exists; refusing to overwrite it"
    with pytest.raises(OutputError):
        live_view(kept)
    assert kept.read_bytes() == b"a view someone keeps"
    assert [p.name for p in tmp_path.iterdir()] == ["kept.rrd"]


def test_the_file_appears_whole_when_the_view_ends_and_no_temporary_is_left(
    tmp_path: Path,
) -> None:
    out = tmp_path / "live.rrd"
    live = live_view(out)
    live.start()
    try:
        (writing,) = tmp_path.iterdir()  # the stream is open: it writes beside the target
        assert writing.name.startswith(".live.") and writing.suffix == ".rrd"
    finally:
        report = live.stop(None)
    assert report.problem == "the recorder did not report on the view"  # no recorder here
    assert [p.name for p in tmp_path.iterdir()] == ["live.rrd"]
    assert "saved" in Rrd(out).static(paths.ABOUT, "TextDocument:text")[0]


def test_a_file_made_there_during_the_session_is_kept_and_the_view_is_not_written(
    tmp_path: Path,
) -> None:
    out = tmp_path / "live.rrd"
    live = live_view(out)
    live.start()
    out.write_bytes(b"made meanwhile")
    report = live.stop(None)
    assert report.problem == f"{out}: already exists; refusing to overwrite it"
    assert out.read_bytes() == b"made meanwhile"
    assert [p.name for p in tmp_path.iterdir()] == ["live.rrd"]
