"""The compiled admittance kernel: one loop shared by the live ``step`` and offline ``simulate``.

Per tick n and axis i the kernel reads f[n, i], updates the group's contact state (Algorithm 2,
or contact while above delta without it), picks b and k from the law, applies the Theorem 1
rate guard, discretises (``zoh.py``) and integrates one period: offset[n] = e(t_n + dt). ``run``
is the entry point; with the state machine it is ``run_machine`` below, without it ``bare.py``'s
``run_bare`` (inlined: a call between compiled functions costs ``step`` seven arrays' refcounts).
The packed layout (row indices) and one axis's arithmetic are ``axis.py``'s.

``run`` compiles ``axis.py``, ``bare.py``, ``blocks.py``, ``block_terms.py`` and ``zoh.py`` into
itself (and ``hilrig/tick/kernel.py`` compiles ``run`` into itself); numba's cache is keyed on
the sources of all of them (:mod:`hilrig.compiled`), so a change to any one recompiles them.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.control.axis import (
    BD,
    BETA_READING,
    CHI,
    CNT_ABOVE,
    CNT_BELOW,
    CONTACT,
    DEBOUNCE,
    DELTA,
    FREE,
    GABOVE,
    GROWTH,
    GSETTLED,
    GSUMSQ,
    GUARD,
    HOLD,
    HOLDING,
    INTEGRATOR,
    KD,
    LAW,
    NC,
    RECOVERING,
    RELEASE,
    SM,
    STATE,
    TICKS,
    TOL,
    ZOH,
    B,
    E,
    K,
    advance,
    discretise,
    law_gains,
)
from hilrig.control.bare import run_bare


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
    if cfg[SM] != 0:
        return run_machine(force, P, cfg, S, G, out, contact)
    return run_bare(force, P, cfg, S, G, out, contact)


@njit(cache=True)
def run_machine(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    out: NDArray[np.float64],
    contact: NDArray[np.int8],
) -> int:
    """``run`` with the Algorithm 2 state machine."""
    T: int = force.shape[0]
    A: int = force.shape[1]
    law = cfg[LAW]
    chi_reading = cfg[CHI]
    beta_reading = cfg[BETA_READING]
    zoh = cfg[INTEGRATOR] == ZOH
    guard = cfg[GUARD] != 0
    debounce = cfg[DEBOUNCE]
    release = cfg[RELEASE]
    hold = cfg[HOLD]
    # A group is busy unless it is free with no pending debounce; with no busy group, no force
    # above delta and a law whose free parameters are nominal, a tick is the cached LTI update.
    busy = 0
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
        if not any_above and busy == 0:
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
            if state == FREE or state == RECOVERING:
                b = P[BD, i]
                k = P[KD, i]
            else:
                b, k = law_gains(law, chi_reading, beta_reading, P, i, f, S[GSUMSQ, g])
                if state == HOLDING:
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
        for g in range(A):
            if G[STATE, g] != FREE or G[CNT_ABOVE, g] != 0:
                busy += 1
    return -1
