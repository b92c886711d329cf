"""Contact identification against synthetic collisions with known bodies (the oracle), and its
refusals."""

from __future__ import annotations

import numpy as np
import pytest

from hilrig.errors import ParameterError
from hilrig.world.contact import ContactModel, Mechanics, SurfaceMotion, fit_contact

T = np.arange(0.0, 3.0, 0.001)
U = np.array([0.0, 0.6, 0.8])  # the push's direction, base frame


def yielding_tool() -> np.ndarray:
    """The tool moving away along U by up to 12 mm and back (smooth, unlike the surface)."""
    travel = 0.012 * np.sin(np.clip((T - 0.5) / 2.0, 0.0, 1.0) * np.pi) ** 2
    return np.outer(travel, U) + np.array([0.4, 0.0, 0.5])


def collision(model: ContactModel, noise_n: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    tool = yielding_tool()
    assert model.motion is not None
    h, h_rate = model.motion.at(T)
    y = (tool - tool[0]) @ U
    f = model.force(h - y, h_rate - np.gradient(y, T))
    f = f + np.random.default_rng(0).normal(0.0, noise_n, len(T)) * (f > 0)
    return np.outer(f, U), tool


MOTION = SurfaceMotion(t_full_s=1.2, t_back_s=1.8, h_max_m=0.03, v_in_m_s=0.1, v_out_m_s=0.08)


@pytest.mark.parametrize(
    ("mechanics", "stiffness", "damping"),
    [(Mechanics.SPRING_DAMPER, 500.0, 15.0), (Mechanics.HUNT_CROSSLEY, 2.0e4, 0.5)],
)
def test_a_known_body_is_identified(mechanics: Mechanics, stiffness: float, damping: float) -> None:
    truth = ContactModel(mechanics, (0.0, 0.6, 0.8), stiffness, damping, MOTION)
    force, tool = collision(truth, noise_n=0.02)
    fit = fit_contact(T, force, tool)
    assert fit.model.mechanics is mechanics
    np.testing.assert_allclose(fit.model.direction_in_base, U, atol=1e-9)
    assert fit.model.stiffness == pytest.approx(stiffness, rel=0.05)
    assert fit.r2 > 0.99 and fit.rms_n < 0.05 * fit.peak_n
    assert fit.motion_gain > 10  # the robot's yielding shaped the force
    fit.check("event 1")  # good enough to predict from


def test_a_scripted_force_is_a_force_source() -> None:
    # a trapezoid in time, whatever the tool does (the paper's profiles are such)
    profile = np.interp(T, [0.5, 1.0, 1.5, 2.0], [0.0, 8.0, 8.0, 0.0])
    fit = fit_contact(T, np.outer(profile, U), yielding_tool())
    assert fit.model.mechanics is Mechanics.FORCE_SOURCE
    assert fit.motion_gain < 3


def test_a_poor_fit_refuses_to_predict_in_one_line() -> None:
    rng = np.random.default_rng(1)
    force = np.outer(np.abs(rng.normal(5.0, 3.0, len(T))), U)
    fit = fit_contact(T, force, yielding_tool())
    with pytest.raises(ParameterError) as caught:
        fit.check("event 3 (x, 4.02 s)")
    assert str(caught.value).startswith("event 3 (x, 4.02 s): the contact model ")


def test_no_force_is_refused() -> None:
    with pytest.raises(ParameterError) as caught:
        fit_contact(T, np.zeros((len(T), 3)), yielding_tool())
    assert str(caught.value) == "no contact force to fit a contact model to"
