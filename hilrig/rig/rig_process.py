"""The emulated rig in a child process, so its device loop never competes with the loop's GIL.

``RigProcess(scenario).start()`` spawns a process that opens an :class:`EmulatedRig` and
returns its endpoints. The child runs the rig's one slot loop in its main thread (real-time
priority where permitted, see :mod:`hilrig.drivers.emulated.slots`), with this pipe among the
descriptors it waits on: faults and counter requests are served between slots, no other thread.
``counters()`` returns what the rig has sent so far; ``stop()`` ends it and returns the final
counts (after its devices closed), also kept in ``final_counters``. The child ignores SIGINT
(the parent handles Ctrl-C and stops it in order) and stops by itself when the parent goes away.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import signal
import threading
from multiprocessing.connection import Connection

from hilrig.drivers.emulated.rig import EmulatedRig, RigConfig, RigCounters, RigEndpoints
from hilrig.errors import HilrigError, LinkError

__all__ = ["FAULTS", "RigCounters", "RigProcess"]

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
REPLY_TIMEOUT_S = 10.0


def _serve(conn: Connection, scenario: str, config: RigConfig) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    rig = EmulatedRig(scenario, config=config)
    conn.send(rig.open())

    def on_message() -> None:
        try:
            message = conn.recv()
        except EOFError:  # the parent is gone
            rig.request_stop()
            return
        if message == "stop":
            rig.request_stop()
        elif message == "counters":
            conn.send(rig.counters())
        else:
            name, args = message
            part, method = name.split(".")
            getattr(getattr(rig, part), method)(*args)
            conn.send("ok")

    rig.loop.watch(conn.fileno(), on_message)
    try:
        rig.run()
    finally:
        rig.loop.unwatch(conn.fileno())
        rig.close()
        with contextlib.suppress(OSError):
            conn.send(rig.counters())


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
        self._lock = threading.Lock()  # one request and its reply at a time
        self.final_counters: RigCounters | None = None

    def start(self, timeout_s: float = 60.0) -> RigEndpoints:
        """Spawn the rig and wait for its endpoints; raises LinkError if it does not come up."""
        self._process.start()
        self._child.close()
        if not self._conn.poll(timeout_s):
            self.stop()
            raise LinkError(f"the emulated rig did not start within {timeout_s} s")
        endpoints: RigEndpoints = self._conn.recv()
        return endpoints

    def stop(self) -> RigCounters | None:
        """Stop the rig (its devices close in order), join the process and return its final
        counters (None if it had died or did not report them)."""
        with self._lock:
            if self._process.is_alive():
                with contextlib.suppress(OSError, EOFError):  # the rig may be gone already
                    self._conn.send("stop")
                    while self._conn.poll(REPLY_TIMEOUT_S):
                        reply = self._conn.recv()
                        if isinstance(reply, RigCounters):
                            self.final_counters = reply
                            break
                self._process.join(timeout=10)
            if self._process.is_alive():
                self._process.kill()
                self._process.join(timeout=5)
            self._conn.close()
        return self.final_counters

    def counters(self) -> RigCounters:
        """What the running rig has sent and applied so far."""
        reply = self._request("counters")
        if not isinstance(reply, RigCounters):
            raise LinkError("the emulated rig did not report its counters")
        return reply

    def fault(self, name: str, *args: object) -> None:
        """Inject fault ``name`` (one of FAULTS, e.g. "ft.stall", 0.05) into the running rig;
        it applies from the rig's next slot."""
        if name not in FAULTS:
            raise HilrigError(f"unknown fault {name!r}; known: {', '.join(sorted(FAULTS))}")
        if self._request((name, args)) != "ok":
            raise LinkError(f"the emulated rig did not take fault {name}")

    def _request(self, message: object) -> object:
        with self._lock:
            self._conn.send(message)
            if not self._conn.poll(REPLY_TIMEOUT_S):
                return None
            reply: object = self._conn.recv()
            return reply

    @property
    def pid(self) -> int | None:
        return self._process.pid

    def __enter__(self) -> RigEndpoints:
        return self.start()

    def __exit__(self, *_: object) -> None:
        self.stop()
