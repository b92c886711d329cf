"""The closed-form zero-order hold of one axis's 2x2 admittance model, on scalars.

With x = b dt/(2m), kappa = k dt^2/m and q = kappa - x^2, A dt = Y - x I where Y^2 = -q I, so
Phi = e^-x (C I + S Y), C = cos sqrt(q), S = sin(sqrt(q))/sqrt(q) (cosh, sinh for q < 0), and
Gamma = (Psi01, Phi01)/m with Psi01 = dt^2 (1 - Phi00)/kappa, each evaluated without
cancellation (docs/control.md, Integrators). Every function returns (Phi00, E1, Phi11, Gamma0)
where Phi01 = dt E1, Phi10 = -(k dt/m) E1 and Gamma1 = (dt/m) E1; ``axis.py`` stores them.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit

# Taylor coefficients of Ch(q) = (1 - cos sqrt(q))/q, Sh(q) = (1 - sin(sqrt(q))/sqrt(q))/q and
# phi_2(z) = (e^z - 1 - z)/z^2: entire functions, evaluated by their series for small arguments.
C_HAT = np.array([(-1.0) ** j / math.factorial(2 * j + 2) for j in range(11)])
S_HAT = np.array([(-1.0) ** j / math.factorial(2 * j + 3) for j in range(11)])
PHI2 = np.array([1.0 / math.factorial(n + 2) for n in range(18)])
#: (Phi00, E1, Phi11, Gamma0)
Terms = tuple[float, float, float, float]
#: |q| up to which the four-term series of ``near_critical`` hold (every preset, dt <= 10 ms).
NEAR_CRITICAL_Q = 1e-3


@njit(cache=True, inline="always")
def poly(c: NDArray[np.float64], z: float, n: int) -> float:
    """sum_{j < n} c[j] z^j (Horner)."""
    r = float(c[n - 1])
    for j in range(n - 2, -1, -1):
        r = r * z + c[j]
    return r


@njit(cache=True)
def damping_terms(b: float, dtm: float) -> tuple[float, float, float]:
    """x = b dt/(2m), e^-x and 1 - (1 + x) e^-x = e^-x x^2 phi_2(x): the terms of b alone."""
    x = 0.5 * b * dtm
    e = math.exp(-x)
    # (1 + x) e^-x <= 2/e from x = 1 on: no cancellation there
    p = e * x * x * poly(PHI2, x, 7 if x <= 0.01 else 18) if x < 1.0 else 1.0 - (1.0 + x) * e
    return x, e, p


@njit(cache=True, inline="always")
def is_near_critical(x: float, kappa: float) -> bool:
    """Whether ``near_critical`` applies: |q| small, zeta <= 2 and k > 0."""
    return abs(kappa - x * x) <= NEAR_CRITICAL_Q and kappa >= 0.25 * x * x and kappa > 0.0


@njit(cache=True, inline="always", error_model="numpy")
def near_critical(x: float, e: float, p: float, kappa: float, k: float) -> Terms:
    """``shifted`` at |q| <= NEAR_CRITICAL_Q, its series written out (no branch, so the kernel
    can run it for every axis at once; garbage, never an error, where it does not apply)."""
    q = kappa - x * x
    ch = ((C_HAT[3] * q + C_HAT[2]) * q + C_HAT[1]) * q + C_HAT[0]
    sh = ((S_HAT[3] * q + S_HAT[2]) * q + S_HAT[1]) * q + S_HAT[0]
    eq = e * q
    ec = e - eq * ch
    e1 = e - eq * sh
    return ec + x * e1, e1, ec - x * e1, (p + eq * (ch + x * sh)) / k


@njit(cache=True)
def shifted(x: float, e: float, p: float, kappa: float, k: float) -> Terms:
    """For zeta <= 2 from Phi = e^-x (C I + S Y), Y^2 = -q I."""
    q = kappa - x * x
    if q >= -4.0:
        if q <= 4.0:
            n = 4 if abs(q) <= 1e-3 else 11
            ch = poly(C_HAT, q, n)
            sh = poly(S_HAT, q, n)
            c = 1.0 - q * ch
            s = 1.0 - q * sh
        else:
            a = math.sqrt(q)
            h = math.sin(0.5 * a)
            c = math.cos(a)
            s = math.sin(a) / a
            ch = 2.0 * h * h / q
            sh = (1.0 - s) / q
        # 1 - Phi00 = (1 - (1 + x) e^-x) + e^-x q (Ch + x Sh): no cancellation for zeta <= 2.
        ec = e * c
        es = e * s
        return ec + x * es, es, ec - x * es, (p + e * q * (ch + x * sh)) / k
    a = math.sqrt(-q)  # e^-x cosh(a), e^-x sinh(a) from e^(a - x), e^(-a - x): no overflow
    hi = math.exp(-kappa / (x + a))
    lo = math.exp(-(x + a))
    ec = 0.5 * (hi + lo)
    es = 0.5 * (hi - lo) / a
    phi00 = ec + x * es
    return phi00, es, ec - x * es, (1.0 - phi00) / k


@njit(cache=True)
def eigen(x: float, kappa: float, kx: float) -> Terms:
    """For zeta > 2 (or k = 0) from the real roots -r, -s."""
    a = math.sqrt(x * x - kappa)
    if a == 0.0:  # b = k = 0
        return 1.0, 1.0, 1.0, 0.5 * kx
    s = x + a
    r = kappa / s  # x - a without cancelling
    em_r = math.expm1(-r)
    em_s = math.expm1(-s)
    w = 0.5 / a  # 1/(s - r)
    e_r = math.exp(-r)
    e_s = math.exp(-s)
    if s < 1.0:  # F = (s phi_2(-s) - r phi_2(-r))/(s - r): the terms differ by a factor > 13
        n = 7 if s <= 0.01 else 18
        f = s * poly(PHI2, -s, n) - r * poly(PHI2, -r, n)
    else:  # F = (phi_1(-r) - phi_1(-s))/(s - r), phi_1(z) = expm1(z)/z
        f = (1.0 if r == 0.0 else em_r / -r) - em_s / -s
    e1 = (em_r - em_s) if r < 0.5 else (e_r - e_s)  # whichever difference does not cancel
    return (e_r * s - e_s * r) * w, e1 * w, (e_s * s - e_r * r) * w, f * w * kx


@njit(cache=True)
def terms(x: float, e: float, p: float, kappa: float, k: float, kx: float) -> Terms:
    """(Phi00, E1, Phi11, Gamma0) for any b >= 0, k >= 0 from the b terms (x, e, p)."""
    if is_near_critical(x, kappa):
        return near_critical(x, e, p, kappa, k)
    if kappa >= 0.25 * x * x and kappa > 0.0:
        return shifted(x, e, p, kappa, k)
    return eigen(x, kappa, kx)
