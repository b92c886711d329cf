"""HIL replay: a session that plays a recorded force trace into the loop as a virtual collision.

    virtual = VirtualInput.from_columns(trace.t_s, trace.columns, start_s=2.0, duration_s=3.0)
    session = playback_session(virtual, "S012", source="session.mcap from 2.0 s")
    result = record_session(session, stop=threading.Event())  # a new recording

The session holds the start pose, so the robot moves only as the played push makes it yield.
"""

from __future__ import annotations

from pathlib import Path

from hilrig.emulator.rig import RigEndpoints
from hilrig.rig.config_file import session_path
from hilrig.rig.kinds import RigKind
from hilrig.rig.loop import LoopConfig
from hilrig.rig.session_config import SessionConfig
from hilrig.rig.virtual import VirtualInput

#: Seconds the session goes on after the trace has played, for the robot to recover.
RECOVER_S = 2.0


def playback_session(
    virtual: VirtualInput,
    subject_id: str,
    *,
    source: str,
    rig: RigKind = RigKind.EMULATED,
    rate_hz: float = 1000.0,
    endpoints: RigEndpoints | None = None,
    out: Path | None = None,
) -> SessionConfig:
    """A session on ``rig`` holding the start pose while ``virtual`` plays into its controller,
    recorded to ``out`` (default: a new file in recordings/); ``source`` says where the trace
    came from (kept in the recording's config)."""
    return SessionConfig(
        out=session_path(out, f"{subject_id}-replay"),
        subject_id=subject_id,
        scenario="none",
        rig=rig,
        endpoints=endpoints,
        duration_s=virtual.delay_s + virtual.duration_s + RECOVER_S,
        trajectory="hold",
        loop=LoopConfig(rate_hz=rate_hz),
        virtual=virtual,
        virtual_source=source,
    )
