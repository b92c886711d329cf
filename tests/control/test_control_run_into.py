"""``run_into``: blocks of ticks into the caller's arrays, equal to ``simulate`` bit for bit."""

import numpy as np
import pytest

from hilrig.control import (
    OUTPUTS,
    NonFiniteForceError,
    ParameterError,
    combine,
    damping_ratio,
    make,
    preset,
    simulate,
)

PARAMS = combine((preset("adaptive"), 3), (preset("adaptive-joint"), 2))
DT = 0.001


def push(ticks: int = 3000) -> np.ndarray:
    force = np.zeros((ticks, 5))
    force[100:900, 0] = 4.0
    force[400:1600, 3] = -2.5
    return force


def test_blocks_into_strided_columns_equal_simulate() -> None:
    force = push()
    expected = simulate("adaptive", force, DT, PARAMS)
    controller = make("adaptive", PARAMS, dt=DT)
    columns = np.zeros((5, len(OUTPUTS) + 1, 3000))  # (axes, quantities, ticks), as a table's
    contact = np.zeros((5, 3000), dtype=np.int8)
    for start in range(0, 3000, 700):
        rows = slice(start, min(start + 700, 3000))
        out = columns[:, : len(OUTPUTS), rows].transpose(1, 2, 0)
        controller.run_into(force[rows], out, contact[:, rows].T)
    for row, quantity in enumerate(OUTPUTS):
        np.testing.assert_array_equal(columns[:, row].T, getattr(expected, quantity))
    np.testing.assert_array_equal(contact.T, expected.contact)
    np.testing.assert_array_equal(controller.offset, expected.offset[-1])
    np.testing.assert_array_equal(controller.contact, expected.contact[-1])
    zeta = columns[:, len(OUTPUTS)]
    damping = columns[:, OUTPUTS.index("damping")]
    stiffness = columns[:, OUTPUTS.index("stiffness")]
    damping_ratio(damping, stiffness, controller.mass[:, None], out=zeta)
    np.testing.assert_array_equal(zeta.T, expected.zeta)


def test_step_continues_where_run_into_stopped() -> None:
    force = push(1200)
    expected = simulate("adaptive", force, DT, PARAMS)
    controller = make("adaptive", PARAMS, dt=DT)
    out = np.empty((len(OUTPUTS), 1000, 5))
    controller.run_into(force[:1000], out, np.empty((1000, 5), dtype=np.int8))
    for n in range(1000, 1200):
        np.testing.assert_array_equal(controller.step(force[n]), expected.offset[n])


def test_non_finite_force_stops_at_its_tick() -> None:
    force = push(50)
    force[30, 2] = np.nan
    controller = make("adaptive", PARAMS, dt=DT)
    out = np.zeros((len(OUTPUTS), 50, 5))
    with pytest.raises(NonFiniteForceError) as err:
        controller.run_into(force, out, np.zeros((50, 5), dtype=np.int8))
    assert str(err.value) == (
        "force[30, 2] is nan: non-finite force is refused and nothing from that tick on was "
        "integrated"
    )
    expected = simulate("adaptive", force[:30], DT, PARAMS)
    np.testing.assert_array_equal(controller.offset, expected.offset[-1])
    assert not out[:, 30:].any()


def test_arrays_of_the_wrong_shape_or_type_are_refused() -> None:
    controller = make("adaptive", PARAMS, dt=DT)
    with pytest.raises(ParameterError) as err:
        controller.run_into(np.zeros((10, 5)), np.zeros((4, 10, 5)), np.zeros((10, 5)))
    assert str(err.value) == (
        "run_into takes force (T, 5) and out (4, T, 5) float64, contact (T, 5) int8; "
        "got (10, 5) float64, (4, 10, 5) float64, (10, 5) float64"
    )
    with pytest.raises(ParameterError, match=r"got \(10, 3\) float64"):
        controller.run_into(np.zeros((10, 3)), np.zeros((4, 10, 5)), np.zeros((10, 5), np.int8))
