"""A recorded HIL session, end to end: rig up, drivers connected, tare, loop, file closed.

``record_session`` starts the emulated rig in its own process (or uses the endpoints of a real
AUBO rig), connects the three drivers, tares the wrist sensor at the start pose (the tool's
gravity accounted for), starts the recorder process (and, with ``view``, the live view's
viewer-feed process, :mod:`hilrig.viz.live`) and runs the loop until the duration has passed or
``stop`` is set (Ctrl-C, SIGTERM). Whatever happens, the robot is left holding and the
recording is closed cleanly: the ExitStack unwinds in reverse order.
"""

from __future__ import annotations

import io
import json
import threading
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from hilrig.drivers.emulated.rig import RigEndpoints
from hilrig.drivers.emulated.scenarios import scenario as make_scenario
from hilrig.drivers.ft_serial import FtSerial
from hilrig.drivers.gravity import GravityCompensator, ToolLoad
from hilrig.drivers.joint_targets import JointTargetsWriter, ModbusEndpoint
from hilrig.drivers.robot_state import RobotStateClient
from hilrig.errors import HilrigError, RecordingError
from hilrig.recording import Attachment, SessionInfo, validate_subject_id
from hilrig.recording.samples import EventRecord
from hilrig.rig.loop import ControlLoop, LoopConfig, LoopSummary
from hilrig.rig.recorder import RecorderFeed, RecorderProcess
from hilrig.rig.records import AXIS_NAMES
from hilrig.rig.rig_process import RigProcess
from hilrig.rig.safety import SafetyClamp, SafetyConfig
from hilrig.rig.trajectory import make_trajectory
from hilrig.rig.virtual import VirtualInput
from hilrig.robot import RobotModel
from hilrig.viz.live import LiveReport, LiveView, check_sink
from hilrig.viz.sinks import Sink

EMULATED_TOOL = ToolLoad(mass_kg=0.5, com_in_sensor_m=(0.0, 0.0, 0.05))


@dataclass(frozen=True)
class SessionConfig:
    """One session: who (pseudonym), what (scenario, trajectory, controller), how long, where.

    ``rig`` is "emulated" (started here) or "aubo" with ``endpoints`` of the real devices.
    ``view``: where the live view goes (None: no live view).
    """

    out: Path
    subject_id: str
    scenario: str = "paper-end-effector"
    rig: str = "emulated"
    endpoints: RigEndpoints | None = None
    duration_s: float | None = 20.0
    trajectory: str = "circle"
    trajectory_options: dict[str, object] = field(default_factory=dict)  # e.g. waypoints' points
    loop: LoopConfig = field(default_factory=LoopConfig)
    tool: ToolLoad = EMULATED_TOOL
    tare_s: float = 0.2
    session_id: str = ""
    virtual: VirtualInput | None = None  # a recorded trace played as a virtual collision
    virtual_source: str = ""  # where that trace came from (file, start, duration)
    view: Sink | None = None

    def as_json(self) -> str:
        """The configuration as JSON, attached to the recording (the virtual trace summarised;
        its values are attached as virtual_input.npy)."""
        record = asdict(replace(self, virtual=None))
        record["out"] = str(self.out)
        if self.virtual is not None:
            record["virtual"] = {
                "rows": self.virtual.force.shape[0],
                "dt_s": self.virtual.dt_s,
                "delay_s": self.virtual.delay_s,
            }
        return json.dumps(record, indent=2, default=str, sort_keys=True)

    def attachments(self) -> list[Attachment]:
        """The config (JSON), the scenario name and, when one plays, the virtual trace (.npy)."""
        files = [
            Attachment("config.json", "application/json", self.as_json().encode()),
            Attachment("scenario.txt", "text/plain", self.scenario.encode()),
        ]
        if self.virtual is not None:
            buffer = io.BytesIO()
            np.save(buffer, self.virtual.force)
            files.append(Attachment("virtual_input.npy", "application/x-npy", buffer.getvalue()))
        return files


@dataclass
class SessionResult:
    """What a session produced: the file, the loop's summary, the recorder's counts and how the
    live view went (None without one)."""

    path: Path
    summary: LoopSummary
    messages_written: int | None  # None when the recorder died: see recorder_error
    drops: int
    events: list[EventRecord]
    recorder_error: str = ""  # why the file may be truncated ("" when it closed cleanly)
    view: LiveReport | None = None


def record_session(
    config: SessionConfig,
    *,
    stop: threading.Event | None = None,
    on_start: Callable[[ControlLoop], None] | None = None,
    on_event: Callable[[EventRecord], None] | None = None,
    rig_ready: Callable[[RigProcess], None] | None = None,
    recorder_ready: Callable[[RecorderProcess], None] | None = None,
) -> SessionResult:
    """Run and record one session; raises HilrigError (one line) when it cannot start.

    ``on_start`` gets the loop before it ticks (e.g. for a status line), ``on_event`` every
    event (called on the tick: it must only queue), ``rig_ready`` and ``recorder_ready`` the
    emulated rig and recorder processes (fault injection in tests).
    """
    validate_subject_id(config.subject_id)
    if config.rig not in ("emulated", "aubo"):
        raise HilrigError(f"rig {config.rig!r} is not one of: emulated, aubo")
    make_scenario(config.scenario)  # an unknown scenario fails before anything starts
    if config.view is not None:
        check_sink(config.view)
    stop = stop or threading.Event()
    events: list[EventRecord] = []

    def collect(record: EventRecord) -> None:
        events.append(record)
        if on_event is not None:
            on_event(record)

    session_id = config.session_id or time.strftime("%Y%m%d-%H%M%S")
    model = RobotModel()
    with ExitStack() as stack:
        live = None
        if config.view is not None:  # first: its start-up must not delay the rig's scenario
            live = LiveView(
                config.view,
                session_id=session_id,
                controller=config.loop.law,
                source=str(config.out),
                loop_rate_hz=config.loop.rate_hz,
                urdf=model.urdf_xml,
            )
            stack.callback(live.close)
            live.start()
        if config.rig == "emulated":
            rig = RigProcess(config.scenario)
            endpoints = rig.start()
            stack.callback(rig.stop)
            if rig_ready is not None:
                rig_ready(rig)
        else:
            if config.endpoints is None:
                raise HilrigError("rig aubo needs its endpoints (a config file)")
            endpoints = config.endpoints
        sensor = FtSerial(endpoints.ft_wrist_port)
        sensor.connect()
        stack.callback(sensor.close)
        robot = RobotStateClient(*endpoints.robot_state)
        robot.connect()
        stack.callback(robot.close)
        targets = JointTargetsWriter(ModbusEndpoint(*endpoints.modbus))
        targets.connect()
        stack.callback(targets.close)

        latest = robot.latest()
        assert latest is not None  # connect() waited for the first frame
        q0 = np.asarray(latest.state.q_rad)
        start_pose = model.fk(q0)
        compensator = GravityCompensator(config.tool)
        compensator.tare(sensor.average(config.tare_s), start_pose[:3, :3])
        info = SessionInfo.starting_now(
            session_id=session_id,
            subject_id=config.subject_id,
            rig=config.rig,
            controller=config.loop.law,
            controller_params=config.loop.params_record(),
        )
        feed = RecorderFeed()
        stack.callback(feed.close)
        recorder = RecorderProcess(
            config.out,
            info,
            feed=feed,
            urdf=model.urdf_xml,
            attachments=config.attachments(),
            calibration={
                "bias_in_sensor": compensator.bias_in_sensor.tolist(),
                "tool_mass_kg": config.tool.mass_kg,
                "tool_com_in_sensor_m": list(config.tool.com_in_sensor_m),
            },
            controller=config.loop.law,
            axis_names=AXIS_NAMES,
            view=None if live is None else live.queue,
        )
        recorder.start()
        if recorder_ready is not None:
            recorder_ready(recorder)
        loop = ControlLoop(
            config.loop,
            sensor=sensor,
            robot=robot,
            targets=targets,
            compensator=compensator,
            trajectory=make_trajectory(config.trajectory, start_pose, **config.trajectory_options),
            safety=SafetyClamp(SafetyConfig(dt_s=1.0 / config.loop.rate_hz), model, q0),
            model=model,
            feed=feed,
            on_event=collect,
            virtual=config.virtual,
        )
        if on_start is not None:
            on_start(loop)
        recorder_error = ""
        messages: int | None = None
        view = None
        try:
            summary = loop.run(config.duration_s, stop)
        finally:
            try:
                messages, drops = recorder.stop()
            except RecordingError as err:  # the recorder died: the file ends where it did
                recorder_error = f"{err}; `hilrig recover {config.out} -o OUT` restores it"
                drops = feed.drops
            if live is not None:  # after the recorder: its last batch is queued by now
                view = live.stop(recorder.view_counts)
    return SessionResult(config.out, summary, messages, drops, events, recorder_error, view)
