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
#: channel link (:func:`_link_momentum`).
Work = namedtuple(
    "Work",
    ["diag", "rhs", "zk", "src", "qlat", "netq", "fixed", "fixed_val", "off", "lval", "area", "fco", "rco",
     "un", "qn", "rq0", "rslope", "struct_links", "pump_links", "stats", "zlo", "zhi", "p_z", "p_v", "p_w",
     "cb", "cs", "cc2r", "cdz"],
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
        cb=np.ones(n_l), cs=np.zeros(n_l), cc2r=np.ones(n_l), cdz=np.zeros(n_l),
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
def channel_coefficients(net, work, z, u, q, fric, dt, min_depth):
    """Flux area A (m²), f (1/s) and r (m/s) of every channel link from the state at time n.

    Upwind flow area and implicit friction; upwind advection from the velocity of the link that
    feeds the upwind point (inflow-weighted over all feeding links at a junction; none across
    structures or from a boundary); the lateral-inflow momentum sink u q_lat / A with q_lat the
    mean lateral inflow per unit length (m²/s) of the link's two points.

    Two passes: :func:`_link_momentum` gathers, per link, the terms of its momentum equation (table
    look-ups and branches); :func:`_link_newton` solves it, a branch-free loop over all links that
    the compiler vectorises (its square root and three divisions dominate the cost of a link). The
    coefficients it writes for structure and pump links are replaced before use, by
    :func:`switch_pumps` and :func:`structure_coefficients`.
    """
    _link_momentum(net, work, z, u, q, fric, dt, min_depth)
    _link_newton(net.lk_ilen, work.area, work.cb, work.cs, work.cc2r, work.cdz, work.fco, work.rco)


@kernel
def _link_momentum(net, work, z, u, q, fric, dt, min_depth):
    """Per channel link: flux area A (m², 0 when dry), and in ``work`` the momentum terms of :func:`_link_newton`.

    The momentum equation of a link, per unit mass, is ``b u + kappa |u| u = s - g (z2 - z1) / dx`` with
    b (1/s) the inertia, lateral-inflow and implicit advection terms, kappa = g / (C² R) (1/m), and
    s (m/s²) the explicit terms; ``cs`` holds s - g (z2 - z1) / dx at the levels of time n, ``cc2r``
    C² R (m²/s²), ``cb`` b and ``cdz`` z2 - z1 (m).
    """
    area, qlat = work.area, work.qlat
    cb, cs, cc2r, cdz = work.cb, work.cs, work.cc2r, work.cdz
    lk_k1, lk_k2, lk_type, lk_ilen, lk_fric = net.lk_k1, net.lk_k2, net.lk_type, net.lk_ilen, net.lk_fric
    lk_b1, lk_b2, lk_p1, lk_p2 = net.lk_b1, net.lk_b2, net.lk_p1, net.lk_p2
    lk_nb1, lk_ns1, lk_nb2, lk_ns2 = net.lk_nb1, net.lk_ns1, net.lk_nb2, net.lk_ns2
    nl_ptr, nl_link, nl_sign, fr_type = net.nl_ptr, net.nl_link, net.nl_sign, net.fr_type
    tab_off, tab_n, tab_idd, tab_top, tab_wf_top = net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top
    tab_af, tab_pf = net.tab_af, net.tab_pf
    inv_dt = 1.0 / dt
    for link in range(lk_k1.size):
        area[link] = 0.0
        if lk_type[link] != 0:
            continue
        k1 = np.uint64(lk_k1[link])
        k2 = np.uint64(lk_k2[link])
        u0 = u[link]
        if u0 > 0.0 or (u0 == 0.0 and z[k1] >= z[k2]):
            sign, kup, depth, prof = 1.0, lk_k1[link], z[k1] - lk_b1[link], np.uint64(lk_p1[link])
        else:
            sign, kup, depth, prof = -1.0, lk_k2[link], z[k2] - lk_b2[link], np.uint64(lk_p2[link])
        if depth < min_depth:
            continue
        a_up, per, r43 = flow_geometry(tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf,
                                       net.tab_flow, prof, depth)
        if a_up <= 0.0:
            continue
        group = np.uint64(lk_fric[link])
        ftype = fr_type[group]
        radius = (a_up / per if per > 0.0 else depth) if ftype == 2 else 0.0
        ql = qlat[k1] + qlat[k2]
        b = inv_dt + 0.5 * ql / a_up if ql != 0.0 else inv_dt  # skips a division: exact, the term is +0 then
        rhs_u = u0 * inv_dt
        ilen = lk_ilen[link]
        if u0 != 0.0:
            ul = sign * u0
            qin = 0.0
            uin = 0.0
            if sign > 0.0:
                m, sm = lk_nb1[link], lk_ns1[link]
            else:
                m, sm = lk_nb2[link], lk_ns2[link]
            if m >= 0:  # one feeding channel link: the common case along a branch
                mu = np.uint64(m)
                if sm * q[mu] > 0.0:
                    qin = sm * q[mu]
                    uin = sm * u[mu]
            elif m == -1:  # junction: inflow-weighted velocity of the feeding links
                quin = 0.0
                blocked = False
                for c in range(nl_ptr[kup], nl_ptr[kup + 1]):
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
        area[link] = a_up
        cb[link] = b
        cs[link] = rhs_u - G * ilen * dzl
        cc2r[link] = friction_c2r(ftype, fric[group], radius, r43)
        cdz[link] = dzl


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
def assemble(net, work, zk, vol, u, theta, dt):
    """The level system linearised at ``zk`` into ``work``: diagonal, off-diagonal per edge, right-hand side.

    Rating boundaries store their linearised outflow ``rq0 + rslope * z`` (m³/s) for the balance.
    A point's volume is linear on each piece ``[zlo, zhi]`` (m AD) of its volume curve
    (:func:`.lookup.hp_volume_width_piece`): ``V = p_v + p_w (z - p_z)``; the tables are read only when
    ``zk`` leaves the piece of the last look-up. The linear form depends on the piece alone, so a run's
    result does not depend on what was simulated before it. :func:`finish_step` uses the piece too.
    """
    diag, off, rhs, src, fixed, fixed_val = work.diag, work.off, work.rhs, work.src, work.fixed, work.fixed_val
    area, fco, rco = work.area, work.fco, work.rco
    sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin = (
        net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin)
    tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt = (
        net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top, net.tab_at, net.tab_wt)
    lk_k1, lk_k2, lk_type, lk_edge = net.lk_k1, net.lk_k2, net.lk_type, net.lk_edge
    zlo, zhi, p_z, p_v, p_w = work.zlo, work.zhi, work.p_z, work.p_v, work.p_w
    inv_dt = 1.0 / dt
    for i in range(zk.size):
        z = zk[i]
        if not zlo[i] <= z <= zhi[i]:  # z left the piece of the last look-up: find its piece
            zlo[i], zhi[i], p_z[i], p_v[i], p_w[i] = hp_volume_width_piece(
                sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin, tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top,
                tab_at, tab_wt, i, z)
        w = p_w[i]
        v = p_v[i] + w * (z - p_z[i])
        diag[i] = w * inv_dt
        rhs[i] = (w * z - (v - vol[i])) * inv_dt + src[i]
    off[:] = 0.0
    for link in range(lk_k1.size):
        k1 = np.uint64(lk_k1[link])
        k2 = np.uint64(lk_k2[link])
        if lk_type[link] == 3:
            rhs[k1] -= rco[link]
            rhs[k2] += rco[link]
            continue
        th = theta if lk_type[link] == 0 else 1.0
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
            off[np.uint64(lk_edge[link])] -= c
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
    """
    zk, netq, src = work.zk, work.netq, work.src
    area, fco, rco = work.area, work.fco, work.rco
    lk_k1, lk_k2, lk_type = net.lk_k1, net.lk_k2, net.lk_type
    for i in range(src.size):
        netq[i] = src[i]
    for link in range(lk_k1.size):
        k1 = np.uint64(lk_k1[link])
        k2 = np.uint64(lk_k2[link])
        t = lk_type[link]
        if t == 3:
            un[link] = 0.0
            q = rco[link]
        elif area[link] > 0.0:
            un[link] = rco[link] - fco[link] * (zk[k2] - zk[k1])
            th = theta if t == 0 else 1.0
            q = area[link] * (th * un[link] + (1.0 - th) * u[link])
        else:
            un[link] = 0.0
            q = 0.0
        qn[link] = q
        netq[k1] -= q
        netq[k2] += q
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
        drains |= not fixed[i] and vol[i] + dt * netq[i] < 0.0
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
    check: ``STATUS_OK`` or the h-point / link at fault.
    """
    zk, netq, fixed, fixed_val = work.zk, work.netq, work.fixed, work.fixed_val
    bad_link = -1
    for link in range(un.size - 1, -1, -1):  # backwards: bad_link ends as the first link at fault
        if not math.fabs(un[link]) <= vmax:  # also NaN
            bad_link = link
    for bnd in range(net.b_hp.size):
        i = net.b_hp[bnd]
        t = net.b_type[bnd]
        if t == 0:
            balance[bnd] += dt * forcing[n, net.b_col[bnd]]
        elif t == 2:
            balance[bnd] -= dt * (work.rq0[bnd] + work.rslope[bnd] * zk[i])
        else:
            inflow = 0.0
            for c in range(net.nl_ptr[i], net.nl_ptr[i + 1]):
                inflow -= net.nl_sign[c] * qn[net.nl_link[c]]
            balance[bnd] += dt * inflow
    for i in range(z.size):
        z_old = z[i]
        if fixed[i]:
            z[i] = fixed_val[i]
            vol[i] = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                                     net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                                     net.tab_at, net.tab_wt, i, z[i])[0]
        else:
            vol[i] += dt * netq[i]
            # While zk lies in the piece of the volume curve the system was linearised on (work.zlo..zhi),
            # V is linear there and the solved system says V(zk) = V^n + Δt Σ Q exactly, up to the round-off
            # of the solve: zk is the level of the new volume, and what round-off leaves enters the next
            # step's right-hand side (as any linearisation difference does). Outside it V bends: Newton.
            zi = zk[i]
            if not work.zlo[i] <= zi <= work.zhi[i]:
                zi = level_of_volume(net, i, vol[i], zi)
            z[i] = zi
        dz[i] = z[i] - z_old
        if not math.isfinite(z[i]) or math.fabs(z[i] - net.hp_bed[i]) > 1.0e4:
            return STATUS_LEVEL, i
    if bad_link >= 0:
        return STATUS_VELOCITY, bad_link
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
def _solve(net, work, zk, vol, u, theta, dt):
    """Assemble at ``zk``, solve, store the solution in ``zk``; returns the largest level change (m)."""
    rhs = work.rhs
    assemble(net, work, zk, vol, u, theta, dt)
    ldl_solve_packed(net.sv_sched, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr, net.sv_ue1,
              net.sv_ue2, net.sv_utgt, work.diag, work.off, work.lval, rhs)
    change = 0.0
    for i in range(zk.size):
        change = max(change, math.fabs(rhs[i] - zk[i]))
        zk[i] = rhs[i]
    return change


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
    for n in range(forcing.shape[0]):
        balance[n_b] += dt * apply_forcing(net, work, n, forcing, dt, vol)
        channel_coefficients(net, work, z, u0, q0, fric, dt, min_depth)
        switch_pumps(net, work, z, pump_on)
        # linearise first at the extrapolated level z^n + (z^n - z^{n-1}) (not below the bed): when the
        # extrapolation is good one solve suffices (the convergence test compares with it)
        for i in range(z.size):
            zk[i] = max(z[i] + dz[i], min(z[i], net.hp_bed[i] + min_depth))
        work.stats[0] += 1
        for _ in range(max_iter):
            structure_coefficients(net, work, zk, dz, 0.0, u0, crest, dt)
            change = _solve(net, work, zk, vol, u0, theta, dt)
            work.stats[1] += 1
            if change < tol:
                break
        for attempt in range(9):  # drying: no point may lose more water than it holds within a step
            compute_fluxes(net, work, theta, u0, u1, q1)
            if attempt == 8 or limit_draining_links(net, work, vol, dt, q1) == 0:
                break
            _solve(net, work, zk, vol, u0, theta, dt)
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
