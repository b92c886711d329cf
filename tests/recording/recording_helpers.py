"""Sessions written with hilrig's writer, for the recording tests to read back."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hilrig.recording import (
    Attachment,
    ControllerSample,
    EventKind,
    EventRecord,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    SessionInfo,
    SessionWriter,
    TextSample,
    WrenchSample,
    default_channels,
)

START_UTC_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00:00Z
START_MONO_NS = 5_000_000_000
URDF = '<?xml version="1.0"?>\n<robot name="aubo_i5"><link name="base_link"/></robot>\n'


def session_info() -> SessionInfo:
    return SessionInfo(
        session_id="2026-01-01-S012-a",
        subject_id="S012",
        rig="emulated",
        controller="adaptive",
        start_utc_ns=START_UTC_NS,
        start_monotonic_ns=START_MONO_NS,
        controller_params={"m": 20.0, "b_d": 150.0, "k_d": 300.0, "delta": 0.2},
    )


@dataclass(frozen=True)
class Written:
    """A session on disk and everything that was written to it, in order."""

    path: Path
    info: SessionInfo
    samples: list[tuple[str, Sample]]

    def log_ns(self, sample: Sample) -> int:
        return sample.t_ns + self.info.clock_offset_ns

    def of(self, topic: str) -> list[Sample]:
        return [s for t, s in self.samples if t == topic]


def samples(ticks: int, *, seed: int = 0, period_ns: int = 1_000_000) -> list[tuple[str, Sample]]:
    """``ticks`` ticks of every topic of docs/recording-format.md, random values, some events."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str, Sample]] = []
    for i in range(ticks):
        t = START_MONO_NS + i * period_ns
        f = rng.normal(size=30).tolist()
        out += [
            ("/ft/wrist", WrenchSample(t, (f[0], f[1], f[2]), (f[3], f[4], f[5]))),
            ("/ft/base", WrenchSample(t + 17, (f[6], f[7], f[8]), (f[9], f[10], f[11]))),
            (
                "/joint_states",
                JointSample(t, f[0:6], f[6:12], f[12:18], device_t_ns=77 * i, device_seq=3 + i),
            ),
            ("/controller/input", WrenchSample(t, (f[12], f[13], f[14]), (f[15], f[16], f[17]))),
            (
                "/controller/state",
                ControllerSample(
                    t,
                    f[0:9],
                    f[1:10],
                    f[2:11],
                    f[3:12],
                    f[4:13],
                    f[5:14],
                    f[6:15],
                    [int(x) for x in rng.integers(0, 4, 9)],
                ),
            ),
            ("/trajectory/desired", PoseSample(t, (f[20], f[21], f[22]), (0.0, 0.0, 0.6, 0.8))),
            ("/trajectory/commanded", JointSample(t, f[24:30])),
            ("/robot/servo", JointSample(t, f[18:24])),
            ("/diagnostics/loop", LoopTiming(t, i, period_ns, 200_000 + i, i % 7, i // 50, 0)),
        ]
        if i % 97 == 5:
            kind = EventKind(1 + i % 5)
            out.append(("/events", EventRecord(t, kind, "test", f"event at tick {i}", "x", f[0])))
    return out


def write_session(path: Path, ticks: int, *, seed: int = 0, **options: object) -> Written:
    info = session_info()
    written = samples(ticks, seed=seed)
    attachments = [
        Attachment("config.toml", "application/toml", b"rate_hz = 1000\n", log_time=START_UTC_NS),
    ]
    with SessionWriter(
        path,
        info,
        channels=default_channels(),
        calibration={"ft_wrist.bias_N": [0.1, -0.2, 0.05], "tool_mass_kg": 0.8},
        attachments=attachments,
        urdf=URDF,
        **options,  # type: ignore[arg-type]
    ) as writer:
        for topic, sample in written:
            writer.write(topic, sample)
    robot = ("/robot_description", TextSample(START_MONO_NS, URDF))  # written by the writer
    return Written(path, info, [robot, *written])
