"""The bare law's loop (no state machine): ``run`` without ``cfg[SM]``.

A group is in contact while one of its axes is above delta, and the law's (b, k) change on
(nearly) every tick (chi follows the sensor noise), so every tick discretises. A trace of at
least ``MIN_BLOCK_TICKS`` ticks under the ZOH integrator goes to ``blocks.py`` (blocks of ticks,
phase by phase); a shorter one (``step``: one tick), the Euler integrator and the fixed law go
tick by tick here. Both give ``run_machine``'s arithmetic: the results are the same to the bit.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.control.axis import (
    BETA_READING,
    CB,
    CE,
    CHI,
    CHI_GROUP_SQUARE,
    CONTACT,
    CP,
    CX,
    DELTA,
    FIXED,
    FREE,
    GABOVE,
    GROWTH,
    GSUMSQ,
    GUARD,
    INTEGRATOR,
    KX,
    LAW,
    NC,
    OUT_DAMPING,
    OUT_STIFFNESS,
    STATE,
    ZOH,
    B,
    K,
    advance,
    discretise,
    integrate,
    law_gains,
    store,
)
from hilrig.control.blocks import run_blocks
from hilrig.control.zoh import is_near_critical, near_critical

#: Traces from this many ticks on go to ``blocks.py``: below, its scratch costs more than it saves.
MIN_BLOCK_TICKS = 16


@njit(cache=True, inline="always", error_model="numpy")
def run_bare(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    out: NDArray[np.float64],
    contact: NDArray[np.int8],
) -> int:
    """``run`` without the state machine; -1, or n*A+i of a non-finite f. Inlined into ``run``:
    a call between compiled functions costs ``step`` the reference counts of seven arrays."""
    if force.shape[0] >= MIN_BLOCK_TICKS and cfg[INTEGRATOR] == ZOH and cfg[LAW] != FIXED:
        return run_blocks(force, P, cfg, S, G, out, contact)
    return bare_ticks(force, P, cfg, S, G, out, contact)


@njit(cache=True, error_model="numpy")
def bare_ticks(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    out: NDArray[np.float64],
    contact: NDArray[np.int8],
) -> int:
    """``run_bare`` tick by tick: every tick discretises (``gains_phases``), with the
    arithmetic of ``run_machine``'s path: the results are the same to the bit."""
    T: int = force.shape[0]
    A: int = force.shape[1]
    law = cfg[LAW]
    chi_reading = cfg[CHI]
    beta_reading = cfg[BETA_READING]
    zoh = cfg[INTEGRATOR] == ZOH
    guard = cfg[GUARD] != 0
    for n in range(T):
        for g in range(A):
            S[GABOVE, g] = 0.0
            S[GSUMSQ, g] = 0.0
        for i in range(A):
            f = force[n, i]
            if not math.isfinite(f):
                return n * A + i
            g = cfg[NC + i]
            if abs(f) > P[DELTA, i]:
                S[GABOVE, g] = 1.0
            if chi_reading == CHI_GROUP_SQUARE:
                S[GSUMSQ, g] += f * f
        for g in range(A):
            G[STATE, g] = CONTACT if S[GABOVE, g] > 0.0 else FREE
        if law == FIXED:  # (b, k) are those it was discretised with at rest
            for i in range(A):
                advance(S, out, n, i, force[n, i])
                contact[n, i] = G[STATE, cfg[NC + i]]
            continue
        gains_phases(law, chi_reading, beta_reading, zoh, guard, P, cfg, S, force, out, n)
        for i in range(A):  # (b, k) are in out already
            integrate(S, out, n, i, force[n, i])
            contact[n, i] = G[STATE, cfg[NC + i]]
    return -1


@njit(cache=True, inline="always", error_model="numpy")
def gains_phases(
    law: int,
    chi_reading: int,
    beta_reading: int,
    zoh: bool,
    guard: bool,
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    force: NDArray[np.float64],
    out: NDArray[np.float64],
    n: int,
) -> None:
    """``run_bare``'s tick n up to the integration: (b, k) of every axis into ``out``, then Phi
    and Gamma into S. Each phase's iterations are independent, so the CPU overlaps the axes:
    the near-critical series for every axis (no branch; the cached b terms assumed), then the
    full discretisation where that did not apply."""
    A: int = force.shape[1]
    for i in range(A):
        f = force[n, i]
        b, k = law_gains(law, chi_reading, beta_reading, P, i, f, S[GSUMSQ, cfg[NC + i]])
        if guard:
            k = min(k, S[K, i] * P[GROWTH, i])
        out[OUT_DAMPING, n, i] = b
        out[OUT_STIFFNESS, n, i] = k
    if zoh:
        for i in range(A):
            k = out[OUT_STIFFNESS, n, i]
            kappa = k * P[KX, i]
            store(P, S, i, k, near_critical(S[CX, i], S[CE, i], S[CP, i], kappa, k))
    for i in range(A):
        b = out[OUT_DAMPING, n, i]
        k = out[OUT_STIFFNESS, n, i]
        if not zoh or b != S[CB, i] or not is_near_critical(S[CX, i], k * P[KX, i]):
            discretise(P, S, i, b, k, zoh)
        S[B, i] = b
        S[K, i] = k
