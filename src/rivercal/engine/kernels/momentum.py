"""The momentum equation of the channel links: coefficients of ``u = r - f (z2 - z1)`` for a time step.

From the state at time n (reference note §A; Stelling & Duinmeijer 2003): explicit upwind advection
(energy-head conservative where the flow accelerates, momentum conservative where it decelerates, with the
link's own velocity taken implicitly) and the momentum that lateral inflow takes from the flow (u q_lat / A,
the inflow arriving without velocity along the channel; implicit); and, at the geometry's levels
(:func:`_at`), the upwind flow area A and the implicit friction g|u|u/(C²R). The geometry's levels are those
of time n, except where a step moves the level by more than ``GEOMETRY_FROM``: there they move towards the
current iterate of the new time level (θ-weighted with those of time n), which they reach at
``GEOMETRY_FULL``, and the Picard iterations of the step evaluate the geometry at their iterate, as SOBEK's
non-linear iterations do, so that a flood wave's conveyance does not lag a step behind its levels (with the
geometry of time n the Waal ran 5 cm high on its rising limb and 8 cm low on its falling limb at its own
3600 s step). Where the levels move slowly the geometry stays that of time n: a steady state stays exact,
and the iterations do not leave a noise of the size of their tolerance. The direction of the flow, which
selects the upwind side, is that of time n. The friction is linearised by Newton
around the exact solution u* of the link's momentum equation at the levels of time n (a quadratic
in u), giving ``u = r - f (z2 - z1)``: exact in steady flow, and bounded by friction when flow
starts from rest (a Picard linearisation with |u^n| has no friction at u^n = 0 and overshoots
there).

Wetting and drying: a channel link carries no flow while its upwind depth is below ``min_depth``.

In the loops over all links, the point, profile and link indices read from the network's arrays are
cast to ``np.uint64``: numba then adds no negative-index wraparound to the accesses they make (as in
:func:`.solver.ldl_solve_packed`; the arithmetic is unchanged).
"""

from __future__ import annotations

import math

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import (
    FRICTION_CHEZY,
    FRICTION_GRADUAL,
    FRICTION_SPLIT,
    GEOMETRY_FROM,
    GEOMETRY_FULL,
    LINK_CHANNEL,
    MO_COUNT,
    MO_K1,
    MO_LINK,
    NB_JUNCTION,
    NB_OUTFALL,
)
from rivercal.engine.kernels.lookup import flow_geometry
from rivercal.engine.kernels.structures import G, friction_c2r, friction_c2r_any

__all__ = ["channel_coefficients"]


@kernel
def channel_coefficients(net, work, z, zk, theta, u, q, dt, min_depth, iterate=True):
    """Flux area A (m²), f (1/s) and r (m/s) of every channel link from the state at time n and the iterate ``zk``.

    The geometry (flow area, friction) is that of the geometry's levels (:func:`_at`) between ``z`` and the
    iterate ``zk`` (m AD), or of ``z`` itself without ``iterate``; the upwind side and the momentum terms are
    those of the state at time n (levels ``z``, m AD, velocities ``u``, m/s, fluxes ``q``, m³/s).

    Returns the largest |u| / Δx of the wet channel links (1/s), the screen of the step control
    (:func:`.timeloop.run`): times Δt their largest Courant number.

    Upwind flow area and implicit friction; upwind advection from the velocity of the link that
    feeds the upwind point (none across structures or from a boundary); the lateral-inflow momentum
    sink u q_lat / A with q_lat the mean lateral inflow per unit length (m²/s) of the link's two
    points. The friction value of each link is ``work.lfric`` (set by :func:`.timeloop.run` from the
    run's parameters).

    At a junction a link leaving the upwind point takes its own share of what arrives there: the
    inflow times its share of the outflow, |q_L| / Σ outflows, at the inflow-weighted velocity of the
    feeding links. The momentum arriving at a junction is so divided among the links that leave it
    (their shares add up to one); a link that carries nothing away, such as a dead-end branch at rest,
    takes none, and rests at the junction's level.

    Three passes: :func:`_link_geometry` looks up the flow geometry at the upwind depth (a gather from
    the tables); :func:`_momentum_simple` gathers the momentum terms of the links inside a branch, whose
    neighbours are the links before and after them (``net.mo_runs``), in a branch-free loop that
    reads contiguously and vectorises; :func:`_momentum_other` does the same for the other channel links
    (at junctions, structures and branch ends). Both solve each link's momentum equation as soon as its terms
    are known (:func:`_link_newton`), so the terms never go through memory (a fourth pass over every link that
    read them back took a tenth of the step). The coefficients of a link without flow are 0 (set with its flux
    area by :func:`_link_geometry`); those of structure and pump links are replaced before use, by
    :func:`.structures.switch_pumps` and :func:`.structures.structure_coefficients`.
    """
    fastest = _link_geometry(net, work, z, zk, theta, u, min_depth, iterate)
    _momentum_simple(net, work, z, u, q, dt)
    for link in net.mo_other:
        _momentum_other(net, work, link, z, zk, theta, u, q, dt)
    return fastest


@kernel
def _at(z, zk, theta, k):
    """The level (m AD) at point ``k`` at which a step takes the geometry: z + w θ (zk - z).

    ``z`` is the level at time n and ``zk`` the iterate of the new time level (m AD); w rises linearly from 0
    where they differ by ``GEOMETRY_FROM`` to 1 where they differ by ``GEOMETRY_FULL`` or more. With ``zk`` the
    levels of time n it is exactly those.
    """
    d = zk[k] - z[k]
    w = min(max((math.fabs(d) - GEOMETRY_FROM) * (1.0 / (GEOMETRY_FULL - GEOMETRY_FROM)), 0.0), 1.0)
    return z[k] + (w * theta) * d


@kernel
def _upwind(net, link, z, zk, theta, u):
    """Direction (+1 along the branch, -1 against), upwind depth (m) and upwind profile of a channel link.

    The direction is that of time n, the depth that of the geometry's levels (:func:`_at`).
    """
    k1 = np.uint64(net.lk_k1[link])
    k2 = np.uint64(net.lk_k2[link])
    u0 = u[link]
    if u0 > 0.0 or (u0 == 0.0 and z[k1] >= z[k2]):
        return 1.0, _at(z, zk, theta, k1) - net.lk_b1[link], np.uint64(net.lk_p1[link])
    return -1.0, _at(z, zk, theta, k2) - net.lk_b2[link], np.uint64(net.lk_p2[link])


@kernel
def _link_geometry(net, work, z, zk, theta, u, min_depth, iterate):
    """Per link: flux area (m²; 0 when dry or not a channel) at the upwind depth, and the friction geometry.

    The upwind side is that of time n (velocity ``u``, levels ``z``), the depths those of the geometry's levels
    z + θ (zk - z) (:func:`_at`).

    The friction geometry — flow area (m²), wetted perimeter (m) and R^(4/3) (m^(4/3)) in ``work.cam``,
    ``work.cper`` and ``work.cr43`` — is that of the upwind depth, except where the surface falls towards the
    downstream end: where the downstream depth is smaller by ``FRICTION_SPLIT`` of the upwind one or more, it
    is that of a depth that moves linearly to the mean of the two depths at twice that, and stays there up to
    ``FRICTION_GRADUAL`` (beyond, a drop in the bed or a jump, the surface is not gradually varied and the
    friction stays upwind). Upwind friction is first order in Δx: on a drawdown towards a critical control
    the friction of the deeper upwind section is too small (a M2 curve to a free outfall stood 25-30 mm low at
    0.5-1 km with Δx = 100 m). Friction at the mean depth makes the friction slope second order,
    Q|Q| / K(d_mean)² with K = A C √R, while the flux area stays upwind (the positivity of the scheme). The
    velocity of the link is Q / A_up, so ``work.cr43`` holds R^(4/3) of the friction geometry times
    (A_fr / A_up)²: friction_c2r then gives C² R (A_fr / A_up)², and the friction term g |u| u / (C² R) that
    Q|Q| / K(d_mean)² asks for. Only towards a drawdown: on a rising surface the friction of the shallower
    upwind section errs on the safe side, and a friction that falls as the level downstream rises made fast
    flow on a steep reach unstable.

    Returns the largest |u| / Δx of the wet links (1/s), found on the way. The coefficients f and r of every link
    (``work.fco``, ``work.rco``) are set to 0 here; the momentum passes set those of the links with flow.
    """
    area, cam, cper, cr43, lk_type, ilen = work.area, work.cam, work.cper, work.cr43, net.lk_type, net.lk_ilen
    fco, rco = work.fco, work.rco
    fastest = 0.0
    for link in range(lk_type.size):
        area[link] = 0.0
        fco[link] = 0.0  # a link without flow: the momentum passes leave it
        rco[link] = 0.0
        if lk_type[link] != LINK_CHANNEL:
            continue
        k1 = np.uint64(net.lk_k1[link])
        k2 = np.uint64(net.lk_k2[link])
        g1 = _at(z, zk, theta, k1) if iterate else z[k1]
        g2 = _at(z, zk, theta, k2) if iterate else z[k2]
        u0 = u[link]
        if u0 > 0.0 or (u0 == 0.0 and z[k1] >= z[k2]):  # as _upwind, with the downstream depth too
            depth, other, prof = g1 - net.lk_b1[link], g2 - net.lk_b2[link], np.uint64(net.lk_p1[link])
        else:
            depth, other, prof = g2 - net.lk_b2[link], g1 - net.lk_b1[link], np.uint64(net.lk_p2[link])
        if depth < min_depth:
            continue
        a_up, per, r43 = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af,
                                       net.tab_pf, net.tab_flow, prof, depth)
        if a_up <= 0.0:
            continue
        area[link] = a_up
        fastest = max(fastest, math.fabs(u0) * ilen[link])
        cam[link] = a_up
        cper[link] = per
        cr43[link] = r43
        gap = depth - other
        if FRICTION_SPLIT * depth < gap < FRICTION_GRADUAL * depth and other > min_depth:
            shift = 0.5 * min(gap / (FRICTION_SPLIT * depth) - 1.0, 1.0) * gap
            a_fr, per_fr, r43_fr = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top,
                                                 net.tab_af, net.tab_pf, net.tab_flow, prof, depth - shift)
            ratio = a_fr / a_up
            cam[link] = a_fr
            cper[link] = per_fr
            cr43[link] = r43_fr * (ratio * ratio)
    return fastest


@kernel
def _momentum_simple(net, work, z, u, q, dt):
    """The momentum terms of :func:`_momentum_other` for the links of ``net.mo_runs``, without branches.

    Such a link joins points k1 and k1 + 1, neither of which receives a lateral, has no Chézy friction, and
    its upwind neighbour is link - 1 (flowing into k1) or link + 1 (flowing out of k2, so -q and -u point
    towards it). Every quantity is computed for every link and the right one selected, in the same
    floating-point operations as :func:`_momentum_other`, and solved (:func:`_link_newton`); a dry link gets
    meaningless terms (numpy's error model: a division by its zero area gives inf, no exception), which the
    loop masks: its f and r are 0.
    """
    area, cr43, lfric, fco, rco = work.area, work.cr43, work.lfric, work.fco, work.rco
    lk_ilen, lk_ftype = net.lk_ilen, net.lk_ftype
    inv_dt = 1.0 / dt
    one = np.uint64(1)
    for run in net.mo_runs:
        l0, k0 = run[MO_LINK], run[MO_K1]
        for j in range(run[MO_COUNT]):
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
            f_u, r_u = _link_newton(ilen, (b + uc * ilen) if advect else b,
                                    ((rhs_u + sign * uc * uin * ilen) if advect else rhs_u) - G * ilen * dzl,
                                    friction_c2r(lk_ftype[link], lfric[link], 0.0, cr43[link]),  # not Chézy: no radius
                                    dzl)
            wet = a_up > 0.0
            fco[link] = f_u if wet else 0.0
            rco[link] = r_u if wet else 0.0


@kernel
def _momentum_other(net, work, link, z, zk, theta, u, q, dt):
    """The coefficients f and r (``work.fco``, ``work.rco``) of one channel link with flux area > 0.

    The momentum equation of a link, per unit mass, is ``b u + kappa |u| u = s - g (z2 - z1) / dx`` with
    b (1/s) the inertia, lateral-inflow and implicit advection terms, kappa = g / (C² R) (1/m), and
    s (m/s²) the explicit terms; :func:`_link_newton` solves it from b, s - g (z2 - z1) / dx at the levels of
    time n, C² R (m²/s²) and z2 - z1 (m).
    """
    a_up = work.area[link]
    if a_up <= 0.0:
        return
    lk_type, nl_ptr, nl_link, nl_sign = net.lk_type, net.nl_ptr, net.nl_link, net.nl_sign
    qlat = work.qlat
    k1 = np.uint64(net.lk_k1[link])
    k2 = np.uint64(net.lk_k2[link])
    u0 = u[link]
    sign, depth, _ = _upwind(net, link, z, zk, theta, u)
    per = work.cper[link]
    ftype = net.lk_ftype[link]
    conveyance = 1.0  # R^(4/3) of the friction geometry holds (A_fr / A_up)² already (_link_geometry)
    radius = 0.0
    if ftype >= FRICTION_CHEZY:  # Chézy, White-Colebrook: from the radius of the friction geometry
        a_fr = work.cam[link]
        radius = a_fr / per if per > 0.0 else depth
        ratio = a_fr / a_up
        conveyance = ratio * ratio
    down = net.lk_nb2[link] if sign > 0.0 else net.lk_nb1[link]
    if down >= 0 and (net.lk_nb1[np.uint64(down)] == NB_OUTFALL or net.lk_nb2[np.uint64(down)] == NB_OUTFALL):
        a_up, conveyance = _toward_outfall(net, work, link, z, zk, theta, sign, a_up, conveyance)
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
        elif m == NB_JUNCTION:  # junction: the link's share of the inflow, at the inflow-weighted velocity
            quin = 0.0
            qout = 0.0
            blocked = False
            for c in range(nl_ptr[kup], nl_ptr[kup + np.uint64(1)]):
                j = nl_link[c]
                qj = nl_sign[c] * q[j]
                if qj < 0.0:
                    qout -= qj
                elif qj > 0.0 and j != link:
                    if lk_type[j] != LINK_CHANNEL:
                        blocked = True
                    qin += qj
                    quin += qj * nl_sign[c] * u[j]
            if blocked or qout <= 0.0:
                qin = 0.0
            elif qin > 0.0:
                uin = quin / qin
                qin *= math.fabs(q[link]) / qout
        if qin > 0.0:
            if uin < ul:
                uc = 0.5 * (ul + uin)  # contraction: energy-head conservative
            else:
                uc = 0.5 * (qin + math.fabs(q[link])) / a_up  # expansion: momentum conservative
            if uc > 0.0:
                b += uc * ilen
                rhs_u += sign * uc * uin * ilen
    dzl = z[k2] - z[k1]
    c2r = friction_c2r_any(ftype, work.lfric[link], radius, work.cr43[link]) * conveyance
    work.fco[link], work.rco[link] = _link_newton(ilen, b, rhs_u - G * ilen * dzl, c2r, dzl)


@kernel
def _toward_outfall(net, work, link, z, zk, theta, sign, a_up, conveyance):
    """The flux area (m²) and friction conveyance factor of a channel link that feeds the reach to a free outfall.

    The reach to the outfall balances the energy between its upstream point and the brink exactly
    (:mod:`.outfall`); the upwind scheme's links account for the rise of the velocity head one cell late (a
    link's velocity is that of its upwind point), so the rise over the cell just above that reach would be
    missed, and every level upstream would stand too low by it (7 mm on a M2 drawdown with Δx = 100 m). This
    link therefore carries the velocity of its downstream point, Q / A(d_down), when that section is the
    narrower, so that its energy-conservative advection adds that rise; its friction stays that of its own
    friction geometry at the same discharge (``conveyance``, the factor so far, times (A_up / A_down)²).
    """
    if sign > 0.0:
        k, bed, prof = np.uint64(net.lk_k2[link]), net.lk_b2[link], net.lk_p2[link]
    else:
        k, bed, prof = np.uint64(net.lk_k1[link]), net.lk_b1[link], net.lk_p1[link]
    a_down = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af, net.tab_pf,
                           net.tab_flow, prof, _at(z, zk, theta, k) - bed)[0]
    if not 0.0 < a_down < a_up:
        return a_up, conveyance
    work.area[link] = a_down
    ratio = a_up / a_down
    return a_down, conveyance * ratio * ratio


@kernel(inline=True)
def _link_newton(ilen, b, s_u, c2r, dzl):
    """Coefficients f (1/s) and r (m/s) of ``u = r - f (z2 - z1)`` of one link from its momentum terms.

    ``ilen`` is 1/Δx (1/m), ``b`` (1/s) and ``s_u`` (m/s²) the terms of b u + kappa |u| u = s - g (z2 - z1) / dx with
    ``s_u`` = s - g (z2 - z1) / dx at the levels of time n, ``c2r`` C² R (m²/s², kappa = g / (C² R)) and ``dzl``
    z2 - z1 (m). Newton linearisation around its solution u* at the levels of time n:
    u* = 2 s / (b + sqrt(b² + 4 kappa |s|)), du/d(z2 - z1) = -g / (dx sqrt(...)). Exact in steady flow, and
    bounded by friction when flow starts from rest. Branch-free, so that the loops that call it stay vectorised;
    they mask the links without flow.
    """
    kappa = G / c2r
    root = math.sqrt(b * b + 4.0 * kappa * math.fabs(s_u))
    f_u = G * ilen / root
    return f_u, 2.0 * s_u / (b + root) + f_u * dzl
