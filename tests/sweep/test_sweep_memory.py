"""A sweep worker keeps the memory it frees (counted in page faults, in a process of its own:
the setting is the whole process's)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

PROBE = """
import json, resource, sys
import numpy as np
from hilrig.sweep.memory import keep_freed_memory
if sys.argv[1] == "keep":
    keep_freed_memory()
    keep_freed_memory()  # once per process: a second call changes nothing
faults = []
for _ in range(3):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    block = np.ones(8 << 20)  # 64 MiB, allocated, touched and freed
    faults.append(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
    del block
print(json.dumps(faults))
"""


def faults(mode: str) -> list[int]:
    """Page faults of three 64 MiB allocations in a row, in a new process."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE, mode], capture_output=True, text=True, check=True
    )
    counts: list[int] = json.loads(done.stdout)
    return counts


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_memory_freed_by_a_worker_is_reused_without_page_faults() -> None:
    first, *later = faults("keep")
    assert first > 0 and max(later) * 10 < first
    first, *later = faults("default")  # the control: without it, every allocation faults
    assert min(later) * 2 > first
