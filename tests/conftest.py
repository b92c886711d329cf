"""Set-up shared by the whole suite."""

from __future__ import annotations

import signal

import pytest


def pytest_configure(config: pytest.Config) -> None:
    """Ctrl-C as a terminal delivers it. A shell that starts the suite in the background without
    job control (``(make test &)`` in a script) leaves SIGINT ignored, and every process the
    tests start inherits that: the tests that interrupt a command or a Rerun server with SIGINT
    would see it ignored. The default handler here is reset to the default action in children."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
