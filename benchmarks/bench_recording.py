"""Recording: writer and loader throughput, as ratios to the official MCAP libraries run alongside.

- Writer: hilrig's SessionWriter vs the ``mcap_ros2`` writer, the same 10 s of every topic at
  1 kHz (prebuilt typed samples vs prebuilt dicts), messages per second.
- Loader: ``hilrig.recording.load`` of a 10-minute 1 kHz session of every topic (4.8 M messages)
  vs iterating the same file with the ``mcap`` reader and the ``mcap_ros2`` decoder (over its
  first seconds, as a rate). A *sample* is one numeric field value of one message (a cell of the
  loaded columns, index and record fields excluded); messages per second are reported beside.
- Crash: a writer paced at 1 kHz is killed with SIGKILL; the log time lost after ``recover``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer

from benchmarks.harness import Result
from hilrig.recording import (
    ControllerSample,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    SessionInfo,
    SessionWriter,
    WrenchSample,
    default_channels,
    load,
    recover,
)
from hilrig.recording.msgdef import full_definition
from hilrig.recording.schema import TOPICS

SUITE = "recording"
SESSION_TICKS = 600_000  # 10 minutes at 1 kHz
WRITER_TICKS = 10_000  # 10 s at 1 kHz, for both writers
ANCHOR_SECONDS = 6  # of the session, decoded by the generic reader
INFO = SessionInfo(
    session_id="bench",
    subject_id="S001",
    rig="emulated",
    controller="adaptive",
    start_utc_ns=1_767_225_600_000_000_000,
    start_monotonic_ns=1_000_000_000,
)
SPECS = {spec.topic: spec for spec in default_channels()}


def tick_samples(i: int, f: list[float]) -> Iterator[tuple[str, Sample]]:
    """A loop tick of each periodic topic of docs/recording-format.md (no events), values ``f``."""
    t = INFO.start_monotonic_ns + i * 1_000_000
    v, w, j = (f[0], f[1], f[2]), (f[3], f[4], f[5]), f[:6]
    yield "/ft/wrist", WrenchSample(t, v, w)
    yield "/ft/base", WrenchSample(t, w, v)
    yield "/joint_states", JointSample(t, j, j, j, device_t_ns=i * 1000, device_seq=i)
    yield "/controller/input", WrenchSample(t, v, w)
    yield "/controller/state", ControllerSample(t, f, f, f, f, f, f, f, [1] * 9)
    yield "/trajectory/desired", PoseSample(t, v, (0.0, 0.0, 0.0, 1.0))
    yield "/trajectory/commanded", JointSample(t, j)
    yield "/diagnostics/loop", LoopTiming(t, i, 1_000_000, 200_000, 1000, 0, 0)


def values(rng: np.random.Generator) -> list[list[float]]:
    return rng.normal(size=(1000, 9)).tolist()  # type: ignore[no-any-return]


def as_dict(topic: str, s: Sample, log_ns: int) -> dict[str, Any]:
    """The same message for the mcap_ros2 writer."""
    sec, nanosec = divmod(log_ns, 1_000_000_000)
    header = {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": SPECS[topic].frame_id}
    names = list(SPECS[topic].names)
    if isinstance(s, WrenchSample):
        x, y = s.force, s.torque
        force, torque = dict(zip("xyz", x, strict=True)), dict(zip("xyz", y, strict=True))
        return {"header": header, "wrench": {"force": force, "torque": torque}}
    if isinstance(s, JointSample):
        return {
            "header": header,
            "name": names,
            "position": list(s.position),
            "velocity": list(s.velocity),
            "effort": list(s.effort),
        }
    if isinstance(s, PoseSample):
        orientation = dict(zip("xyzw", s.orientation, strict=True))
        position = dict(zip("xyz", s.position, strict=True))
        return {"header": header, "pose": {"position": position, "orientation": orientation}}
    if isinstance(s, ControllerSample):
        arrays = ("force", "offset", "offset_rate", "damping", "stiffness", "chi", "zeta")
        message = {"header": header, "controller": "adaptive", "axis_names": names}
        message.update({a: list(getattr(s, a)) for a in arrays})
        message["contact_state"] = list(s.contact_state)
        return message
    assert isinstance(s, LoopTiming)
    fields = ("tick", "period_ns", "compute_ns", "lateness_ns", "overruns", "queue_drops")
    return {"header": header, **{k: getattr(s, k) for k in fields}}


def bench_writers(tmp: Path) -> list[Result]:
    f = values(np.random.default_rng(1))
    messages = [m for i in range(WRITER_TICKS) for m in tick_samples(i, f[i % 1000])]
    best = float("inf")
    for attempt in range(3):
        path = tmp / f"hilrig-{attempt}.mcap"
        start = time.perf_counter()
        with SessionWriter(path, INFO, channels=default_channels()) as writer:
            for topic, sample in messages:
                writer.write(topic, sample)
        best = min(best, time.perf_counter() - start)
    ours = len(messages) / best
    offset = INFO.clock_offset_ns
    dicts = [(t, as_dict(t, s, s.t_ns + offset), s.t_ns + offset) for t, s in messages]
    start = time.perf_counter()
    with open(tmp / "mcap_ros2.mcap", "wb") as out:
        writer2 = Ros2Writer(out)
        schemas = {
            k: writer2.register_msgdef(v.value, full_definition(v.value)) for k, v in TOPICS.items()
        }
        for topic, message, log_ns in dicts:
            writer2.write_message(topic, schemas[topic], message, log_time=log_ns)
        writer2.finish()
    anchor = len(messages) / (time.perf_counter() - start)
    ratio = ours / anchor
    detail = {"messages": len(messages), "hilrig_msg_per_s": ours, "mcap_ros2_msg_per_s": anchor}
    return [
        Result(SUITE, "writer messages/s", ours, "msg/s", detail=detail),
        Result(SUITE, "mcap_ros2 writer messages/s (anchor)", anchor, "msg/s"),
        Result(SUITE, "writer vs mcap_ros2 writer", ratio, "x", ">= 5", ratio >= 5, detail),
    ]


def write_session(path: Path) -> float:
    """The 10-minute session, samples built as the loop would; returns messages per second."""
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    with SessionWriter(path, INFO, channels=default_channels()) as writer:
        write = writer.write
        for block in range(SESSION_TICKS // 1000):
            f = values(rng)
            for k in range(1000):
                for topic, sample in tick_samples(block * 1000 + k, f[k]):
                    write(topic, sample)
    return 8 * SESSION_TICKS / (time.perf_counter() - start)


def numeric_cells(frames: dict[str, Any]) -> tuple[int, dict[str, int]]:
    """Samples loaded (numeric field values) and numeric fields per message, per topic."""
    per_topic = {
        topic: sum(
            1
            for c, d in frame.dtypes.items()
            if d.kind in "iufb" and c not in ("publish_time_ns", "sequence")
        )
        for topic, frame in frames.items()
    }
    return sum(len(frames[t]) * n for t, n in per_topic.items()), per_topic


def generic_rate(path: Path, fields: dict[str, int]) -> tuple[float, float, float]:
    """Samples/s and messages/s decoding with mcap + mcap_ros2, and raw messages/s."""
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        end = summary.statistics.message_start_time + ANCHOR_SECONDS * 1_000_000_000
        start = time.perf_counter()
        messages = cells = 0
        for item in reader.iter_decoded_messages(ending_before=end):
            messages += 1
            cells += fields[item.channel.topic]
        elapsed = time.perf_counter() - start
        start = time.perf_counter()
        raw = sum(1 for _ in reader.iter_messages(ending_before=end))
        raw_rate = raw / (time.perf_counter() - start)
    return cells / elapsed, messages / elapsed, raw_rate


def bench_loader(tmp: Path) -> list[Result]:
    path = tmp / "session.mcap"
    end_to_end = write_session(path)
    load(path)  # warm the page cache and imports
    timings = []
    for _ in range(3):
        start = time.perf_counter()
        frames = load(path)
        timings.append(time.perf_counter() - start)
        cells, fields = numeric_cells(frames)
        messages = sum(len(frame) for frame in frames.values())
        del frames
    seconds = sorted(timings)[1]  # the median of three
    ours, ours_msgs = cells / seconds, messages / seconds
    anchor, anchor_msgs, raw = generic_rate(path, fields)
    detail = {
        "file_MB": path.stat().st_size / 1e6,
        "messages": messages,
        "samples": cells,
        "load_s": timings,
        "messages_per_s": ours_msgs,
        "generic_messages_per_s": anchor_msgs,
        "raw_mcap_iter_messages_per_s": raw,
        "ratio_to_raw_iteration": ours_msgs / raw,
        "session_write_msg_per_s_incl_building_samples": end_to_end,
    }
    ratio = ours / anchor
    return [
        Result(
            SUITE,
            "load samples/s (10 min, all topics)",
            ours,
            "samples/s",
            ">= 1e7",
            ours >= 1e7,
            detail,
        ),
        Result(SUITE, "load messages/s", ours_msgs, "msg/s"),
        Result(SUITE, "mcap + mcap_ros2 generic reader samples/s (anchor)", anchor, "samples/s"),
        Result(SUITE, "load vs generic reader", ratio, "x", ">= 100", ratio >= 100, detail),
    ]


CHILD = textwrap.dedent(
    """
    import sys, time
    from hilrig.recording import SessionInfo, SessionWriter, WrenchSample, default_channels
    info = SessionInfo.starting_now(session_id="kill", subject_id="S001", rig="bench",
                                    controller="none")
    writer = SessionWriter(sys.argv[1], info, channels=default_channels())
    next_tick = time.monotonic_ns()
    while True:
        next_tick += 1_000_000
        while time.monotonic_ns() < next_tick:
            pass
        writer.write("/ft/wrist", WrenchSample(next_tick, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0)))
        print(next_tick + info.clock_offset_ns, flush=True)
    """
)


def bench_crash(tmp: Path) -> list[Result]:
    losses = []
    for run, run_s in enumerate((1.3, 2.07, 2.61)):
        path = tmp / f"killed-{run}.mcap"
        child = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(path)], stdout=subprocess.PIPE, text=True
        )
        assert child.stdout is not None
        child.stdout.readline()  # writing: run_s from here (its imports take seconds when busy)
        time.sleep(run_s)
        os.kill(child.pid, signal.SIGKILL)
        output, _ = child.communicate()
        last_written = int(output.split()[-1])
        recovered = recover(path, tmp / f"recovered-{run}.mcap")
        assert recovered.end_ns is not None
        losses.append((last_written - recovered.end_ns) / 1e9)
    worst = max(losses)
    return [
        Result(
            SUITE,
            "log time lost by a killed writer",
            worst,
            "s",
            "<= 0.5",
            worst <= 0.5,
            {"losses_s": losses},
        ),
    ]


def run() -> list[Result]:
    with tempfile.TemporaryDirectory(prefix="hilrig-bench-") as tmp:
        folder = Path(tmp)
        return [*bench_writers(folder), *bench_loader(folder), *bench_crash(folder)]
