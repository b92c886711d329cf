"""Joint targets to the robot over Modbus RTU (function 16), from a latest-value writer thread.

``write(q_rad)`` never blocks: it stores the newest targets and wakes the writer thread, which
writes the register map (joint_targets_map.py) with a fresh watchdog counter. Targets replaced
before they were written are counted as superseded (latest-value semantics: the robot should
only ever get the newest). Modbus exception replies become ModbusExceptionError, counted by
code; timeouts and lost links are counted and the link is reopened with backoff. No exception
escapes the thread: the last one is kept in ``last_error``.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusException

from hilrig.drivers.base import LinkStatus, Writer
from hilrig.drivers.joint_targets_map import JOINTS, JointTargets, Mode, RegisterMap
from hilrig.errors import LinkError, ModbusExceptionError


class ModbusClient(Protocol):
    """The part of a pymodbus sync client the writer uses."""

    def connect(self) -> bool: ...
    def close(self) -> None: ...
    def write_registers(self, address: int, values: list[int], *, device_id: int = 1) -> object: ...


@dataclass(frozen=True)
class ModbusEndpoint:
    """Where the joint-target registers are: RTU over TCP (host, port) or a serial port path."""

    host: str = "127.0.0.1"
    port: int = 502
    serial_port: str | None = None  # e.g. /dev/ttyUSB0; set to use the serial bus instead
    baudrate: int = 115200
    timeout_s: float = 0.05
    retries: int = 1

    def client(self) -> ModbusClient:
        """A pymodbus client with RTU framing for this endpoint (not yet connected)."""
        if self.serial_port is not None:
            return ModbusSerialClient(
                self.serial_port,
                framer=FramerType.RTU,
                baudrate=self.baudrate,
                timeout=self.timeout_s,
                retries=self.retries,
            )
        return ModbusTcpClient(
            self.host,
            port=self.port,
            framer=FramerType.RTU,
            timeout=self.timeout_s,
            retries=self.retries,
            reconnect_delay=0.0,
        )

    def __str__(self) -> str:
        return self.serial_port or f"rtu+tcp://{self.host}:{self.port}"


@dataclass
class WriterStats:
    """Counters since the writer started; ``exceptions`` counts Modbus exception codes."""

    submitted: int = 0
    written: int = 0
    superseded: int = 0
    refused: int = 0  # submits with non-finite targets, never sent
    timeouts: int = 0
    reconnects: int = 0
    exceptions: dict[int, int] = field(default_factory=dict)
    last_write_ns: int = 0  # time.monotonic_ns() when the last write was acknowledged
    last_latency_ns: int = 0  # submit -> acknowledged, of the last write
    last_source_ns: int = 0  # the source time given with the last acknowledged write (or 0)


class JointTargetsWriter(Writer[ArrayLike]):
    """Writes the newest joint targets to the robot; ``with writer:`` connects and closes."""

    def __init__(
        self,
        endpoint: ModbusEndpoint,
        *,
        register_map: RegisterMap | None = None,
        backoff_s: tuple[float, float] = (0.01, 1.0),
    ) -> None:
        self.endpoint = endpoint
        self._map = register_map or RegisterMap()
        self._backoff_s = backoff_s
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._linked = threading.Event()
        self._pending: tuple[NDArray[np.float64], Mode, int, int] | None = None
        self._sequence = 0
        self._thread: threading.Thread | None = None
        self.stats = WriterStats()
        self.errors = 0
        self.last_error: Exception | None = None

    def connect(self, *, timeout_s: float | None = 1.0) -> None:
        """Start the writer thread; wait until the link is open if asked.

        Raises LinkError if the endpoint cannot be reached within ``timeout_s`` (None: do not
        wait; the thread keeps trying with backoff).
        """
        if self.is_connected:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, daemon=True, name="joint-targets")
        self._thread.start()
        if timeout_s is not None and not self._linked.wait(timeout_s):
            self.close()
            raise LinkError(f"cannot connect to Modbus {self.endpoint} within {timeout_s} s")

    def close(self) -> None:
        """Stop the thread (after the write in flight) and close the link. Idempotent."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    @property
    def is_connected(self) -> bool:
        """True while the thread runs and the link is open."""
        return self._thread is not None and self._thread.is_alive() and self._linked.is_set()

    def write(self, value: ArrayLike, mode: Mode = Mode.TRACK, *, source_ns: int = 0) -> None:
        """Queue the newest joint targets (6, rad); never blocks.

        ``source_ns`` (monotonic) is when the input these targets answer arrived, e.g. the F/T
        frame; it comes back as ``stats.last_source_ns`` once the write is acknowledged, so the
        caller can measure sensor-to-command latency. Non-finite targets are refused (counted in
        ``stats.refused``), never sent.
        """
        q = np.array(value, dtype=np.float64).reshape(JOINTS)  # a copy: the caller may reuse
        if not np.isfinite(q).all():
            self.stats.refused += 1
            return
        now = time.monotonic_ns()
        with self._lock:
            if self._pending is not None:
                self.stats.superseded += 1
            self._pending = (q, mode, now, source_ns)
            self.stats.submitted += 1
        self._wake.set()

    def status(self) -> LinkStatus:
        """Link health; ``samples`` counts acknowledged writes, ``age_ns`` the last one's age."""
        last = self.stats.last_write_ns
        return LinkStatus(
            endpoint=str(self.endpoint),
            connected=self.is_connected,
            samples=self.stats.written,
            rate_hz=0.0,
            age_ns=None if last == 0 else time.monotonic_ns() - last,
            stalls=0,
            reconnects=self.stats.reconnects,
            errors=self.errors,
            last_error="" if self.last_error is None else str(self.last_error),
        )

    def _take(self) -> tuple[NDArray[np.float64], Mode, int, int] | None:
        with self._lock:
            pending, self._pending = self._pending, None
        return pending

    def _run(self) -> None:
        client: ModbusClient | None = None
        delay_s = self._backoff_s[0]
        while not self._stop.is_set():
            try:
                if client is None:
                    client = self._open()
                    if client is None:
                        self._stop.wait(delay_s)
                        delay_s = min(2 * delay_s, self._backoff_s[1])
                        continue
                    delay_s = self._backoff_s[0]
                self._wake.wait(0.1)
                self._wake.clear()
                pending = self._take()
                if pending is not None and not self._write(client, *pending):
                    self._drop(client)
                    client = None
            except Exception as err:  # whatever happens (even a bug), the thread carries on
                self.errors += 1
                self.last_error = err
                if client is not None:
                    self._drop(client)
                    client = None
        if client is not None:
            client.close()
        self._linked.clear()

    def _open(self) -> ModbusClient | None:
        client = self.endpoint.client()
        if client.connect():
            self._linked.set()
            return client
        self.last_error = LinkError(f"cannot connect to Modbus {self.endpoint}")
        client.close()
        return None

    def _drop(self, client: ModbusClient) -> None:
        client.close()
        self._linked.clear()
        self.stats.reconnects += 1

    def _write(
        self,
        client: ModbusClient,
        q: NDArray[np.float64],
        mode: Mode,
        submitted_ns: int,
        source_ns: int,
    ) -> bool:
        """One write; False when the link must be reopened."""
        self._sequence = (self._sequence + 1) & 0xFFFF
        registers = self._map.encode(JointTargets(tuple(q.tolist()), self._sequence, mode))
        try:
            reply = client.write_registers(
                self._map.start, registers, device_id=self._map.device_id
            )
        except ModbusException as err:
            self.stats.timeouts += 1
            self.errors += 1
            self.last_error = LinkError(f"Modbus {self.endpoint}: {err}")
            return False
        if getattr(reply, "isError", lambda: False)():
            code = int(getattr(reply, "exception_code", 0))
            self.stats.exceptions[code] = self.stats.exceptions.get(code, 0) + 1
            self.errors += 1
            name = ExcCodes(code).name if code in ExcCodes._value2member_map_ else "UNKNOWN"
            self.last_error = ModbusExceptionError(
                code, name, f"write of joint targets #{self._sequence} to {self.endpoint}"
            )
            return True
        now = time.monotonic_ns()
        self.stats.written += 1
        self.stats.last_write_ns = now
        self.stats.last_latency_ns = now - submitted_ns
        self.stats.last_source_ns = source_ns
        return True
