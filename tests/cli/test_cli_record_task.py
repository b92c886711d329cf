"""``hilrig record`` with a task the safety clamp would cut: one line, before anything starts."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HILRIG = Path(sys.executable).with_name("hilrig")


def test_a_task_beyond_the_limits_is_one_line_and_nothing_is_made(tmp_path: Path) -> None:
    (tmp_path / "fast.toml").write_text('[trajectory]\nname = "square"\nside_duration_s = 0.5\n')
    command = ["record", "--subject", "S003", "--config", "fast.toml", "--out", "new/s.mcap"]
    result = subprocess.run(
        [str(HILRIG), *command],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == (
        "error: trajectory 'square': joint 3 jerk 293 rad/s^3 is 1120 % over 80 % of its limit "
        "(24 of 30 rad/s^3); try a longer side_duration_s or a shorter side_m\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fast.toml"]
