"""Shared by the machine's tests: a check run for real as another user."""

from __future__ import annotations

import os
from collections.abc import Callable

import pytest

NOBODY = 65534  # the user and group ids of nobody


@pytest.fixture(name="as_nobody")
def as_nobody_fixture() -> Callable[[Callable[[], object]], str]:
    """:func:`as_nobody`; skips unless the tests run as root (needed to become another user)."""
    if os.geteuid() != 0:
        pytest.skip("needs root, to become another user")
    return as_nobody


def as_nobody(check: Callable[[], object]) -> str:
    """``repr(check())`` as computed by user nobody: in a forked child (the modules are loaded
    already, so it reads no file of the repository) that drops root before it calls."""
    read_end, write_end = os.pipe()
    child = os.fork()
    if child == 0:
        try:
            os.setgroups([])
            os.setgid(NOBODY)
            os.setuid(NOBODY)
            os.write(write_end, repr(check()).encode())
        finally:
            os._exit(0)
    os.close(write_end)
    with os.fdopen(read_end) as answer:
        seen = answer.read()
    assert os.waitpid(child, 0)[1] == 0
    return seen
