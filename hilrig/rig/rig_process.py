"""The emulated rig in a child process, so its device loop never competes with the loop's GIL.

``RigProcess(scenario).start()`` spawns a process that opens an :class:`EmulatedRig` and
returns its endpoints. The child runs the rig's one slot loop in its main thread (real-time
priority where permitted, see :mod:`hilrig.emulator.slots`), with this pipe among the
descriptors it waits on: faults and counter requests are served between slots, no other thread.
``counters()`` returns what the rig has sent so far; ``stop()`` ends it and returns the final
counts (after its devices closed), also kept in ``final_counters``. It runs on the spawn helper
(:class:`~hilrig.rig.child.ChildProcess`): the child ignores SIGINT (the parent handles Ctrl-C
and stops it in order) and stops by itself when the parent goes away. Once set up, the child
freezes its heap (:func:`~hilrig.timing.freeze_heap`): a full pass of the garbage collector over
it stopped both of the rig's streams for 25-30 ms.
"""

from __future__ import annotations

import contextlib
import threading
from multiprocessing.connection import Connection
from typing import Any

from hilrig.emulator.rig import EmulatedRig, RigConfig, RigCounters, RigEndpoints
from hilrig.errors import HilrigError, LinkError
from hilrig.rig.child import ChildProcess, report
from hilrig.timing import freeze_heap
from hilrig.world.scenarios import Scenario

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
        # the emulated AUBO ARCS controller (hilrig/emulator/arcs/controller.py)
        "arcs.protective_stop",
        "arcs.emergency_stop",
        "arcs.drop_links",
        "arcs.stall_rtde",  # (duration_s,)
        "arcs.servo_timeout",
        "arcs.refuse_login",  # (count=1,)
        "arcs.reset",
    }
)
REPLY_TIMEOUT_S = 10.0


def _serve(conn: Connection, scenario: str | Scenario, config: RigConfig) -> None:
    """The child: open the rig, report its endpoints, run its slot loop until told to stop or
    the parent is gone, report the final counters."""
    rig = EmulatedRig(scenario, config=config)
    # no collector pass over the imports stops the rig's one thread mid-session; frozen before
    # open() anchors the slots' grid (the pass took about 50 ms: so many slots were skipped
    # before the first one ran)
    freeze_heap()
    endpoints = rig.open()
    report(conn, "endpoints", endpoints)

    def on_message() -> None:
        try:
            message = conn.recv()
        except EOFError:  # the parent is gone
            rig.request_stop()
            return
        if message == "stop":
            rig.request_stop()
        elif message == "counters":
            report(conn, "counters", rig.counters())
        elif message == "start scenario":
            rig.start_scenario()
            report(conn, "ok")
        else:
            name, args = message
            part, method = name.split(".")
            getattr(getattr(rig, part), method)(*args)
            report(conn, "ok")

    rig.loop.watch(conn.fileno(), on_message)
    try:
        rig.run()
    finally:
        rig.loop.unwatch(conn.fileno())
        rig.close()
        report(conn, "counters", rig.counters())


class RigProcess:
    """An emulated rig in its own process; ``with RigProcess(...) as endpoints:``."""

    def __init__(self, scenario: str | Scenario, *, config: RigConfig | None = None) -> None:
        self._child = ChildProcess("hilrig-emulated-rig", "the emulated rig", LinkError)
        self._args = (scenario, config or RigConfig())
        self._lock = threading.Lock()  # one request and its reply at a time
        self.final_counters: RigCounters | None = None

    def start(self, timeout_s: float = 60.0) -> RigEndpoints:
        """Spawn the rig and wait for its endpoints; raises LinkError if it does not come up."""
        self._child.start(_serve, self._args)
        endpoints: RigEndpoints = self._child.wait_report("endpoints", timeout_s)
        return endpoints

    def stop(self) -> RigCounters | None:
        """Stop the rig (its devices close in order), join the process and return its final
        counters (None if it had died or did not report them). Calling it again is harmless."""
        with self._lock:
            if self._child.alive():
                with contextlib.suppress(HilrigError):  # the rig may be gone already
                    self._child.send("stop")
                    if self._child.poll(REPLY_TIMEOUT_S):
                        self.final_counters = self._child.receive("counters")
            self._child.stop(REPLY_TIMEOUT_S)
            self._child.close()
        return self.final_counters

    def counters(self) -> RigCounters:
        """What the running rig has sent and applied so far; raises LinkError if it is gone."""
        counters: RigCounters = self._request("counters", "counters")
        return counters

    def start_scenario(self) -> None:
        """Start the volunteer scenario's clock now (with ``RigConfig(scenario_starts_at_open=
        False)``, it stands at 0 until then); applies from the rig's next slot."""
        self._request("start scenario", "ok")

    def fault(self, name: str, *args: object) -> None:
        """Inject fault ``name`` (one of FAULTS, e.g. "ft.stall", 0.05) into the running rig;
        it applies from the rig's next slot."""
        if name not in FAULTS:
            raise HilrigError(f"unknown fault {name!r}; known: {', '.join(sorted(FAULTS))}")
        self._request((name, args), "ok")

    def _request(self, message: object, kind: str) -> Any:
        with self._lock:
            self._child.send(message)
            if not self._child.poll(REPLY_TIMEOUT_S):
                raise LinkError(f"the emulated rig did not answer {kind} in {REPLY_TIMEOUT_S} s")
            return self._child.receive(kind)

    @property
    def pid(self) -> int | None:
        return self._child.pid

    def __enter__(self) -> RigEndpoints:
        return self.start()

    def __exit__(self, *_: object) -> None:
        self.stop()
