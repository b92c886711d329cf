"""Fixtures of the recording tests: a small session, written once per run; the fuzz tests'
undamaged file and work folder, once per module."""

from __future__ import annotations

from pathlib import Path

import pytest
from fuzz_helpers import Base, write_base
from recording_helpers import Written, write_session


@pytest.fixture(scope="session")
def small_session(tmp_path_factory: pytest.TempPathFactory) -> Written:
    """1.2 s of every topic at 1 kHz (five chunks of 0.25 s), with events and attachments."""
    return write_session(tmp_path_factory.mktemp("rec") / "small.mcap", 1200)


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Base:
    return write_base(tmp_path_factory.mktemp("fuzz"))


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-work")
