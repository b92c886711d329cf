"""``hilrig`` starts at once: ``import hilrig.cli`` and every ``--help`` load no numeric stack.

Each check runs in a fresh interpreter and names the heavy packages it found loaded.
"""

import json
import subprocess
import sys

import pytest
import typer.main

from hilrig.cli import app

#: Packages a command loads when it runs, never for its help.
HEAVY = (
    "numba",
    "pinocchio",
    "rerun",
    "pandas",
    "scipy",
    "pyarrow",
    "mcap",
    "pymodbus",
    "serial",
    "numpy",
)
#: Runs the CLI with the arguments in argv[1] (JSON), then prints the top-level packages loaded.
PROBE = """
import json, sys
from hilrig.cli import main
sys.argv = ["hilrig", *json.loads(sys.argv[1])]
try:
    main()
finally:
    print(json.dumps(sorted({name.partition(".")[0] for name in sys.modules})), file=sys.stderr)
"""


def command_paths() -> list[list[str]]:
    """Every command and group of the app, as the words that name it ([] is ``hilrig``)."""
    paths: list[list[str]] = []

    def walk(command: object, path: list[str]) -> None:
        paths.append(path)
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, [*path, name])

    walk(typer.main.get_command(app), [])
    return paths


def offenders(loaded: list[str]) -> list[str]:
    return [name for name in HEAVY if name in loaded]


def test_import_loads_no_heavy_package() -> None:
    code = "import json, sys, hilrig.cli; print(json.dumps(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    loaded = sorted({name.partition(".")[0] for name in json.loads(result.stdout)})
    assert offenders(loaded) == []


def test_every_command_is_enumerated() -> None:
    names = {" ".join(path) for path in command_paths()}
    assert {"", "record", "replay", "view", "analyze", "demo", "rig", "rig serve"} <= names


@pytest.mark.parametrize("path", command_paths(), ids=lambda p: " ".join(["hilrig", *p]))
def test_help_prints_usage_without_heavy_packages(path: list[str]) -> None:
    result = subprocess.run(
        [sys.executable, "-c", PROBE, json.dumps([*path, "--help"])],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert f"Usage: {' '.join(['hilrig', *path])}" in result.stdout
    loaded = json.loads(result.stderr.splitlines()[-1])
    assert offenders(loaded) == []
