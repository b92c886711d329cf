"""The emulated rig in a child process, so its device threads never compete with the loop's GIL.

``RigProcess(scenario).start()`` spawns a process that runs :class:`EmulatedRig` and returns its
endpoints; ``stop()`` ends it. The child ignores SIGINT (the parent handles Ctrl-C and stops it
in order) and exits by itself when the parent goes away.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import signal
from multiprocessing.connection import Connection

from hilrig.drivers.emulated.rig import EmulatedRig, RigConfig, RigEndpoints
from hilrig.errors import HilrigError, LinkError

# The faults a parent may inject: "part.method" of the EmulatedRig.
FAULTS = frozenset(
    {
        "ft.stall",
        "ft.drop_link",
        "ft.inject_garbage",
        "ft.split_frames",
        "ft.bad_values",
        "robot_state.stall",
        "robot_state.drop_links",
        "robot_state.inject",
        "modbus.inject_exceptions",
    }
)


def _serve(conn: Connection, scenario: str, config: RigConfig) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    rig = EmulatedRig(scenario, config=config)
    conn.send(rig.start())
    try:
        while True:
            message = conn.recv()  # EOFError when the parent is gone
            if message == "stop":
                break
            name, args = message
            part, method = name.split(".")
            getattr(getattr(rig, part), method)(*args)
            conn.send("ok")
    except EOFError:
        pass
    finally:
        rig.stop()


class RigProcess:
    """An emulated rig in its own process; ``with RigProcess(...) as endpoints:``."""

    def __init__(self, scenario: str, *, config: RigConfig | None = None) -> None:
        context = mp.get_context("spawn")  # the parent has threads: never fork it
        self._conn, child = context.Pipe()
        self._process = context.Process(
            target=_serve,
            args=(child, scenario, config or RigConfig()),
            name="hilrig-emulated-rig",
            daemon=True,
        )
        self._child = child

    def start(self, timeout_s: float = 60.0) -> RigEndpoints:
        """Spawn the rig and wait for its endpoints; raises LinkError if it does not come up."""
        self._process.start()
        self._child.close()
        if not self._conn.poll(timeout_s):
            self.stop()
            raise LinkError(f"the emulated rig did not start within {timeout_s} s")
        endpoints: RigEndpoints = self._conn.recv()
        return endpoints

    def stop(self) -> None:
        """Stop the rig (its devices close in order) and join the process."""
        if self._process.is_alive():
            with contextlib.suppress(OSError):  # the rig may be gone already
                self._conn.send("stop")
            self._process.join(timeout=10)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout=5)
        self._conn.close()

    def fault(self, name: str, *args: object) -> None:
        """Inject fault ``name`` (one of FAULTS, e.g. "ft.stall", 0.05) into the running rig."""
        if name not in FAULTS:
            raise HilrigError(f"unknown fault {name!r}; known: {', '.join(sorted(FAULTS))}")
        self._conn.send((name, args))
        if not self._conn.poll(10) or self._conn.recv() != "ok":
            raise LinkError(f"the emulated rig did not take fault {name}")

    @property
    def pid(self) -> int | None:
        return self._process.pid

    def __enter__(self) -> RigEndpoints:
        return self.start()

    def __exit__(self, *_: object) -> None:
        self.stop()
