"""What the fuzz tests damage and what they compare against: a small session written once, its
interesting regions, and the official reader's view of its messages."""

from __future__ import annotations

import signal
import warnings
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

import numpy as np
import pandas as pd
from click.testing import CliRunner, Result
from hypothesis import strategies as st
from mcap.reader import make_reader
from recording_helpers import write_session
from typer.main import get_command

from hilrig.cli import app
from hilrig.errors import HilrigError
from hilrig.recording import load

#: (topic, log time, publish time, sequence, data) of one message, as the official reader sees it.
Message = tuple[str, int, int, int, bytes]


class Base:
    """The undamaged session: its bytes, byte regions worth damaging, and what it holds (a
    plain class with a short repr: hypothesis prints its arguments with a failing example)."""

    def __init__(
        self,
        path: Path,
        data: bytes,
        regions: tuple[tuple[int, int], ...],
        messages: Counter[Message],
        frames: dict[str, pd.DataFrame],
        counts: dict[str, int],
    ) -> None:
        self.path, self.data, self.regions = path, data, regions
        self.messages, self.frames, self.counts = messages, frames, counts
        self.columns = {
            topic: {name: values(column) for name, column in frame.items()}
            for topic, frame in frames.items()
        }

    def __repr__(self) -> str:
        return f"Base({self.path})"

    def _repr_pretty_(self, printer: object, cycle: bool) -> None:  # what hypothesis prints
        printer.text(repr(self))  # type: ignore[attr-defined]


def values(column: pd.Series) -> np.ndarray:
    """A column's values as one array; a categorical's as its categories' values (None where
    missing), so that two categoricals compare by value whatever their categories."""
    if isinstance(column.dtype, pd.CategoricalDtype):
        codes = column.cat.codes.to_numpy()
        categories = np.append(column.cat.categories.to_numpy(dtype=object), None)
        return categories[np.where(codes >= 0, codes, len(categories) - 1)]
    return column.to_numpy()


def official_messages(path: Path) -> Counter[Message]:
    """Every message of ``path`` through the official reader, CRCs checked; its summary's
    statistics must agree."""
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        found = Counter(
            (channel.topic, m.log_time, m.publish_time, m.sequence, m.data)
            for _, channel, m in reader.iter_messages(log_time_order=False)
        )
    assert sum(found.values()) == summary.statistics.message_count
    return found


def write_base(folder: Path) -> Base:
    """0.2 s of every topic at 1 kHz in chunks of 0.05 s (about 130 kB)."""
    path = write_session(folder / "base.mcap", 200, chunk_span_s=0.05).path
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    first = chunks[0]
    size = path.stat().st_size
    data = path.read_bytes()
    summary_start = int.from_bytes(data[size - 8 - 20 : size - 8 - 12], "little")  # footer's
    metadata_start = min(m.offset for m in summary.metadata_indexes)
    regions = (
        (0, 63),  # magic and header
        (metadata_start, first.chunk_start_offset - 1),  # metadata, attachments, definitions
        (first.chunk_start_offset, first.chunk_start_offset + first.chunk_length + 399),
        (summary_start, size - 38),  # the summary section
        (size - 60, size - 1),  # data end, footer, magic
        (0, size - 1),  # anywhere
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frames = load(path)
    stats = summary.statistics.channel_message_counts
    counts = {c.topic: stats[c.id] for c in summary.channels.values()}
    return Base(path, data, regions, official_messages(path), frames, counts)


#: One change: ("flip", offset, xor mask), ("insert", offset, bytes) or ("cut", offset, b"").
Change = tuple[str, int, int | bytes]


def changes(base: Base) -> st.SearchStrategy[list[Change]]:
    """One to four byte flips, insertions of random bytes and cuts, in ``base``'s regions."""
    one = st.sampled_from(base.regions).flatmap(
        lambda region: st.one_of(
            st.tuples(st.just("flip"), st.integers(*region), st.integers(1, 255)),
            st.tuples(st.just("flip"), st.integers(*region), st.integers(1, 255)),
            st.tuples(st.just("flip"), st.integers(*region), st.integers(1, 255)),
            st.tuples(st.just("insert"), st.integers(*region), st.binary(min_size=1, max_size=24)),
            st.tuples(st.just("cut"), st.integers(*region), st.just(b"")),
        )
    )
    return st.lists(one, min_size=1, max_size=4)


def damaged(data: bytes, plan: list[Change]) -> bytes:
    """``data`` with the changes of ``plan`` made in turn (offsets past its end: its last byte)."""
    out = bytearray(data)
    for kind, offset, value in plan:
        if not out:
            break
        at = min(offset, len(out) - 1)
        if kind == "flip":
            assert isinstance(value, int)
            out[at] ^= value
        elif kind == "insert":
            assert isinstance(value, bytes)
            out[at:at] = value
        else:
            del out[at:]
    return bytes(out)


class HangError(Exception):
    """A call took longer than it may."""


@contextmanager
def bounded(seconds: float) -> Iterator[None]:
    """Raise HangError in the block once ``seconds`` have passed."""

    def expire(signum: int, frame: FrameType | None) -> None:
        raise HangError(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@dataclass(frozen=True)
class Run:
    """A command's exit status and its two streams (an uncaught HilrigError shown as
    ``hilrig`` shows it: ``error: <message>``, exit 2)."""

    exit_code: int
    stdout: str
    stderr: str


#: The command line as click runs it, built once: typer's CliRunner builds it from the app's
#: functions on every call (about 0.1 s each on a slow machine, most of this fuzz's time).
COMMAND = get_command(app)


def hilrig(*args: str, seconds: float = 20.0) -> Run:
    """``hilrig ARGS`` in-process; never a traceback, never a hang, an error is one line."""
    with bounded(seconds):
        result: Result = CliRunner().invoke(COMMAND, list(args), env={"COLUMNS": "200"})
    err = result.exception
    if isinstance(err, HilrigError):  # what hilrig.cli.main does with it
        run = Run(2, result.stdout, f"error: {err}\n")
    else:
        assert err is None or isinstance(err, SystemExit), f"{args}: {err!r}"
        run = Run(result.exit_code, result.stdout, result.stderr)
    assert run.exit_code in (0, 1, 2), (args, run)
    if run.exit_code == 2:
        lines = run.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), (args, run.stderr)
    assert "Traceback" not in run.stderr + run.stdout
    return run
