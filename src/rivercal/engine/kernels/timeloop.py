"""The time loop of the staggered Delft scheme: one compiled call per simulated window.

Per step n → n+1 (reference note §A; Stelling & Duinmeijer 2003):

1. Channel links (:func:`channel_coefficients`): from the state at n, the upwind flow area A,
   implicit friction g|u|u/(C²R), explicit upwind advection (energy-head conservative where the
   flow accelerates, momentum conservative where it decelerates, with the link's own velocity
   taken implicitly) and the momentum that lateral inflow takes from the flow (u q_lat / A, the
   inflow arriving without velocity along the channel; implicit). The friction is linearised by
   Newton around the exact solution u* of the link's momentum equation at the levels of time n
   (a quadratic in u), giving ``u = r - f (z2 - z1)``: exact in steady flow, and bounded by
   friction when flow starts from rest (a Picard linearisation with |u^n| has no friction at
   u^n = 0 and overshoots there).
2. Picard iterations (at most ``max_iter``, stopping when the level change is below ``tol``),
   starting from the extrapolated level z^n + (z^n - z^{n-1}) (one iteration from this predictor
   is as accurate as two from z^n): structure links are linearised at the current iterate
   (:func:`structure_coefficients`); the continuity equation
   ``V(z^k) + w(z^k)(z - z^k) - V^n = Δt Σ Q`` with Q = A(θ u^{n+1} + (1-θ) u^n) gives a symmetric
   positive definite system in the levels (:func:`assemble`), solved by :func:`.solver.ldl_solve_packed`.
   Discharge and rating boundaries and laterals enter the right-hand side; level boundaries are
   Dirichlet rows whose couplings move to the right-hand side, keeping the matrix symmetric.
3. The fluxes of the last iterate update the stored volumes, ``V^{n+1} = V^n + Δt Σ Q``
   (:func:`finish_step`); the volume is the prognostic variable, so mass is conserved to
   round-off whatever the number of iterations or the table resolution. The new level is the
   last iterate; the small difference V(z^{n+1}) - V^{n+1} left by the linearisation is not lost
   but enters the right-hand side of the next step (the ``V(z^k) - V^n`` term).

Wetting and drying: a channel link carries no flow while its upwind depth is below ``min_depth``;
every h-point has a minimum storage area that extends below the bed, so the matrix diagonal stays
positive and a level can never become NaN. Extractions (negative laterals) are limited to half
of the water present at their point per step.

Each phase is its own compiled function taking the network arrays (``net``) and the scratch
arrays (``work``): LLVM optimises these small functions much better than one large loop body.
The per-point look-ups take explicit arrays (see :mod:`.lookup`). In the loops over all links and
points, the point, profile, link and storage indices read from the network's arrays are cast to
``np.uint64``: numba then adds no negative-index wraparound to the accesses they make (as in
:func:`.solver.ldl_solve_packed`; the arithmetic is unchanged).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.lookup import (
    flow_geometry,
    hp_volume_width,
    hp_volume_width_piece,
)
from rivercal.engine.kernels.solver import ldl_solve_packed
from rivercal.engine.kernels.structures import G, culvert_link, friction_c2r, weir_link

__all__ = [
    "STATUS_LEVEL",
    "STATUS_OK",
    "STATUS_VELOCITY",
    "Work",
    "apply_forcing",
    "assemble",
    "channel_coefficients",
    "compute_fluxes",
    "finish_step",
    "gross_outflow",
    "limit_draining_links",
    "make_work",
    "rating_flow",
    "run",
    "structure_coefficients",
    "switch_pumps",
]

STATUS_OK, STATUS_LEVEL, STATUS_VELOCITY = 0, 1, 2

#: Scratch arrays of :func:`run` (kernels do not allocate; see :mod:`._jit`): matrix diagonal,
#: right-hand side, iterate (m AD), sources (m³/s), lateral inflow per unit length (m²/s), net
#: inflow (m³/s), Dirichlet flags and levels,
#: off-diagonals and L multipliers per edge, link flux area (m²) and coefficients f (1/s) and
#: r (m/s), a second buffer of velocities (m/s) and fluxes (m³/s) that :func:`run` swaps with the
#: state's arrays every step, rating-boundary linearisation (m³/s, m²/s), the structure and pump
#: links, counters (steps, solves, drying re-solves), per point the
#: piece of its volume curve last looked up (:func:`assemble`): low and high end and reference level
#: (m AD), the volume there (m³) and the storage area (m²); the momentum terms of each
#: channel link (:func:`_momentum_other`), its wetted perimeter (m) and R^(4/3) (m^(4/3)) at the upwind
#: depth, and its friction value (unit of its friction type).
Work = namedtuple(
    "Work",
    ["diag", "rhs", "zk", "src", "qlat", "netq", "fixed", "fixed_val", "off", "lval", "area", "fco", "rco",
     "un", "qn", "rq0", "rslope", "struct_links", "pump_links", "stats", "zlo", "zhi", "p_z", "p_v", "p_w",
     "cb", "cs", "cc2r", "cdz", "cper", "cr43", "lfric"],
)


def make_work(net) -> Work:
    """Allocate the scratch arrays of :func:`run` for network arrays ``net``."""
    n_h = net.hp_bed.size
    n_l = net.lk_k1.size
    n_b = net.b_hp.size
    return Work(
        diag=np.empty(n_h), rhs=np.empty(n_h), zk=np.empty(n_h), src=np.zeros(n_h), qlat=np.zeros(n_h),
        netq=np.empty(n_h),
        fixed=np.zeros(n_h, dtype=np.bool_), fixed_val=np.zeros(n_h), off=np.zeros(net.sv_nedge),
        lval=np.zeros(net.sv_nedge), area=np.zeros(n_l), fco=np.zeros(n_l), rco=np.zeros(n_l),
        un=np.zeros(n_l), qn=np.zeros(n_l),
        rq0=np.zeros(n_b), rslope=np.zeros(n_b),
        struct_links=np.flatnonzero((net.lk_type == 1) | (net.lk_type == 2)).astype(np.int64),
        pump_links=np.flatnonzero(net.lk_type == 3).astype(np.int64),
        stats=np.zeros(3, dtype=np.int64),
        zlo=np.full(n_h, np.inf), zhi=np.full(n_h, -np.inf), p_z=np.zeros(n_h), p_v=np.zeros(n_h), p_w=np.zeros(n_h),
        cb=np.ones(n_l), cs=np.zeros(n_l), cc2r=np.ones(n_l), cdz=np.zeros(n_l), cper=np.ones(n_l), cr43=np.ones(n_l),
        lfric=np.ones(n_l),
    )


@kernel
def apply_forcing(net, work, n, forcing, dt, vol):
    """Sources (m³/s), Dirichlet levels (m AD) and lateral inflow per unit length (m²/s) of step ``n``.

    Only the entries of forced points are written: the others stay as :func:`run` set them at its start
    (no source, no lateral inflow, not fixed). Returns the total of the laterals (m³/s).
    """
    src, fixed, fixed_val, qlat = work.src, work.fixed, work.fixed_val, work.qlat
    b_hp, b_type, b_col = net.b_hp, net.b_type, net.b_col
    for bnd in range(b_hp.size):
        src[b_hp[bnd]] = 0.0
    for lat in range(net.lat_hp.size):
        src[net.lat_hp[lat]] = 0.0
        qlat[net.lat_hp[lat]] = 0.0
    for bnd in range(b_hp.size):
        i = b_hp[bnd]
        if b_type[bnd] == 0:
            src[i] += forcing[n, b_col[bnd]]
        elif b_type[bnd] == 1:
            fixed[i] = True
            fixed_val[i] = forcing[n, b_col[bnd]]
    total = 0.0
    for lat in range(net.lat_hp.size):
        i = net.lat_hp[lat]
        ql = forcing[n, net.lat_col[lat]]
        if ql < 0.0:
            ql = max(ql, -0.5 * max(vol[i], 0.0) / dt)
        else:
            qlat[i] += ql * net.hp_ilen[i]  # an extraction leaves with the flow's velocity: no momentum change
        src[i] += ql
        total += ql
    return total


@kernel
def channel_coefficients(net, work, z, u, q, dt, min_depth):
    """Flux area A (m²), f (1/s) and r (m/s) of every channel link from the state at time n.

    Upwind flow area and implicit friction; upwind advection from the velocity of the link that
    feeds the upwind point (inflow-weighted over all feeding links at a junction; none across
    structures or from a boundary); the lateral-inflow momentum sink u q_lat / A with q_lat the
    mean lateral inflow per unit length (m²/s) of the link's two points. The friction value of each
    link is ``work.lfric`` (set by :func:`run` from the run's parameters).

    Four passes: :func:`_link_geometry` looks up the flow geometry at the upwind depth (a gather from
    the tables); :func:`_momentum_simple` gathers the momentum terms of the links inside a branch, whose
    neighbours are the links before and after them (``net.mo_runs``), in a branch-free loop that
    reads contiguously and vectorises; :func:`_momentum_other` does the same for the other channel links
    (at junctions, structures and branch ends); :func:`_link_newton` solves each link's momentum equation.
    The coefficients written for structure and pump links are replaced before use, by
    :func:`switch_pumps` and :func:`structure_coefficients`.
    """
    _link_geometry(net, work, z, u, min_depth)
    _momentum_simple(net, work, z, u, q, dt)
    for link in net.mo_other:
        _momentum_other(net, work, link, z, u, q, dt)
    _link_newton(net.lk_ilen, work.area, work.cb, work.cs, work.cc2r, work.cdz, work.fco, work.rco)


@kernel
def _upwind(net, link, z, u):
    """Direction (+1 along the branch, -1 against), upwind depth (m) and upwind profile of a channel link."""
    k1 = np.uint64(net.lk_k1[link])
    k2 = np.uint64(net.lk_k2[link])
    u0 = u[link]
    if u0 > 0.0 or (u0 == 0.0 and z[k1] >= z[k2]):
        return 1.0, z[k1] - net.lk_b1[link], np.uint64(net.lk_p1[link])
    return -1.0, z[k2] - net.lk_b2[link], np.uint64(net.lk_p2[link])


@kernel
def _link_geometry(net, work, z, u, min_depth):
    """Per link: flux area (m²; 0 when dry or not a channel), wetted perimeter (m) and R^(4/3) at the upwind depth."""
    area, cper, cr43, lk_type = work.area, work.cper, work.cr43, net.lk_type
    for link in range(lk_type.size):
        area[link] = 0.0
        if lk_type[link] != 0:
            continue
        _, depth, prof = _upwind(net, link, z, u)
        if depth < min_depth:
            continue
        a_up, per, r43 = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af,
                                       net.tab_pf, net.tab_flow, prof, depth)
        if a_up > 0.0:
            area[link] = a_up
            cper[link] = per
            cr43[link] = r43


@kernel
def _momentum_simple(net, work, z, u, q, dt):
    """The momentum terms of :func:`_momentum_other` for the links of ``net.mo_runs``, without branches.

    Such a link joins points k1 and k1 + 1, neither of which receives a lateral, has no Chézy friction, and
    its upwind neighbour is link - 1 (flowing into k1) or link + 1 (flowing out of k2, so -q and -u point
    towards it). Every quantity is computed for every link and the right one selected, in the same
    floating-point operations as :func:`_momentum_other`; a dry link gets meaningless terms (numpy's error
    model: a division by its zero area gives inf, no exception), which :func:`_link_newton` masks.
    """
    area, cr43, lfric = work.area, work.cr43, work.lfric
    cb, cs, cc2r, cdz = work.cb, work.cs, work.cc2r, work.cdz
    lk_ilen, lk_ftype = net.lk_ilen, net.lk_ftype
    inv_dt = 1.0 / dt
    one = np.uint64(1)
    for run in net.mo_runs:
        l0, k0 = run[0], run[2]
        for j in range(run[1]):
            link = l0 + j
            k1 = k0 + j
            u0 = u[link]
            z1 = z[k1]
            z2 = z[k1 + one]
            up = (u0 > 0.0) | ((u0 == 0.0) & (z1 >= z2))
            sign = 1.0 if up else -1.0
            a_up = area[link]
            b = inv_dt  # no lateral at either end: the lateral-inflow term is 0
            rhs_u = u0 * inv_dt
            ilen = lk_ilen[link]
            ul = sign * u0
            q_nb = q[link - one] if up else -q[link + one]
            u_nb = u[link - one] if up else -u[link + one]
            feeds = (u0 != 0.0) & (q_nb > 0.0)
            qin = q_nb if feeds else 0.0
            uin = u_nb if feeds else 0.0
            uc = 0.5 * (ul + uin) if uin < ul else 0.5 * (qin + math.fabs(q[link])) / a_up
            advect = (qin > 0.0) & (uc > 0.0)
            dzl = z2 - z1
            cb[link] = (b + uc * ilen) if advect else b
            cs[link] = ((rhs_u + sign * uc * uin * ilen) if advect else rhs_u) - G * ilen * dzl
            cc2r[link] = friction_c2r(lk_ftype[link], lfric[link], 0.0, cr43[link])  # not Chézy: no radius
            cdz[link] = dzl


@kernel
def _momentum_other(net, work, link, z, u, q, dt):
    """The momentum terms of one channel link with flux area > 0, in ``work`` (see :func:`_link_newton`).

    The momentum equation of a link, per unit mass, is ``b u + kappa |u| u = s - g (z2 - z1) / dx`` with
    b (1/s) the inertia, lateral-inflow and implicit advection terms, kappa = g / (C² R) (1/m), and
    s (m/s²) the explicit terms; ``cs`` holds s - g (z2 - z1) / dx at the levels of time n, ``cc2r``
    C² R (m²/s²), ``cb`` b and ``cdz`` z2 - z1 (m).
    """
    a_up = work.area[link]
    if a_up <= 0.0:
        return
    lk_type, nl_ptr, nl_link, nl_sign = net.lk_type, net.nl_ptr, net.nl_link, net.nl_sign
    qlat = work.qlat
    k1 = np.uint64(net.lk_k1[link])
    k2 = np.uint64(net.lk_k2[link])
    u0 = u[link]
    sign, depth, _ = _upwind(net, link, z, u)
    per = work.cper[link]
    ftype = net.lk_ftype[link]
    radius = (a_up / per if per > 0.0 else depth) if ftype == 2 else 0.0
    inv_dt = 1.0 / dt
    ql = qlat[k1] + qlat[k2]
    b = inv_dt + 0.5 * ql / a_up if ql != 0.0 else inv_dt  # skips a division: exact, the term is +0 then
    rhs_u = u0 * inv_dt
    ilen = net.lk_ilen[link]
    if u0 != 0.0:
        ul = sign * u0
        qin = 0.0
        uin = 0.0
        if sign > 0.0:
            m, sm, kup = net.lk_nb1[link], net.lk_ns1[link], k1
        else:
            m, sm, kup = net.lk_nb2[link], net.lk_ns2[link], k2
        if m >= 0:  # one feeding channel link
            mu = np.uint64(m)
            if sm * q[mu] > 0.0:
                qin = sm * q[mu]
                uin = sm * u[mu]
        elif m == -1:  # junction: inflow-weighted velocity of the feeding links
            quin = 0.0
            blocked = False
            for c in range(nl_ptr[kup], nl_ptr[kup + np.uint64(1)]):
                j = nl_link[c]
                if j == link:
                    continue
                qj = nl_sign[c] * q[j]
                if qj > 0.0:
                    if lk_type[j] != 0:
                        blocked = True
                    qin += qj
                    quin += qj * nl_sign[c] * u[j]
            if blocked:
                qin = 0.0
            elif qin > 0.0:
                uin = quin / qin
        if qin > 0.0:
            if uin < ul:
                uc = 0.5 * (ul + uin)  # contraction: energy-head conservative
            else:
                uc = 0.5 * (qin + math.fabs(q[link])) / a_up  # expansion: momentum conservative
            if uc > 0.0:
                b += uc * ilen
                rhs_u += sign * uc * uin * ilen
    dzl = z[k2] - z[k1]
    work.cb[link] = b
    work.cs[link] = rhs_u - G * ilen * dzl
    work.cc2r[link] = friction_c2r(ftype, work.lfric[link], radius, work.cr43[link])
    work.cdz[link] = dzl


@kernel
def _link_newton(lk_ilen, area, cb, cs, cc2r, cdz, fco, rco):
    """Coefficients f (1/s) and r (m/s) of ``u = r - f (z2 - z1)`` per link with flux area > 0 (0 for the others).

    Newton linearisation of b u + kappa |u| u = s - g (z2 - z1) / dx around its solution u* at the
    levels of time n: u* = 2 s / (b + sqrt(b² + 4 kappa |s|)), du/d(z2 - z1) = -g / (dx sqrt(...)).
    Exact in steady flow, and bounded by friction when flow starts from rest. The loop has no
    branches (links without flow are masked at the end) so that it runs in SIMD lanes; the inputs
    of a masked link may be stale, which is harmless.
    """
    for link in range(area.size):
        s_u = cs[link]
        b = cb[link]
        kappa = G / cc2r[link]
        root = math.sqrt(b * b + 4.0 * kappa * math.fabs(s_u))
        f_u = G * lk_ilen[link] / root
        r_u = 2.0 * s_u / (b + root) + f_u * cdz[link]
        wet = area[link] > 0.0
        fco[link] = f_u if wet else 0.0
        rco[link] = r_u if wet else 0.0


@kernel
def switch_pumps(net, work, z, pump_on):
    """Pump switches from the suction-side level at time n; a pump link carries a fixed flux ``rco``."""
    for link in work.pump_links:
        s = net.lk_sidx[link]
        ksuc = net.lk_k1[link] if net.p_sign[s] > 0.0 else net.lk_k2[link]
        if pump_on[s] > 0.5 and z[ksuc] <= net.p_off[s]:
            pump_on[s] = 0.0
        elif pump_on[s] < 0.5 and z[ksuc] >= net.p_on[s]:
            pump_on[s] = 1.0
        work.area[link] = 0.0
        work.fco[link] = 0.0
        work.rco[link] = net.p_sign[s] * net.p_cap[s] * pump_on[s]


@kernel
def structure_coefficients(net, work, zk, dz, predict, u, crest, dt):
    """Weir and culvert links linearised at the level ``zk + predict * dz`` (m AD)."""
    for link in work.struct_links:
        s = net.lk_sidx[link]
        k1 = net.lk_k1[link]
        k2 = net.lk_k2[link]
        z1 = zk[k1] + predict * dz[k1]
        z2 = zk[k2] + predict * dz[k2]
        if net.lk_type[link] == 1:
            a, f, r = weir_link(z1, z2, crest[s], net.w_width[s], net.w_cmu[s], net.w_dir[s], net.lk_len[link],
                                u[link], dt)
        else:
            a, f, r = culvert_link(z1, z2, net.c_shape[s], net.c_width[s], net.c_height[s], net.c_invert[s],
                                   net.c_length[s], net.c_xin[s], net.c_xout[s], net.c_ftype[s], net.c_fval[s],
                                   net.c_dir[s], net.lk_len[link], u[link], dt)
        work.area[link] = a
        work.fco[link] = f
        work.rco[link] = r


@kernel
def rating_flow(b_rptr, b_rlev, b_rq, bnd, z):
    """Outflow (m³/s) of rating boundary ``bnd`` at level ``z`` (m AD) and its slope dQ/dz (m²/s).

    Constant below the table, linearly extrapolated above it.
    """
    lo = b_rptr[bnd]
    hi = b_rptr[bnd + 1]
    if z <= b_rlev[lo]:
        return b_rq[lo], 0.0
    for j in range(lo, hi - 1):
        if z <= b_rlev[j + 1]:
            s = (b_rq[j + 1] - b_rq[j]) / (b_rlev[j + 1] - b_rlev[j])
            return b_rq[j] + s * (z - b_rlev[j]), s
    s = (b_rq[hi - 1] - b_rq[hi - 2]) / (b_rlev[hi - 1] - b_rlev[hi - 2])
    return b_rq[hi - 1] + s * (z - b_rlev[hi - 1]), s


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
    if net.lk_type[link] == 3:
        rhs[k1] -= rco[link]
        rhs[k2] += rco[link]
        return
    th = theta if net.lk_type[link] == 0 else 1.0
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
def _in_pieces(zk, zlo, zhi):
    """Whether every level ``zk`` (m AD) lies in the piece ``zlo``..``zhi`` of its volume curve last looked up.

    A conjunction without branches, so that it vectorises; a NaN level counts as outside.
    """
    inside = True
    for i in range(zk.size):
        inside &= (zlo[i] <= zk[i]) & (zk[i] <= zhi[i])
    return inside


@kernel
def assemble(net, work, zk, vol, u, theta, dt):
    """The level system linearised at ``zk`` into ``work``: diagonal, off-diagonal per edge, right-hand side.

    Rating boundaries store their linearised outflow ``rq0 + rslope * z`` (m³/s) for the balance.
    A point's volume is linear on each piece ``[zlo, zhi]`` (m AD) of its volume curve
    (:func:`.lookup.hp_volume_width_piece`): ``V = p_v + p_w (z - p_z)``; the tables are read only when
    ``zk`` leaves the piece of the last look-up. The linear form depends on the piece alone, so a run's
    result does not depend on what was simulated before it. :func:`finish_step` uses the piece too.
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
    if not _in_pieces(zk, zlo, zhi):  # some levels left the piece of their last look-up: find their pieces
        for i in range(zk.size):
            if not zlo[i] <= zk[i] <= zhi[i]:
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
    for run in net.lk_runs:  # run by run, see compute_fluxes: contiguous, vectorised, each point in link order
        l0, k1, k2, e0 = run[0], run[2], run[3], run[4]
        if run[5]:  # a pump, or a link at a level boundary
            _assemble_general_link(net, work, l0, u, theta)
            continue
        for j in range(run[1]):
            link = l0 + j
            th = theta if lk_type[link] == 0 else 1.0
            diag[k2 + j] += th * area[link] * fco[link]
            rhs[k2 + j] += area[link] * (th * rco[link] + (1.0 - th) * u[link])
        for j in range(run[1]):
            link = l0 + j
            th = theta if lk_type[link] == 0 else 1.0
            c = th * area[link] * fco[link]
            diag[k1 + j] += c
            rhs[k1 + j] -= area[link] * (th * rco[link] + (1.0 - th) * u[link])
            off[e0 + j] -= c
    for bnd in range(net.b_hp.size):
        i = net.b_hp[bnd]
        if net.b_type[bnd] == 2:
            qr, slope = rating_flow(net.b_rptr, net.b_rlev, net.b_rq, bnd, zk[i])
            work.rq0[bnd] = qr - slope * zk[i]
            work.rslope[bnd] = slope
            diag[i] += slope
            rhs[i] -= work.rq0[bnd]
        elif net.b_type[bnd] == 1:
            diag[i] = 1.0
            rhs[i] = fixed_val[i]


@kernel
def level_of_volume(net, i, vol, z0):
    """Level (m AD) at which h-point ``i`` holds ``vol`` (m³): Newton from ``z0``, the linearised solution.

    V(z) is convex and strictly increasing, so Newton converges; ``z0`` usually lies in the same table
    cells as the answer, and then the first residual is already at round-off.
    """
    z = z0
    for _ in range(50):
        v, w = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                               net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                               net.tab_at, net.tab_wt, i, z)
        r = vol - v
        if math.fabs(r) <= 1e-12 * (math.fabs(vol) + w):
            break
        z += r / w
    return z


@kernel
def compute_fluxes(net, work, theta, u, un, qn):
    """Link velocities ``un`` (m/s) and fluxes ``qn`` (m³/s) of the current solution ``work.zk``.

    ``u`` is the velocity at time n (m/s). Also, per point, the net inflow (``work.netq``, m³/s).
    The links are visited run by run (:func:`rivercal.engine.compile.link_runs`): within a run the
    levels are read and the inflows written contiguously, so the loops vectorise. Each point receives its
    inflows in link order, as a plain loop over the links would add them (the outflow of run link j-1
    into its point k2 before the outflow of link j from the same point, its k1).
    """
    zk, netq, src = work.zk, work.netq, work.src
    area, fco, rco = work.area, work.fco, work.rco
    lk_type = net.lk_type
    for i in range(src.size):
        netq[i] = src[i]
    for run in net.lk_runs:
        l0, k1, k2 = run[0], run[2], run[3]
        for j in range(run[1]):
            link = l0 + j
            t = lk_type[link]
            ul = rco[link] - fco[link] * (zk[k2 + j] - zk[k1 + j])
            th = theta if t == 0 else 1.0
            ql = area[link] * (th * ul + (1.0 - th) * u[link])
            wet = area[link] > 0.0
            pump = t == 3  # a pump carries its fixed flux rco, and no velocity
            un[link] = ul if wet & (not pump) else 0.0
            qn[link] = rco[link] if pump else (ql if wet else 0.0)
        for j in range(run[1]):
            netq[k2 + j] += qn[l0 + j]
        for j in range(run[1]):
            netq[k1 + j] -= qn[l0 + j]
    for bnd in range(net.b_hp.size):
        if net.b_type[bnd] == 2:
            i = net.b_hp[bnd]
            netq[i] -= work.rq0[bnd] + work.rslope[bnd] * zk[i]


@kernel
def gross_outflow(net, work, qn):
    """Per point, the gross outflow (m³/s) of the fluxes ``qn`` of :func:`compute_fluxes`, into ``work.rhs``."""
    zk, outflow, src = work.zk, work.rhs, work.src
    lk_k1, lk_k2 = net.lk_k1, net.lk_k2
    for i in range(src.size):
        outflow[i] = -min(src[i], 0.0)
    for link in range(lk_k1.size):
        q = qn[link]
        if q > 0.0:
            outflow[lk_k1[link]] += q
        else:
            outflow[lk_k2[link]] -= q
    for bnd in range(net.b_hp.size):
        if net.b_type[bnd] == 2:
            i = net.b_hp[bnd]
            outflow[i] += max(work.rq0[bnd] + work.rslope[bnd] * zk[i], 0.0)


@kernel
def limit_draining_links(net, work, vol, dt, qn):
    """Throttle, for this step, the links that would empty a point below its bed.

    With the fluxes ``qn`` (m³/s) of :func:`compute_fluxes` (and their gross outflow per point,
    :func:`gross_outflow`), a point that would lose more water than it holds plus receives (its
    volume would become negative, the level below the lowest bed) has the flux area of
    every link carrying water out of it scaled by ``0.9 × available / outflow``; a pump drawing from it
    is throttled likewise. Returns the number of points limited; the caller solves again.
    """
    netq, outflow, fixed = work.netq, work.rhs, work.fixed
    drains = False
    for i in range(vol.size):
        drains |= (vol[i] + dt * netq[i] < 0.0) & (not fixed[i])  # no short circuit: the loop vectorises
    if not drains:
        return 0  # the common case
    gross_outflow(net, work, qn)
    limited = 0
    for i in range(vol.size):
        if fixed[i] or vol[i] + dt * netq[i] >= 0.0:
            continue
        inflow = netq[i] + outflow[i]
        factor = 0.9 * max(vol[i] + dt * inflow, 0.0) / (dt * outflow[i])
        for c in range(net.nl_ptr[i], net.nl_ptr[i + 1]):
            link = net.nl_link[c]
            if -net.nl_sign[c] * qn[link] > 0.0:  # water leaves i through this link
                if net.lk_type[link] == 3:
                    work.rco[link] *= factor
                else:
                    work.area[link] *= factor
        limited += 1
    return limited


@kernel
def finish_step(net, work, n, forcing, dt, vmax, z, dz, vol, un, qn, balance):
    """Commit the step: volumes and levels from the net inflows of :func:`compute_fluxes`, the boundary balance.

    ``un`` (m/s) and ``qn`` (m³/s) are the new velocities and fluxes; they become the state by the time
    loop's swap of its velocity and flux arrays, not by a copy. Returns (status, index) of a divergence
    check: ``STATUS_OK`` or the h-point / link at fault (the first one).

    The loops over all points and links have no branches (their checks are conjunctions), so that they
    vectorise; the rare cases (a level outside its linearised piece, a divergence) are handled after them.
    """
    zk, netq, zlo, zhi = work.zk, work.netq, work.zlo, work.zhi
    # While zk lies in the piece of the volume curve the system was linearised on (work.zlo..zhi), V is
    # linear there and the solved system says V(zk) = V^n + Δt Σ Q exactly, up to the round-off of the
    # solve: zk is the level of the new volume, and what round-off leaves enters the next step's right-hand
    # side (as any linearisation difference does). Outside it V bends: Newton, before zk is committed.
    if not _in_pieces(zk, zlo, zhi):
        for i in range(zk.size):
            if not work.fixed[i] and not zlo[i] <= zk[i] <= zhi[i]:
                zk[i] = level_of_volume(net, i, vol[i] + dt * netq[i], zk[i])
    finite = True
    for i in range(zk.size):
        zi = zk[i]
        vol[i] += dt * netq[i]
        dz[i] = zi - z[i]
        z[i] = zi
        finite &= math.fabs(zi - net.hp_bed[i]) <= 1.0e4  # also NaN
    for bnd in range(net.b_hp.size):
        i = net.b_hp[bnd]
        t = net.b_type[bnd]
        if t == 0:
            balance[bnd] += dt * forcing[n, net.b_col[bnd]]
        elif t == 2:
            balance[bnd] -= dt * (work.rq0[bnd] + work.rslope[bnd] * zk[i])
        else:  # a level boundary: the solve returned its level exactly; its volume follows from it
            vol[i] = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                                     net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                                     net.tab_at, net.tab_wt, i, z[i])[0]
            inflow = 0.0
            for c in range(net.nl_ptr[i], net.nl_ptr[i + 1]):
                inflow -= net.nl_sign[c] * qn[net.nl_link[c]]
            balance[bnd] += dt * inflow
    if not finite:
        for i in range(z.size):
            if not math.fabs(z[i] - net.hp_bed[i]) <= 1.0e4:
                return STATUS_LEVEL, i
    calm = True
    for link in range(un.size):
        calm &= math.fabs(un[link]) <= vmax  # also NaN
    if not calm:
        for link in range(un.size):
            if not math.fabs(un[link]) <= vmax:
                return STATUS_VELOCITY, link
    return STATUS_OK, -1


@kernel
def record(net, row, z, q, obs_out, z_out, q_out):
    """Write the observables (and, if requested, the full fields) of output row ``row``."""
    if row < obs_out.shape[0]:
        for o in range(net.ob_type.size):
            if net.ob_type[o] == 0:
                w = net.ob_w[o]
                obs_out[row, o] = w * z[net.ob_i1[o]] + (1.0 - w) * z[net.ob_i2[o]]
            else:
                obs_out[row, o] = net.ob_w[o] * q[net.ob_i1[o]]
    if row < z_out.shape[0]:
        for i in range(z.size):
            z_out[row, i] = z[i]
        for link in range(q.size):
            q_out[row, link] = q[link]


@kernel
def _solve(net, work, zk, vol, u, theta, dt, tol):
    """Assemble at ``zk``, solve, store the solution in ``zk``; returns whether no level changed by ``tol`` (m) or more.

    The test is a conjunction over the points, not a running maximum: it vectorises (a NaN counts as a change).
    """
    rhs = work.rhs
    assemble(net, work, zk, vol, u, theta, dt)
    ldl_solve_packed(net.sv_sched, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr, net.sv_ue1,
              net.sv_ue2, net.sv_utgt, work.diag, work.off, work.lval, rhs)
    converged = True
    for i in range(zk.size):
        converged &= math.fabs(rhs[i] - zk[i]) < tol
        zk[i] = rhs[i]
    return converged


@kernel
def run(net, work, crest, fric, z, dz, vol, u, q, pump_on, forcing, dt, theta, max_iter, tol, min_depth, vmax,
        out_every, obs_out, z_out, q_out, balance):
    """Advance the state over ``forcing.shape[0]`` steps of ``dt`` seconds.

    Parameters
    ----------
    net
        :class:`~rivercal.engine.compile.NetArrays`.
    work
        :class:`Work` arrays (scratch, allocated once by the caller).
    crest, fric
        Run-time parameters: weir crest levels (m AD) and friction values per branch.
    z, dz, vol, u, q, pump_on
        State, updated in place: levels (m AD), their change over the last step (m) and volumes
        (m³) at h-points, velocities (m/s) and fluxes (m³/s) at links, pump switches (0/1).
    forcing
        Per step and forcing column: the step-mean discharge (m³/s) or the level at the end of
        the step (m AD).
    dt, theta, max_iter, tol, min_depth, vmax
        Step (s), implicitness, Picard iterations, level tolerance (m), minimum flow depth (m),
        divergence velocity (m/s).
    out_every, obs_out, z_out, q_out
        Output every ``out_every`` steps: observables into ``obs_out`` (row 0 = initial state) and,
        when they have rows, full levels and fluxes into ``z_out`` and ``q_out``.
    balance
        Accumulates the volume (m³) that entered through each boundary (first entries) and through
        all laterals (last entry).

    Returns
    -------
    tuple of int
        (status, step, index): ``STATUS_OK``, or ``STATUS_LEVEL`` with the h-point, or
        ``STATUS_VELOCITY`` with the link at which the run diverged.
    """
    zk = work.zk
    n_b = net.b_hp.size
    record(net, 0, z, q, obs_out, z_out, q_out)
    # velocities and fluxes at time n (u0, q0) and n+1 (u1, q1): the arrays swap roles after each step
    u0, q0, u1, q1 = u, q, work.un, work.qn
    work.src[:] = 0.0
    work.qlat[:] = 0.0
    work.fixed[:] = False
    for link in range(work.lfric.size):
        work.lfric[link] = fric[net.lk_fric[link]]
    for n in range(forcing.shape[0]):
        balance[n_b] += dt * apply_forcing(net, work, n, forcing, dt, vol)
        channel_coefficients(net, work, z, u0, q0, dt, min_depth)
        switch_pumps(net, work, z, pump_on)
        # linearise first at the extrapolated level z^n + (z^n - z^{n-1}) (not below the bed): when the
        # extrapolation is good one solve suffices (the convergence test compares with it)
        for i in range(z.size):
            zk[i] = max(z[i] + dz[i], min(z[i], net.hp_bed[i] + min_depth))
        work.stats[0] += 1
        for _ in range(max_iter):
            structure_coefficients(net, work, zk, dz, 0.0, u0, crest, dt)
            converged = _solve(net, work, zk, vol, u0, theta, dt, tol)
            work.stats[1] += 1
            if converged:
                break
        for attempt in range(9):  # drying: no point may lose more water than it holds within a step
            compute_fluxes(net, work, theta, u0, u1, q1)
            if attempt == 8 or limit_draining_links(net, work, vol, dt, q1) == 0:
                break
            _solve(net, work, zk, vol, u0, theta, dt, tol)
            work.stats[2] += 1
        status, index = finish_step(net, work, n, forcing, dt, vmax, z, dz, vol, u1, q1, balance)
        u0, q0, u1, q1 = u1, q1, u0, q0
        if status != STATUS_OK:
            _keep(u0, q0, u, q)
            return status, n, index
        if (n + 1) % out_every == 0:
            record(net, (n + 1) // out_every, z, q0, obs_out, z_out, q_out)
    _keep(u0, q0, u, q)
    return STATUS_OK, forcing.shape[0], -1


@kernel
def _keep(u_last, q_last, u, q):
    """Copy the last velocities and fluxes into the state arrays ``u``, ``q`` unless they are already there."""
    if u_last.ctypes.data != u.ctypes.data:
        for link in range(u.size):
            u[link] = u_last[link]
            q[link] = q_last[link]
