"""The Kunwei F/T sensor, emulated on a pseudo-terminal: byte-exact frames, one per slot.

The emulator owns a pty pair in raw mode and keeps a symlink to its slave at ``port_path``; a
driver opens that path with pyserial as it would ``/dev/ttyUSB0``. The link is made only where
nothing is (an existing file, device node or link is refused, never replaced) and removed only
while it is still the emulator's own. Like the real sensor it
streams only after the start command ``48 AA 0D 0A`` and stops on ``43 AA 0D 0A``.

It is a device of a :class:`SlotLoop`: ``attach(loop)`` makes the pty and has the loop read
commands as they arrive; ``tick(slot_ns)`` sends that slot's frame. The emulated rig drives it
in its one thread; ``start()``/``stop()`` (or ``with``) run it alone in a loop thread of its own,
and ``python -m hilrig.emulator.ft_emulator --port-path /tmp/ft`` as its own process.

Each frame carries ``source(t_s)`` (the external wrench on the sensor, N and N*m, ``t_s`` the
frame's slot time in s since the loop started) plus bias, Gaussian noise and the tool's gravity
wrench at ``orientation(t_s)`` (R_base_sensor), converted to kgf with ``kgf_scale``. A frame that
finds more than ``MAX_BACKLOG_BYTES`` unsent (nobody reading) is dropped whole (counted).

Faults, requested from any thread and applied at the next slot: ``inject_garbage``,
``split_frames`` (the frame's tail follows one slot later), ``header_in_floats``,
``bad_values``, ``stall`` and ``drop_link`` (the pty is closed and a new one made behind the same
``port_path`` after a pause, like an adapter unplugged and plugged back; the sensor then waits
for the start command again). Frames still unread in a pty when it closes are lost with it.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import struct
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.ft.gravity import STANDARD_GRAVITY_IN_BASE, ToolLoad
from hilrig.drivers.ft.wire import FRAME, HEADER, KGF_N, START_COMMAND, STOP_COMMAND, TAIL
from hilrig.emulator.frame_kernels import ft_frame_into
from hilrig.emulator.outbox import Outbox
from hilrig.emulator.pty_link import PtyLink
from hilrig.emulator.slots import Device, SlotLoop
from hilrig.timing import bound_kernel

Source = Callable[[float], Sequence[float]]
Orientation = Callable[[float], NDArray[np.float64]]
SentHook = Callable[[float, int], None]  # (slot time t_s, monotonic ns just before the write)

MAX_BACKLOG_BYTES = 4096  # unsent bytes beyond which whole frames are dropped
_NOISE_BLOCK = 64  # rows drawn at once: 1024 took 0.4-1 ms of one slot on a slow machine
_FLOAT = struct.Struct("<f")
_WORD = struct.Struct("<I")
_BAD_VALUES = (float("nan"), float("inf"), 1e30)


def no_contact(t_s: float) -> tuple[float, ...]:
    """The default source: no external wrench at any time."""
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class EmulatorConfig:
    """Rate (Hz), unit scale (N per kgf), noise rms per axis, bias (N, N*m), tool and gravity."""

    rate_hz: float = 1000.0
    kgf_scale: float = KGF_N
    noise_force_n: float = 0.0
    noise_torque_nm: float = 0.0
    bias_in_sensor: tuple[float, float, float, float, float, float] = (0.0,) * 6
    tool: ToolLoad = field(default_factory=ToolLoad)
    gravity_in_base: tuple[float, float, float] = STANDARD_GRAVITY_IN_BASE
    seed: int = 0


@dataclass(frozen=True, slots=True)
class EmulatorStats:
    """Counters since start; ``slots_skipped`` counts slots not sent while streaming (stalls)."""

    streaming: bool
    frames_sent: int  # handed whole to the pty
    frames_dropped: int  # the pty was full (nobody reading) or closed under them
    slots_skipped: int
    garbage_bytes: int
    split_frames: int
    header_frames: int
    bad_value_frames: int
    stalls: int
    link_drops: int
    starts: int
    stops: int


class FtEmulator(Device):
    """A Kunwei sensor on a pty; drivers open ``port_path`` (a temporary one unless given).

    ``on_sent(t_s, t_ns)``, if given, is called after each frame written whole at once with its
    slot time and the monotonic time just before the write (latency measurement); quick.
    """

    def __init__(
        self,
        source: Source = no_contact,
        *,
        config: EmulatorConfig | None = None,
        orientation: Orientation | None = None,
        port_path: str | Path | None = None,
        on_sent: SentHook | None = None,
    ) -> None:
        self.config = EmulatorConfig() if config is None else config
        self.standalone_period_ns = round(1e9 / self.config.rate_hz)
        self.thread_name = "ft-emulator"
        if port_path is None:
            self._own_dir: Path | None = Path(tempfile.mkdtemp(prefix="hilrig-ft-"))
            self.port_path = self._own_dir / "tty"
        else:
            self._own_dir = None
            self.port_path = Path(port_path)
        self._source = source
        self._orientation = orientation
        self._on_sent = on_sent
        self._scale = 1.0 / self.config.kgf_scale
        self._rng = np.random.default_rng(self.config.seed)
        self._noise = np.zeros((_NOISE_BLOCK, 6))  # drawn a block at a time, used last row first
        self._noise_rows = 0  # rows of the block not used yet
        noise = self.config
        self._noise_std = np.array([noise.noise_force_n] * 3 + [noise.noise_torque_nm] * 3)
        self._wrench = np.zeros(6)  # the source's, this slot
        self._rotation = np.zeros((3, 3))  # R_base_sensor, this slot
        self._values = np.zeros(6)  # this slot's device values (kgf, kgf*m)
        self._frame = np.frombuffer(bytearray(FRAME.pack(HEADER, *self._values, TAIL)), np.uint8)
        self._make_frame = bound_kernel(
            ft_frame_into,
            self._frame,
            self._values,
            np.zeros(6, dtype=np.float32),
            self._wrench,
            np.array(self.config.bias_in_sensor, dtype=np.float64),
            self._noise,
            self._rotation,
            np.array(self.config.gravity_in_base, dtype=np.float64),
            np.ascontiguousarray(self.config.tool.wrench_map(), dtype=np.float64),
            last=(0, True, 1.0),
        )
        self._requests: deque[Callable[[int], None]] = deque()  # faults, applied by tick()
        self._loop: SlotLoop | None = None
        self._pty: PtyLink | None = None
        self._out = Outbox(lambda data: 0, MAX_BACKLOG_BYTES)
        self._sent_before = self._dropped_before = 0  # by the outboxes of closed ptys
        self._rx = bytearray()
        self._streaming = False
        self._t0_ns = 0
        self._up_at_ns: int | None = None
        self._stall_until_ns = 0
        self._tail = b""  # the second part of a split frame, sent at the next slot
        self._split_left = self._header_left = self._bad_left = 0
        self.slots_skipped = self.garbage_bytes = self.split_count = 0
        self.header_frames = self.bad_value_frames = 0
        self.stalls = self.link_drops = self.starts = self.stops = 0

    # -- as a device of a slot loop ----------------------------------------------------------

    def attach(self, loop: SlotLoop) -> None:
        """Create the pty and ``port_path``; ``loop`` reads its commands from now on."""
        self._loop = loop
        self._t0_ns = loop.t0_ns
        self._link_up()

    def tick(self, slot_ns: int) -> None:
        """Apply requested faults, then send this slot's frame if streaming."""
        while self._requests:
            self._requests.popleft()(slot_ns)
        if self._pty is None:
            if self._up_at_ns is not None and slot_ns >= self._up_at_ns:
                self._link_up()
            return
        if self._tail:
            self._out.put(self._tail)
            self._tail = b""
        if not self._streaming:
            return
        if slot_ns < self._stall_until_ns:
            self.slots_skipped += 1
            return
        self._send(slot_ns)

    def close(self) -> None:
        """Close the pty and remove ``port_path`` (and its temporary folder)."""
        self._link_down()
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)

    def stats(self) -> EmulatorStats:
        """A snapshot of the counters."""
        return EmulatorStats(
            self._streaming,
            self._sent_before + self._out.frames_sent,
            self._dropped_before + self._out.frames_dropped,
            self.slots_skipped,
            self.garbage_bytes,
            self.split_count,
            self.header_frames,
            self.bad_value_frames,
            self.stalls,
            self.link_drops,
            self.starts,
            self.stops,
        )

    # -- faults (any thread) -----------------------------------------------------------------

    def inject_garbage(self, data: bytes) -> None:
        """Send ``data`` between two frames."""
        self._requests.append(lambda _: self._garbage(bytes(data)))

    def split_frames(self, count: int) -> None:
        """Write each of the next ``count`` frames in two parts, one slot apart."""
        self._requests.append(lambda _: setattr(self, "_split_left", self._split_left + count))

    def header_in_floats(self, count: int) -> None:
        """Make the low two bytes of every float of the next ``count`` frames ``48 AA``.

        The values change by less than 1 % (only low mantissa bits), so the frames stay valid.
        """
        self._requests.append(lambda _: setattr(self, "_header_left", self._header_left + count))

    def bad_values(self, count: int) -> None:
        """Send the next ``count`` frames with Fz NaN, inf or 1e30 kgf in turn (valid framing)."""
        self._requests.append(lambda _: setattr(self, "_bad_left", self._bad_left + count))

    def stall(self, duration_s: float) -> None:
        """Send nothing for ``duration_s``; the missed slots are skipped, not sent late."""
        self._requests.append(lambda slot_ns: self._stall(slot_ns + round(duration_s * 1e9)))

    def drop_link(self, down_s: float) -> None:
        """Close the pty now and open a new one behind ``port_path`` after ``down_s``."""
        self._requests.append(lambda slot_ns: self._drop(slot_ns + round(down_s * 1e9)))

    # -- internals (the loop's thread) -------------------------------------------------------

    def _garbage(self, data: bytes) -> None:
        if self._pty is not None:
            self._out.put(data, frame=False)
            self.garbage_bytes += len(data)

    def _stall(self, until_ns: int) -> None:
        self._stall_until_ns = until_ns
        self.stalls += 1

    def _drop(self, up_at_ns: int) -> None:
        if self._pty is not None:
            self.link_drops += 1
        self._link_down()
        self._up_at_ns = up_at_ns

    def _link_up(self) -> None:
        assert self._loop is not None
        pty = self._pty = PtyLink(self.port_path)
        self._out = Outbox(pty.write, MAX_BACKLOG_BYTES)
        self._up_at_ns = None
        self._loop.watch(pty.master, self._read_commands)

    def _link_down(self) -> None:
        if self._pty is not None:
            if self._loop is not None:
                self._loop.unwatch(self._pty.master)
            self._out.discard()
            self._sent_before += self._out.frames_sent
            self._dropped_before += self._out.frames_dropped
            self._out = Outbox(lambda data: 0, MAX_BACKLOG_BYTES)
            self._pty.close(self.port_path)
            self._pty = None
        self._streaming = False  # the sensor restarts and waits for the start command
        self._rx.clear()
        self._tail = b""

    def _read_commands(self) -> None:
        assert self._pty is not None
        try:
            self._rx += os.read(self._pty.master, 4096)
        except BlockingIOError:
            return
        rx = self._rx
        while len(rx) >= len(START_COMMAND):
            if rx.startswith(START_COMMAND):
                if not self._streaming:
                    self._streaming = True
                    self.starts += 1
                del rx[: len(START_COMMAND)]
            elif rx.startswith(STOP_COMMAND):
                if self._streaming:
                    self._streaming = False
                    self.stops += 1
                del rx[: len(STOP_COMMAND)]
            else:
                del rx[0]  # not a command: the sensor ignores it

    def _send(self, slot_ns: int) -> None:
        t_s = (slot_ns - self._t0_ns) * 1e-9
        self._device_values(t_s)
        if self._header_left or self._bad_left:
            frame = self._faulty_frame()
        else:
            frame = self._frame.tobytes()
        if self._split_left:
            self._split_left -= 1
            cut = int(self._rng.integers(1, len(frame)))
            self._out.put(frame[:cut], frame=False)
            self._tail = frame[cut:]
            self.split_count += 1
            return
        if self._on_sent is None:
            self._out.put(frame)
            return
        sent, sent_ns = self._out.frames_sent, time.monotonic_ns()
        self._out.put(frame)
        if self._out.frames_sent > sent:
            self._on_sent(t_s, sent_ns)

    def _device_values(self, t_s: float) -> None:
        """Source + bias + noise + tool gravity at ``t_s``, in device units (kgf, kgf*m), into
        ``_values`` and the frame's bytes (one compiled call)."""
        self._wrench[:] = self._source(t_s)
        if not self._noise_rows:  # in place: normal(0, std) is std times the standard draw
            self._rng.standard_normal(out=self._noise)
            self._noise *= self._noise_std
            self._noise_rows = _NOISE_BLOCK
        self._noise_rows -= 1
        if self._orientation is not None:
            self._rotation[...] = self._orientation(t_s)
        self._make_frame(self._noise_rows, self._orientation is not None, self._scale)

    def _faulty_frame(self) -> bytes:
        """This slot's frame with the faults asked for: header bytes inside the floats, or a
        value that is not one."""
        values = self._values.tolist()
        if self._header_left:
            self._header_left -= 1
            values = [_with_header_bytes(v) for v in values]
            self.header_frames += 1
        if self._bad_left:
            self._bad_left -= 1
            values[2] = _BAD_VALUES[self.bad_value_frames % len(_BAD_VALUES)]
            self.bad_value_frames += 1
        return FRAME.pack(HEADER, *values, TAIL)


def _with_header_bytes(value: float) -> float:
    """``value`` with its float32 low two bytes (little-endian) set to the header ``48 AA``."""
    (word,) = _WORD.unpack(_FLOAT.pack(value))
    (out,) = _FLOAT.unpack(_WORD.pack((word & 0xFFFF0000) | 0xAA48))
    return float(out)


def main(argv: Sequence[str] | None = None) -> int:
    """Run an emulated sensor (no contact, optional noise and bias) until SIGINT or SIGTERM."""
    parser = argparse.ArgumentParser(description="Emulated Kunwei F/T sensor on a pty.")
    parser.add_argument("--port-path", default=None, help="symlink to create (default: temporary)")
    parser.add_argument("--rate-hz", type=float, default=1000.0)
    parser.add_argument("--kgf-scale", type=float, default=KGF_N)
    parser.add_argument("--noise-force-n", type=float, default=0.0)
    parser.add_argument("--noise-torque-nm", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    config = EmulatorConfig(
        rate_hz=args.rate_hz,
        kgf_scale=args.kgf_scale,
        noise_force_n=args.noise_force_n,
        noise_torque_nm=args.noise_torque_nm,
        seed=args.seed,
    )
    done = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: done.set())
    with FtEmulator(config=config, port_path=args.port_path) as emulator:
        print(f"F/T emulator at {args.rate_hz:g} Hz on {emulator.port_path}", flush=True)
        done.wait()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
