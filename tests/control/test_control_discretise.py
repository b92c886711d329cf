"""The closed-form ZOH discretisation against exact oracles over the whole parameter range.

The reference is exp(M dt) of the block matrix M = [[A, B], [0, 0]] (so [Phi, Gamma] is its top
rows): computed in 80-digit decimal arithmetic (Taylor series with scaling and squaring: exact
to float64 for every input) and, as the integrator tests do, with scipy.linalg.expm.
"""

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from hilrig.control import axis as K  # noqa: N812 - the kernel's notation (axis.py)


def closed_form(m: float, b: float, k: float, dt: float) -> np.ndarray:
    """[[Phi00, Phi01, Gamma0], [Phi10, Phi11, Gamma1]] from the kernel's discretise."""
    P = np.zeros((K.NP, 1))
    P[K.M], P[K.DT], P[K.DTM], P[K.KX] = m, dt, dt / m, dt * dt / m
    S = np.zeros((K.NS, 1))
    S[K.CB] = np.nan
    K.discretise(P, S, 0, b, k, True)
    rows = ((K.P00, K.P01, K.G0), (K.P10, K.P11, K.G1))
    return np.array([[S[r, 0] for r in row] for row in rows])


def exact(m: float, b: float, k: float, dt: float) -> np.ndarray:
    """The same in 80-digit arithmetic from the float inputs as given."""
    with localcontext() as ctx:
        ctx.prec = 80
        dm, db, dk, ddt = (Decimal(v) for v in (m, b, k, dt))
        zero = Decimal(0)
        x = [[zero, ddt, zero], [-dk / dm * ddt, -db / dm * ddt, ddt / dm], [zero, zero, zero]]
        norm = max(sum(abs(v) for v in row) for row in x)
        squarings = max(0, math.ceil(math.log2(float(norm) / 0.25))) if norm > 0.25 else 0
        x = [[v / 2**squarings for v in row] for row in x]

        def mul(a: list[list[Decimal]], c: list[list[Decimal]]) -> list[list[Decimal]]:
            return [[sum(a[i][j] * c[j][n] for j in range(3)) for n in range(3)] for i in range(3)]

        result = [[Decimal(int(i == n)) for n in range(3)] for i in range(3)]
        term = [row[:] for row in result]
        for j in range(1, 50):
            term = [[v / j for v in row] for row in mul(term, x)]
            result = [[result[i][n] + term[i][n] for n in range(3)] for i in range(3)]
        for _ in range(squarings):
            result = mul(result, result)
        return np.array([[float(v) for v in row] for row in result[:2]])


def scipy_expm(m: float, b: float, k: float, dt: float) -> np.ndarray:
    block = np.array([[0.0, 1.0, 0.0], [-k / m, -b / m, 1.0 / m], [0.0, 0.0, 0.0]])
    return expm(block * dt)[:2]


def error(m: float, dt: float, got: np.ndarray, want: np.ndarray) -> float:
    """Largest normwise relative error of Phi and of Gamma, in dimensionless units (a block
    that underflows to zero must be zero)."""
    scale = np.array([[1.0, 1.0 / dt, m / dt**2], [dt, 1.0, m / dt]])
    got, want = got * scale, want * scale
    return max(
        np.abs(got[:, block] - want[:, block]).max() / max(np.abs(want[:, block]).max(), 1e-300)
        for block in (slice(0, 2), slice(2, 3))
    )


def size(m: float, b: float, k: float, dt: float) -> float:
    """||A dt|| in the sense of the spectral radius's bound max(b dt/m, sqrt(k/m) dt)."""
    return max(b * dt / m, math.sqrt(k / m) * dt)


@st.composite
def parameters(draw: st.DrawFn, largest: float) -> tuple[float, float, float, float]:
    """(m, b, k, dt) with b dt/m and k dt^2/m spread over decades, near-critical included."""
    m = 10.0 ** draw(st.floats(-3.0, 3.0))
    dt = 10.0 ** draw(st.floats(-5.0, 0.0))
    beta = 10.0 ** draw(st.floats(-10.0, math.log10(largest)))
    b = beta * m / dt
    kind = draw(st.sampled_from(["any", "critical", "zero"]))
    if kind == "critical":  # zeta = 1 within a relative 1e-12 .. 1
        eps = 10.0 ** draw(st.floats(-12.0, 0.0)) * draw(st.sampled_from([-1.0, 1.0]))
        k = b * b / (4.0 * m) * (1.0 + eps)
    elif kind == "zero":
        k = 0.0
    else:
        k = 10.0 ** draw(st.floats(-12.0, 2.0 * math.log10(largest))) * m / dt**2
    return m, b, k, dt


@settings(max_examples=300, deadline=None)
@given(parameters(1e3))
def test_closed_form_is_exact_to_rounding(case: tuple[float, float, float, float]) -> None:
    m, _, _, dt = case
    # Below ||A dt|| = 1 (every preset at any dt under 40 ms) the result is exact to a few ulp;
    # beyond, a few ulp of the inputs move it by about ||A dt||^2 ulp (so would any algorithm).
    tolerance = 4e-15 * max(1.0, size(*case)) ** 2
    assert error(m, dt, closed_form(*case), exact(*case)) <= tolerance


@settings(max_examples=300, deadline=None)
@given(parameters(2.0))
def test_closed_form_matches_scipy_expm(case: tuple[float, float, float, float]) -> None:
    m, _, _, dt = case
    assert error(m, dt, closed_form(*case), scipy_expm(*case)) <= 1e-12


@pytest.mark.parametrize(
    ("m", "b", "k", "dt"),
    [
        (20.0, 150.0, 300.0, 0.001),  # paper end effector: zeta = 0.97
        (20.0, 150.0, 90.0, 0.001),  # its k_min: zeta = 1.77
        (30.0, 40.0, 150.0, 0.001),  # paper joint
        (4.0, 8.0, 4.0, 0.002),  # zeta = 1 exactly
        (1.0, 4.0, 1.0, 0.01),  # zeta = 2: the boundary of the two forms
        (1.0, 4.0, 0.0, 0.01),  # pure damper
        (1.0, 0.0, 100.0, 0.01),  # undamped
        (1.0, 0.0, 0.0, 0.01),  # free mass
        (1.0, 1e-300, 1e-300, 1.0),  # b, k -> 0
        (1e-3, 1e3, 1e-3, 1.0),  # zeta = 5e5: slow root 1e-6 per tick
        (1.0, 2e3, 1e6, 1.0),  # zeta = 1, b dt/(2m) = 1e3: e^-x underflows
        (1.0, 1e6, 0.0, 1.0),  # b dt/m = 1e6, as large as the validator allows
        (1.0, 1.0, 1e6, 1.0),  # 159 undamped turns per tick
    ],
)
def test_edge_cases(m: float, b: float, k: float, dt: float) -> None:
    got = closed_form(m, b, k, dt)
    assert np.isfinite(got).all()
    tolerance = 4e-15 * max(1.0, size(m, b, k, dt)) ** 2
    assert error(m, dt, got, exact(m, b, k, dt)) <= tolerance
