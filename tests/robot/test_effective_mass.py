"""The arm's effective mass at the TCP against an independent path: the TCP's acceleration
under a force there, by pinocchio's articulated-body algorithm (ABA) from rest."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.robot import RobotModel

MODEL = RobotModel()
HOME = np.array([0.0, -0.3, 1.6, 0.3, np.pi / 2, 0.0])


def oracle(q: np.ndarray, u: np.ndarray) -> float:
    """F / (a . u) for a force F along u at the TCP, no gravity, from rest."""
    model = pin.buildModelFromXML(MODEL.urdf_xml)
    model.gravity.linear[:] = 0.0
    data = model.createData()
    jac = MODEL.jacobian(q)[:3]
    force = 10.0
    qdd = pin.aba(model, data, q, np.zeros(6), jac.T @ (force * u))
    return force / float((jac @ qdd) @ u)


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.floats(-0.5, 0.5), min_size=6, max_size=6),
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(
        lambda v: np.linalg.norm(v) > 0.1
    ),
)
def test_the_effective_mass_is_what_a_push_accelerates(
    offsets: list[float], v: list[float]
) -> None:
    q = HOME + np.array(offsets)
    u = np.array(v) / np.linalg.norm(v)
    assert MODEL.effective_mass_kg(q, u) == pytest.approx(oracle(q, u), rel=1e-9)
    assert MODEL.effective_mass_kg(q, 3.0 * u) == pytest.approx(oracle(q, u), rel=1e-9)
