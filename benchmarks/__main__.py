"""Run every ``benchmarks/bench_*.py`` (each exposes ``run() -> list[Result]``).

Writes ``benchmarks/results/latest.json`` and prints a table. ``python -m benchmarks NAME ...``
runs only the named suites (e.g. ``control``); ``--help`` lists them. ``python -m benchmarks
report`` writes docs/benchmarks.md and the README's table from the dated runs in
``benchmarks/results`` (``benchmarks/report.py``).
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import signal
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from rich.console import Console
from rich.table import Table

from benchmarks.harness import Result

HERE = Path(__file__).parent


def main(argv: list[str]) -> int:
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        # started in the background by a script: SIGINT is ignored and every child would
        # inherit that, so the Rerun server the session suite stops with Ctrl-C would not stop
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if argv[:1] == ["report"]:
        from benchmarks.report import main as report

        return report(argv[1:])
    suites = sorted(p.stem.removeprefix("bench_") for p in HERE.glob("bench_*.py"))
    if argv and argv[0] in ("-h", "--help"):
        print(f"{__doc__}\nThe suites: {' '.join(suites)}")
        return 0
    unknown = [name for name in argv if name not in suites]
    if unknown:
        print(
            f"benchmarks: no suite {unknown[0]!r}; the suites: {' '.join(suites)}", file=sys.stderr
        )
        return 2
    names = argv or suites
    console = Console()
    results: list[Result] = []
    for name in names:
        console.print(f"[bold]benchmark suite {name}[/]")
        started = time.perf_counter()
        module = importlib.import_module(f"benchmarks.bench_{name}")
        results.extend(module.run())
        console.print(f"  done in {time.perf_counter() - started:.1f} s")
    table = Table(title="hilrig benchmarks")
    for column in ("suite", "name", "value", "unit", "target", "ok"):
        table.add_column(column)
    for r in results:
        ok = "" if r.passed is None else ("yes" if r.passed else "NO")
        table.add_row(r.suite, r.name, f"{r.value:.4g}", r.unit, r.target, ok)
    console.print(table)
    report = {
        "when_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": {
            "python": platform.python_version(),
            "cpu": cpu_model(),
            "kernel": f"Linux {platform.release()}",
            "virtual": "virtual machine" if "hypervisor" in cpu_flags() else "",
            "cores": os.cpu_count(),
        },
        "suites": names,
        "results": [r.as_dict() for r in results],
    }
    out = HERE / "results" / "latest.json"
    out.write_text(json.dumps(report, indent=2) + "\n")
    console.print(f"wrote {out}")
    return 0 if all(r.passed is not False for r in results) else 1


def _cpuinfo(key: str) -> str:
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return ""
    return next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith(key)), "")


def cpu_model() -> str:
    """The CPU's model name, as the kernel reports it ("" where it does not)."""
    return _cpuinfo("model name") or platform.processor()


def cpu_flags() -> set[str]:
    return set(_cpuinfo("flags").split())


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
