"""Phase 2 of ``blocks.py``: (b, k), Phi and Gamma of every (tick, axis) entry of a block.

The fast axes (b = b0 on every tick of the block, chi its series, k where the near-critical
series apply: the bulk of a session) in loops over all entries of the block, which LLVM
vectorises; each loop is a short chain, so the CPU overlaps its iterations (one loop from the
force to Gamma is a chain too long to overlap). The scratch W and the per-axis constants Q are
rows of entries t * A + i (tick t of the block, axis i), so these loops are plain elementwise
ones. The other axes of a block: ``general_axis``, scalar, ``bare_ticks``'s arithmetic.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.control.axis import (
    A2,
    CB,
    CE,
    CHI_ABS,
    CHI_SQUARE,
    CP,
    CX,
    DELTA,
    DT,
    DTM,
    GROWTH,
    KD,
    KX,
    T1,
    T2,
    T3,
    T4,
    T5,
    K,
    law_gains,
)
from hilrig.control.zoh import C_HAT, S_HAT, damping_terms, is_near_critical, terms

# Rows of the scratch W (NW, BLOCK * A), entry t * A + i: tick t of the block, axis i.
WB, WK, W00, W01, W10, W11, WG0, WG1, WF, WX, WQ, WCH, WSH = range(13)
NW = 13
# Rows of the per-axis constants broadcast to the entries of W, so phase 2's loops are flat.
QA2, QKD, QDELTA, QKX, QXX, QX, QE, QP, QDT, QDTM, QB0 = range(11)
NQ = 11


@njit(cache=True, inline="always")
def chi_input(chi_reading: int, f: float, group_sumsq: float) -> float:
    """The x of chi = tanh(x), as ``law_gains`` reads it."""
    if chi_reading == CHI_SQUARE:
        return f * f
    if chi_reading == CHI_ABS:
        return abs(f)
    return group_sumsq


@njit(cache=True, error_model="numpy")
def constants(
    law: int,
    chi_reading: int,
    beta_reading: int,
    guard: bool,
    P: NDArray[np.float64],
    Q: NDArray[np.float64],
    b0: NDArray[np.float64],
    kmin: NDArray[np.float64],
    near: NDArray[np.bool_],
    ticks: int,
) -> None:
    """Per axis: b0, the least k of the law (chi = 1), and whether the near-critical series
    apply at b0 for every k in [kmin, k_d] (their conditions hold on an interval of kappa, so
    its ends tell); the constants of phase 2 broadcast to ``ticks`` ticks of Q."""
    A: int = P.shape[1]
    for i in range(A):
        b0[i] = law_gains(law, chi_reading, beta_reading, P, i, 0.0, 0.0)[0]
        kmin[i] = (1.0 - P[A2, i] * 1.0) * P[KD, i]
        x, e, p = damping_terms(b0[i], P[DTM, i])
        near[i] = (
            is_near_critical(x, kmin[i] * P[KX, i])
            and is_near_critical(x, P[KD, i] * P[KX, i])
            and (not guard or P[GROWTH, i] >= 1.0)  # the guard then keeps k >= kmin
        )
        for t in range(ticks):
            j = t * A + i
            Q[QA2, j] = P[A2, i]
            Q[QKD, j] = P[KD, i]
            Q[QDELTA, j] = P[DELTA, i]
            Q[QKX, j] = P[KX, i]
            Q[QXX, j] = x * x
            Q[QX, j] = x
            Q[QE, j] = e
            Q[QP, j] = p
            Q[QDT, j] = P[DT, i]
            Q[QDTM, j] = P[DTM, i]
            Q[QB0, j] = b0[i]


@njit(cache=True, error_model="numpy")
def fast_entries(
    chi_reading: int,
    W: NDArray[np.float64],
    Q: NDArray[np.float64],
    dk: NDArray[np.float64],
    m: int,
) -> int:
    """k of the law (chi its series) for entries 0 .. m - 1 into dk; how many of them are
    above delta or have x > 1/16 (the fast path does not hold for their axes)."""
    wf = W[WF]
    wx = W[WX]
    qa2 = Q[QA2]
    qkd = Q[QKD]
    qdelta = Q[QDELTA]
    outside = 0
    for j in range(m):
        f = wf[j]
        x = chi_input(chi_reading, f, wx[j])
        outside += (x > 0.0625) | (abs(f) > qdelta[j])
        y = x * x
        chi = x + x * y * (((((T5 * y + T4) * y + T3) * y + T2) * y) + T1)
        dk[j] = (1.0 - qa2[j] * chi) * qkd[j]
    return outside


@njit(cache=True, error_model="numpy")
def fast_terms(
    W: NDArray[np.float64],
    Q: NDArray[np.float64],
    db: NDArray[np.float64],
    dk: NDArray[np.float64],
    m: int,
) -> None:
    """``near_critical`` and ``store`` for entries 0 .. m - 1 at b0's cached terms, in two
    loops (each a short chain)."""
    wq = W[WQ]
    wch = W[WCH]
    wsh = W[WSH]
    qkx = Q[QKX]
    qxx = Q[QXX]
    for j in range(m):
        q = dk[j] * qkx[j] - qxx[j]
        wq[j] = q
        wch[j] = ((C_HAT[3] * q + C_HAT[2]) * q + C_HAT[1]) * q + C_HAT[0]
        wsh[j] = ((S_HAT[3] * q + S_HAT[2]) * q + S_HAT[1]) * q + S_HAT[0]
    w00 = W[W00]
    w01 = W[W01]
    w10 = W[W10]
    w11 = W[W11]
    wg0 = W[WG0]
    wg1 = W[WG1]
    qx = Q[QX]
    qe = Q[QE]
    qp = Q[QP]
    qdt = Q[QDT]
    qdtm = Q[QDTM]
    qb0 = Q[QB0]
    for j in range(m):
        k = dk[j]
        q = wq[j]
        ch = wch[j]
        sh = wsh[j]
        x = qx[j]
        e = qe[j]
        dtm = qdtm[j]
        db[j] = qb0[j]
        eq = e * q
        ec = e - eq * ch
        e1 = e - eq * sh
        w00[j] = ec + x * e1
        w01[j] = qdt[j] * e1
        w10[j] = -(k * dtm) * e1
        w11[j] = ec - x * e1
        wg0[j] = (qp[j] + eq * (ch + x * sh)) / k
        wg1[j] = dtm * e1


@njit(cache=True, error_model="numpy")
def general_axis(
    law: int,
    chi_reading: int,
    beta_reading: int,
    guard: bool,
    P: NDArray[np.float64],
    S: NDArray[np.float64],
    W: NDArray[np.float64],
    db: NDArray[np.float64],
    dk: NDArray[np.float64],
    i: int,
    nb: int,
) -> None:
    """Axis i's entries of the block as ``bare_ticks`` computes them: ``law_gains`` (tanh
    where its series does not apply), the guard, ``terms`` with the b-only terms cached."""
    A: int = P.shape[1]
    kx = P[KX, i]
    dt = P[DT, i]
    dtm = P[DTM, i]
    for t in range(nb):
        j = t * A + i
        b, k = law_gains(law, chi_reading, beta_reading, P, i, W[WF, j], W[WX, j])
        if guard:
            k = min(k, S[K, i] * P[GROWTH, i])
        S[K, i] = k
        db[j] = b
        dk[j] = k
        if b != S[CB, i]:
            S[CB, i] = b
            S[CX, i], S[CE, i], S[CP, i] = damping_terms(b, dtm)
        phi00, e1, phi11, g0 = terms(S[CX, i], S[CE, i], S[CP, i], k * kx, k, kx)
        W[W00, j] = phi00
        W[W01, j] = dt * e1
        W[W10, j] = -(k * dtm) * e1
        W[W11, j] = phi11
        W[WG0, j] = g0
        W[WG1, j] = dtm * e1
