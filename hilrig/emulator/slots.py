"""One thread, 1 ms slots: the pacing and I/O loop every emulated device runs in.

``SlotLoop.run()`` calls ``on_slot(slot_ns, now_ns)`` once per period at absolute deadlines on
``time.monotonic_ns`` (``slot_ns`` is the deadline, ``now_ns`` when the slot began). Between
slots it sleeps; at the start of each slot it first serves whatever arrived on the watched file
descriptors (pty masters, listening and client sockets, a parent's pipe) since the last one, as
a robot controller serves its fieldbus once per cycle. The descriptors are watched with epoll:
one system call a slot that returns only the ready ones (``select`` rebuilt and scanned the
whole set every slot, about a tenth of the rig's time per slot here). One wake-up a period,
whatever the traffic: that is what keeps the rig cheap on a small machine (a wake-up per Modbus
request cost it about 10 % of a core more). No spinning: under SCHED_FIFO (or with 1 us timer
slack) the sleep ends within tens of microseconds, which is all the precision an emulated device
needs. A loop more than ``MAX_BEHIND`` periods late skips the missed slots (counted) instead of
bursting them.

``run()`` puts its thread under SCHED_FIFO at ``RIG_PRIORITY`` (40, below the control loop's 50:
the rig stands for hardware that the lab PC's load does not slow down) where the OS permits it
(root or CAP_SYS_NICE); elsewhere it silently runs at normal priority.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Self

from hilrig.timing import LatencyHistogram, raise_priority, tighten_timer_slack

RIG_PRIORITY = 40
MAX_BEHIND = 5

SlotHandler = Callable[[int, int], None]  # (slot deadline ns, now ns)


class SlotLoop:
    """Deadline-paced slots plus select()-driven I/O in one thread; ``stop()`` from anywhere."""

    def __init__(self, period_ns: int, on_slot: SlotHandler) -> None:
        self.period_ns = period_ns
        self._on_slot = on_slot
        self._handlers: dict[int, Callable[[], None]] = {}
        self._poller = select.epoll()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self.t0_ns = time.monotonic_ns()
        self.slots = 0  # slots run
        self.slots_late = 0  # slots begun a period or more after their deadline
        self.slots_skipped = 0  # slots not run: the loop was more than MAX_BEHIND late
        self.lateness = LatencyHistogram()  # each slot's start after its deadline

    def watch(self, fd: int, on_readable: Callable[[], None]) -> None:
        """Call ``on_readable()`` in the loop whenever ``fd`` is readable (or hung up)."""
        self._handlers[fd] = on_readable
        try:
            self._poller.register(fd, select.EPOLLIN)
        except FileExistsError:  # watched already: the new handler serves it
            self._poller.modify(fd, select.EPOLLIN)

    def unwatch(self, fd: int) -> None:
        """Stop serving ``fd`` (before closing it; a descriptor closed first has left already)."""
        if self._handlers.pop(fd, None) is not None:
            with contextlib.suppress(OSError):
                self._poller.unregister(fd)

    def stop(self) -> None:
        """Make ``run()`` return after the current slot (any thread, or a signal handler)."""
        self._stopping = True

    def start_thread(self, name: str) -> None:
        """Run the loop in a daemon thread (in-process use: tests, the standalone emulators)."""
        self._thread = threading.Thread(target=self.run, daemon=True, name=name)
        self._thread.start()

    def join(self) -> None:
        """Stop the loop's thread and wait for it."""
        self.stop()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def run(self) -> None:
        """The loop; returns after ``stop()``."""
        previous = raise_priority(RIG_PRIORITY)
        tighten_timer_slack()
        period = self.period_ns
        deadline = self.t0_ns
        try:
            while not self._stopping:
                now = self._wait_until(deadline)
                behind = (now - deadline) // period
                if behind > MAX_BEHIND:
                    self.slots_skipped += behind
                    deadline += behind * period
                if behind >= 1:
                    self.slots_late += 1
                self.lateness.add(now - deadline)
                self._on_slot(deadline, now)
                self.slots += 1
                deadline += period
        finally:
            if previous is not None:
                os.sched_setscheduler(0, *previous)

    def _wait_until(self, deadline: int) -> int:
        """Sleep to ``deadline``, then serve what arrived meanwhile; returns the wake-up time."""
        now = time.monotonic_ns()
        if now < deadline and not self._stopping:
            time.sleep((deadline - now) / 1e9)
            now = time.monotonic_ns()
        handlers = self._handlers
        for fd, _ in self._poller.poll(0):
            handler = handlers.get(fd)  # an earlier handler may have closed it
            if handler is not None:
                handler()
        return now


def accept_client(listener: socket.socket) -> socket.socket | None:
    """The next client waiting on the non-blocking ``listener``, set non-blocking with
    TCP_NODELAY; None when none waits."""
    try:
        sock, _ = listener.accept()
    except BlockingIOError:
        return None
    sock.setblocking(False)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


class Device:
    """A device of a slot loop: ``attach(loop)``, ``tick(slot_ns)`` each slot, ``close()``.

    ``start()``/``stop()`` (or ``with``) run one alone in a loop thread of its own, every
    ``standalone_period_ns``; faults and requests then come from other threads, so devices take
    them through thread-safe queues applied by ``tick``.
    """

    standalone_period_ns = 1_000_000
    thread_name = "emulated-device"
    _own_loop: SlotLoop | None = None

    def attach(self, loop: SlotLoop) -> None:
        raise NotImplementedError

    def tick(self, slot_ns: int) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def start(self) -> Self:
        """Attach to a loop of its own and run it in a daemon thread; returns self."""
        loop = SlotLoop(self.standalone_period_ns, lambda slot_ns, _: self.tick(slot_ns))
        self._own_loop = loop
        self.attach(loop)
        loop.start_thread(self.thread_name)
        return self

    def stop(self) -> None:
        """Stop the own loop's thread and close the device."""
        if self._own_loop is not None:
            self._own_loop.join()
            self._own_loop = None
            self.close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()
