"""The joint-target holding-register map (docs/protocols.md), as data.

Written with Modbus function 16 (write multiple registers) in one transaction::

    address count field
    0       12    six float32 joint targets, rad (IEEE 754, big-endian words and bytes)
    12      1     sequence / watchdog counter, uint16, +1 per write (wraps)
    13      1     mode (Mode)

The robot follows the targets only in mode TRACK and only while the counter keeps changing;
a counter that stops for longer than the robot's watchdog makes it hold position. A real
controller with another map plugs in a different ``RegisterMap``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum

from hilrig.errors import DriverError, ProtocolError

JOINTS = 6


class Mode(IntEnum):
    """What the robot does with the targets."""

    HOLD = 0  # hold the current position, ignore targets
    TRACK = 1  # follow the targets
    STOP = 2  # protective stop: hold and latch until told otherwise


@dataclass(frozen=True)
class JointTargets:
    """One write: targets (rad), counter, mode."""

    q_rad: tuple[float, ...]
    sequence: int
    mode: Mode


@dataclass(frozen=True)
class RegisterMap:
    """Where each field lives: ``{name: (address, count)}`` plus the device id."""

    targets: tuple[int, int] = (0, 2 * JOINTS)
    sequence: tuple[int, int] = (12, 1)
    mode: tuple[int, int] = (13, 1)
    device_id: int = 1

    @property
    def start(self) -> int:
        """First register of the block written in one transaction."""
        return min(self.targets[0], self.sequence[0], self.mode[0])

    @property
    def count(self) -> int:
        """Registers in the block written in one transaction."""
        end = max(sum(self.targets), sum(self.sequence), sum(self.mode))
        return end - self.start

    def encode(self, targets: JointTargets) -> list[int]:
        """The register values of one write (raises DriverError on non-finite targets)."""
        if len(targets.q_rad) != JOINTS or not all(math.isfinite(q) for q in targets.q_rad):
            raise DriverError(f"joint targets must be {JOINTS} finite values, got {targets.q_rad}")
        registers = [0] * self.count
        raw = struct.pack(f">{JOINTS}f", *targets.q_rad)
        words = struct.unpack(f">{2 * JOINTS}H", raw)
        at = self.targets[0] - self.start
        registers[at : at + 2 * JOINTS] = words
        registers[self.sequence[0] - self.start] = targets.sequence & 0xFFFF
        registers[self.mode[0] - self.start] = int(targets.mode)
        return registers

    def decode(self, registers: list[int]) -> JointTargets:
        """The inverse of ``encode`` (raises ProtocolError on an unknown mode or a target that
        is not finite: no robot takes those): precompiled structs, one finiteness check of the
        sum (float32 values cannot overflow it), the mode by table. The emulated robot's
        whole-map writes take ``frame.RequestReader`` instead, held to this in the tests."""
        start = self.start
        at = self.targets[0] - start
        q = _FLOATS.unpack(_WORDS.pack(*registers[at : at + 2 * JOINTS]))
        if not math.isfinite(sum(q)):
            raise ProtocolError(f"joint targets: not finite {q}")
        code = registers[self.mode[0] - start]
        mode = _MODES.get(code)
        if mode is None:
            raise ProtocolError(f"joint targets: unknown mode {code}")
        return JointTargets(q, registers[self.sequence[0] - start], mode)


_WORDS = struct.Struct(f">{2 * JOINTS}H")
_FLOATS = struct.Struct(f">{JOINTS}f")
_MODES = {int(mode): mode for mode in Mode}
