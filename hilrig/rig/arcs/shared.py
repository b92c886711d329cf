"""What crosses between the loop and the ARCS link's process: three shared-memory rings.

- ``commands`` (the loop produces, the link consumes): every tick's joint targets with their
  mode and the sensor sample they answer; the link's servo stream sends the newest one.
- ``states`` (the link produces, the loop consumes): every RTDE joint-state sample as a row of
  the loop's own :data:`~hilrig.drivers.robot_state.wire.STATE_DTYPE`, stamped on receipt.
- ``servo`` (the link produces, the loop consumes): every ``servoJoint`` call, its targets,
  when it left and returned, the controller's answer (:data:`~hilrig.rig.records.SERVO_DTYPE`);
  the loop passes them on to the recorder's ring of the same rows.

Rings are the recorder's (:mod:`hilrig.rig.rings`): no locks, no system calls, a full ring
refuses and counts. The loop creates all three (it outlives the link) and the link attaches.
:func:`take_rows` is a ring's consumer side in compiled code, into rows made once: the loop's
thread allocates nothing per tick to read them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.drivers.joint_targets.wire import Mode
from hilrig.drivers.robot_state.wire import JOINTS, STATE_DTYPE, RobotStatus
from hilrig.rig.records import SERVO_DTYPE
from hilrig.rig.rings import Ring, RingSpec
from hilrig.ring_kernels import READ_AT, WRITE_AT

COMMAND_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),  # when the tick wrote it
        ("source_ns", np.int64),  # the receive time of the sensor sample it answers (0: none)
        ("mode", np.int64),  # a Mode
        ("q", np.float64, (JOINTS,)),  # rad
    ]
)
COMMAND_ROWS = 4096  # 4 s of ticks at 1 kHz
STATE_ROWS = 4096  # 8 s at 500 Hz
SERVO_ROWS = 2048  # 10 s at 200 Hz

TRACK, HOLD, STOP = int(Mode.TRACK), int(Mode.HOLD), int(Mode.STOP)
NO_ANSWER = -1000  # a servo row's code when the call got no answer (not one of AUBO's codes)
# the status bits a joint-state row carries (RobotStatus), from the controller's modes
ENABLED, TRACKING = int(RobotStatus.ENABLED), int(RobotStatus.TRACKING)
PROTECTIVE_STOP, EMERGENCY_STOP = int(RobotStatus.PROTECTIVE_STOP), int(RobotStatus.EMERGENCY_STOP)
FAULT = int(RobotStatus.FAULT)


@dataclass(frozen=True)
class RingSpecs:
    """The three rings' names and shapes (picklable: handed to the link's process)."""

    commands: RingSpec
    states: RingSpec
    servo: RingSpec

    @classmethod
    def unique(cls) -> RingSpecs:
        return cls(
            RingSpec.unique("cmd", COMMAND_DTYPE, COMMAND_ROWS),
            RingSpec.unique("rtde", STATE_DTYPE, STATE_ROWS),
            RingSpec.unique("servo", SERVO_DTYPE, SERVO_ROWS),
        )


@dataclass
class Rings:
    """One process's ends of the three rings."""

    commands: Ring
    states: Ring
    servo: Ring

    @classmethod
    def create(cls, specs: RingSpecs) -> Rings:
        """Make the three rings (this process owns them)."""
        return cls._open(specs, Ring.create, owner=True)

    @classmethod
    def attach(cls, specs: RingSpecs) -> Rings:
        """Map the three rings another process made."""
        return cls._open(specs, Ring.attach, owner=False)

    @classmethod
    def _open(cls, specs: RingSpecs, opener: Callable[[RingSpec], Ring], *, owner: bool) -> Rings:
        made: list[Ring] = []
        try:
            for spec in (specs.commands, specs.states, specs.servo):
                made.append(opener(spec))
        except BaseException:
            _release(made, unlink=owner)
            raise
        return cls(*made)

    def close(self) -> None:
        """Unmap the rings here (and unlink them where they were made)."""
        rings = [self.commands, self.states, self.servo]
        _release(rings, unlink=rings[0].owner)


def _release(rings: list[Ring], *, unlink: bool) -> None:
    for ring in rings:
        ring.close()
        if unlink:
            ring.unlink()


@njit(cache=True)
def take_rows(slots: NDArray[np.void], header: NDArray[np.int64], out: NDArray[np.void]) -> int:
    """Copy the committed rows not read yet, oldest first, into ``out`` (at most its length;
    the rest stay for the next call) and release their slots; returns how many."""
    capacity = slots.shape[0]
    read = header[READ_AT]
    count = min(header[WRITE_AT] - read, out.shape[0])  # the index before the rows it publishes
    for i in range(count):
        out[i] = slots[(read + i) % capacity]
    header[READ_AT] = read + count  # after the copies: x86-64 keeps loads before later stores
    taken: int = count
    return taken


@njit(cache=True)
def newest_row(slots: NDArray[np.void], header: NDArray[np.int64], out: NDArray[np.void]) -> int:
    """Release every committed row not read yet and copy only the newest into ``out[0]``;
    returns how many rows were waiting (0: ``out`` untouched)."""
    capacity = slots.shape[0]
    read = header[READ_AT]
    count = header[WRITE_AT] - read
    if count > 0:
        out[0] = slots[(read + count - 1) % capacity]
        header[READ_AT] = read + count
    waiting: int = count
    return waiting
