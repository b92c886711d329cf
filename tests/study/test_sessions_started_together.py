"""Two `hilrig record` started together (the second waits for the machine, its id already
minted) are two sessions: ids apart, both in the catalogue and in the report."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from hilrig.cli import run
from hilrig.study.catalogue import index, sessions

HILRIG = Path(sys.executable).with_name("hilrig")
ULID = r"[0-9A-HJKMNP-TV-Z]{26}"
#: A short hand contact on the held pose: the hand meets the tool at once and leaves by 1 s.
CONTACT = ("--scenario", "hand-contact", "--trajectory", "hold", "--duration", "3")
SETTINGS = ("start_s=0.2", "gap_m=0.01", "hold_s=0.3")


def test_two_sessions_started_together_are_two_sessions_in_the_catalogue_and_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "study"
    options = [*CONTACT, *(a for s in SETTINGS for a in ("--scenario-set", s))]
    started = [
        subprocess.Popen(
            [str(HILRIG), "record", "--subject", subject, "--controller", law, *options, *out],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        for subject, law in (("S001", "adaptive"), ("S002", "fixed"))
        for out in [("--out", str(root / subject / "session.mcap"))]
    ]
    for process in started:  # generous: the machine's other sessions are waited for
        _, err = process.communicate(timeout=900)
        assert process.returncode == 0, err
    catalogue = sessions(index(root)[0])
    ids = list(catalogue["session"])
    assert len(ids) == 2 and ids[0] != ids[1] and all(re.fullmatch(ULID, i) for i in ids)
    assert list(catalogue["subject"]) == ["S001", "S002"]
    assert not catalogue["flags"].str.contains("duplicate-id").any()
    out = tmp_path / "report.html"
    assert run(["report", str(root), "-o", str(out), "--resamples", "999"]) == 0
    printed, _ = capsys.readouterr()
    assert printed.startswith(f"wrote {out}: 2 sessions of 2 subjects, 0 excluded")
    html = out.read_text(encoding="utf-8")
    assert all(f"<code>{i}</code>" in html for i in ids)
