"""Fixtures of the recording tests: a small session, written once per run."""

from __future__ import annotations

import pytest
from recording_helpers import Written, write_session


@pytest.fixture(scope="session")
def small_session(tmp_path_factory: pytest.TempPathFactory) -> Written:
    """1.2 s of every topic at 1 kHz (five chunks of 0.25 s), with events and attachments."""
    return write_session(tmp_path_factory.mktemp("rec") / "small.mcap", 1200)
