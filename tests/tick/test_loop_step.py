"""The live loop's tick (tick/loop_step.py): freshness, command flags and what changed, judged in
the compiled call, against the loop's former Python (staleness from the drivers' receive times,
the event detector's change tests) driving a twin tick through ``step(flags)``."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.ft.gravity import GravityCompensator, ToolLoad
from hilrig.drivers.ft.wire import SAMPLE_DTYPE
from hilrig.drivers.robot_state.wire import STATE_DTYPE
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.rig.loop import LoopConfig
from hilrig.robot import RobotModel
from hilrig.tick.kernel import COMMAND_OK, ROBOT_OK, SENSOR_OK, STOPPED, CompiledTick, TickInputs
from hilrig.tick.loop_step import (
    CLAMP_CHANGED,
    HOLD_UNTIL_NS,
    IS_STOPPED,
    REPORT,
    ROBOT_CHANGED,
    ROBOT_IS_OK,
    SENSOR_CHANGED,
    SENSOR_IS_OK,
    loop_words,
)
from hilrig.tick.safety import SafetyClamp, SafetyConfig

MODEL = RobotModel()
Q0 = np.asarray(HOME_Q_RAD, dtype=np.float64)
STALE_NS = 5_000_000
PERIOD_NS = 1_000_000
KERNEL_BITS = (1 << 12) - 1  # the tick kernel's own result bits


def build(inputs: TickInputs | None = None) -> CompiledTick:
    compensator = GravityCompensator(ToolLoad(mass_kg=0.5, com_in_sensor_m=(0.0, 0.0, 0.05)))
    clamp = SafetyClamp(SafetyConfig(), MODEL, Q0)
    controller = LoopConfig().controller()
    return CompiledTick.build(controller, MODEL, clamp, compensator, Q0, 1e-3, inputs)


# one tick: the sample's and the state's age in periods (None: nothing received yet), whether
# a command fault holds, the wrist force (N, along x) and a joint's drift (rad)
ticks = st.tuples(
    st.one_of(st.none(), st.integers(0, 8)),
    st.one_of(st.none(), st.integers(0, 8)),
    st.booleans(),
    st.floats(-400.0, 400.0),
    st.floats(-0.05, 0.05),
)


@settings(max_examples=40, deadline=None)
@given(sequence=st.lists(ticks, min_size=1, max_size=120))
def test_the_loops_tick_judges_and_reports_as_the_python_it_replaced(
    sequence: list[tuple[int | None, int | None, bool, float, float]],
) -> None:
    sample, state = np.zeros(1, SAMPLE_DTYPE), np.zeros(1, STATE_DTYPE)
    # as the loop binds it: the kernel reads the newest rows in place
    newest = TickInputs(sample[0]["wrench"], state[0]["q"], state[0]["tau"])
    loop, twin = build(newest), build()
    words = loop_words(STALE_NS)
    step = loop.loop_step(sample, state, words)
    links = {"sensor": True, "robot": True}  # the event detector's first view
    clamp_was = 0
    for n, (sample_age, state_age, fault, force_n, drift) in enumerate(sequence):
        start_ns = 10**9 + n * PERIOD_NS
        sample[0]["t_ns"] = 0 if sample_age is None else start_ns - sample_age * PERIOD_NS
        state[0]["t_ns"] = 0 if state_age is None else start_ns - state_age * PERIOD_NS
        sample[0]["wrench"][0] = force_n
        state[0]["q"][:] = Q0 + drift
        words[HOLD_UNTIL_NS] = start_ns + 1 if fault else 0
        twin.inputs.raw_wrench[:] = sample[0]["wrench"]  # the twin is given copies
        twin.inputs.q_measured[:] = state[0]["q"]
        twin.inputs.torque_measured[:] = state[0]["tau"]
        # the loop's former Python
        sensor_ok = sample_age is not None and sample_age * PERIOD_NS <= STALE_NS
        robot_ok = state_age is not None and state_age * PERIOD_NS <= STALE_NS
        flags = (SENSOR_OK if sensor_ok else 0) | (ROBOT_OK if robot_ok else 0)
        flags |= 0 if fault else COMMAND_OK
        expected = twin.step(flags)

        result = step(start_ns)

        assert result & KERNEL_BITS == expected
        np.testing.assert_array_equal(loop.q_cmd, twin.q_cmd)
        assert bool(result & SENSOR_IS_OK) == sensor_ok
        assert bool(result & ROBOT_IS_OK) == robot_ok
        assert bool(result & SENSOR_CHANGED) == (sensor_ok != links["sensor"])
        assert bool(result & ROBOT_CHANGED) == (robot_ok != links["robot"])
        assert bool(result & CLAMP_CHANGED) == ((expected & 0xFF) != clamp_was)
        assert bool(result & IS_STOPPED) == bool(twin.counters[STOPPED])
        links = {"sensor": sensor_ok, "robot": robot_ok}
        clamp_was = expected & 0xFF
        if not result & REPORT:
            assert not result & (SENSOR_CHANGED | ROBOT_CHANGED | CLAMP_CHANGED)
