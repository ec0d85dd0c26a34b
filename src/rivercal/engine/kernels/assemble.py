"""The level system of one Picard iteration: ``V(z^k) + w(z^k)(z - z^k) - V^n = Δt Σ Q``.

With Q = A(θ u^{n+1} + (1-θ) u^n) and each link's ``u = r - f (z2 - z1)``, the continuity equation of
every h-point is linear in the levels: a symmetric positive definite system (reference note §A,
after D-Flow FM ``s1ini.f90``/``s1nod.f90``). Discharge and rating boundaries and laterals enter the
right-hand side; level boundaries are Dirichlet rows whose couplings move to the right-hand side,
keeping the matrix symmetric. Every h-point has a minimum storage area that extends below the bed,
so the diagonal stays positive and a level can never become NaN.
"""

from __future__ import annotations

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import (
    BOUNDARY_LEVEL,
    BOUNDARY_RATING,
    LINK_CHANNEL,
    LINK_PUMP,
    RUN_COUNT,
    RUN_EDGE,
    RUN_GENERAL,
    RUN_K1,
    RUN_K2,
    RUN_LINK,
)
from rivercal.engine.kernels.forcing import rating_flow
from rivercal.engine.kernels.lookup import hp_volume_width_piece

__all__ = ["assemble", "in_pieces"]


@kernel
def assemble(net, work, zk, vol, u, theta, dt):
    """The level system linearised at ``zk`` into ``work``: diagonal, off-diagonal per edge, right-hand side.

    Rating boundaries store their linearised outflow ``rq0 + rslope * z`` (m³/s) for the balance.
    A point's volume is linear on each piece ``[zlo, zhi]`` (m AD) of its volume curve
    (:func:`.lookup.hp_volume_width_piece`): ``V = p_v + p_w (z - p_z)``; the tables are read only when
    ``zk`` leaves the piece of the last look-up. The linear form depends on the piece alone, so a run's
    result does not depend on what was simulated before it. :func:`finish_step` uses the piece too.

    The points whose level left its piece are listed first (``work.outside``, a pass without a branch per point)
    and looked up from the list: a flowing network has some in every step (the synthetic one 19 of its 412 points
    per step, its levels crossing the tables' 5 mm cells), a branch per point mispredicted at each of them, and
    from the list the look-ups also overlap (the assembly in the time loop 1.64 µs per step before, 1.42 after:
    ``benchmarks/engine_cycles.py``, docs/explanation/engine.md).
    """
    diag, off, rhs, src, fixed_val = work.diag, work.off, work.rhs, work.src, work.fixed_val
    area, fco, rco = work.area, work.fco, work.rco
    sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin = (
        net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin)
    tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt = (
        net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top, net.tab_at, net.tab_wt)
    lk_type = net.lk_type
    zlo, zhi, p_z, p_v, p_w = work.zlo, work.zhi, work.p_z, work.p_v, work.p_w
    inv_dt = 1.0 / dt
    if not in_pieces(zk, zlo, zhi):  # some levels left the piece of their last look-up: find their pieces
        outside = work.outside
        n_out = 0
        for i in range(zk.size):  # their list first, without a branch per point (see the docstring)
            outside[n_out] = i
            n_out += not ((zlo[i] <= zk[i]) & (zk[i] <= zhi[i]))
        for k in range(n_out):
            i = outside[k]
            zlo[i], zhi[i], p_z[i], p_v[i], p_w[i] = hp_volume_width_piece(
                sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin, tab_off, tab_n, tab_dd, tab_idd, tab_top,
                tab_wt_top, tab_at, tab_wt, i, zk[i])
    for i in range(zk.size):  # no branch: vectorises
        z = zk[i]
        w = p_w[i]
        v = p_v[i] + w * (z - p_z[i])
        diag[i] = w * inv_dt
        rhs[i] = (w * z - (v - vol[i])) * inv_dt + src[i]
    off[:] = 0.0
    for run in net.lk_runs:  # run by run, see .fluxes.compute_fluxes: contiguous, vectorised, each point in link order
        l0, k1, k2, e0 = run[RUN_LINK], run[RUN_K1], run[RUN_K2], run[RUN_EDGE]
        if run[RUN_GENERAL]:  # a pump, or a link at a level boundary
            _assemble_general_link(net, work, l0, u, theta)
            continue
        for j in range(run[RUN_COUNT]):
            link = l0 + j
            th = theta if lk_type[link] == LINK_CHANNEL else 1.0
            diag[k2 + j] += th * area[link] * fco[link]
            rhs[k2 + j] += area[link] * (th * rco[link] + (1.0 - th) * u[link])
        for j in range(run[RUN_COUNT]):
            link = l0 + j
            th = theta if lk_type[link] == LINK_CHANNEL else 1.0
            c = th * area[link] * fco[link]
            diag[k1 + j] += c
            rhs[k1 + j] -= area[link] * (th * rco[link] + (1.0 - th) * u[link])
            off[e0 + j] -= c
    for bnd in range(net.b_hp.size):
        i = net.b_hp[bnd]
        if net.b_type[bnd] == BOUNDARY_RATING:
            qr, slope = rating_flow(net.b_rptr, net.b_rlev, net.b_rq, bnd, zk[i])
            work.rq0[bnd] = qr - slope * zk[i]
            work.rslope[bnd] = slope
            diag[i] += slope
            rhs[i] -= work.rq0[bnd]
        elif net.b_type[bnd] == BOUNDARY_LEVEL:
            diag[i] = 1.0
            rhs[i] = fixed_val[i]


@kernel
def _assemble_general_link(net, work, link, u, theta):
    """The contribution of one pump, or of a link at a level-boundary point, to the level system.

    A pump's flux is fixed: it enters the right-hand sides. A level-boundary point has a Dirichlet row; the
    coupling of its neighbour moves to the neighbour's right-hand side, keeping the matrix symmetric.
    """
    diag, rhs, fixed, fixed_val = work.diag, work.rhs, work.fixed, work.fixed_val
    area, fco, rco = work.area, work.fco, work.rco
    k1 = net.lk_k1[link]
    k2 = net.lk_k2[link]
    if net.lk_type[link] == LINK_PUMP:
        rhs[k1] -= rco[link]
        rhs[k2] += rco[link]
        return
    th = theta if net.lk_type[link] == LINK_CHANNEL else 1.0
    c = th * area[link] * fco[link]
    a = area[link] * (th * rco[link] + (1.0 - th) * u[link])
    diag[k1] += c
    diag[k2] += c
    rhs[k1] -= a
    rhs[k2] += a
    if fixed[k1] or fixed[k2]:
        if not fixed[k2]:
            rhs[k2] += c * fixed_val[k1]
        elif not fixed[k1]:
            rhs[k1] += c * fixed_val[k2]
    else:
        work.off[net.lk_edge[link]] -= c


@kernel
def in_pieces(zk, zlo, zhi):
    """Whether every level ``zk`` (m AD) lies in the piece ``zlo``..``zhi`` of its volume curve last looked up.

    A conjunction without branches, so that it vectorises; a NaN level counts as outside.
    """
    inside = True
    for i in range(zk.size):
        inside &= (zlo[i] <= zk[i]) & (zk[i] <= zhi[i])
    return inside
