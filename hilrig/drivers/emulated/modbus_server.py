"""The robot's Modbus RTU joint-target endpoint, emulated: pymodbus over loopback TCP.

RTU framing (CRC-16, no MBAP header) over a TCP socket on 127.0.0.1 with an OS-chosen port,
the way RTU-over-TCP gateways carry a serial bus. The server runs its asyncio loop in its own
thread; every accepted write of the register map is decoded and handed to ``on_targets`` (from
that thread). ``inject_exceptions`` makes the next writes fail with a Modbus exception code.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from concurrent.futures import Future

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from hilrig.drivers.joint_targets_map import JointTargets, RegisterMap

WRITE_MULTIPLE_REGISTERS = 16


class EmulatedModbusServer:
    """A Modbus RTU-over-TCP server holding the joint-target register map.

    ``start()`` returns once it listens; ``port`` is then the bound port. ``stop()`` closes it.
    """

    def __init__(
        self,
        on_targets: Callable[[JointTargets], None],
        *,
        register_map: RegisterMap | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        self._map = register_map or RegisterMap()
        self._on_targets = on_targets
        self._address = (host, port)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True, name="modbus")
        self._server: ModbusTcpServer | None = None
        self._fail_next = 0
        self._fail_code = ExcCodes.DEVICE_BUSY
        self.port = 0
        self.writes = 0
        self.exceptions_sent = 0
        self.rejected = 0

    def start(self) -> None:
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self._serve(), self._loop).result(timeout=10)

    def stop(self) -> None:
        if self._server is not None:
            done: Future[None] = asyncio.run_coroutine_threadsafe(
                self._server.shutdown(),  # type: ignore[no-untyped-call]
                self._loop,
            )
            done.result(timeout=10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)
        self._loop.close()

    def inject_exceptions(self, count: int, code: ExcCodes = ExcCodes.DEVICE_BUSY) -> None:
        """Answer the next ``count`` writes with Modbus exception ``code`` (nothing applied)."""
        self._fail_code = code
        self._fail_next = count

    def __enter__(self) -> EmulatedModbusServer:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop()

    async def _serve(self) -> None:
        device = SimDevice(
            id=self._map.device_id,
            simdata=[
                SimData(address=self._map.start, count=self._map.count, datatype=DataType.REGISTERS)
            ],
            action=self._action,
        )
        self._server = ModbusTcpServer(device, framer=FramerType.RTU, address=self._address)
        await self._server.serve_forever(background=True)
        listener = self._server.transport
        self.port = int(listener.sockets[0].getsockname()[1])  # type: ignore[attr-defined]

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        current_registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        if function_code != WRITE_MULTIPLE_REGISTERS or set_values is None:
            return None
        if self._fail_next > 0:
            self._fail_next -= 1
            self.exceptions_sent += 1
            return self._fail_code
        if address != self._map.start or count != self._map.count:
            self.rejected += 1
            return ExcCodes.ILLEGAL_ADDRESS
        try:
            targets = self._map.decode([int(v) for v in set_values])
        except ValueError:
            self.rejected += 1
            return ExcCodes.ILLEGAL_VALUE
        self.writes += 1
        self._on_targets(targets)
        return None
