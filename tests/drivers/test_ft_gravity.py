"""Tare and tool gravity compensation, and tool load identification, on synthetic readings."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hilrig.drivers.ft.gravity import (
    GravityCompensator,
    ToolLoad,
    gravity_wrench,
    identify_tool_load,
)
from hilrig.errors import ParameterError

LOAD = ToolLoad(1.25, (0.01, -0.02, 0.08))
BIAS = np.array([1.0, -2.0, 0.5, 0.05, -0.1, 0.02])
ORIENTATIONS = Rotation.random(10, random_state=3).as_matrix()


def reading(r_base_sensor: np.ndarray, external: np.ndarray | None = None) -> np.ndarray:
    extra = np.zeros(6) if external is None else external
    return BIAS + gravity_wrench(LOAD, r_base_sensor) + extra


def test_tool_hanging_below_a_level_sensor_pulls_along_minus_z() -> None:
    wrench = gravity_wrench(ToolLoad(2.0, (0.0, 0.0, 0.1)), np.eye(3))
    np.testing.assert_allclose(wrench, [0.0, 0.0, -2.0 * 9.80665, 0.0, 0.0, 0.0], atol=1e-12)


def test_offset_centre_of_gravity_makes_torque_c_cross_f() -> None:
    wrench = gravity_wrench(ToolLoad(1.0, (0.1, 0.0, 0.0)), np.eye(3))
    np.testing.assert_allclose(wrench[3:], [0.0, 0.980665, 0.0], atol=1e-12)  # x cross -z = +y


def test_tare_then_compensate_leaves_only_the_external_wrench() -> None:
    compensator = GravityCompensator(LOAD)
    compensator.tare(reading(ORIENTATIONS[0]), ORIENTATIONS[0])
    np.testing.assert_allclose(compensator.bias_in_sensor, BIAS, atol=1e-12)
    external = np.array([3.0, 0.0, -1.0, 0.0, 0.2, 0.0])
    for r_base_sensor in ORIENTATIONS[1:]:
        out = compensator.compensate(reading(r_base_sensor, external), r_base_sensor)
        np.testing.assert_allclose(out, external, atol=1e-12)


def test_compensate_into_out_returns_out() -> None:
    compensator = GravityCompensator(LOAD, bias_in_sensor=BIAS)
    out = np.empty(6)
    result = compensator.compensate(reading(ORIENTATIONS[2]), ORIENTATIONS[2], out)
    assert result is out
    np.testing.assert_allclose(out, 0.0, atol=1e-12)


def test_without_a_tool_tare_is_plain_offset_removal() -> None:
    compensator = GravityCompensator()
    compensator.tare(BIAS, ORIENTATIONS[0])
    np.testing.assert_allclose(compensator.compensate(BIAS + 1.0, ORIENTATIONS[5]), 1.0)


def test_identify_tool_load_recovers_mass_centre_and_bias() -> None:
    readings = np.array([reading(r) for r in ORIENTATIONS])
    load, bias = identify_tool_load(readings, ORIENTATIONS)
    assert load.mass_kg == pytest.approx(LOAD.mass_kg)
    np.testing.assert_allclose(load.com_in_sensor_m, LOAD.com_in_sensor_m, atol=1e-12)
    np.testing.assert_allclose(bias, BIAS, atol=1e-12)


def test_identify_refuses_orientations_about_one_axis() -> None:
    about_z = Rotation.from_rotvec(
        [[0.0, 0.0, angle] for angle in (0.0, 1.0, 2.0, 3.0)]
    ).as_matrix()
    readings = np.array([reading(r) for r in about_z])
    with pytest.raises(ParameterError, match="orientations too alike"):
        identify_tool_load(readings, about_z)


def test_negative_mass_is_refused() -> None:
    with pytest.raises(ParameterError, match=r"ToolLoad\.mass_kg must be >= 0, got -1\.0"):
        ToolLoad(-1.0)
