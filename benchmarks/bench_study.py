"""Studies: indexing 100 sessions of 10 minutes, re-indexing after one new file, and the
report of that study (``hilrig report``), wall seconds.

The study (:mod:`benchmarks.study_data`: 50 subjects x adaptive and fixed, 1 kHz, a collision
every 30 s, 20 per session) is generated once and cached. Timed, each from a study folder with
no stored catalogue or analyses (``.hilrig-study`` removed first), the files in the page cache:

- index: every file's summary, metadata, ``/events`` and data-section CRC (hilrig study index);
- re-index after one new session was added: one file read, 100 checked unchanged (target
  <= 1 s);
- report, cold: every session analysed (a process pool, one worker per core), statistics
  across the 50 subjects, figures, the HTML written; and warm: the same again with the stored
  analyses (what a second ``hilrig report`` costs after an exclusion).
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from benchmarks.harness import Result
from benchmarks.study_data import SUBJECTS, ensure_study, session_path, study_root, write_one
from hilrig.study.assemble import ReportOptions, assemble
from hilrig.study.catalogue import STORE, index
from hilrig.study.report_html import write_report

SUITE = "study"
REINDEX_TARGET_S = 1.0


def run() -> list[Result]:
    root = study_root()
    generated_s = ensure_study(root)
    if generated_s is not None:
        print(f"  generated the study ({2 * SUBJECTS} sessions) in {generated_s:.0f} s")
    shutil.rmtree(root / STORE, ignore_errors=True)
    extra = session_path(root, SUBJECTS + 1, "adaptive")
    shutil.rmtree(extra.parent, ignore_errors=True)
    size_gb = sum(p.stat().st_size for p in root.rglob("*.mcap")) / 1e9

    start = time.perf_counter()
    files, read = index(root)
    index_s = time.perf_counter() - start
    write_one(root, SUBJECTS + 1, "adaptive")
    start = time.perf_counter()
    _, reread = index(root)
    reindex_s = time.perf_counter() - start
    shutil.rmtree(extra.parent)
    index(root)

    out = Path(tempfile.mkdtemp(prefix="hilrig-bench-study-")) / "report.html"
    options = ReportOptions()
    start = time.perf_counter()
    report = assemble(root, options, "hilrig report study -o report.html")
    write_report(report, out)
    cold_s = time.perf_counter() - start
    start = time.perf_counter()
    again = assemble(root, options, "hilrig report study -o report.html")
    write_report(again, out, overwrite=True)
    warm_s = time.perf_counter() - start
    events = int(report.observations[["session", "event"]].drop_duplicates().shape[0])
    detail = {
        "sessions": len(files),
        "files_read": read,
        "files_reread": reread,
        "study_GB": round(size_gb, 2),
        "events": events,
        "report_MB": round(out.stat().st_size / 1e6, 2),
        "generated_s": generated_s,
    }
    print(
        f"  index {len(files)} sessions ({size_gb:.1f} GB): {index_s:.2f} s; re-index after one "
        f"new: {reindex_s:.3f} s; report cold {cold_s:.1f} s, warm {warm_s:.1f} s ({events} events)"
    )
    return [
        Result(SUITE, "index 100 sessions of 10 min", index_s, "s", "", None, detail),
        Result(SUITE, "re-index after one new session", reindex_s, "s",
               f"<= {REINDEX_TARGET_S:g}", reindex_s <= REINDEX_TARGET_S and reread == 1, detail),
        Result(SUITE, "report of the 100 sessions, cold (every session analysed)", cold_s, "s",
               "", None, detail),
        Result(SUITE, "report again, analyses stored", warm_s, "s", "", None, detail),
    ]  # fmt: skip
