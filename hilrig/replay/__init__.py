"""Offline replay: recorded force traces through any set of controllers and parameter sweeps.

    trace = load_trace("session.mcap")                 # or .csv / .parquet
    specs = parse_specs(["adaptive", "fixed"], sets=["adaptive.a1=10"])
    table = run(trace, specs)                          # one row per (run, tick)
    write_parquet(table, "results.parquet")            # load_results() reads it back
    report = verify("session.mcap")                    # the recorded controller, bit for bit

The result table's columns are fixed by :mod:`hilrig.replay.results`; ``docs/replay.md``
describes inputs, the spec syntax, outputs, ``--verify`` and performance.
"""

from hilrig.errors import ReplayError
from hilrig.replay.engine import Progress, choose_jobs, replay, run
from hilrig.replay.inputs import load_trace
from hilrig.replay.outputs import load_results, write_mcap, write_parquet
from hilrig.replay.results import INPUT_KEY, RUNS_KEY, Run, column_names, peak_offsets
from hilrig.replay.specs import ControllerSpec, Setting, parse_specs
from hilrig.replay.trace import ForceTrace
from hilrig.replay.verify import VerifyReport, verify

__all__ = [
    "INPUT_KEY",
    "RUNS_KEY",
    "ControllerSpec",
    "ForceTrace",
    "Progress",
    "ReplayError",
    "Run",
    "Setting",
    "VerifyReport",
    "choose_jobs",
    "column_names",
    "load_results",
    "load_trace",
    "parse_specs",
    "peak_offsets",
    "replay",
    "run",
    "verify",
    "write_mcap",
    "write_parquet",
]
