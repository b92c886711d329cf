"""The control kernel's packed layout and one axis's arithmetic, shared by its loops.

State and parameters travel as a few packed float64/int64 arrays (row indices below) so that a
call from Python pays numba's dispatch for five arrays, not twenty. Per tick and axis: the law's
(b, k) (``law_gains``), the discretisation of one period (``discretise``, ``zoh.py``) and the
integration (``integrate``). ``kernel.py`` (with the state machine), ``bare.py`` and ``blocks.py``
(the bare law) are the loops over ticks and axes. Nothing here allocates.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.control.zoh import Terms, damping_terms, terms
from hilrig.recording.samples import ContactState

# Rows of the parameter array P (NP, A).
# DTM = dt/m, KX = dt^2/m.
M, BD, KD, A1, A2, BETA, DELTA, BMIN, GROWTH, TOL, DT, DTM, KX = range(13)
NP = 13
# Entries of the int config cfg (NC + A): options, then each axis's group index.
LAW, CHI, BETA_READING, INTEGRATOR, SM, GUARD, DEBOUNCE, RELEASE, HOLD = range(9)
NC = 9
# Rows of the float state S (NS, A): per axis, then per-group scratch (indexed by group), then
# the per-axis cache of the terms that depend on b only (CB: the b they are for; NaN at rest).
E, V, B, K, P00, P01, P10, P11, G0, G1, GABOVE, GSUMSQ, GSETTLED, CB, CX, CE, CP = range(17)
NS = 17
# Rows of the int group state G (NG, A), indexed by group.
STATE, CNT_ABOVE, CNT_BELOW, TICKS = range(4)
NG = 4
# Rows of the output array out (len(OUTPUTS), T, A); zeta is derived from damping and stiffness.
OUTPUTS = ("offset", "velocity", "damping", "stiffness")
OUT_OFFSET, OUT_VELOCITY, OUT_DAMPING, OUT_STIFFNESS = range(len(OUTPUTS))

# Codes shared with params.py's enums (by position) and the recording's ContactState.
FIXED, VARIABLE_STIFFNESS, ADAPTIVE = 0, 1, 2
CHI_SQUARE, CHI_ABS, CHI_GROUP_SQUARE = 0, 1, 2
BETA_CAP, BETA_MAX = 0, 1
ZOH, EULER = 0, 1
FREE, CONTACT, HOLDING, RECOVERING = (int(state) for state in ContactState)
TANH_IS_ONE = 19.1
# tanh(x) = x + x^3 (T1 + T2 x^2 + ... + T5 x^8) + O(x^13).
T1, T2, T3, T4, T5 = -1.0 / 3.0, 2.0 / 15.0, -17.0 / 315.0, 62.0 / 2835.0, -1382.0 / 155925.0


@njit(cache=True, inline="always")
def store(P: NDArray[np.float64], S: NDArray[np.float64], i: int, k: float, z: Terms) -> None:
    """Axis i's Phi and Gamma from ``zoh``'s (Phi00, E1, Phi11, Gamma0) for stiffness k."""
    phi00, e1, phi11, g0 = z
    dtm = P[DTM, i]
    S[P00, i] = phi00
    S[P01, i] = P[DT, i] * e1
    S[P10, i] = -(k * dtm) * e1
    S[P11, i] = phi11
    S[G0, i] = g0
    S[G1, i] = dtm * e1


@njit(cache=True, inline="always")
def discretise(
    P: NDArray[np.float64], S: NDArray[np.float64], i: int, b: float, k: float, zoh: bool
) -> None:
    """Write Phi and Gamma of axis i with (b, k) frozen over one period into S: the closed-form
    ZOH of ``zoh.py`` (its b-only terms cached per axis) or semi-implicit Euler."""
    dt = P[DT, i]
    dtm = P[DTM, i]
    if not zoh:
        r = b * dtm
        S[P00, i] = 1.0 - k * P[KX, i]
        S[P01, i] = dt * (1.0 - r)
        S[P10, i] = -k * dtm
        S[P11, i] = 1.0 - r
        S[G0, i] = dt * dtm
        S[G1, i] = dtm
        return
    if b != S[CB, i]:
        S[CB, i] = b
        S[CX, i], S[CE, i], S[CP, i] = damping_terms(b, dtm)
    store(P, S, i, k, terms(S[CX, i], S[CE, i], S[CP, i], k * P[KX, i], k, P[KX, i]))


@njit(cache=True, inline="always")
def law_gains(
    law: int,
    chi_reading: int,
    beta_reading: int,
    P: NDArray[np.float64],
    i: int,
    f: float,
    group_sumsq: float,
) -> tuple[float, float]:
    """Damping and stiffness the law commands on axis i for force f (docs/control.md)."""
    b_d = P[BD, i]
    k_d = P[KD, i]
    if law == FIXED:
        return b_d, k_d
    if chi_reading == CHI_SQUARE:
        x = f * f
    elif chi_reading == CHI_ABS:
        x = abs(f)
    else:
        x = group_sumsq
    # tanh(x) rounds to exactly 1.0 in float64 from x = 19.0616 on; below 1/16 (sensor noise)
    # its Taylor series to x^11 is exact to 1e-17 relative: libm's 10-16 ns only in between.
    if x >= TANH_IS_ONE:
        chi = 1.0
    elif x <= 0.0625:
        y = x * x
        chi = x + x * y * (((((T5 * y + T4) * y + T3) * y + T2) * y) + T1)
    else:
        chi = math.tanh(x)
    k = (1.0 - P[A2, i] * chi) * k_d
    if law == VARIABLE_STIFFNESS:
        return b_d, k
    reduction = P[A1, i] * abs(f) if abs(f) > P[DELTA, i] else 0.0
    if beta_reading == BETA_CAP:
        return b_d - min(reduction, P[BETA, i]), k
    return max(b_d - max(reduction, P[BETA, i]), P[BMIN, i]), k


@njit(cache=True)
def gains(
    law: int,
    chi_reading: int,
    beta_reading: int,
    P: NDArray[np.float64],
    groups: NDArray[np.int64],
    force: NDArray[np.float64],
    b_out: NDArray[np.float64],
    k_out: NDArray[np.float64],
) -> None:
    """The bare law's (b, k) for every row of force (T, A), without state machine or guard."""
    T, A = force.shape
    sumsq = np.zeros(A)
    for n in range(T):
        sumsq[:] = 0.0
        for i in range(A):
            sumsq[groups[i]] += force[n, i] * force[n, i]
        for i in range(A):
            b, k = law_gains(law, chi_reading, beta_reading, P, i, force[n, i], sumsq[groups[i]])
            b_out[n, i] = b
            k_out[n, i] = k


@njit(cache=True, inline="always")
def integrate(S: NDArray[np.float64], out: NDArray[np.float64], n: int, i: int, f: float) -> None:
    """Integrate axis i over tick n with its cached Phi, Gamma; write its offset and velocity."""
    e = S[E, i]
    v = S[V, i]
    e_next = S[P00, i] * e + S[P01, i] * v + S[G0, i] * f
    v_next = S[P10, i] * e + S[P11, i] * v + S[G1, i] * f
    S[E, i] = e_next
    S[V, i] = v_next
    out[OUT_OFFSET, n, i] = e_next
    out[OUT_VELOCITY, n, i] = v_next


@njit(cache=True, inline="always")
def advance(S: NDArray[np.float64], out: NDArray[np.float64], n: int, i: int, f: float) -> None:
    """``integrate``, and the tick's damping and stiffness written beside."""
    integrate(S, out, n, i, f)
    out[OUT_DAMPING, n, i] = S[B, i]
    out[OUT_STIFFNESS, n, i] = S[K, i]
