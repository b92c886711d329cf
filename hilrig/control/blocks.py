"""The bare law over blocks of ticks: ``bare.py``'s loop, phase by phase over up to BLOCK ticks.

Per block: (1) tick by tick, the force into a scratch row and the contact flags, stopping
before a non-finite force; (2) the law's (b, k) and Phi, Gamma of every (tick, axis) entry of
the block, in loops over all entries that LLVM vectorises, for the axes whose b is b0 (the law's
b at or below delta) on every tick of the block, chi its series (x <= 1/16) and k in a range
where the near-critical series apply: the bulk of a session. Each loop is a short chain, so the
CPU overlaps its iterations (one loop from the force to Gamma is a chain too long to overlap).
The other axes of the block take the general path after, scalar: ``law_gains`` with tanh, the
guard, ``terms`` with the b terms cached, as ``bare_ticks``. (3) Tick by tick, the integration.
The scratch rows are tick-major (entry t * A + i), so where ``out`` is C-contiguous its damping
and stiffness of the block are contiguous too and phase 2 writes them there directly.

The arithmetic is ``bare_ticks``'s operation for operation (no reordering, no contraction), so
the results are the same to the bit; ``tests/control/test_control_blocks.py`` checks it.
"""

from __future__ import annotations

import math

import numpy as np
from numba.extending import overload
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.control.axis import (
    BETA_READING,
    CB,
    CHI,
    CHI_GROUP_SQUARE,
    CONTACT,
    DELTA,
    FREE,
    G0,
    G1,
    GABOVE,
    GROWTH,
    GSUMSQ,
    GUARD,
    LAW,
    NC,
    OUT_DAMPING,
    OUT_OFFSET,
    OUT_STIFFNESS,
    OUT_VELOCITY,
    P00,
    P01,
    P10,
    P11,
    STATE,
    B,
    E,
    K,
    V,
)
from hilrig.control.block_terms import (
    NQ,
    NW,
    W00,
    W01,
    W10,
    W11,
    WB,
    WF,
    WG0,
    WG1,
    WK,
    WX,
    chi_input,
    constants,
    fast_entries,
    fast_terms,
    general_axis,
)

#: Ticks per block: its scratch (24 rows of BLOCK * A float64) stays in the L2 cache.
BLOCK = 128


def slab(
    out: NDArray[np.float64], q: int, start: int, stop: int, m: int, scratch: NDArray[np.float64]
) -> NDArray[np.float64]:
    """out[q, start:stop] as m contiguous entries where out is C-contiguous, else scratch[:m]."""
    raise NotImplementedError  # compiled only: the overload below


@overload(slab)
def _slab(out, q, start, stop, m, scratch):  # type: ignore[no-untyped-def]
    if out.layout == "C":
        return lambda out, q, start, stop, m, scratch: out[q, start:stop].reshape(m)
    return lambda out, q, start, stop, m, scratch: scratch[:m]


def is_c(a: NDArray[np.float64]) -> bool:
    """Whether a's type is C-contiguous (the case where ``slab`` is a view of it)."""
    raise NotImplementedError  # compiled only: the overload below


@overload(is_c)
def _is_c(a):  # type: ignore[no-untyped-def]
    contiguous = a.layout == "C"
    return lambda a: contiguous


@njit(cache=True)
def contact_ticks(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    W: NDArray[np.float64],
    contact: NDArray[np.int8],
    start: int,
    stop: int,
) -> tuple[int, int]:
    """Phase 1 over ticks start .. stop - 1: the force into W, the contact flags; (the tick
    the block ends before, -1 or n*A+i of the first non-finite force)."""
    A: int = force.shape[1]
    group = cfg[CHI] == CHI_GROUP_SQUARE
    for n in range(start, stop):
        j0 = (n - start) * A
        any_above = False
        finite = True
        for i in range(A):
            f = force[n, i]
            W[WF, j0 + i] = f
            finite = finite and math.isfinite(f)
            any_above = any_above or abs(f) > P[DELTA, i]
        if not finite:  # the state as ``bare_ticks`` leaves it when it stops there
            if n > start:
                group_state(force, P, cfg, S, G, n - 1)
            for g in range(A):
                S[GABOVE, g] = 0.0
                S[GSUMSQ, g] = 0.0
            for i in range(A):
                f = force[n, i]
                if not math.isfinite(f):
                    return n, n * A + i
                g = cfg[NC + i]
                if abs(f) > P[DELTA, i]:
                    S[GABOVE, g] = 1.0
                if group:
                    S[GSUMSQ, g] += f * f
        if not any_above and not group:
            for i in range(A):
                contact[n, i] = FREE
            if n == stop - 1:
                group_state(force, P, cfg, S, G, n)
            continue
        group_state(force, P, cfg, S, G, n)
        for i in range(A):
            g = cfg[NC + i]
            contact[n, i] = CONTACT if S[GABOVE, g] > 0.0 else FREE
            W[WX, j0 + i] = S[GSUMSQ, g]
    return stop, -1


@njit(cache=True, inline="always")
def group_state(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    n: int,
) -> None:
    """Tick n's group scratch and contact state, as ``bare_ticks`` leaves them."""
    A: int = force.shape[1]
    for g in range(A):
        S[GABOVE, g] = 0.0
        S[GSUMSQ, g] = 0.0
    for i in range(A):
        f = force[n, i]
        g = cfg[NC + i]
        if abs(f) > P[DELTA, i]:
            S[GABOVE, g] = 1.0
        if cfg[CHI] == CHI_GROUP_SQUARE:
            S[GSUMSQ, g] += f * f
    for g in range(A):
        G[STATE, g] = CONTACT if S[GABOVE, g] > 0.0 else FREE


@njit(cache=True)
def integrate_block(
    W: NDArray[np.float64],
    S: NDArray[np.float64],
    force: NDArray[np.float64],
    out: NDArray[np.float64],
    start: int,
    nb: int,
) -> None:
    """Phase 3: integrate ticks start .. start + nb - 1 with the Phi, Gamma of W's entries."""
    A: int = force.shape[1]
    for t in range(nb):
        n = start + t
        j0 = t * A
        for i in range(A):
            j = j0 + i
            f = force[n, i]
            e = S[E, i]
            v = S[V, i]
            e_next = W[W00, j] * e + W[W01, j] * v + W[WG0, j] * f
            v_next = W[W10, j] * e + W[W11, j] * v + W[WG1, j] * f
            S[E, i] = e_next
            S[V, i] = v_next
            out[OUT_OFFSET, n, i] = e_next
            out[OUT_VELOCITY, n, i] = v_next


@njit(cache=True, error_model="numpy")
def run_blocks(
    force: NDArray[np.float64],
    P: NDArray[np.float64],
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],
    G: NDArray[np.int64],
    out: NDArray[np.float64],
    contact: NDArray[np.int8],
) -> int:
    """``run_bare`` for the ZOH integrator and a law other than fixed, over blocks of ticks."""
    T: int = force.shape[0]
    A: int = force.shape[1]
    law = cfg[LAW]
    chi_reading = cfg[CHI]
    beta_reading = cfg[BETA_READING]
    guard = cfg[GUARD] != 0
    ticks = min(BLOCK, T)
    W = np.empty((NW, ticks * A))  # the one allocation: scratch for the call
    Q = np.empty((NQ, ticks * A))
    b0 = np.empty(A)
    kmin = np.empty(A)
    near = np.empty(A, dtype=np.bool_)
    fast = np.empty(A, dtype=np.bool_)
    constants(law, chi_reading, beta_reading, guard, P, Q, b0, kmin, near, ticks)
    for start in range(0, T, ticks):
        stop, bad = contact_ticks(force, P, cfg, S, G, W, contact, start, min(start + ticks, T))
        nb = stop - start
        if nb == 0:
            return bad
        m = nb * A
        db = slab(out, OUT_DAMPING, start, stop, m, W[WB])
        dk = slab(out, OUT_STIFFNESS, start, stop, m, W[WK])
        all_fast = True
        for i in range(A):
            fast[i] = near[i] and S[CB, i] == b0[i] and (not guard or S[K, i] >= kmin[i])
            all_fast = all_fast and fast[i]
        outside = fast_entries(chi_reading, W, Q, dk, m)
        if outside > 0 or not all_fast:
            for i in range(A):
                for t in range(nb):
                    f = W[WF, t * A + i]
                    if chi_input(chi_reading, f, W[WX, t * A + i]) > 0.0625 or abs(f) > P[DELTA, i]:
                        fast[i] = False
                        break
        if guard:
            for i in range(A):
                if fast[i]:
                    growth = P[GROWTH, i]
                    k = S[K, i]
                    for t in range(nb):
                        k = min(dk[t * A + i], k * growth)
                        dk[t * A + i] = k
        fast_terms(W, Q, db, dk, m)
        for i in range(A):
            if not fast[i]:
                general_axis(law, chi_reading, beta_reading, guard, P, S, W, db, dk, i, nb)
        last = (nb - 1) * A
        for i in range(A):
            S[B, i] = db[last + i]
            S[K, i] = dk[last + i]
        integrate_block(W, S, force, out, start, nb)
        if not is_c(out):
            for t in range(nb):
                for i in range(A):
                    out[OUT_DAMPING, start + t, i] = db[t * A + i]
                    out[OUT_STIFFNESS, start + t, i] = dk[t * A + i]
        for i in range(A):
            S[P00, i] = W[W00, last + i]
            S[P01, i] = W[W01, last + i]
            S[P10, i] = W[W10, last + i]
            S[P11, i] = W[W11, last + i]
            S[G0, i] = W[WG0, last + i]
            S[G1, i] = W[WG1, last + i]
        if bad >= 0:
            return bad
    return -1
