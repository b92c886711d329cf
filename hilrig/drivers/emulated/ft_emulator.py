"""The Kunwei F/T sensor, emulated on a pseudo-terminal: byte-exact frames at a fixed rate.

The emulator owns a pty pair in raw mode and keeps a symlink to its slave at ``port_path``; a
driver opens that path with pyserial as it would ``/dev/ttyUSB0``. Like the real sensor it
streams only after the start command ``48 AA 0D 0A`` and stops on ``43 AA 0D 0A``. Frames are
paced by absolute deadlines on the monotonic clock at ``rate_hz``; a frame more than
``MAX_LATE_SLOTS`` periods late is skipped (counted), not burst out.

Each frame carries ``source(t_s)`` (the external wrench on the sensor, N and N*m, ``t_s`` the
frame's slot time in s since ``start()``) plus bias, Gaussian noise and the tool's gravity
wrench at ``orientation(t_s)`` (R_base_sensor), converted to kgf with ``kgf_scale``.

Faults, each applied by the emulator thread at the next frame: ``inject_garbage``,
``split_frames``, ``header_in_floats``, ``bad_values``, ``stall`` and ``drop_link`` (the pty is
closed and a new one made behind the same ``port_path`` after a pause, like an adapter unplugged
and plugged back; the sensor then waits for the start command again).

Runs as a thread (:class:`FtEmulator`, ``start()``/``stop()`` or ``with``) or as its own
process: ``python -m hilrig.drivers.emulated.ft_emulator --port-path /tmp/ft``.
"""

from __future__ import annotations

import argparse
import os
import select
import shutil
import signal
import struct
import tempfile
import threading
import time
import tty
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.ft_sensor import FRAME, HEADER, KGF_N, START_COMMAND, STOP_COMMAND, TAIL
from hilrig.drivers.gravity import STANDARD_GRAVITY_IN_BASE, ToolLoad

Source = Callable[[float], Sequence[float]]
Orientation = Callable[[float], NDArray[np.float64]]
SentHook = Callable[[float, int], None]  # (slot time t_s, monotonic ns just before the write)

MAX_LATE_SLOTS = 5
MAX_BACKLOG_BYTES = 4096  # unsent bytes beyond which whole frames are dropped
_IDLE_WAIT_NS = 20_000_000
_NOISE_BLOCK = 1024
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
    split_pause_s: float = 0.0003


@dataclass(slots=True)
class _Counters:
    frames_sent: int = 0
    frames_dropped: int = 0  # the pty was full (nobody reading): whole frames dropped
    slots_skipped: int = 0  # frame slots not sent: stalls, lateness, link down
    garbage_bytes: int = 0
    split_frames: int = 0
    header_frames: int = 0
    bad_value_frames: int = 0
    stalls: int = 0
    link_drops: int = 0
    starts: int = 0
    stops: int = 0


@dataclass(frozen=True, slots=True)
class EmulatorStats:
    """Counters since ``start()``; ``slots_skipped`` counts frames not sent (stalls, lateness)."""

    streaming: bool
    frames_sent: int
    frames_dropped: int
    slots_skipped: int
    garbage_bytes: int
    split_frames: int
    header_frames: int
    bad_value_frames: int
    stalls: int
    link_drops: int
    starts: int
    stops: int


class _Pty:
    """One raw pty pair; the slave stays open here so the master never reads EIO."""

    def __init__(self, link: Path) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        temporary = link.with_name(link.name + ".new")
        temporary.unlink(missing_ok=True)
        os.symlink(os.ttyname(self.slave), temporary)
        os.replace(temporary, link)

    def close(self, link: Path) -> None:
        link.unlink(missing_ok=True)
        os.close(self.master)
        os.close(self.slave)


class FtEmulator:
    """A Kunwei sensor on a pty; drivers open ``port_path`` (a temporary one unless given).

    ``on_sent(t_s, t_ns)``, if given, is called in the emulator thread after each frame with its
    slot time and the monotonic time just before its last byte was written (for latency
    measurement); it must be quick.
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
        if port_path is None:
            self._own_dir: Path | None = Path(tempfile.mkdtemp(prefix="hilrig-ft-"))
            self.port_path = self._own_dir / "tty"
        else:
            self._own_dir = None
            self.port_path = Path(port_path)
        self._source = source
        self._orientation = orientation
        self._on_sent = on_sent
        self._period_ns = round(1e9 / self.config.rate_hz)
        self._scale = 1.0 / self.config.kgf_scale
        self._bias = self.config.bias_in_sensor
        self._tool_map = self.config.tool.wrench_map()
        self._gravity = np.array(self.config.gravity_in_base, dtype=np.float64)
        self._rng = np.random.default_rng(self.config.seed)
        self._noise: list[list[float]] = []
        self._stop = threading.Event()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        self._thread = threading.Thread(target=self._run, daemon=True, name="ft-emulator")
        self._pty: _Pty | None = None
        self._rx = bytearray()
        self._tx = bytearray()
        self._counts = _Counters()
        self._streaming = False
        self._t0_ns = 0
        self._next_ns = 0
        self._up_at_ns: int | None = None
        # fault requests: set by any thread under _lock, taken by the emulator thread
        self._lock = threading.Lock()
        self._garbage = bytearray()
        self._split_left = 0
        self._header_left = 0
        self._bad_left = 0
        self._stall_ns = 0
        self._drop_ns: int | None = None

    # -- lifecycle ---------------------------------------------------------------------------

    def start(self) -> FtEmulator:
        """Create the pty and ``port_path`` and start the emulator thread; returns self."""
        self._pty = _Pty(self.port_path)
        self._t0_ns = time.monotonic_ns()
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread, close the pty and remove ``port_path`` (and its temporary folder)."""
        if self._wake_w < 0:
            return  # already stopped
        self._stop.set()
        self._wake()
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        if self._pty is not None:
            self._pty.close(self.port_path)
            self._pty = None
        for fd in (self._wake_r, self._wake_w):
            os.close(fd)
        self._wake_r = self._wake_w = -1
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)

    def __enter__(self) -> FtEmulator:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def stats(self) -> EmulatorStats:
        """A snapshot of the counters."""
        c = self._counts
        return EmulatorStats(
            self._streaming,
            c.frames_sent,
            c.frames_dropped,
            c.slots_skipped,
            c.garbage_bytes,
            c.split_frames,
            c.header_frames,
            c.bad_value_frames,
            c.stalls,
            c.link_drops,
            c.starts,
            c.stops,
        )

    # -- faults ------------------------------------------------------------------------------

    def inject_garbage(self, data: bytes) -> None:
        """Send ``data`` between two frames."""
        with self._lock:
            self._garbage += data
        self._wake()

    def split_frames(self, count: int) -> None:
        """Write each of the next ``count`` frames in two parts, ``split_pause_s`` apart."""
        with self._lock:
            self._split_left += count

    def header_in_floats(self, count: int) -> None:
        """Make the low two bytes of every float of the next ``count`` frames ``48 AA``.

        The values change by less than 1 % (only low mantissa bits), so the frames stay valid.
        """
        with self._lock:
            self._header_left += count

    def bad_values(self, count: int) -> None:
        """Send the next ``count`` frames with Fz NaN, inf or 1e30 kgf in turn (valid framing)."""
        with self._lock:
            self._bad_left += count

    def stall(self, duration_s: float) -> None:
        """Send nothing for ``duration_s``; the missed slots are skipped, not sent late."""
        with self._lock:
            self._stall_ns = round(duration_s * 1e9)
        self._wake()

    def drop_link(self, down_s: float) -> None:
        """Close the pty now and open a new one behind ``port_path`` after ``down_s``."""
        with self._lock:
            self._drop_ns = round(down_s * 1e9)
        self._wake()

    # -- the emulator thread -----------------------------------------------------------------

    def _wake(self) -> None:
        if self._wake_w >= 0:
            os.write(self._wake_w, b"\0")

    def _run(self) -> None:
        period = self._period_ns
        stall_until_ns = 0
        while not self._stop.is_set():
            now = time.monotonic_ns()
            with self._lock:
                drop_ns, self._drop_ns = self._drop_ns, None
                stall_ns, self._stall_ns = self._stall_ns, 0
            if stall_ns:
                stall_until_ns = now + stall_ns
                self._counts.stalls += 1
            if drop_ns is not None:
                self._link_down(now + drop_ns)
            if self._pty is None and self._up_at_ns is not None and now >= self._up_at_ns:
                self._pty = _Pty(self.port_path)
                self._up_at_ns = None
            sending = self._streaming and self._pty is not None and now >= stall_until_ns
            if sending and now >= self._next_ns:
                late_slots = (now - self._next_ns) // period
                if late_slots >= MAX_LATE_SLOTS:
                    self._next_ns += late_slots * period
                    self._counts.slots_skipped += late_slots
                self._send(self._next_ns)
                self._next_ns += period
                continue
            wait_ns = self._next_ns - now if sending else _IDLE_WAIT_NS
            if self._pty is None and self._up_at_ns is not None:
                wait_ns = min(wait_ns, self._up_at_ns - now)
            elif not sending and stall_until_ns > now:
                wait_ns = min(wait_ns, stall_until_ns - now)
            self._wait(wait_ns)

    def _wait(self, wait_ns: int) -> None:
        fds = [self._wake_r] if self._pty is None else [self._wake_r, self._pty.master]
        ready, _, _ = select.select(fds, [], [], max(wait_ns, 0) / 1e9)
        if self._wake_r in ready:
            os.read(self._wake_r, 4096)
        if self._pty is not None and self._pty.master in ready:
            self._read_commands(self._pty.master)

    def _read_commands(self, master: int) -> None:
        try:
            self._rx += os.read(master, 4096)
        except BlockingIOError:
            return
        rx = self._rx
        while len(rx) >= len(START_COMMAND):
            if rx.startswith(START_COMMAND):
                if not self._streaming:
                    self._streaming = True
                    self._counts.starts += 1
                    elapsed = time.monotonic_ns() - self._t0_ns
                    self._next_ns = self._t0_ns - (-elapsed // self._period_ns) * self._period_ns
                del rx[: len(START_COMMAND)]
            elif rx.startswith(STOP_COMMAND):
                if self._streaming:
                    self._streaming = False
                    self._counts.stops += 1
                del rx[: len(STOP_COMMAND)]
            else:
                del rx[0]  # not a command: the sensor ignores it

    def _link_down(self, up_at_ns: int) -> None:
        if self._pty is not None:
            self._pty.close(self.port_path)
            self._pty = None
            self._counts.link_drops += 1
        self._streaming = False  # the sensor restarts and waits for the start command
        self._rx.clear()
        self._tx.clear()
        self._up_at_ns = up_at_ns

    def _send(self, slot_ns: int) -> None:
        t_s = (slot_ns - self._t0_ns) * 1e-9
        values = self._device_values(t_s)
        with self._lock:
            garbage, self._garbage = self._garbage, bytearray()
            split, self._split_left = self._split_left > 0, max(self._split_left - 1, 0)
            header, self._header_left = self._header_left > 0, max(self._header_left - 1, 0)
            bad, self._bad_left = self._bad_left > 0, max(self._bad_left - 1, 0)
        counts = self._counts
        if header:
            values = [_with_header_bytes(v) for v in values]
            counts.header_frames += 1
        if bad:
            values[2] = _BAD_VALUES[counts.bad_value_frames % len(_BAD_VALUES)]
            counts.bad_value_frames += 1
        if len(self._tx) > MAX_BACKLOG_BYTES:
            counts.frames_dropped += 1
            return
        frame = FRAME.pack(HEADER, *values, TAIL)
        if garbage:
            self._tx += garbage
            counts.garbage_bytes += len(garbage)
        if split:
            cut = int(self._rng.integers(1, len(frame)))
            self._tx += frame[:cut]
            self._flush()
            time.sleep(self.config.split_pause_s)
            frame = frame[cut:]
            counts.split_frames += 1
        self._tx += frame
        sent_ns = time.monotonic_ns()
        self._flush()
        counts.frames_sent += 1
        if self._on_sent is not None:
            self._on_sent(t_s, sent_ns)

    def _flush(self) -> None:
        if self._pty is None:
            return
        try:
            written = os.write(self._pty.master, self._tx)
        except BlockingIOError:
            return
        del self._tx[:written]

    def _device_values(self, t_s: float) -> list[float]:
        """Source + bias + noise + tool gravity at ``t_s``, in device units (kgf, kgf*m)."""
        external = self._source(t_s)
        if not self._noise:
            std = [self.config.noise_force_n] * 3 + [self.config.noise_torque_nm] * 3
            self._noise = self._rng.normal(0.0, std, size=(_NOISE_BLOCK, 6)).tolist()
        noise = self._noise.pop()
        tool: Sequence[float] = (0.0,) * 6
        if self._orientation is not None:
            tool = (self._tool_map @ (self._gravity @ self._orientation(t_s))).tolist()
        scale = self._scale
        return [
            (e + b + n + g) * scale
            for e, b, n, g in zip(external, self._bias, noise, tool, strict=True)
        ]


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
