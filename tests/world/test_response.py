"""The arm's response model: the servo kernel against the emulated plant it models, and its
identification from commanded vs measured joints (the oracle: a known bandwidth and delay)."""

from __future__ import annotations

import numpy as np
import pytest

from hilrig.drivers.joint_targets.wire import Mode
from hilrig.errors import ParameterError
from hilrig.robot import RobotModel
from hilrig.world.plant import JointServoPlant, servo_limits
from hilrig.world.response import fit_response, track

LIMITS = RobotModel().limits
Q0 = np.array([0.0, -0.3, 1.6, 0.3, np.pi / 2, 0.0])


def commands(seconds: float = 2.0, dt: float = 0.001) -> tuple[np.ndarray, np.ndarray]:
    """Smooth joint targets around Q0: a few mrad of sine per joint, at 1 kHz."""
    t = np.arange(0.0, seconds, dt)
    wiggle = 0.02 * np.sin(2 * np.pi * np.outer(t, [0.5, 0.8, 1.1, 1.3, 0.7, 0.9]))
    return t, Q0 + wiggle


def test_track_is_the_emulated_plant_driven_by_the_same_targets() -> None:
    t, q = commands(0.5)
    plant = JointServoPlant(LIMITS, q0_rad=Q0, bandwidth_rad_s=60.0)
    measured = []
    ns = (t * 1e9).round().astype(np.int64)
    for k in range(len(t)):
        plant.advance(int(ns[k]))
        measured.append(plant.q_rad)
        plant.set_targets(q[k], k, Mode.TRACK, int(ns[k]))
    modelled = track(t, q, t, Q0, servo_limits(LIMITS), 60.0, 0.0005, 0.0)
    np.testing.assert_allclose(modelled, np.array(measured), atol=1e-12)


@pytest.mark.parametrize(("wn", "delay_s"), [(60.0, 0.0), (35.0, 0.002), (120.0, 0.0035)])
def test_bandwidth_and_delay_are_identified(wn: float, delay_s: float) -> None:
    t, q = commands()
    measured = track(t, q, t, Q0, servo_limits(LIMITS), wn, 0.0005, delay_s)
    fitted = fit_response(t, q, t, measured, LIMITS)
    assert fitted.delay_s == pytest.approx(delay_s, abs=1e-12)
    assert fitted.bandwidth_rad_s == pytest.approx(wn, rel=1e-3)
    assert fitted.rms_rad < 1e-6
    known = fit_response(t, q, t, measured, LIMITS, bandwidth_rad_s=wn)
    assert (known.bandwidth_rad_s, known.delay_s) == (wn, pytest.approx(delay_s, abs=1e-12))
    assert known.source == "emulated plant, delay identified"


def test_too_little_to_fit_is_refused_in_one_line() -> None:
    t, q = commands(0.005)
    with pytest.raises(ParameterError) as caught:
        fit_response(t, q, t, q, LIMITS)
    assert str(caught.value) == (
        "too few commanded (5) or measured (5) joint samples to identify the robot's response"
    )
