"""Safety verdicts: what judging a 10-minute session's collisions against ISO/TS 15066 adds to
``hilrig analyze``'s time (target <= 10 %).

The session is the view suite's 10-minute 1 kHz file (generated once into the temporary folder,
the paper's collision profiles repeated, every topic). Timed, median of several: reading it and
analysing it (events, metrics) without a body region, and the same with ``hand`` (a verdict per
Cartesian collision: the effective mass at the onset, the phases' peaks, pressure, energy).
"""

from __future__ import annotations

import statistics
import time

from benchmarks.bench_view import session_path, write_session
from benchmarks.harness import Result
from hilrig.analysis import analyze, load_session
from hilrig.analysis.verdict import VerdictConfig

SUITE = "safety"
REPEATS = 3
TARGET_PCT = 10.0


def run() -> list[Result]:
    path = session_path()
    if not path.exists():
        write_session(path)
    plain: list[float] = []
    judged: list[float] = []
    verdicts = 0
    for attempt in range(2 * REPEATS + 1):  # the first warms up (imports, file cache)
        # alternately with and without: neither always reads the file right after the other
        safety = VerdictConfig(body_region="hand") if attempt % 2 else VerdictConfig()
        start = time.perf_counter()
        analysis = analyze(load_session(path), safety=safety)
        wall = time.perf_counter() - start
        if attempt:
            (judged if analysis.verdicts else plain).append(wall)
            verdicts = max(verdicts, len(analysis.verdicts))
    base, with_verdicts = statistics.median(plain), statistics.median(judged)
    added = 100.0 * (with_verdicts - base) / base
    detail = {"plain_s": plain, "judged_s": judged, "verdicts": verdicts, "session": path.name}
    print(f"  analyze 10 min: {base:.2f} s; with verdicts ({verdicts}) {with_verdicts:.2f} s")
    return [
        Result(SUITE, "analyze a 10-min session, no body region", base, "s", "", None, detail),
        Result(SUITE, "... with ISO/TS 15066 verdicts", with_verdicts, "s", "", None, detail),
        Result(SUITE, "... time the verdicts add", added, "%", f"<= {TARGET_PCT:g}",
               added <= TARGET_PCT, detail),
    ]  # fmt: skip
