"""The compiled tick's call: its arrays by address against the same kernel given its arrays.

The live loop calls the tick (``CompiledTick.step``, :func:`hilrig.tick.step_kernel.tick_entry`)
with its 25 arrays in an :class:`~hilrig.array_table.ArrayTable`: one array for numba to unbox a
call. The reference is the same kernel bound the former way (``hilrig.timing.bound_kernel``:
every array unboxed on every call), on the same arrays, in this process: ``ROUNDS`` rounds of
``CALLS`` calls each, alternating, the median per call of each. The tick is a real one (a fresh
sample, the arm at its home pose), so the ratio is of the whole call, the kernel's work included.
``python -m benchmarks tick`` prints them.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np

from benchmarks.harness import Result
from hilrig.control import combine, make, preset
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.robot import RobotModel
from hilrig.tick.kernel import COMMAND_OK, ROBOT_OK, SENSOR_OK, CompiledTick
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.tick.step_kernel import tick_kernel
from hilrig.timing import bound_kernel

ROUNDS = 15
CALLS = 20_000
FLAGS = SENSOR_OK | ROBOT_OK | COMMAND_OK


def per_call_ns(step: Callable[[int], int]) -> float:
    """One round's time per call, ns."""
    start = time.perf_counter_ns()
    for _ in range(CALLS):
        step(FLAGS)
    return (time.perf_counter_ns() - start) / CALLS


def run() -> list[Result]:
    model = RobotModel()
    q0 = np.asarray(HOME_Q_RAD, dtype=np.float64)
    controller = make("adaptive", combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6)))
    clamp = SafetyClamp(SafetyConfig(), model, q0)
    tick = CompiledTick.build(controller, model, clamp, GravityCompensator(), q0, 0.001)
    tick.inputs.q_measured[:] = q0
    unboxed = bound_kernel(tick_kernel, *tick.kernel_args(), last=(0,))
    by_address = tick.step
    times: dict[str, list[float]] = {"address": [], "unboxed": []}
    for _ in range(ROUNDS):
        times["unboxed"].append(per_call_ns(unboxed))
        times["address"].append(per_call_ns(by_address))
    address, reference = statistics.median(times["address"]), statistics.median(times["unboxed"])
    detail = {"rounds": ROUNDS, "calls": CALLS, "per_call_ns": times}
    return [
        Result(
            "tick",
            "compiled tick per call, arrays by address",
            address / 1000,
            "us",
            "",
            None,
            detail,
        ),
        Result(
            "tick",
            "... its 25 arrays unboxed (the former binding)",
            reference / 1000,
            "us",
            "",
            None,
            detail,
        ),
        Result("tick", "... by address / unboxed", address / reference, "x", "", None, detail),
    ]


if __name__ == "__main__":
    for result in run():
        print(f"{result.name}: {result.value:.3f} {result.unit}")
