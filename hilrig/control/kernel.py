"""The compiled admittance kernel: one loop shared by the live ``step`` and offline ``simulate``.

State and parameters travel as a few packed float64/int64 arrays (row indices below) so that a
call from Python pays numba's dispatch for five arrays, not twenty. Per tick n and axis i the
kernel reads f[n, i], updates the group's contact state (Algorithm 2), picks b and k from the
law, applies the Theorem 1 rate guard, re-discretises only when (b, k) changed, and integrates
one period: offset[n] = e(t_n + dt). Nothing here allocates.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from hilrig.recording.samples import ContactState

# Rows of the parameter array P (NP, A).
M, BD, KD, A1, A2, BETA, DELTA, BMIN, GROWTH, TOL, NTERMS, NSQ, DT = range(13)
NP = 13
# Entries of the int config cfg (NC + A): options, then each axis's group index.
LAW, CHI, BETA_READING, INTEGRATOR, SM, GUARD, DEBOUNCE, RELEASE, HOLD = range(9)
NC = 9
# Rows of the float state S (NS, A): per axis, then per-group scratch (indexed by group).
E, V, B, K, P00, P01, P10, P11, G0, G1, GABOVE, GSUMSQ, GSETTLED = range(13)
NS = 13
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


@njit(cache=True, inline="always")
def discretise(
    P: NDArray[np.float64], S: NDArray[np.float64], i: int, b: float, k: float, zoh: bool
) -> None:
    """Write Phi and Gamma of axis i with (b, k) frozen over one period into S."""
    m = P[M, i]
    dt = P[DT, i]
    if not zoh:
        r = b * dt / m
        S[P00, i] = 1.0 - k * dt * dt / m
        S[P01, i] = dt * (1.0 - r)
        S[P10, i] = -k * dt / m
        S[P11, i] = 1.0 - r
        S[G0, i] = dt * dt / m
        S[G1, i] = dt / m
        return
    # exp(A*dt) and Psi = int_0^dt exp(A*s) ds from the series phi_1(X) = sum X^j/(j+1)! at
    # X = A*h, h = dt/2^nsq. By Cayley-Hamilton X^2 = -beta*X - kappa*I (beta = b*h/m,
    # kappa = k*h^2/m), so every series in X is u*I + w*X and Horner's step Q <- I + c*X*Q is
    # two scalar updates. Gamma = Psi[:, 1]/m keeps full relative precision where 1 - Phi would
    # cancel. Terms and scaling are chosen per axis (controller.py) for 1e-16 truncation.
    nsq = int(P[NSQ, i])
    h = dt / (1 << nsq)
    beta = b * h / m
    kappa = k * h * h / m
    u = 1.0
    w = 0.0
    for j in range(int(P[NTERMS, i]), 0, -1):
        c = 1.0 / (j + 1)
        u, w = 1.0 - c * kappa * w, c * (u - beta * w)
    # Phi = I + X*Q = (1 - kappa*w)*I + (u - beta*w)*X;  Psi = h*Q.
    a = 1.0 - kappa * w
    g = u - beta * w
    f00 = a
    f01 = g * h
    f10 = -g * kappa / h
    f11 = a - g * beta
    s01 = w * h * h
    s11 = g * h
    for _ in range(nsq):
        n01 = (1.0 + f00) * s01 + f01 * s11
        n11 = f10 * s01 + (1.0 + f11) * s11
        s01 = n01
        s11 = n11
        a00 = f00 * f00 + f01 * f10
        a01 = f00 * f01 + f01 * f11
        a10 = f10 * f00 + f11 * f10
        a11 = f10 * f01 + f11 * f11
        f00 = a00
        f01 = a01
        f10 = a10
        f11 = a11
    S[P00, i] = f00
    S[P01, i] = f01
    S[P10, i] = f10
    S[P11, i] = f11
    S[G0, i] = s01 / m
    S[G1, i] = s11 / m


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
    # tanh(x) rounds to exactly 1.0 in float64 from x = 19.0616 on; skip libm's 16 ns there.
    chi = 1.0 if x >= TANH_IS_ONE else math.tanh(x)
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
def advance(S: NDArray[np.float64], out: NDArray[np.float64], n: int, i: int, f: float) -> None:
    """Integrate axis i over tick n with its cached Phi, Gamma; write the tick's outputs."""
    e = S[E, i]
    v = S[V, i]
    e_next = S[P00, i] * e + S[P01, i] * v + S[G0, i] * f
    v_next = S[P10, i] * e + S[P11, i] * v + S[G1, i] * f
    S[E, i] = e_next
    S[V, i] = v_next
    out[OUT_OFFSET, n, i] = e_next
    out[OUT_VELOCITY, n, i] = v_next
    out[OUT_DAMPING, n, i] = S[B, i]
    out[OUT_STIFFNESS, n, i] = S[K, i]


@njit(cache=True)
def run(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    out: NDArray[np.float64],
    contact: NDArray[np.int8],
) -> int:
    """Advance the controller over every row of force (T, A); -1, or n*A+i of a non-finite f."""
    T: int = force.shape[0]
    A: int = force.shape[1]
    law = cfg[LAW]
    chi_reading = cfg[CHI]
    beta_reading = cfg[BETA_READING]
    zoh = cfg[INTEGRATOR] == ZOH
    sm = cfg[SM] != 0
    guard = cfg[GUARD] != 0
    debounce = cfg[DEBOUNCE]
    release = cfg[RELEASE]
    hold = cfg[HOLD]
    # A group is busy unless it is free with no pending debounce; with no busy group, no force
    # above delta and a law whose free parameters are nominal, a tick is the cached LTI update.
    busy = 0
    if sm:
        for g in range(A):
            if G[STATE, g] != FREE or G[CNT_ABOVE, g] != 0:
                busy += 1
    for n in range(T):
        any_above = False
        for i in range(A):
            f = force[n, i]
            if not math.isfinite(f):
                return n * A + i
            if abs(f) > P[DELTA, i]:
                any_above = True
        if not any_above and busy == 0 and (sm or law == FIXED):
            for i in range(A):
                advance(S, out, n, i, force[n, i])
                contact[n, i] = FREE
            continue
        for g in range(A):
            S[GABOVE, g] = 0.0
            S[GSUMSQ, g] = 0.0
            S[GSETTLED, g] = 1.0
        for i in range(A):
            g = cfg[NC + i]
            f = force[n, i]
            if abs(f) > P[DELTA, i]:
                S[GABOVE, g] = 1.0
            S[GSUMSQ, g] += f * f
            if abs(S[E, i]) > P[TOL, i] or S[K, i] != P[KD, i] or S[B, i] != P[BD, i]:
                S[GSETTLED, g] = 0.0
        for g in range(A):
            above = S[GABOVE, g] > 0.0
            if not sm:
                G[STATE, g] = CONTACT if above else FREE
                continue
            state = G[STATE, g]
            if state == FREE or state == RECOVERING:
                if above:
                    G[CNT_ABOVE, g] += 1
                    if G[CNT_ABOVE, g] >= debounce:
                        state = CONTACT
                        G[TICKS, g] = 0
                        G[CNT_BELOW, g] = 0
                        G[CNT_ABOVE, g] = 0
                else:
                    G[CNT_ABOVE, g] = 0
                    if state == RECOVERING and S[GSETTLED, g] > 0.0:
                        state = FREE
            else:
                G[TICKS, g] += 1
                if above:
                    G[CNT_BELOW, g] = 0
                else:
                    G[CNT_BELOW, g] += 1
                    if G[CNT_BELOW, g] >= release:
                        state = RECOVERING
                        G[CNT_ABOVE, g] = 0
                if state == CONTACT and G[TICKS, g] >= hold:
                    state = HOLDING
            G[STATE, g] = state
        for i in range(A):
            g = cfg[NC + i]
            state = G[STATE, g]
            f = force[n, i]
            k_prev = S[K, i]
            if sm and (state == FREE or state == RECOVERING):
                b = P[BD, i]
                k = P[KD, i]
            else:
                b, k = law_gains(law, chi_reading, beta_reading, P, i, f, S[GSUMSQ, g])
                if sm and state == HOLDING:
                    k = min(k, k_prev)  # sustained contact keeps the avoidance pose
            if guard:
                k = min(k, k_prev * P[GROWTH, i])
            if b != S[B, i] or k != k_prev:
                discretise(P, S, i, b, k, zoh)
                S[B, i] = b
                S[K, i] = k
            advance(S, out, n, i, f)
            contact[n, i] = state
        busy = 0
        if sm:
            for g in range(A):
                if G[STATE, g] != FREE or G[CNT_ABOVE, g] != 0:
                    busy += 1
    return -1
