"""A recorded HIL session, end to end: rig up, drivers connected, tare, loop, file closed.

Start-up is ordered so that nothing is lost and nothing costs the first ticks:

0. the machine's session lock is taken (:mod:`.machine_lock`: one session at a time on a
   machine; a second one says so and waits);
1. the compiled tick is loaded and run once (numba's first-call costs), before any device talks;
2. the recorder process and (emulated) rig process are spawned side by side, and the live view's
   viewer-feed process if asked;
3. the drivers connect; from the first byte on, the loop's thread reads them and every sample
   goes to the recorder's rings (sized for start-up, :data:`STARTUP_RING_ROWS`);
4. the wrist sensor is tared at the start pose (the tool's gravity accounted for) from the
   samples read meanwhile, which are recorded too;
5. the recorder gets the session metadata and calibration and opens the file; the rows waiting
   in the rings are written first;
6. the loop ticks until the duration has passed, ``stop`` is set (Ctrl-C, SIGTERM: a
   :class:`~.stop.SessionStop` says which) or the watchdog ends it (the robot's fault, the
   recorder's death or a write its disk refused); ``ended_by`` says which.

Whatever happens, the robot is left holding and the recording is closed cleanly: the ExitStack
unwinds in reverse order.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.drivers.ft.link import FtSerial, SampleRows
from hilrig.emulator.rig import RigConfig, RigEndpoints
from hilrig.errors import LinkError, OutputError, RecordingError
from hilrig.machine.settings import session_warnings
from hilrig.recording import SessionInfo, SessionOutcome
from hilrig.recording.outcome import ran_its_course, stopped_from_outside
from hilrig.recording.samples import EventRecord
from hilrig.rig.device_io import DeviceIO
from hilrig.rig.disk_space import check_free_space
from hilrig.rig.kinds import RigKind
from hilrig.rig.live_port import LiveReportLike, LiveViewPort
from hilrig.rig.loop import ControlLoop, Watchdog
from hilrig.rig.loop_figures import LoopSummary
from hilrig.rig.machine_lock import one_session_at_a_time
from hilrig.rig.recorder_feed import RecorderFeed
from hilrig.rig.recorder_process import RecorderProcess
from hilrig.rig.records import AXIS_NAMES
from hilrig.rig.rig_process import RigCounters, RigProcess
from hilrig.rig.robot_links import RobotLink, open_robot_link
from hilrig.rig.session_config import SessionConfig
from hilrig.rig.warm_up import warm_up
from hilrig.rig.write_failure import WriteFailure
from hilrig.robot import RobotModel
from hilrig.tick.links import ROBOT_LINK, SENSOR_LINK
from hilrig.timing import freeze_heap
from hilrig.world.scenarios import settings_of

__all__ = ["STARTUP_RING_ROWS", "SessionConfig", "SessionResult", "record_session"]
STARTUP_RING_ROWS = 16384  # 16 s at 1 kHz: samples read before the recorder has its file open
FIRST_SAMPLE_TIMEOUT_S = 5.0
RECORDER_READY_TIMEOUT_S = 60.0
QUIET_S = 0.05  # at a session's end: a link silent this long has delivered all it sent
MAX_DRAIN_S = 2.0


@dataclass
class SessionResult:
    """What a session produced: the file, the loop's summary, the recorder's counts, how the
    live view went (None without one) and how the session ended."""

    path: Path
    summary: LoopSummary
    messages_written: int | None  # None when the recorder died: see recorder_error
    drops: int
    events: list[EventRecord]
    recorder_error: str = ""  # why the file may be truncated ("" when it closed cleanly)
    view: LiveReportLike | None = None
    rig_counters: RigCounters | None = None  # what the emulated rig sent (None: a real rig)
    ended_by: str = ""  # how it ended (outcome.py): duration reached, a stop, a fault
    robot_link: dict[str, object] = field(default_factory=dict)  # which, and what it did
    write_failure: WriteFailure | None = None  # the write a disk refused (ended_by says it)

    @property
    def fault(self) -> str:
        """Why a fault ended the session early (the robot, the recorder, the disk): its
        ``ended_by``; "" when it ran its course or was stopped from outside."""
        early = not ran_its_course(self.ended_by) and not stopped_from_outside(self.ended_by)
        return self.ended_by if early else ""


def record_session(
    config: SessionConfig,
    *,
    stop: threading.Event | None = None,
    live: LiveViewPort | None = None,
    on_start: Callable[[ControlLoop], None] | None = None,
    on_event: Callable[[EventRecord], None] | None = None,
    rig_ready: Callable[[RigProcess], None] | None = None,
    recorder_ready: Callable[[RecorderProcess], None] | None = None,
    on_wait: Callable[[str], None] | None = None,
    on_warning: Callable[[str], None] | None = None,
) -> SessionResult:
    """Run and record one session; raises HilrigError (one line) when it cannot start.

    Every input is checked (:meth:`SessionConfig.check`) before anything starts, and the file is
    created only once the devices are connected and the sensor tared: a session that cannot
    start leaves nothing behind (not even the folder it made). Once the file is open it is kept
    whatever happens: an error raised later carries a note saying where the recording is (and,
    if the recorder died, how to ``hilrig recover`` it).

    ``live`` is the live view (built by the caller, e.g. ``hilrig.viz.live.LiveView``);
    ``on_start`` gets the loop before it ticks (e.g. for a status line), ``on_event`` every
    event (called on the tick: it must only queue), ``rig_ready`` and ``recorder_ready`` the
    emulated rig and recorder processes (fault injection in tests), ``on_wait`` a line saying
    that another session holds the machine (this one then waits for it, or for ``stop``), and
    ``on_warning`` a line for each setting of the machine that would cost the session most
    (:func:`hilrig.machine.settings.session_warnings`; the session runs all the same) and for a
    disk with little room for it (:func:`.disk_space.check_free_space`, which refuses one that
    has too little). The
    machine's settings are read once the machine is this session's, and attached to the file.
    """
    config.check()
    stop = stop or threading.Event()
    events: list[EventRecord] = []

    def collect(record: EventRecord) -> None:
        events.append(record)
        if on_event is not None:
            on_event(record)

    session_id = config.session_id_or_new()
    model = RobotModel()
    with ExitStack() as stack:
        stack.enter_context(one_session_at_a_time(stop, on_wait))
        space = check_free_space(config.out, config.duration_s)  # too little: refused here
        if space and on_warning is not None:
            on_warning(space)
        machine = config.machine_settings()
        if on_warning is not None:
            for line in session_warnings(machine):
                on_warning(line)
        warm_up()  # numba's first-call costs, before any device talks
        freeze_heap()  # and the collector's big pass: the loop's own (realtime_python) is short
        made = _make_folders(config.out)
        stack.callback(_remove_empty, made)  # at the end, unless the file is there
        if live is not None:  # first: its start-up must not delay the rig's scenario
            stack.callback(live.close)
            live.start()
        feed = RecorderFeed(rows=STARTUP_RING_ROWS)
        stack.callback(feed.close)
        recorder = RecorderProcess(
            config.out,
            feed=feed,
            urdf=model.urdf_xml,
            attachments=config.attachments(machine),
            controller=config.loop.law.value,
            axis_names=AXIS_NAMES,
            view=None if live is None else live.queue,
        )
        recorder.spawn()  # imports while the rig comes up
        stack.callback(_stop_quietly, recorder)  # a session that cannot start: no recorder left
        rig = None
        volunteer: dict[str, Any] = {}  # the emulated volunteer, for the session record
        if config.rig is RigKind.EMULATED:
            scenario = config.volunteer()
            volunteer = {"scenario": config.scenario, "scenario_settings": settings_of(scenario)}
            # the scenario's clock starts with the first tick, however long start-up takes
            rig = RigProcess(scenario, config=RigConfig(scenario_starts_at_open=False))
            endpoints = rig.start()
            stack.callback(rig.stop)
            if rig_ready is not None:
                rig_ready(rig)
        else:
            assert config.endpoints is not None
            endpoints = config.endpoints
        devices, link = _connect(stack, endpoints, feed, config)
        q0 = np.array(_wait_for_robot(devices)["q"], dtype=np.float64)
        start_pose = model.fk(q0)
        compensator = GravityCompensator(config.tool)
        compensator.tare(_average_wrench(devices, config.tare_s), start_pose[:3, :3])
        trajectory, safety = config.task(model, q0)  # a task the clamp would cut is refused
        loop = ControlLoop(
            config.loop,
            io=devices,
            compensator=compensator,
            trajectory=trajectory,
            safety=safety,
            model=model,
            on_event=collect,
            virtual=config.virtual,
            watchdog=_watchdog(recorder, link),
            robot_period_ns=link.state_period_ns,
        )
        recorder.begin(
            SessionInfo.starting_now(
                session_id=session_id,
                subject_id=config.subject_id,
                rig=config.rig.value,
                controller=config.loop.law.value,
                controller_params=config.loop.params_record(),
                body_region=config.region(),
                contact_area_cm2=config.contact_area_cm2,
                **volunteer,
            ),
            {
                "bias_in_sensor": compensator.bias_in_sensor.tolist(),
                "tool_mass_kg": config.tool.mass_kg,
                "tool_com_in_sensor_m": list(config.tool.com_in_sensor_m),
            },
        )
        _wait_for_recorder(devices, recorder)
        # the file is open: from here on it is kept, whatever happens
        failure: BaseException | None = None
        outcome: SessionOutcome | None = None
        try:
            if recorder_ready is not None:
                recorder_ready(recorder)
            if on_start is not None:
                on_start(loop)
            link.arm()  # servo mode: the link is up and its first state fresh
            if rig is not None:
                rig.start_scenario()
            summary = loop.run(config.duration_s, stop)
            if not loop.ended_by.startswith("robot:"):
                link.disarm()  # out of servo mode before the rig's streams end
            _read_to_the_end(devices, rig)
            outcome = summary.outcome(recorder_drops=feed.drops, ended_by=loop.ended_by)
        except BaseException as err:  # noted and raised once the file is closed
            failure = err
        recorder_error = ""
        messages: int | None = None
        try:
            messages, drops = recorder.stop(outcome=outcome)
        except RecordingError as err:  # the recorder died: the file ends where it did
            recorder_error = f"{err}; `hilrig recover {config.out} -o OUT` restores it"
            drops = feed.drops
        if failure is not None:
            kept = recorder_error or f"what was recorded until then is in {config.out}"
            failure.add_note(kept)
            raise failure
        view = None
        if live is not None:  # after the recorder: its last batch is queued by now
            view = live.stop(recorder.view_counts)
    counters = None if rig is None else rig.final_counters
    return SessionResult(
        config.out,
        summary,
        messages,
        drops,
        events,
        recorder_error,
        view,
        counters,
        loop.ended_by,
        {**link.describe, **link.figures()},
        recorder.failure(),
    )


def _make_folders(path: Path) -> list[Path]:
    """Make the missing folders of ``path`` (checked writable before); the ones made, innermost
    first. Raises OutputError naming the folder that cannot be made."""
    missing = [p for p in path.parents if not p.exists()]
    for folder in reversed(missing):
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        except OSError as err:
            _remove_empty(missing[missing.index(folder) + 1 :])
            raise OutputError(f"{path}: folder {folder} cannot be made ({err.strerror})") from None
    return missing


def _remove_empty(folders: list[Path]) -> None:
    """Remove each of ``folders`` (innermost first) that is empty."""
    for folder in folders:
        with contextlib.suppress(OSError):
            folder.rmdir()


def _stop_quietly(recorder: RecorderProcess) -> None:
    """Stop a recorder the session did not stop itself (it could not start): it then exits
    without a file, or finishes the one it opened."""
    with contextlib.suppress(RecordingError):
        recorder.stop()


def _connect(
    stack: ExitStack, endpoints: RigEndpoints, feed: RecorderFeed, config: SessionConfig
) -> tuple[DeviceIO, RobotLink]:
    """Open the sensor's and the robot's links (no waiting for data: the loop's thread reads
    from now on). Both are made before any connects: nothing slow may come between the
    sensor's first byte and the loop's reads."""
    sensor = FtSerial(endpoints.ft_wrist_port)
    link = open_robot_link(stack, config.robot_link, endpoints, config.arcs)
    link.record_into(feed.servo)
    sensor.connect(first_sample_timeout_s=None)
    stack.callback(sensor.close)
    return DeviceIO(sensor, link.states, link.targets, feed), link


def _watchdog(recorder: RecorderProcess, link: RobotLink) -> Watchdog:
    """What ends the session early: a write the recorder's disk refused, the recorder's death,
    or the robot link's fault (a protective or emergency stop, servo mode left, the link
    lost)."""

    def reason() -> str:
        failure = recorder.failure()  # it exits once it said so: its sentinel wakes the loop
        if failure is not None:
            return failure.problem
        if not recorder.alive():
            return "the recorder process died"
        fault = link.fault()
        return f"robot: {fault}" if fault else ""

    fds = (recorder.sentinel,) if link.fault_fd < 0 else (recorder.sentinel, link.fault_fd)
    return Watchdog(fds, reason)


def _wait_for_robot(devices: DeviceIO) -> np.void:
    """Read (and record) until the robot's first joint state and the sensor's first frame."""
    give_up = time.monotonic_ns() + round(FIRST_SAMPLE_TIMEOUT_S * 1e9)
    robot, sensor = devices.robot, devices.sensor
    if not devices.pump_until(lambda _: None not in (robot.latest(), sensor.latest()), give_up):
        missing = ROBOT_LINK if robot.latest() is None else SENSOR_LINK
        raise LinkError(f"{missing}: no valid frame within {FIRST_SAMPLE_TIMEOUT_S} s")
    latest = robot.latest()
    assert latest is not None
    return latest


def _average_wrench(devices: DeviceIO, duration_s: float) -> NDArray[np.float64]:
    """The mean raw wrist wrench over ``duration_s`` of samples (all recorded): the tare."""
    samples: list[list[float]] = []
    end = time.monotonic_ns() + round(duration_s * 1e9)

    def enough(new: SampleRows) -> bool:
        samples.extend(new["wrench"].tolist())
        return bool(samples) and time.monotonic_ns() >= end

    if not devices.pump_until(enough, end + round(FIRST_SAMPLE_TIMEOUT_S * 1e9)):
        raise LinkError("wrist F/T sensor: no samples to tare")
    mean: NDArray[np.float64] = np.mean(np.asarray(samples, dtype=np.float64), axis=0)
    return mean


def _read_to_the_end(devices: DeviceIO, rig: RigProcess | None) -> None:
    """Stop the sensor's stream and record the frames still on their way; with the emulated rig,
    stop it and record every joint state it says it sent (the ARCS link's process may hand on
    its last ones late on a loaded machine)."""
    devices.sensor.stop_streaming()
    _read_until_quiet(devices, sensor_only=True)
    if rig is not None:
        counters = rig.stop()
        sent = (
            0 if counters is None else max(counters.rtde_samples_sent, counters.joint_frames_sent)
        )
        _read_until_quiet(devices, sensor_only=False, robot_states=sent)


def _read_until_quiet(devices: DeviceIO, *, sensor_only: bool, robot_states: int = 0) -> None:
    """Read (and record) until no data came for QUIET_S and ``robot_states`` joint states came
    in all, or MAX_DRAIN_S passed. With ``sensor_only`` only the wrist sensor's silence counts:
    the robot streams on (waiting for it to fall silent took MAX_DRAIN_S at every session's
    end)."""
    quiet_ns = round(QUIET_S * 1e9)
    last = [devices.samples_read, time.monotonic_ns()]  # samples read, when new data came last

    def quiet(wrist: SampleRows) -> bool:
        now = time.monotonic_ns()
        if len(wrist) or (not sensor_only and devices.samples_read != last[0]):
            last[:] = [devices.samples_read, now]
        all_in = devices.robot.status().samples >= robot_states
        return now - last[1] >= quiet_ns and all_in

    devices.pump_until(quiet, time.monotonic_ns() + round(MAX_DRAIN_S * 1e9), step_ns=quiet_ns)


def _wait_for_recorder(devices: DeviceIO, recorder: RecorderProcess) -> None:
    """Keep reading (and queueing) samples until the recorder has its file open."""
    give_up = time.monotonic_ns() + round(RECORDER_READY_TIMEOUT_S * 1e9)
    if not devices.pump_until(lambda _: recorder.ready(), give_up, step_ns=5_000_000):
        raise RecordingError(
            f"recorder of {recorder.path}: not ready within {RECORDER_READY_TIMEOUT_S} s"
        )
