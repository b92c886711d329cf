"""Driving polled drivers from the test thread: select, poll, repeat until a condition holds.

Bounded by a generous deadline; nothing asserts on a duration.
"""

import select
import time
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np


class Polled(Protocol):
    def fileno(self) -> int: ...
    def poll(self, now_ns: int) -> Any: ...


def poll_until(
    condition: Callable[[], bool],
    *drivers: Polled,
    sink: list[Any] | None = None,
    timeout_s: float = 10.0,
) -> None:
    """Poll ``drivers`` until ``condition()`` holds; what readers return goes to ``sink``.

    AssertionError if the condition has not held within ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"condition not reached within {timeout_s} s")
        fds = [fd for driver in drivers if (fd := driver.fileno()) >= 0]
        if fds:
            select.select(fds, [], [], 0.002)
        else:
            time.sleep(0.002)
        now_ns = time.monotonic_ns()
        for driver in drivers:
            got = driver.poll(now_ns)
            if sink is not None and len(got):
                # a driver's rows are reused by its next poll: keep copies
                sink.extend(got.copy() if isinstance(got, np.ndarray) else got)


def poll_for(duration_s: float, *drivers: Polled, sink: list[Any] | None = None) -> None:
    """Poll ``drivers`` for ``duration_s`` (to let something that must not happen show)."""
    end = time.monotonic() + duration_s
    poll_until(lambda: time.monotonic() >= end, *drivers, sink=sink, timeout_s=duration_s + 10)
