"""Turn per-tick states into events: collisions, recoveries, link faults, safety clamps.

Each event is emitted once, on the tick its condition changes, never every tick it holds, so
``/events`` reads as a log an experimenter can scan. Contact states are the controller's per
axis codes (Algorithm 2); the two axis groups are the Cartesian axes (0-2) and the joints (3-8).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from hilrig.control import ContactState
from hilrig.recording.samples import EventKind, EventRecord
from hilrig.tick.clamp_kernels import Clamp
from hilrig.tick.links import FRESH_AGAIN, STALE

GROUPS = (("end effector", 0), ("joints", 3))  # (name, first axis) of each axis group
#: What limiting a command does (docs/rig.md).
CLAMPED = " (the commanded motion was limited to stay safe)"


class EventDetector:
    """Remembers the last state of each condition and reports changes to ``on_event``."""

    def __init__(self, on_event: Callable[[EventRecord], None]) -> None:
        self._emit = on_event
        self._contact = [int(ContactState.FREE)] * len(GROUPS)
        self._links: dict[str, bool] = {}
        self._clamp = 0

    def contact(self, codes: NDArray[np.int8], t_ns: int) -> None:
        """Collision start (-> contact), end (-> recovering), recovered (recovering -> free)."""
        for index, (name, axis) in enumerate(GROUPS):
            now = int(codes[axis])
            before = self._contact[index]
            if now == before:
                continue
            self._contact[index] = now
            if now == ContactState.CONTACT and before != ContactState.HOLDING:
                self._emit(EventRecord(t_ns, EventKind.COLLISION_START, "controller", "", name))
            elif now == ContactState.RECOVERING:
                self._emit(EventRecord(t_ns, EventKind.COLLISION_END, "controller", "", name))
            elif now == ContactState.FREE and before == ContactState.RECOVERING:
                self._emit(EventRecord(t_ns, EventKind.RECOVERED, "controller", "", name))

    def link(self, device: str, ok: bool, t_ns: int) -> None:
        """A device's data going stale or coming back."""
        before = self._links.get(device, True)
        if ok == before:
            return
        self._links[device] = ok
        detail = FRESH_AGAIN if ok else STALE
        self._emit(EventRecord(t_ns, EventKind.FAULT, device, detail))

    def clamp(self, flags: int, t_ns: int) -> None:
        """The safety clamp engaging (or changing what it clamps)."""
        if flags == self._clamp:
            return
        self._clamp = flags
        if flags:
            self._emit(EventRecord(t_ns, EventKind.FAULT, "safety", CLAMP_DETAILS[flags]))

    def fault(self, source: str, detail: str, t_ns: int, *, value: float = float("nan")) -> None:
        """Any other fault, emitted as given."""
        self._emit(EventRecord(t_ns, EventKind.FAULT, source, detail, value=value))

    def mark(self, source: str, detail: str, t_ns: int) -> None:
        """An operator or session mark (not a fault)."""
        self._emit(EventRecord(t_ns, EventKind.OPERATOR_MARK, source, detail))


def clamp_names(flags: int) -> str:
    """The safety clamp's flags as words, e.g. ``velocity, acceleration`` (docs/rig.md)."""
    return ", ".join(CLAMP_WORDS[flag] for flag in Clamp if flags & flag)


CLAMP_WORDS = {
    Clamp.POSITION: "position limit",
    Clamp.VELOCITY: "velocity limit",
    Clamp.ACCELERATION: "acceleration limit",
    Clamp.WORKSPACE: "workspace box",
    Clamp.NON_FINITE: "non-finite target",
    Clamp.HOLDING: "controlled stop",
}

#: Each combination of the clamp's flags, as the detail of its event (made once: on the tick,
#: naming the flags took about 13 us)
CLAMP_DETAILS = tuple(
    f"clamp engaged: {clamp_names(flags)}{CLAMPED}" for flags in range(2 ** len(Clamp))
)
