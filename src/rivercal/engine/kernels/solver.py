"""Sparse LDLᵀ factorisation and solve of the symmetric positive definite level system.

The elimination order and fill pattern come from
:func:`rivercal.engine.compile.elimination_order`. The matrix is given as its diagonal and one
value per (original or fill) edge; both are overwritten by the factorisation. No pivoting is
needed: the level matrix is a symmetric, diagonally dominant M-matrix.
"""

from __future__ import annotations

from rivercal.engine.kernels._jit import kernel

__all__ = ["ldl_solve"]


@kernel
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
    for p in range(n):
        k = order[p]
        inv = 1.0 / diag[k]
        diag[k] = inv
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
    for p in range(n):
        bk = rhs[order[p]]
        for c in range(cptr[p], cptr[p + 1]):
            rhs[cother[c]] -= lval[cedge[c]] * bk
    for i in range(n):
        rhs[i] *= diag[i]
    for p in range(n - 1, -1, -1):
        k = order[p]
        s = rhs[k]
        for c in range(cptr[p], cptr[p + 1]):
            s -= lval[cedge[c]] * rhs[cother[c]]
        rhs[k] = s
