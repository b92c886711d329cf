"""The local engine's warm-up: the kernels a task's controllers run are loaded in the sweep's own
process, so that forked workers inherit them. Counted in fresh processes: the compiled
signatures (numba overloads) that appear in hilrig's kernels, by the warm-up and by a task."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from sweep_helpers import force_table

SCRIPT = """
import json, sys
from pathlib import Path
from numba.core.registry import CPUDispatcher
from hilrig.replay import parse_specs
from hilrig.sweep import find_inputs, plan
from hilrig.sweep.tasks import run_task, warm_up

def loaded():
    found = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("hilrig"):
            for attr, value in vars(module).items():
                if isinstance(value, CPUDispatcher) and value.overloads:
                    found[f"{value.__module__}.{value.__name__}"] = len(value.overloads)
    return found

source, out, warm = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "warm"
specs = parse_specs(["adaptive", "fixed"], sweeps=["adaptive.a1=5,10"])
tasks = plan(find_inputs([source]), specs, closed_loop=False)
before = loaded()
if warm:
    warm_up(tasks)
warmed = loaded()
for task in tasks:
    assert not run_task(task, out).error
after = loaded()
print(json.dumps({
    "warm_up": sorted(k for k in warmed if warmed[k] != before.get(k)),
    "tasks": sorted(k for k in after if after[k] != warmed.get(k)),
}))
"""


def loads(tmp_path: Path, warm: bool) -> dict[str, list[str]]:
    source = force_table(tmp_path / "trace.parquet", 12.0)
    out = tmp_path / ("warm" if warm else "cold")
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(source), str(out), "warm" if warm else "cold"],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    loaded: dict[str, list[str]] = json.loads(done.stdout.splitlines()[-1])
    return loaded


@pytest.mark.parametrize("warm", [False, True])
def test_after_the_warm_up_a_task_loads_no_compiled_code_of_its_own(
    tmp_path: Path, warm: bool
) -> None:
    """With the warm-up, the controllers' kernels are loaded by it and the tasks (three
    parameter sets of two laws) load nothing more; without it (the control), the first task
    loads them."""
    loaded = loads(tmp_path, warm)
    kernels = {"hilrig.control.kernel.run", "hilrig.control.axis.discretise"}
    if warm:
        assert kernels <= set(loaded["warm_up"]) and loaded["tasks"] == []
    else:
        assert loaded["warm_up"] == [] and kernels <= set(loaded["tasks"])
