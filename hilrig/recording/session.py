"""Session metadata: who, when, on what rig, with which controller - and nothing that names anyone.

Subjects are recorded only under pseudonymous ids such as ``S012``; :func:`validate_subject_id`
refuses anything else, in particular anything that looks like a personal name.

Time: every sample's host receive time is a monotonic-clock reading (``time.monotonic_ns``).
A session fixes one offset, ``start_utc_ns - start_monotonic_ns``, taken when it starts, and
every MCAP log time is ``monotonic + offset``: nanoseconds since the Unix epoch (what Foxglove,
Rerun and rosbag2 expect) that never jump with NTP. The raw monotonic time is recoverable
exactly from the session metadata.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime

from hilrig import __version__
from hilrig.errors import RecordingError

FORMAT_VERSION = "hilrig-recording/1"
SUBJECT_ID_PATTERN = re.compile(r"^[A-Z]{1,3}[0-9]{2,5}$")
SESSION_METADATA = "session"
CALIBRATION_METADATA = "calibration"

ParamValue = float | int | str | bool


def validate_subject_id(subject_id: str) -> str:
    """Return ``subject_id`` if it is a pseudonym: 1-3 capital letters then 2-5 digits (``S012``).

    Raises RecordingError (a one-line message) for anything else, so that no personal name,
    initials-with-birthday or free text ever reaches a recording.
    """
    if not isinstance(subject_id, str) or not SUBJECT_ID_PATTERN.fullmatch(subject_id):
        raise RecordingError(
            f"subject id {subject_id!r} is not a pseudonym like S012 (1-3 capital letters, then"
            " 2-5 digits); personal names must never be recorded"
        )
    return subject_id


def utc_iso(t_ns: int) -> str:
    """``t_ns`` (ns since the Unix epoch) as ISO 8601 UTC with nanoseconds, e.g.
    ``2026-03-01T09:30:00.000000123Z``; a time no calendar date can show as ``<t_ns> ns``."""
    seconds, ns = divmod(t_ns, 1_000_000_000)
    try:
        day = datetime.fromtimestamp(seconds, UTC)
    except (OverflowError, OSError, ValueError):
        return f"{t_ns} ns"
    return day.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns:09d}Z"


#: Messages may come before the session's start (rows waiting in the rings) by this much...
MAX_BEFORE_START_NS = 3_600 * 1_000_000_000
#: ... and after it by this much (the last part of a split session included).
MAX_AFTER_START_NS = 7 * 86_400 * 1_000_000_000
#: No log time of any file is later than this (2200-01-01T00:00:00Z).
LATEST_NS = 7_258_118_400 * 1_000_000_000


@dataclass(frozen=True)
class TimeWindow:
    """The log times (int64 ns) a file's messages can have; ``why`` names what set them."""

    earliest: int = 0
    latest: int = LATEST_NS
    why: str = "no log time is negative or after 2200"

    @classmethod
    def of(cls, session: SessionInfo) -> TimeWindow:
        start = session.start_utc_ns
        why = f"the session started at {utc_iso(start)}: within 1 h before and 7 days after it"
        return cls(start - MAX_BEFORE_START_NS, min(start + MAX_AFTER_START_NS, LATEST_NS), why)

    def problem(self, start: int, end: int) -> str | None:
        """Why log times ``start``..``end`` are impossible here, or None if they are not."""
        if self.earliest <= start <= end <= self.latest:
            return None
        return f"impossible log times {utc_iso(start)} to {utc_iso(end)} ({self.why})"


@dataclass(frozen=True)
class SessionInfo:
    """What a recording is: stored as the MCAP metadata record ``session``.

    ``start_utc_ns`` and ``start_monotonic_ns`` are the wall-clock and monotonic readings taken
    together at the start; ``controller_params`` are the controller's parameters in SI units.
    Raises RecordingError if ``subject_id`` is not a pseudonym or a text field has a newline.
    """

    session_id: str
    subject_id: str
    rig: str
    controller: str
    start_utc_ns: int
    start_monotonic_ns: int
    controller_params: Mapping[str, ParamValue] = field(default_factory=dict)
    software_version: str = __version__
    scenario: str = ""  # the emulated volunteer ("" on a real rig: a person)
    scenario_settings: Mapping[str, object] = field(default_factory=dict)
    body_region: str = ""  # what the robot hits (ISO/TS 15066 region; "" not given)
    contact_area_cm2: float | None = None  # the contact's area (None: the standard's probe's)

    def __post_init__(self) -> None:
        validate_subject_id(self.subject_id)
        for name in ("session_id", "rig", "controller", "software_version"):
            value = getattr(self, name)
            if not value or "\n" in value:
                raise RecordingError(f"session {name} must be one non-empty line, got {value!r}")
        if not isinstance(self.scenario, str) or "\n" in self.scenario:
            raise RecordingError(f"session scenario must be one line, got {self.scenario!r}")
        if not isinstance(self.body_region, str) or "\n" in self.body_region:
            raise RecordingError(f"session body_region must be one line, got {self.body_region!r}")
        if not isinstance(self.scenario_settings, Mapping):
            raise RecordingError(
                f"session scenario_settings must be a table, got {self.scenario_settings!r}"
            )

    @classmethod
    def starting_now(
        cls,
        *,
        session_id: str,
        subject_id: str,
        rig: str,
        controller: str,
        controller_params: Mapping[str, ParamValue] | None = None,
        scenario: str = "",
        scenario_settings: Mapping[str, object] | None = None,
        body_region: str = "",
        contact_area_cm2: float | None = None,
    ) -> SessionInfo:
        """A session starting now: both clocks are read back to back."""
        mono = time.monotonic_ns()
        utc = time.time_ns()
        return cls(
            session_id=session_id,
            subject_id=subject_id,
            rig=rig,
            controller=controller,
            start_utc_ns=utc,
            start_monotonic_ns=mono,
            controller_params=dict(controller_params or {}),
            scenario=scenario,
            scenario_settings=dict(scenario_settings or {}),
            body_region=body_region,
            contact_area_cm2=contact_area_cm2,
        )

    @property
    def clock_offset_ns(self) -> int:
        """Add to a monotonic reading (ns) to get its MCAP log time (ns since the Unix epoch)."""
        return self.start_utc_ns - self.start_monotonic_ns

    def to_metadata(self, *, part: int) -> dict[str, str]:
        """The ``session`` metadata record of file number ``part`` (0 unless split)."""
        return {
            "format": FORMAT_VERSION,
            "session_id": self.session_id,
            "part": str(part),
            "subject_id": self.subject_id,
            "start_utc": utc_iso(self.start_utc_ns),
            "start_utc_ns": str(self.start_utc_ns),
            "start_monotonic_ns": str(self.start_monotonic_ns),
            "clock": "log_time = header.stamp = host monotonic receive time + clock_offset_ns",
            "clock_offset_ns": str(self.clock_offset_ns),
            "rig": self.rig,
            "controller": self.controller,
            "controller_params": json.dumps(dict(self.controller_params), sort_keys=True),
            "software_version": self.software_version,
            "scenario": self.scenario,
            "scenario_settings": json.dumps(dict(self.scenario_settings), sort_keys=True),
            "body_region": self.body_region,
            "contact_area_cm2": ""
            if self.contact_area_cm2 is None
            else repr(self.contact_area_cm2),
        }

    @classmethod
    def from_metadata(cls, record: Mapping[str, str]) -> SessionInfo:
        """Parse a ``session`` metadata record. Raises RecordingError if a field is missing."""
        try:
            return cls(
                session_id=record["session_id"],
                subject_id=record["subject_id"],
                rig=record["rig"],
                controller=record["controller"],
                start_utc_ns=int(record["start_utc_ns"]),
                start_monotonic_ns=int(record["start_monotonic_ns"]),
                controller_params=json.loads(record.get("controller_params", "{}")),
                software_version=record["software_version"],
                scenario=record.get("scenario", ""),  # absent in files before it was recorded
                scenario_settings=json.loads(record.get("scenario_settings", "{}")),
                body_region=record.get("body_region", ""),  # absent before it was recorded
                contact_area_cm2=float(area) if (area := record.get("contact_area_cm2")) else None,
            )
        except (KeyError, ValueError) as err:
            raise RecordingError(f"session metadata is incomplete or malformed ({err})") from err

    @classmethod
    def checked(cls, record: Mapping[str, str]) -> SessionInfo:
        """:meth:`from_metadata`, and the record's redundant fields must agree (format, start
        time in both forms, clock offset, part number), else RecordingError saying which."""
        session = cls.from_metadata(record)
        start = session.start_utc_ns
        problems = [
            f"format {record.get('format')!r} is not {FORMAT_VERSION!r}"
            if record.get("format") != FORMAT_VERSION
            else "",
            f"start_utc_ns {start} is impossible" if not 0 <= start <= LATEST_NS else "",
            "start_utc does not match start_utc_ns"
            if record.get("start_utc") != utc_iso(start)
            else "",
            "clock_offset_ns is not start_utc_ns - start_monotonic_ns"
            if record.get("clock_offset_ns") != str(session.clock_offset_ns)
            else "",
            "part is not a number" if not record.get("part", "").isdigit() else "",
        ]
        found = [p for p in problems if p]
        if found:
            raise RecordingError(f"session metadata is inconsistent: {'; '.join(found)}")
        return session


def calibration_metadata(calibration: Mapping[str, object]) -> dict[str, str]:
    """The ``calibration`` metadata record: strings kept, anything else stored as JSON."""
    return {k: v if isinstance(v, str) else json.dumps(v) for k, v in calibration.items()}
