"""The rig's public surface: every exported name resolves, and importing the package loads
none of the heavy libraries (they come with the modules that need them)."""

from __future__ import annotations

import subprocess
import sys

import hilrig.rig

HEAVY = ("numba", "pinocchio", "rerun", "pandas")


def test_every_exported_name_resolves() -> None:
    for name in hilrig.rig.__all__:
        assert getattr(hilrig.rig, name) is not None, name


def test_importing_the_package_loads_no_heavy_library() -> None:
    probe = f"import sys, hilrig.rig; print([m for m in {HEAVY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
