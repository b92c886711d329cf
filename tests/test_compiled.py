"""numba's cache keyed on the kernels' sources (hilrig/compiled.py): a change to any module a
kernel compiles in gives a new folder, one to a module no kernel uses does not, every kernel
module takes ``njit`` from there, and numba writes its cache into that folder."""

from __future__ import annotations

import re
from pathlib import Path

import numba
import numpy as np
import pytest

import hilrig
from hilrig import compiled
from hilrig.control import simulate

PACKAGE = Path(hilrig.__file__).parent


def package(root: Path, files: dict[str, str]) -> Path:
    """A package named hilrig under ``root`` with ``files`` (relative path -> source)."""
    top = root / "hilrig"
    for name, text in files.items():
        (top / name).parent.mkdir(parents=True, exist_ok=True)
        (top / name).write_text(text)
    return top


FILES = {
    "__init__.py": "",
    "kernel.py": "from hilrig.compiled import njit\nfrom hilrig.consts import SCALE\n",
    "consts.py": "from hilrig.maths import helpers\nSCALE = 2.0\n",
    "maths/__init__.py": "",
    "maths/helpers.py": "def twice(x): return 2 * x\n",
    "maths/more.py": "ONE = 1\n",
    "cli.py": "import hilrig.kernel\nHELP = 'text'\n",
}


def test_the_sources_are_the_kernel_modules_and_what_they_import_transitively(
    tmp_path: Path,
) -> None:
    top = package(tmp_path, FILES)
    names = [str(p.relative_to(top)) for p in compiled.sources(top)]
    # a package imported brings all of its modules (its __init__ may load them by name)
    assert names == [
        "consts.py",
        "kernel.py",
        "maths/__init__.py",
        "maths/helpers.py",
        "maths/more.py",
    ]


@pytest.mark.parametrize(
    ("changed", "new_key"),
    [
        ("consts.py", True),  # a constant a kernel compiles in
        ("maths/more.py", True),  # in a package a kernel's module imports
        ("kernel.py", True),
        ("cli.py", False),  # imports a kernel, but no kernel imports it
        ("__init__.py", False),
    ],
)
def test_the_key_changes_with_a_source_a_kernel_compiles_in_and_only_then(
    tmp_path: Path, changed: str, new_key: bool
) -> None:
    top = package(tmp_path, FILES)
    before = compiled.source_key(top)
    assert compiled.source_key(top) == before
    (top / changed).write_text((top / changed).read_text() + "# changed\n")
    assert (compiled.source_key(top) != before) == new_key


def test_every_module_with_compiled_code_takes_njit_from_hilrig_compiled() -> None:
    direct = re.compile(r"^\s*from numba import .*\bnjit\b|\bnumba\.njit\b", re.MULTILINE)
    users = []
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text()
        if path.name == "compiled.py":
            continue
        assert not direct.search(text), f"{path}: takes njit from numba, not hilrig.compiled"
        if "@njit" in text:
            users.append(path)
            assert "from hilrig.compiled import njit" in text, path
    assert len(users) >= 15
    assert set(users) <= set(compiled.sources())


def test_numba_writes_the_kernels_cache_into_the_keyed_folder() -> None:
    folder = compiled.cache_folder(compiled.source_key())
    assert str(folder) == numba.config.CACHE_DIR
    assert folder.name == compiled.source_key() and folder.is_dir()
    simulate("adaptive", np.zeros((20, 3)), 1e-3, "adaptive")  # compiles or loads the kernel
    assert any(folder.rglob("kernel.run-*.nbi"))


def test_the_folder_is_under_numba_cache_dir_or_the_users_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert compiled.cache_folder("k1") == tmp_path / "numba" / "hilrig" / "k1"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert compiled.cache_folder("k1") == tmp_path / "xdg" / "hilrig" / "numba" / "k1"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert compiled.cache_folder("k1") == tmp_path / "home" / ".cache" / "hilrig" / "numba" / "k1"
