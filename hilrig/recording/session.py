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
    ``2026-03-01T09:30:00.000000123Z``."""
    seconds, ns = divmod(t_ns, 1_000_000_000)
    return datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%dT%H:%M:%S") + f".{ns:09d}Z"


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

    def __post_init__(self) -> None:
        validate_subject_id(self.subject_id)
        for name in ("session_id", "rig", "controller", "software_version"):
            value = getattr(self, name)
            if not value or "\n" in value:
                raise RecordingError(f"session {name} must be one non-empty line, got {value!r}")

    @classmethod
    def starting_now(
        cls,
        *,
        session_id: str,
        subject_id: str,
        rig: str,
        controller: str,
        controller_params: Mapping[str, ParamValue] | None = None,
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
            )
        except (KeyError, ValueError) as err:
            raise RecordingError(f"session metadata is incomplete or malformed ({err})") from err


def calibration_metadata(calibration: Mapping[str, object]) -> dict[str, str]:
    """The ``calibration`` metadata record: strings kept, anything else stored as JSON."""
    return {k: v if isinstance(v, str) else json.dumps(v) for k, v in calibration.items()}
