"""A session's configuration: who, what, how long, where; checked before anything starts, and
attached to its recording as ``config.json`` (file names only: no folder, which may hold a
person's name), beside the machine's settings (``machine.json``)."""

from __future__ import annotations

import io
import json
import math
import re
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.ft.gravity import ToolLoad
from hilrig.emulator.rig import HOME_Q_RAD, RigEndpoints
from hilrig.errors import HilrigError
from hilrig.machine import Setting, port_settings, read_settings
from hilrig.recording import Attachment, validate_subject_id
from hilrig.recording.session_ids import new_session_id
from hilrig.rig.arcs.settings import ArcsSettings
from hilrig.rig.config_file import check_recording_path
from hilrig.rig.kinds import RigKind, RobotLinkKind
from hilrig.rig.loop import LoopConfig
from hilrig.rig.virtual import VirtualInput
from hilrig.robot import RobotModel
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.tick.task_limits import check_task
from hilrig.tick.trajectory import Trajectory, make_trajectory
from hilrig.timing import check_cpu
from hilrig.world.body import body_region
from hilrig.world.scenarios import DEFAULT_BODY_REGION, Scenario
from hilrig.world.scenarios import scenario as make_scenario

EMULATED_TOOL = ToolLoad(mass_kg=0.5, com_in_sensor_m=(0.0, 0.0, 0.05))


@dataclass(frozen=True)
class SessionConfig:
    """One session: who (pseudonym), what (scenario, trajectory, controller), how long, where.

    ``rig`` is "emulated" (started here) or "aubo" with ``endpoints`` of the real devices;
    ``robot_link`` the robot's interface (AUBO's ARCS, or the Modbus pair), ``arcs`` the ARCS
    link's user, password and servo stream (host and ports: the endpoints').
    """

    out: Path
    subject_id: str
    scenario: str = "paper-end-effector"
    scenario_settings: dict[str, object] = field(default_factory=dict)  # e.g. stiffness_n_m
    rig: RigKind = RigKind.EMULATED
    endpoints: RigEndpoints | None = None
    robot_link: RobotLinkKind = RobotLinkKind.ARCS
    arcs: ArcsSettings = field(default_factory=ArcsSettings)
    duration_s: float | None = 20.0
    trajectory: str = "circle"
    trajectory_options: dict[str, object] = field(default_factory=dict)  # e.g. waypoints' points
    loop: LoopConfig = field(default_factory=LoopConfig)
    tool: ToolLoad = EMULATED_TOOL
    tare_s: float = 0.2
    session_id: str = ""
    body_region: str = ""  # what the robot hits (ISO/TS 15066; "": the scenario's default)
    contact_area_cm2: float | None = None  # the contact's area (None: the standard's probe's)
    virtual: VirtualInput | None = None  # a recorded trace played as a virtual collision
    virtual_source: str = ""  # where that trace came from (file, start, duration)

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "rig", RigKind(self.rig))
        except ValueError:
            known = ", ".join(kind.value for kind in RigKind)
            raise HilrigError(f"rig {self.rig!r} is not one of: {known}") from None
        try:
            object.__setattr__(self, "robot_link", RobotLinkKind(self.robot_link))
        except ValueError:
            known = ", ".join(kind.value for kind in RobotLinkKind)
            raise HilrigError(f"robot link {self.robot_link!r} is not one of: {known}") from None
        if self.rig is RigKind.AUBO and self.endpoints is None:
            raise HilrigError("rig aubo needs its endpoints (a config file)")
        duration = self.duration_s
        if duration is not None and not (math.isfinite(duration) and duration > 0):
            raise HilrigError(f"duration {duration} s: must be a finite number of seconds > 0")

    def check(self) -> None:
        """Raise HilrigError (one line) for anything that would fail later: subject, scenario
        and its settings, trajectory and its options, controller parameters, and the output (a
        new file in a folder that exists, or can be made, and is writable). Nothing is
        created."""
        validate_subject_id(self.subject_id)
        self.volunteer()
        make_trajectory(self.trajectory, np.eye(4), **self.trajectory_options)
        if self.rig is RigKind.EMULATED:  # its start is known now: the task is checked from it
            self.task(RobotModel(), np.array(HOME_Q_RAD))
        self.loop.controller()
        if self.body_region:
            body_region(self.body_region)
        area = self.contact_area_cm2
        if area is not None and not (math.isfinite(area) and area > 0):
            raise HilrigError(f"contact area {area:g} cm^2: must be a finite area > 0")
        check_recording_path(self.out)
        check_cpu(self.loop.cpu)

    def task(
        self, model: RobotModel, q0_rad: NDArray[np.float64]
    ) -> tuple[Trajectory, SafetyClamp]:
        """The task from the start joints ``q0_rad`` (rad) and the safety clamp it runs under;
        ParameterError (one line) for a task that would leave the clamp's limits, with margin,
        within the session (:mod:`hilrig.tick.task_limits`)."""
        safety = SafetyClamp(SafetyConfig(dt_s=1.0 / self.loop.rate_hz), model, q0_rad)
        start_pose = model.fk(q0_rad)
        trajectory = make_trajectory(self.trajectory, start_pose, **self.trajectory_options)
        check_task(self.trajectory, trajectory, safety, self.duration_s)
        return trajectory, safety

    def region(self) -> str:
        """The body region the session records: the one given, else the emulated scenario's
        default (none on a real rig)."""
        if self.body_region or self.rig is not RigKind.EMULATED:
            return self.body_region
        return DEFAULT_BODY_REGION.get(self.scenario, "")

    def volunteer(self) -> Scenario:
        """The emulated volunteer: the scenario with its settings (ParameterError, one line)."""
        return make_scenario(self.scenario, self.scenario_settings)

    def as_json(self) -> str:
        """The configuration as JSON, attached to the recording (the virtual trace summarised;
        its values are attached as virtual_input.npy). Paths keep only their file names: a
        folder may hold a person's name (/home/jane.doe/...)."""
        record = asdict(replace(self, virtual=None))
        record["out"] = self.out.name
        del record["arcs"]["password"]  # never in a recording
        record["virtual_source"] = without_folders(self.virtual_source)
        if self.virtual is not None:
            record["virtual"] = {
                "rows": self.virtual.force.shape[0],
                "dt_s": self.virtual.dt_s,
                "delay_s": self.virtual.delay_s,
            }
        return json.dumps(record, indent=2, default=str, sort_keys=True)

    def attachments(self, machine: Iterable[Setting]) -> list[Attachment]:
        """The config (JSON), the scenario name, the ``machine``'s settings (JSON,
        :func:`machine_json`) and, when one plays, the virtual trace (.npy)."""
        files = [
            Attachment("config.json", "application/json", self.as_json().encode()),
            Attachment("scenario.txt", "text/plain", self.scenario.encode()),
            Attachment("machine.json", "application/json", machine_json(machine).encode()),
        ]
        if self.virtual is not None:
            buffer = io.BytesIO()
            np.save(buffer, self.virtual.force)
            files.append(Attachment("virtual_input.npy", "application/x-npy", buffer.getvalue()))
        return files

    def machine_settings(self) -> list[Setting]:
        """The machine's settings that bear on the loop as ``hilrig doctor`` reads them now,
        and a real rig's F/T port's."""
        settings = read_settings()
        if self.rig is RigKind.AUBO and self.endpoints is not None:
            settings += port_settings(Path(self.endpoints.ft_wrist_port))
        return settings

    def session_id_or_new(self) -> str:
        """The configured session id, or a new one."""
        return self.session_id or new_session_id()


def machine_json(settings: Iterable[Setting]) -> str:
    """A machine's settings as JSON (name, value, verdict, note; values keep file names only):
    what a session's timing figures are to be read against, later and elsewhere."""
    records = [asdict(replace(s, value=without_folders(s.value))) for s in settings]
    return json.dumps(records, indent=2)


def without_folders(text: str) -> str:
    """``text`` with every path in it cut to its last part (``/home/jane.doe/s.mcap`` ->
    ``s.mcap``)."""
    return re.sub(r"[^\s'\"]*[/\\]([^\s'\"/\\]*)", r"\1", text)
