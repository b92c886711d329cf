"""Write docs/benchmarks.md and the README's performance table from ``benchmarks/results``.

``python -m benchmarks report`` reads every dated run (``results/*.json``; ``latest.json`` is
the newest run's copy and is skipped), takes for each suite the newest run that measured it,
and renders each suite's figures beside that run's calibration: the ``lfilter`` reference speed,
the ``mcap_ros2`` writer's speed and the machine's timing floor, each from the same run (a
figure compared across runs means little when one machine is 3x slower than another). Runs
that are only history stay in their JSON files. ``--check`` writes nothing and exits 1 when a
committed page differs from what the results give.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jinja2

HERE = Path(__file__).parent
ROOT = HERE.parent
RESULTS = HERE / "results"
PAGE = ROOT / "docs" / "benchmarks.md"
README = ROOT / "README.md"
BEGIN = "<!-- benchmarks:begin (written by python -m benchmarks report) -->"
END = "<!-- benchmarks:end -->"

# The calibration figures: (suite, name, how the page names it).
CALIBRATION = (
    ("control", "lfilter fixed (reference), median / best run", "scipy lfilter, median"),
    ("recording", "mcap_ros2 writer messages/s (anchor)", "mcap_ros2 writer"),
    ("machine", "bare thread's 1 kHz wake-ups over a period late", "bare 1 kHz wake-ups late"),
)
# The README's table: the few figures a newcomer asks about first, as (suite, name, label).
HEADLINES = (
    ("control", "step mean (9 axes, adaptive+SM)", "controller step, 9 axes, mean"),
    ("control", "simulate adaptive: median / lfilter's best run", "1 h offline, time / lfilter's"),
    ("session", "compute per tick p99", "1 kHz session: compute per tick p99"),
    ("session", "missed deadlines", "1 kHz session: missed deadlines"),
    ("session", "sensor-to-servoJoint p99", "1 kHz session: sensor to servoJoint p99"),
    ("session", "servo periods missed", "1 kHz session: servo periods missed"),
    ("session", "recorder drops", "1 kHz session: recorder drops"),
    ("recording", "writer vs mcap_ros2 writer", "recording writer / mcap_ros2's"),
    ("recording", "load samples/s (10 min, all topics)", "loading a recording"),
    (
        "closed_loop",
        "closed-loop prediction, peak |F| error median",
        "closed-loop replay: peak force error, median",
    ),
    ("replay", "... as x real time", "replay, 1 h x 3 controllers, x real time"),
    ("study", "re-index after one new session", "study re-index after one new session"),
)


@dataclass(frozen=True)
class Run:
    """One ``make bench`` run as its JSON file holds it."""

    file: str
    when_utc: str
    machine: Mapping[str, Any]
    suites: tuple[str, ...]
    results: tuple[Mapping[str, Any], ...]

    def figure(self, suite: str, name: str) -> Mapping[str, Any] | None:
        return next((r for r in self.results if r["suite"] == suite and r["name"] == name), None)


def load_runs(folder: Path = RESULTS) -> list[Run]:
    """Every dated run in ``folder``, oldest first."""
    runs = []
    for path in sorted(folder.glob("*.json")):
        if path.name == "latest.json":
            continue
        data = json.loads(path.read_text())
        runs.append(
            Run(
                file=path.name,
                when_utc=str(data["when_utc"]),
                machine=data.get("machine", {}),
                suites=tuple(data["suites"]),
                results=tuple(data["results"]),
            )
        )
    return sorted(runs, key=lambda run: (run.when_utc, run.file))


def newest_by_suite(runs: Iterable[Run]) -> dict[str, Run]:
    """For each suite, the newest run that measured it."""
    newest: dict[str, Run] = {}
    for run in runs:
        for suite in run.suites:
            newest[suite] = run
    return dict(sorted(newest.items()))


def number(value: float) -> str:
    """A figure as the page prints it: four significant digits, thousands grouped."""
    if abs(value) >= 10_000:
        return f"{float(f'{value:.4g}'):,.0f}"
    if value != 0 and abs(value) < 1e-3:
        return f"{value:.3g}"
    return f"{value:.4g}"


def met(result: Mapping[str, Any]) -> str:
    passed = result.get("passed")
    return "" if passed is None else ("yes" if passed else "**no**")


def machine_text(run: Run) -> str:
    machine = run.machine
    cpu = machine.get("cpu") or "CPU not recorded"
    parts = [f"{machine.get('cores', '?')} cores", str(cpu)]
    parts += [str(machine[k]) for k in ("kernel", "virtual") if machine.get(k)]
    return ", ".join(parts) + f"; Python {machine.get('python', '?')}"


def calibration(run: Run) -> list[str]:
    lines = []
    for suite, name, label in CALIBRATION:
        result = run.figure(suite, name)
        if result is None:
            lines.append(f"{label}: not measured in this run")
            continue
        best = str(result.get("target", "")).removeprefix("best ")
        extra = f" (best {best})" if best and suite == "control" else ""
        lines.append(f"{label}: {number(float(result['value']))}{extra} {result['unit']}")
    return lines


def render(runs: list[Run]) -> tuple[str, str]:
    """The page and the README's table, from ``runs``."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(HERE / "templates"),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        autoescape=False,  # Markdown, not HTML
    )
    env.filters |= {"number": number, "met": met}
    newest = newest_by_suite(runs)
    suites = [
        {
            "name": suite,
            "run": run,
            "machine": machine_text(run),
            "calibration": calibration(run),
            "results": [r for r in run.results if r["suite"] == suite],
        }
        for suite, run in newest.items()
    ]
    headlines: list[dict[str, Any]] = []
    for suite, name, label in HEADLINES:
        run = newest.get(suite)
        result = None if run is None else run.figure(suite, name)
        if run is not None and result is not None:
            headlines.append({"label": label, "run": run, "result": result})
    page = env.get_template("benchmarks.md.j2").render(suites=suites, runs=runs)
    cited = sorted({h["run"].file: h["run"] for h in headlines}.values(), key=lambda r: r.file)
    for h in headlines:
        h["mark"] = cited.index(h["run"]) + 1
    about = [
        {"mark": i, "file": run.file, "machine": machine_text(run), "calibration": calibration(run)}
        for i, run in enumerate(cited, 1)
    ]
    table = env.get_template("readme_table.md.j2").render(headlines=headlines, runs=about)
    return page, table


def with_table(readme: str, table: str) -> str:
    """``readme`` with the text between the markers replaced by ``table``."""
    head, sep, rest = readme.partition(BEGIN)
    _, sep2, tail = rest.partition(END)
    if not sep or not sep2:
        raise SystemExit(f"benchmarks report: {README.name} has no {BEGIN!r} ... {END!r} block")
    return f"{head}{BEGIN}\n{table}{END}{tail}"


def main(argv: list[str]) -> int:
    check = argv == ["--check"]
    if argv and not check:
        print("usage: python -m benchmarks report [--check]", file=sys.stderr)
        return 2
    page, table = render(load_runs())
    readme = with_table(README.read_text(), table)
    pages = ((PAGE, page), (README, readme))
    stale = [p.name for p, text in pages if not p.exists() or p.read_text() != text]
    if check:
        for name in stale:
            print(f"benchmarks report: {name} differs from the results; run it without --check")
        return 1 if stale else 0
    PAGE.write_text(page)
    README.write_text(readme)
    print(f"wrote {PAGE.relative_to(ROOT)} and the table in {README.name}")
    return 0
