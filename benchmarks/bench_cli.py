"""Command line start-up: the wall time of ``hilrig --help`` and of each ``hilrig COMMAND --help``
(every command and group of the app), beside ``python -c pass`` measured in the same run.

Each is a fresh process, run REPEATS times round-robin (so a busy moment of the machine hits
them all alike) after one warm-up run each; the median is reported, and its ratio to the
reference, which scales it to another machine.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

import typer.main

from benchmarks.harness import Result
from hilrig.cli import app

SUITE = "cli"
REPEATS = 7
TARGET_S = 0.3
HILRIG = Path(sys.executable).with_name("hilrig")
REFERENCE = "python -c pass"


def help_commands() -> dict[str, list[str]]:
    """``hilrig [COMMAND ...] --help`` for the app and every command and group in it."""
    commands: dict[str, list[str]] = {}

    def walk(command: object, words: list[str]) -> None:
        line = [str(HILRIG), *words, "--help"]
        commands[" ".join(["hilrig", *words, "--help"])] = line
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, [*words, name])

    walk(typer.main.get_command(app), [])
    return commands


def wall_s(command: list[str]) -> float:
    """Seconds from start to exit of ``command`` (its output discarded); it must succeed."""
    start = time.perf_counter()
    subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - start


def run() -> list[Result]:
    commands = {REFERENCE: [sys.executable, "-c", "pass"], **help_commands()}
    for command in commands.values():  # warm-up: page cache, bytecode
        wall_s(command)
    samples: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(REPEATS):
        for name, command in commands.items():
            samples[name].append(wall_s(command))
    medians = {name: statistics.median(times) for name, times in samples.items()}
    reference = medians.pop(REFERENCE)
    detail = {"samples_s": samples[REFERENCE]}
    results = [Result(SUITE, f"{REFERENCE} (reference)", reference, "s", detail=detail)]
    for name, median_s in medians.items():
        ratio = median_s / reference
        detail = {"samples_s": samples[name], "vs_reference": ratio}
        results.append(
            Result(SUITE, name, median_s, "s", f"<= {TARGET_S}", median_s <= TARGET_S, detail)
        )
        results.append(Result(SUITE, f"{name} vs {REFERENCE}", ratio, "x"))
    return results
