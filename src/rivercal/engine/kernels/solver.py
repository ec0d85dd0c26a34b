"""Sparse LDLᵀ factorisation and solve of the symmetric positive definite level system.

The elimination order and fill pattern come from
:func:`rivercal.engine.plan.elimination_order`. The matrix is given as its diagonal and one
value per (original or fill) edge; both are overwritten by the factorisation. No pivoting is
needed: the level matrix is a symmetric, diagonally dominant M-matrix.

:func:`ldl_solve` is the plain algorithm on the CSR arrays of the symbolic factorisation (factorisation and
forward elimination in one pass, then the back substitution).
:func:`ldl_solve_packed`, which the time loop uses, does the same arithmetic in the same order
(bit-identical results) several times as fast: along a branch every elimination step depends on
the previous one (divide, multiply, multiply, subtract), so the solve is bound by the latency of
that chain, and the packed version overlaps up to four chains and keeps each short (see its notes).
"""

from __future__ import annotations

import numpy as np

from rivercal.engine.kernels._jit import entry
from rivercal.engine.kernels.codes import SCHED_LANES, SCHED_WIDTH

__all__ = ["ldl_solve", "ldl_solve_packed"]

#: Values per step of the schedule: ``SCHED_LANES`` lanes (the solve below is written out for four).
_STEP = SCHED_LANES * SCHED_WIDTH
assert SCHED_LANES == 4, "ldl_solve_packed is written out for four lanes"


@entry
def ldl_solve(order, cptr, cedge, cother, uptr, ue1, ue2, utgt, diag, off, lval, rhs):
    """Factorise and solve in place; on return ``rhs`` holds the solution.

    Parameters
    ----------
    order, cptr, cedge, cother, uptr, ue1, ue2, utgt
        The symbolic factorisation (``sv_*`` fields of the network arrays).
    diag
        Diagonal of the matrix; overwritten by 1/D.
    off
        Off-diagonal value per edge (fill edges must be 0 on entry); overwritten by Schur updates.
    lval
        Work array, one value per edge: the multipliers of L.
    rhs
        Right-hand side; overwritten by the solution.
    """
    n = order.size
    for p in range(n):  # factorise and eliminate forward (rhs[k] has all its updates once p is reached)
        k = order[p]
        inv = 1.0 / diag[k]
        diag[k] = inv
        _eliminate_general(p, inv, rhs[k], cptr, cedge, cother, uptr, ue1, ue2, utgt, diag, off, lval, rhs)
    for i in range(n):
        rhs[i] *= diag[i]
    for p in range(n - 1, -1, -1):
        k = order[p]
        s = rhs[k]
        for c in range(cptr[p], cptr[p + 1]):
            s -= lval[cedge[c]] * rhs[cother[c]]
        rhs[k] = s


@entry
def _forward(rec, carried, d_carried, b_carried, diag, off, lval, rhs):
    """Eliminate the point of one schedule lane ``rec`` (its updates when it has at most two later points).

    ``carried`` is the point whose updated pivot ``d_carried`` and right-hand side ``b_carried`` the lane
    holds from its previous step. Returns the point the lane carries on with its pivot and right-hand
    side (point n: none, as for an empty lane), then 1/D and the unscaled right-hand side of ``rec``'s
    point for :func:`_eliminate_general`.
    """
    n = np.uint64(diag.size)  # unsigned like the schedule: mixing it with int64 would give float64
    k = rec[0]
    if k >= n:
        return n, 0.0, 0.0, 0.0, 0.0
    if k == carried:
        d = d_carried
        bk = b_carried
    else:
        d = diag[k]
        bk = rhs[k]
    inv = 1.0 / d
    diag[k] = inv
    rhs[k] = bk * inv
    m = rec[1]
    if m == 0 or m > 2:
        return n, 0.0, 0.0, inv, bk
    e1 = rec[2]
    o1 = rec[3]
    a1 = off[e1]
    l1 = a1 * inv
    lval[e1] = l1
    d1 = diag[o1] - l1 * a1
    b1 = rhs[o1] - l1 * bk
    diag[o1] = d1
    rhs[o1] = b1
    if m == 1:
        return o1, d1, b1, inv, bk
    e2 = rec[4]  # two later points: the updates (o1, o1), (o1, o2), (o2, o2) of plan.elimination_order
    o2 = rec[5]
    a2 = off[e2]
    l2 = a2 * inv
    lval[e2] = l2
    off[rec[6]] -= l1 * a2
    d2 = diag[o2] - l2 * a2
    b2 = rhs[o2] - l2 * bk
    diag[o2] = d2
    rhs[o2] = b2
    if rec[7] == 0:
        return o1, d1, b1, inv, bk
    return o2, d2, b2, inv, bk


@entry
def _eliminate_general(p, inv, bk, cptr, cedge, cother, uptr, ue1, ue2, utgt, diag, off, lval, rhs):
    """The updates of the elimination at position ``p`` of the CSR factorisation (any number of later points)."""
    for c in range(cptr[p], cptr[p + 1]):
        e = cedge[c]
        lval[e] = off[e] * inv
    for u in range(uptr[p], uptr[p + 1]):
        v = lval[ue1[u]] * off[ue2[u]]
        t = utgt[u]
        if t < 0:
            diag[-1 - t] -= v
        else:
            off[t] -= v
    for c in range(cptr[p], cptr[p + 1]):
        rhs[cother[c]] -= lval[cedge[c]] * bk


@entry
def _back(rec, solved, x_solved, lval, rhs):
    """Back substitution of one schedule lane with at most two later points; returns its point and value.

    ``solved`` is the point the lane solved last, with value ``x_solved``; an empty lane returns point n.
    """
    n = np.uint64(rhs.size)
    k = rec[0]
    if k >= n:
        return n, 0.0
    x = rhs[k]
    m = rec[1]
    if m == 1 or m == 2:
        o = rec[3]
        x -= lval[rec[2]] * (x_solved if o == solved else rhs[o])
        if m == 2:
            o = rec[5]
            x -= lval[rec[4]] * (x_solved if o == solved else rhs[o])
    rhs[k] = x
    return k, x


@entry
def ldl_solve_packed(sched, cptr, cedge, cother, uptr, ue1, ue2, utgt, diag, off, lval, rhs):
    """:func:`ldl_solve` on the four-lane schedule of the factorisation (bit-identical result).

    Parameters
    ----------
    sched
        :func:`rivercal.engine.plan.solver_schedule` (``sv_sched``).
    cptr, cedge, cother, uptr, ue1, ue2, utgt
        The CSR arrays of the symbolic factorisation, read only for eliminations with more than two
        later neighbours.
    diag, off, lval, rhs
        As in :func:`ldl_solve`.

    Notes
    -----
    - Factorisation, forward substitution and the scaling by 1/D run in one pass: when point k is
      eliminated, all updates of its right-hand side have been made (they come from points
      eliminated before it).
    - Each step eliminates up to four independent points (the schedule's lanes): their
      dependency chains (divide, multiply, multiply, subtract) overlap in the processor. With two lanes
      the synthetic network's solve took 243 steps, with four 126 (its longest chain; the elimination
      order of :func:`rivercal.engine.plan.elimination_order` keeps that short).
    - Along a chain the point a lane updates is the one it eliminates next: its pivot and
      right-hand side stay in registers (the lane's "carry") instead of a store and a reload;
      the back substitution carries the last value each lane solved.
    - The schedule's indices are unsigned: numba adds no negative-index wraparound to the accesses.
    """
    n = np.uint64(diag.size)
    n_steps = sched.size // _STEP
    w = SCHED_WIDTH
    ka = kb = kc = kd = n  # the point each lane carries, with its pivot and right-hand side
    da = db = dc = dd = ba = bb = bc = bd = 0.0
    for s in range(n_steps):
        at = _STEP * s
        ra = sched[at : at + w]
        ka, da, ba, inv, bk = _forward(ra, ka, da, ba, diag, off, lval, rhs)
        kb, db, bb, _, _ = _forward(sched[at + w : at + 2 * w], kb, db, bb, diag, off, lval, rhs)
        kc, dc, bc, _, _ = _forward(sched[at + 2 * w : at + 3 * w], kc, dc, bc, diag, off, lval, rhs)
        kd, dd, bd, _, _ = _forward(sched[at + 3 * w : at + _STEP], kd, dd, bd, diag, off, lval, rhs)
        if ra[1] > 2:  # such a step has one lane
            _eliminate_general(ra[6], inv, bk, cptr, cedge, cother, uptr, ue1, ue2, utgt, diag, off, lval, rhs)
    ka = kb = kc = kd = n  # the point each lane solved last, with its value
    xa = xb = xc = xd = 0.0
    for s in range(n_steps - 1, -1, -1):
        at = _STEP * s
        ra = sched[at : at + w]
        if ra[1] > 2:
            xa = rhs[ra[0]]
            for c in range(cptr[ra[6]], cptr[ra[6] + 1]):
                xa -= lval[cedge[c]] * rhs[cother[c]]
            ka = ra[0]
            rhs[ka] = xa
        else:
            ka, xa = _back(ra, ka, xa, lval, rhs)
        kb, xb = _back(sched[at + w : at + 2 * w], kb, xb, lval, rhs)
        kc, xc = _back(sched[at + 2 * w : at + 3 * w], kc, xc, lval, rhs)
        kd, xd = _back(sched[at + 3 * w : at + _STEP], kd, xd, lval, rhs)
