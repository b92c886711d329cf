"""What the loop needs of a robot link, whichever controller is behind it.

A robot link is two things the loop's thread polls, never waiting: the robot's joint states
(:class:`JointStateSource`, rows of :data:`~hilrig.drivers.robot_state.wire.STATE_DTYPE`) and
its joint targets (:class:`JointTargetSink`). Both the Modbus pair
(:class:`~hilrig.drivers.robot_state.link.RobotStateClient`,
:class:`~hilrig.drivers.joint_targets.link.JointTargetsWriter`) and AUBO's ARCS interface
(:mod:`hilrig.rig.arcs.link`) have this shape; :mod:`hilrig.rig.robot_links` chooses which.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.base import LinkStatus
from hilrig.drivers.joint_targets.wire import Mode


class JointStateSource(Protocol):
    """The robot's joint states: ``poll`` returns those received since the last poll (rows of
    ``rows``, which the next poll reuses); ``newest`` is the newest row, kept current in place
    (the compiled tick reads it there)."""

    rows: NDArray[np.void]
    newest: NDArray[np.void]

    def poll(self, now_ns: int) -> NDArray[np.void]: ...

    def latest(self) -> np.void | None: ...

    def status(self) -> LinkStatus:
        """The link's counts (``samples``: the states received since it connected)."""
        ...

    def close(self) -> None: ...


class TargetStats(Protocol):
    """How many targets left and were accepted, and when the last did (monotonic ns), with the
    receive time of the sensor sample each answered."""

    sent: int
    written: int
    last_sent_ns: int
    last_sent_source_ns: int
    last_write_ns: int
    last_source_ns: int


class JointTargetSink(Protocol):
    """The robot's joint targets: ``write`` never blocks; ``poll`` takes replies; ``errors``
    counts failed writes (the last one's reason in ``last_error``)."""

    @property
    def stats(self) -> TargetStats: ...

    @property
    def errors(self) -> int: ...

    @property
    def last_error(self) -> object:
        """The last failure (its ``str`` is one line), or None/"" before the first."""
        ...

    def write(
        self, q_rad: NDArray[np.float64], mode: Mode = Mode.TRACK, *, source_ns: int = 0
    ) -> None: ...

    def poll(self, now_ns: int) -> None: ...

    def close(self) -> None: ...
