"""The time loop of the staggered Delft scheme: one compiled call per simulated window.

Per step n → n+1 (reference note §A; Stelling & Duinmeijer 2003):

1. Channel links (:func:`channel_coefficients`): from the state at n, the upwind flow area A,
   implicit friction g|u|/(C²R) and explicit upwind advection (energy-head conservative where the
   flow accelerates, momentum conservative where it decelerates, with the link's own velocity
   taken implicitly) give ``u = r - f (z2 - z1)`` with f = g/(Δx b).
2. Picard iterations (at most ``max_iter``, stopping when the level change is below ``tol``),
   starting from the extrapolated level z^n + (z^n - z^{n-1}) (one iteration from this predictor
   is as accurate as two from z^n): structure links are linearised at the current iterate
   (:func:`structure_coefficients`); the
   continuity equation ``V(z^k) + w(z^k)(z - z^k) - V^n = Δt Σ Q`` with
   Q = A(θ u^{n+1} + (1-θ) u^n) gives a symmetric positive definite system in the levels
   (:func:`assemble`), solved by :func:`.solver.ldl_solve`. Discharge and rating boundaries and
   laterals enter the right-hand side; level boundaries are Dirichlet rows whose couplings move
   to the right-hand side, keeping the matrix symmetric.
3. The fluxes of the last iterate update the stored volumes, ``V^{n+1} = V^n + Δt Σ Q``
   (:func:`finish_step`); the volume is the prognostic variable, so mass is conserved to
   round-off whatever the number of iterations or the table resolution. The new level is the
   last iterate; the small difference V(z^{n+1}) - V^{n+1} left by the linearisation is not lost
   but enters the right-hand side of the next step (the ``V(z^k) - V^n`` term).

Wetting and drying: a channel link carries no flow while its upwind depth is below ``min_depth``;
every h-point has a minimum storage area that extends below the bed, so the matrix diagonal stays
positive and a level can never become NaN. Extractions (negative laterals) are limited to half
of the water present at their point per step.

Each phase is its own compiled function taking the arrays it needs: LLVM optimises these small
functions much better than one large loop body, and passing explicit arrays avoids reference
counting every field of the network namedtuple (see :mod:`.lookup`).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.lookup import flow_geometry, hp_volume_width
from rivercal.engine.kernels.solver import ldl_solve
from rivercal.engine.kernels.structures import G, culvert_link, friction_c2r, weir_link

__all__ = [
    "STATUS_LEVEL",
    "STATUS_OK",
    "STATUS_VELOCITY",
    "Work",
    "apply_forcing",
    "assemble",
    "channel_coefficients",
    "finish_step",
    "make_work",
    "rating_flow",
    "run",
    "structure_coefficients",
]

STATUS_OK, STATUS_LEVEL, STATUS_VELOCITY = 0, 1, 2

#: Scratch arrays of :func:`run` (kernels do not allocate; see :mod:`._jit`).
Work = namedtuple(
    "Work",
    ["diag", "rhs", "zk", "src", "netq", "fixed", "fixed_val", "off", "lval", "area", "fco", "rco",
     "rq0", "rslope", "struct_links", "pump_links"],
)


def make_work(net) -> Work:
    """Allocate the scratch arrays of :func:`run` for network arrays ``net``."""
    n_h = net.hp_bed.size
    n_l = net.lk_k1.size
    n_b = net.b_hp.size
    return Work(
        diag=np.empty(n_h), rhs=np.empty(n_h), zk=np.empty(n_h), src=np.empty(n_h), netq=np.empty(n_h),
        fixed=np.zeros(n_h, dtype=np.bool_), fixed_val=np.zeros(n_h), off=np.zeros(net.sv_nedge),
        lval=np.zeros(net.sv_nedge), area=np.zeros(n_l), fco=np.zeros(n_l), rco=np.zeros(n_l),
        rq0=np.zeros(n_b), rslope=np.zeros(n_b),
        struct_links=np.flatnonzero((net.lk_type == 1) | (net.lk_type == 2)).astype(np.int64),
        pump_links=np.flatnonzero(net.lk_type == 3).astype(np.int64),
    )


@kernel
def apply_forcing(n, forcing, dt, vol, b_hp, b_type, b_col, lat_hp, lat_col, src, fixed, fixed_val):
    """Sources (m³/s) and Dirichlet levels (m AD) of step ``n``; returns the lateral total (m³/s)."""
    src[:] = 0.0
    fixed[:] = False
    for bnd in range(b_hp.size):
        i = b_hp[bnd]
        if b_type[bnd] == 0:
            src[i] += forcing[n, b_col[bnd]]
        elif b_type[bnd] == 1:
            fixed[i] = True
            fixed_val[i] = forcing[n, b_col[bnd]]
    total = 0.0
    for lat in range(lat_hp.size):
        i = lat_hp[lat]
        ql = forcing[n, lat_col[lat]]
        if ql < 0.0:
            ql = max(ql, -0.5 * max(vol[i], 0.0) / dt)
        src[i] += ql
        total += ql
    return total


@kernel
def channel_coefficients(z, u, q, fric, dt, min_depth, lk_k1, lk_k2, lk_b1, lk_b2, lk_p1, lk_p2, lk_ilen,
                         lk_fric, lk_type, lk_nb1, lk_ns1, lk_nb2, lk_ns2, fr_type, nl_ptr, nl_link, nl_sign,
                         tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf, tab_r43, area, fco, rco):
    """Flux area A (m²), f (1/s) and r (m/s) of every channel link from the state at time n.

    Upwind flow area and implicit friction; upwind advection from the velocity of the link that
    feeds the upwind point (inflow-weighted over all feeding links at a junction; none across
    structures or from a boundary).
    """
    inv_dt = 1.0 / dt
    for link in range(lk_k1.size):
        if lk_type[link] != 0:
            continue
        area[link] = 0.0
        fco[link] = 0.0
        rco[link] = 0.0
        k1 = lk_k1[link]
        k2 = lk_k2[link]
        u0 = u[link]
        if u0 > 0.0 or (u0 == 0.0 and z[k1] >= z[k2]):
            sign, kup, depth, prof = 1.0, k1, z[k1] - lk_b1[link], lk_p1[link]
        else:
            sign, kup, depth, prof = -1.0, k2, z[k2] - lk_b2[link], lk_p2[link]
        if depth < min_depth:
            continue
        a_up, per, r43 = flow_geometry(tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf,
                                       tab_r43, prof, depth)
        if a_up <= 0.0:
            continue
        group = lk_fric[link]
        ftype = fr_type[group]
        radius = (a_up / per if per > 0.0 else depth) if ftype == 2 else 0.0
        b = inv_dt + G * math.fabs(u0) / friction_c2r(ftype, fric[group], radius, r43)
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
                if sm * q[m] > 0.0:
                    qin = sm * q[m]
                    uin = sm * u[m]
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
        inv_b = 1.0 / b
        area[link] = a_up
        fco[link] = G * ilen * inv_b
        rco[link] = rhs_u * inv_b


@kernel
def switch_pumps(z, pump_on, pump_links, lk_k1, lk_k2, lk_sidx, p_sign, p_cap, p_on, p_off, area, fco, rco):
    """Pump switches from the suction-side level at time n; a pump link carries a fixed flux ``rco``."""
    for link in pump_links:
        s = lk_sidx[link]
        ksuc = lk_k1[link] if p_sign[s] > 0.0 else lk_k2[link]
        if pump_on[s] > 0.5 and z[ksuc] <= p_off[s]:
            pump_on[s] = 0.0
        elif pump_on[s] < 0.5 and z[ksuc] >= p_on[s]:
            pump_on[s] = 1.0
        area[link] = 0.0
        fco[link] = 0.0
        rco[link] = p_sign[s] * p_cap[s] * pump_on[s]


@kernel
def structure_coefficients(zk, u, crest, dt, struct_links, lk_type, lk_k1, lk_k2, lk_len, lk_sidx,
                           w_width, w_cmu, w_dir, c_shape, c_width, c_height, c_invert, c_length, c_xin,
                           c_xout, c_ftype, c_fval, c_dir, area, fco, rco):
    """Weir and culvert links linearised at the iterate ``zk``."""
    for link in struct_links:
        s = lk_sidx[link]
        z1 = zk[lk_k1[link]]
        z2 = zk[lk_k2[link]]
        if lk_type[link] == 1:
            area[link], fco[link], rco[link] = weir_link(
                z1, z2, crest[s], w_width[s], w_cmu[s], w_dir[s], lk_len[link], u[link], dt)
        else:
            area[link], fco[link], rco[link] = culvert_link(
                z1, z2, c_shape[s], c_width[s], c_height[s], c_invert[s], c_length[s], c_xin[s], c_xout[s],
                c_ftype[s], c_fval[s], c_dir[s], lk_len[link], u[link], dt)


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
def assemble(zk, vol, u, src, fixed, fixed_val, theta, dt, sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin,
             tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt,
             lk_k1, lk_k2, lk_type, lk_edge, area, fco, rco, b_hp, b_type, b_rptr, b_rlev, b_rq, rq0, rslope,
             diag, off, rhs):
    """The level system linearised at ``zk``: diagonal, one off-diagonal per edge, right-hand side.

    Rating boundaries store their linearised outflow ``rq0 + rslope * z`` (m³/s) for the balance.
    """
    inv_dt = 1.0 / dt
    for i in range(zk.size):
        v, w = hp_volume_width(sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin,
                               tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt, i, zk[i])
        diag[i] = w * inv_dt
        rhs[i] = (w * zk[i] - (v - vol[i])) * inv_dt + src[i]
    off[:] = 0.0
    for link in range(lk_k1.size):
        k1 = lk_k1[link]
        k2 = lk_k2[link]
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
            off[lk_edge[link]] -= c
    for bnd in range(b_hp.size):
        i = b_hp[bnd]
        if b_type[bnd] == 2:
            qr, slope = rating_flow(b_rptr, b_rlev, b_rq, bnd, zk[i])
            rq0[bnd] = qr - slope * zk[i]
            rslope[bnd] = slope
            diag[i] += slope
            rhs[i] -= rq0[bnd]
        elif b_type[bnd] == 1:
            diag[i] = 1.0
            rhs[i] = fixed_val[i]


@kernel
def finish_step(n, forcing, dt, theta, vmax, zk, z, dz, vol, u, q, src, fixed, fixed_val, netq,
                sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin,
                tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt,
                lk_k1, lk_k2, lk_type, area, fco, rco, nl_ptr, nl_link, nl_sign,
                b_hp, b_type, b_col, rq0, rslope, balance):
    """Fluxes of the last iterate → volumes, levels and the boundary balance of step ``n``.

    Returns (status, index) of a divergence check: ``STATUS_OK`` or the h-point / link at fault.
    """
    for i in range(src.size):
        netq[i] = src[i]
    for link in range(lk_k1.size):
        k1 = lk_k1[link]
        k2 = lk_k2[link]
        t = lk_type[link]
        if t == 3:
            qn = rco[link]
            u[link] = 0.0
        elif area[link] > 0.0:
            un = rco[link] - fco[link] * (zk[k2] - zk[k1])
            th = theta if t == 0 else 1.0
            qn = area[link] * (th * un + (1.0 - th) * u[link])
            u[link] = un
        else:
            qn = 0.0
            u[link] = 0.0
        q[link] = qn
        netq[k1] -= qn
        netq[k2] += qn
    for bnd in range(b_hp.size):
        i = b_hp[bnd]
        t = b_type[bnd]
        if t == 0:
            balance[bnd] += dt * forcing[n, b_col[bnd]]
        elif t == 2:
            qout = rq0[bnd] + rslope[bnd] * zk[i]
            netq[i] -= qout
            balance[bnd] -= dt * qout
        else:
            inflow = 0.0
            for c in range(nl_ptr[i], nl_ptr[i + 1]):
                inflow -= nl_sign[c] * q[nl_link[c]]
            balance[bnd] += dt * inflow
    for i in range(z.size):
        z_old = z[i]
        if fixed[i]:
            z[i] = fixed_val[i]
            vol[i] = hp_volume_width(sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin,
                                     tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt, i, z[i])[0]
        else:
            vol[i] += dt * netq[i]
            z[i] = zk[i]
        dz[i] = z[i] - z_old
        if not math.isfinite(z[i]) or math.fabs(z[i] - hp_bed[i]) > 1.0e4:
            return STATUS_LEVEL, i
    for link in range(u.size):
        if not math.isfinite(u[link]) or math.fabs(u[link]) > vmax:
            return STATUS_VELOCITY, link
    return STATUS_OK, -1


@kernel
def _record(row, z, q, ob_type, ob_i1, ob_i2, ob_w, obs_out, z_out, q_out):
    if row < obs_out.shape[0]:
        for o in range(ob_type.size):
            if ob_type[o] == 0:
                obs_out[row, o] = ob_w[o] * z[ob_i1[o]] + (1.0 - ob_w[o]) * z[ob_i2[o]]
            else:
                obs_out[row, o] = ob_w[o] * q[ob_i1[o]]
    if row < z_out.shape[0]:
        for i in range(z.size):
            z_out[row, i] = z[i]
        for link in range(q.size):
            q_out[row, link] = q[link]


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
    hp_bed, hp_amin = net.hp_bed, net.hp_amin
    sc_ptr, sc_prof, sc_bed, sc_len = net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len
    nl_ptr, nl_link, nl_sign = net.nl_ptr, net.nl_link, net.nl_sign
    lk_k1, lk_k2, lk_type, lk_len, lk_sidx = net.lk_k1, net.lk_k2, net.lk_type, net.lk_len, net.lk_sidx
    tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_at, tab_wt, tab_wt_top = (
        net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_at, net.tab_wt, net.tab_wt_top)
    b_hp, b_type, b_col = net.b_hp, net.b_type, net.b_col
    n_h = z.size
    diag, rhs, zk, src, netq, fixed_val = work.diag, work.rhs, work.zk, work.src, work.netq, work.fixed_val
    fixed, off, lval, area, fco, rco = work.fixed, work.off, work.lval, work.area, work.fco, work.rco
    rq0, rslope, struct_links, pump_links = work.rq0, work.rslope, work.struct_links, work.pump_links
    n_b = b_hp.size

    _record(0, z, q, net.ob_type, net.ob_i1, net.ob_i2, net.ob_w, obs_out, z_out, q_out)
    for n in range(forcing.shape[0]):
        balance[n_b] += dt * apply_forcing(n, forcing, dt, vol, b_hp, b_type, b_col, net.lat_hp, net.lat_col,
                                           src, fixed, fixed_val)
        channel_coefficients(z, u, q, fric, dt, min_depth, lk_k1, lk_k2, net.lk_b1, net.lk_b2, net.lk_p1,
                             net.lk_p2, net.lk_ilen, net.lk_fric, lk_type, net.lk_nb1, net.lk_ns1, net.lk_nb2,
                             net.lk_ns2, net.fr_type, nl_ptr, nl_link, nl_sign,
                             tab_off, tab_n, tab_idd, tab_top, net.tab_wf_top, net.tab_af, net.tab_pf, net.tab_r43,
                             area, fco, rco)
        switch_pumps(z, pump_on, pump_links, lk_k1, lk_k2, lk_sidx, net.p_sign, net.p_cap, net.p_on, net.p_off,
                     area, fco, rco)
        # linearise at the extrapolated level z^n + (z^n - z^{n-1}); dz holds the last change
        for i in range(n_h):
            zk[i] = z[i] + dz[i]
        for _ in range(max_iter):
            structure_coefficients(zk, u, crest, dt, struct_links, lk_type, lk_k1, lk_k2, lk_len, lk_sidx,
                                   net.w_width, net.w_cmu, net.w_dir, net.c_shape, net.c_width, net.c_height,
                                   net.c_invert, net.c_length, net.c_xin, net.c_xout, net.c_ftype, net.c_fval,
                                   net.c_dir, area, fco, rco)
            assemble(zk, vol, u, src, fixed, fixed_val, theta, dt, sc_ptr, sc_prof, sc_bed, sc_len, hp_bed,
                     hp_amin, tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt, lk_k1, lk_k2,
                     lk_type, net.lk_edge, area, fco, rco, b_hp, b_type, net.b_rptr, net.b_rlev, net.b_rq, rq0, rslope,
                     diag, off, rhs)
            ldl_solve(net.sv_order, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr, net.sv_ue1,
                      net.sv_ue2, net.sv_utgt, diag, off, lval, rhs)
            change = 0.0
            for i in range(n_h):
                change = max(change, math.fabs(rhs[i] - zk[i]))
                zk[i] = rhs[i]
            if change < tol:
                break
        status, index = finish_step(
            n, forcing, dt, theta, vmax, zk, z, dz, vol, u, q, src, fixed, fixed_val, netq,
            sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin, tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top,
            tab_at, tab_wt, lk_k1, lk_k2, lk_type, area, fco, rco, nl_ptr, nl_link, nl_sign, b_hp, b_type, b_col,
            rq0, rslope, balance)
        if status != STATUS_OK:
            return status, n, index
        if (n + 1) % out_every == 0:
            _record((n + 1) // out_every, z, q, net.ob_type, net.ob_i1, net.ob_i2, net.ob_w, obs_out, z_out, q_out)
    return STATUS_OK, forcing.shape[0], -1
