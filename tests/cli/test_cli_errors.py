"""Expected failures: one line on stderr naming what and where, exit status 2, no traceback."""

import os
import subprocess
import sys
from pathlib import Path

HILRIG = Path(sys.executable).with_name("hilrig")


def test_an_expected_error_is_one_line_at_any_terminal_width() -> None:
    result = subprocess.run(
        [str(HILRIG), "rig", "serve", "--scenario", "[bold]shove"],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "40"},
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stdout == ""
    assert result.stderr == (
        "error: unknown scenario '[bold]shove'; known: hand-contact, none, paper-body, "
        "paper-end-effector\n"
    )


def test_version() -> None:
    result = subprocess.run([str(HILRIG), "--version"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    assert result.stdout.startswith("hilrig 0.1.0")
