"""The design in the repository: the layers of docs/architecture.md hold for every import under
``hilrig/``, no module is over 400 lines, and nothing cites a design file the repository lacks.

The layer table is read from docs/architecture.md (between its ``layers: begin`` and
``layers: end`` markers), so the page and this test cannot drift apart.
"""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "hilrig"
DOC = ROOT / "docs" / "architecture.md"
MAX_LINES = 400
BEGIN, END = "<!-- layers: begin", "<!-- layers: end"
# the starting design's file name, spelled so that this file does not contain it
ABSENT_DESIGN_FILE = "DESIGN" + ".md"


@cache
def layers() -> dict[str, int]:
    """``{package or module: layer}`` from the marked table of docs/architecture.md."""
    text = DOC.read_text(encoding="utf-8")
    start, end = text.index(BEGIN), text.index(END)
    table: dict[str, int] = {}
    for line in text[start:end].splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if len(cells) < 2 or not cells[0].isdigit():
            continue
        for name in re.findall(r"`(hilrig(?:\.\w+)*)`", cells[1]):
            assert name not in table, f"{name} is in two rows of the layer table"
            table[name] = int(cells[0])
    return table


def layer_key(module: str) -> str | None:
    """The table entry ``module`` belongs to: the longest dotted prefix in the table (the
    package root ``hilrig`` only for itself); None if there is none."""
    table = layers()
    parts = module.split(".")
    for n in range(len(parts), 1, -1):
        prefix = ".".join(parts[:n])
        if prefix in table:
            return prefix
    return "hilrig" if module == "hilrig" and "hilrig" in table else None


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


@cache
def modules() -> dict[str, Path]:
    return {module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


def imported(module: str, path: Path) -> list[tuple[str, int]]:
    """Every ``hilrig`` module ``module`` imports, with its line: module level, in functions,
    under TYPE_CHECKING; relative imports resolved; ``from package import name`` counts as the
    submodule ``package.name`` when there is one."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: list[tuple[str, int]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join([*base, node.module] if node.module else base)
            else:
                target = node.module or ""
            for alias in node.names:
                submodule = f"{target}.{alias.name}"
                found.append((submodule if submodule in modules() else target, node.lineno))
    return [(name, line) for name, line in found if name.split(".")[0] == "hilrig"]


def test_the_layer_table_is_read_from_the_doc() -> None:
    table = layers()
    assert set(table.values()) == set(range(max(table.values()) + 1)), table  # no gaps
    assert table["hilrig"] == 0
    assert table["hilrig.cli"] == max(table.values())
    assert [name for name in table if name not in modules()] == [], "rows naming no module"


def test_every_module_has_a_layer() -> None:
    unplaced = [module for module in modules() if layer_key(module) is None]
    assert unplaced == [], f"add {unplaced} to the layer table of {DOC.relative_to(ROOT)}"


def test_imports_go_only_to_lower_layers_or_within_a_package() -> None:
    table = layers()
    violations = []
    for module, path in modules().items():
        source = layer_key(module)
        if source is None:  # test_every_module_has_a_layer names it
            continue
        for target_module, line in imported(module, path):
            target = layer_key(target_module)
            if target == source:
                continue
            if target is None or table[target] >= table[source]:
                violations.append(
                    f"{module} (layer {table[source]}, {path.relative_to(ROOT)}:{line}) imports "
                    f"{target_module} (layer {'?' if target is None else table[target]})"
                )
    assert violations == [], "imports against the layers:\n" + "\n".join(violations)


def test_the_import_walk_sees_every_kind_of_import(tmp_path: Path) -> None:
    """Imports in functions, under TYPE_CHECKING and relative ones count too, or the rule
    would pass unchecked (a module of hilrig.rig, written out here)."""
    source = """
from __future__ import annotations
from typing import TYPE_CHECKING
import numpy
import hilrig.errors
from hilrig import __version__
from . import rings
from .records import FT_DTYPE
from ..control import make
if TYPE_CHECKING:
    from hilrig.viz.live import LiveView

def later() -> None:
    from hilrig.cli import app
"""
    fake = tmp_path / "recorder_child.py"
    fake.write_text(source)
    names = {name for name, _ in imported("hilrig.rig.recorder_child", fake)}
    assert names == {
        "hilrig.errors",
        "hilrig",
        "hilrig.rig.rings",
        "hilrig.rig.records",
        "hilrig.control",
        "hilrig.viz.live",
        "hilrig.cli.app",  # from a package: the submodule, when it is one
    }
    assert [layer_key(name) for name in ("hilrig", "hilrig.viz.live", "hilrig.rig.rings")] == [
        "hilrig",
        "hilrig.viz",
        "hilrig.rig",
    ]


def test_no_module_is_over_the_line_limit() -> None:
    too_long = {
        str(path.relative_to(ROOT)): lines
        for path in modules().values()
        if (lines := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert too_long == {}, f"split {too_long} by job (at most {MAX_LINES} lines a module)"


def test_no_tracked_file_cites_the_starting_design_file() -> None:
    """docs/architecture.md and the other docs pages hold the design; the file it started as
    is not in the repository, so nothing may send a reader to it."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    listed = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True
    ).stdout.split(b"\0")
    needle = ABSENT_DESIGN_FILE.encode()
    citing = []
    for name in filter(None, listed):
        path = ROOT / name.decode()
        if path.is_file() and needle in path.read_bytes():
            citing.append(name.decode())
    assert citing == [], (
        f"these cite {ABSENT_DESIGN_FILE}, which is not in the repository: {citing}"
    )
