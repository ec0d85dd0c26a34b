"""The end of a time step: link fluxes of the solved levels, draining limits, and the committed volumes.

The fluxes of the last iterate update the stored volumes, ``V^{n+1} = V^n + Δt Σ Q``
(:func:`finish_step`); the volume is the prognostic variable, so mass is conserved to round-off
whatever the number of iterations or the table resolution. The new level is the last iterate;
the small difference V(z^{n+1}) - V^{n+1} left by the linearisation is not lost but enters the
right-hand side of the next step (the ``V(z^k) - V^n`` term of :mod:`.assemble`).

Drying: a point may not lose more water than it holds within a step; :func:`limit_draining_links`
throttles the links that would drain it, and the levels are solved again.
"""

from __future__ import annotations

import math

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.assemble import in_pieces
from rivercal.engine.kernels.codes import (
    BOUNDARY_DISCHARGE,
    BOUNDARY_RATING,
    FLICKER_DZ,
    FLICKER_LIMIT,
    FLICKER_TURN,
    LINK_CHANNEL,
    LINK_PUMP,
    RUN_COUNT,
    RUN_K1,
    RUN_K2,
    RUN_LINK,
    STAT_DRYING,
    STAT_FLICKER_AT,
    STAT_FLICKERS,
    STATUS_FLICKER,
    STATUS_LEVEL,
    STATUS_OK,
    STATUS_VELOCITY,
)
from rivercal.engine.kernels.lookup import hp_volume_width
from rivercal.engine.kernels.picard import solve_levels

__all__ = [
    "check_levels",
    "compute_fluxes",
    "finish_step",
    "fluxes_within_volume",
    "gross_outflow",
    "level_of_volume",
    "limit_draining_links",
    "too_fast",
]


@kernel(inline=True)
def fluxes_within_volume(net, work, vol, theta, dt, tol, u, un, qn):
    """The fluxes of the solved levels (:func:`compute_fluxes`), throttled where they would drain a point dry.

    No point may lose more water than it holds within a step: where it would, the links that drain it are
    limited (:func:`limit_draining_links`) and the levels solved again, up to 8 times.
    """
    for attempt in range(9):
        compute_fluxes(net, work, theta, u, un, qn)
        if attempt == 8 or limit_draining_links(net, work, vol, dt, qn) == 0:
            break
        solve_levels(net, work, work.zk, vol, u, theta, dt, tol)
        work.stats[STAT_DRYING] += 1


@kernel
def compute_fluxes(net, work, theta, u, un, qn):
    """Link velocities ``un`` (m/s) and fluxes ``qn`` (m³/s) of the current solution ``work.zk``.

    ``u`` is the velocity at time n (m/s). Also, per point, the net inflow (``work.netq``, m³/s).
    The links are visited run by run (:func:`rivercal.engine.plan.link_runs`): within a run the
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
        l0, k1, k2 = run[RUN_LINK], run[RUN_K1], run[RUN_K2]
        for j in range(run[RUN_COUNT]):
            link = l0 + j
            t = lk_type[link]
            ul = rco[link] - fco[link] * (zk[k2 + j] - zk[k1 + j])
            th = theta if t == LINK_CHANNEL else 1.0
            ql = area[link] * (th * ul + (1.0 - th) * u[link])
            wet = area[link] > 0.0
            pump = t == LINK_PUMP  # a pump carries its fixed flux rco, and no velocity
            un[link] = ul if wet & (not pump) else 0.0
            qn[link] = rco[link] if pump else (ql if wet else 0.0)
        for j in range(run[RUN_COUNT]):
            netq[k2 + j] += qn[l0 + j]
        for j in range(run[RUN_COUNT]):
            netq[k1 + j] -= qn[l0 + j]
    for bnd in range(net.b_hp.size):
        if net.b_type[bnd] == BOUNDARY_RATING:
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
        if net.b_type[bnd] == BOUNDARY_RATING:
            i = net.b_hp[bnd]
            outflow[i] += max(work.rq0[bnd] + work.rslope[bnd] * zk[i], 0.0)


@kernel
def limit_draining_links(net, work, vol, dt, qn):
    """Throttle, for this step, the links that would empty a point below its bed.

    With the fluxes ``qn`` (m³/s) of :func:`compute_fluxes` (and their gross outflow per point,
    :func:`gross_outflow`), a point that would lose more water than it holds plus receives (its
    volume would become negative, the level below the lowest bed) has the flux of every link carrying water
    out of it scaled by ``0.9 × available / outflow``: a channel link's flux area, a structure's (and a pump's)
    coefficients r and f. A structure's law is fully implicit (its flux is A u^{n+1}), so both scale its flux
    alike; scaling its velocity keeps u = Q / A, where a vanishing area would leave a velocity that no
    level answers and that the next step's law starts from (a culvert below a point that ran dry
    accelerated to 20 m/s that way). Returns the number of points limited; the caller solves again.
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
                if net.lk_type[link] == LINK_CHANNEL:
                    work.area[link] *= factor
                else:  # a structure (or pump): its velocity, not its flow area, so that u stays Q / A
                    work.rco[link] *= factor
                    work.fco[link] *= factor
        limited += 1
    return limited


@kernel
def check_levels(net, work, z, dz, shorter, small):
    """Screen the solved levels ``work.zk`` (m AD) of a (sub-)step before :func:`finish_step` commits them.

    Returns (dry, error): the first point whose level lies below ``work.floor``, more than ``DRY_TOLERANCE``
    below its bed (a NaN counts as below), or -1 when there is none (level-boundary points are not checked: their
    floor is -inf); the step control's error estimate, the largest difference (m) at a point that is not a level
    boundary between the solved level and its extrapolation ``z + dz / shorter`` from ``z`` (m AD), the level at
    the (sub-)step's start, and ``dz`` (m), the change of the last (sub-)step, which was ``shorter`` times as long
    (0 when no point differs by more than ``small``, m). One pass over the points that vectorises (counts, no
    floating-point maximum); the error and the dry point are searched only when some point calls for them.
    """
    zk, floor, fixed = work.zk, work.floor, work.fixed
    back = 1.0 / shorter
    low = 0
    off = 0
    for i in range(zk.size):
        low += not zk[i] >= floor[i]
        off += (math.fabs(zk[i] - z[i] - dz[i] * back) > small) & (not fixed[i])
    error = 0.0
    if off > 0:
        for i in range(zk.size):
            if not fixed[i]:
                error = max(error, math.fabs(zk[i] - z[i] - dz[i] * back))
    if low == 0:
        return -1, error
    for i in range(zk.size):
        if not zk[i] >= floor[i]:
            return i, error
    return -1, error


@kernel
def too_fast(un, vmax):
    """Whether a velocity of ``un`` (m/s) exceeds ``vmax`` (m/s), or is NaN (a pass that vectorises)."""
    fast = False
    for link in range(un.size):
        fast |= not math.fabs(un[link]) <= vmax
    return fast


@kernel
def finish_step(net, work, dt, vmax, z, dz, vol, un, qn, balance, counting):
    """Commit the (sub-)step of ``dt`` s: volumes and levels from the net inflows of :func:`compute_fluxes`, balance.

    ``un`` (m/s) and ``qn`` (m³/s) are the new velocities and fluxes; they become the state by the time
    loop's swap of its velocity and flux arrays, not by a copy. Returns (status, index) of a divergence
    check: ``STATUS_OK`` or the h-point / link at fault (the first one). Adds what the withdrawals asked and
    what they lacked (:func:`.forcing.apply_forcing`) to their run totals (``work.wreq_sum``,
    ``work.wshort_sum``, m³).

    Flicker: per point, ``work.swing`` holds the change (m) since its level last turned (from rising to falling or
    back), and a turn after a swing of more than ``FLICKER_DZ`` adds to its count ``work.flick`` (see
    ``FLICKER_LIMIT``). A point that turns too often within a few (sub-)steps makes it return ``STATUS_FLICKER``
    with that point (its count starts again; the step is committed): an oscillation of a few steps' period is not
    resolved by the step. Turns are not counted in a (sub-)step in which a pump switched (``counting`` false): a
    pump cycling between its start and stop level is its control's cycle.

    The loops over all points and links have no branches (their checks are conjunctions), so that they
    vectorise; the rare cases (a level outside its linearised piece, a divergence) are handled after them.
    """
    zk, netq, zlo, zhi = work.zk, work.netq, work.zlo, work.zhi
    # While zk lies in the piece of the volume curve the system was linearised on (work.zlo..zhi), V is
    # linear there and the solved system says V(zk) = V^n + Δt Σ Q exactly, up to the round-off of the
    # solve: zk is the level of the new volume, and what round-off leaves enters the next step's right-hand
    # side (as any linearisation difference does). Outside it V bends: Newton, before zk is committed.
    if not in_pieces(zk, zlo, zhi):
        for i in range(zk.size):
            if not work.fixed[i] and not zlo[i] <= zk[i] <= zhi[i]:
                zk[i] = level_of_volume(net, i, vol[i] + dt * netq[i], zk[i])
    finite = True
    flick, swing = work.flick, work.swing
    worst = 0
    for i in range(zk.size):
        zi = zk[i]
        vol[i] += dt * netq[i]
        d = zi - z[i]
        onward = d * swing[i] >= 0.0
        turned = (not onward) & (math.fabs(swing[i]) > FLICKER_DZ) & counting
        swing[i] = swing[i] + d if onward else d
        flick[i] = flick[i] - (flick[i] > 0) + FLICKER_TURN * turned
        worst = max(worst, flick[i])
        dz[i] = d
        z[i] = zi
        finite &= math.fabs(zi - net.hp_bed[i]) <= 1.0e4  # also NaN
    for bnd in range(net.b_hp.size):
        i = net.b_hp[bnd]
        t = net.b_type[bnd]
        if t == BOUNDARY_DISCHARGE:
            balance[bnd] += dt * work.bq[bnd]
        elif t == BOUNDARY_RATING:
            balance[bnd] -= dt * (work.rq0[bnd] + work.rslope[bnd] * zk[i])
        else:  # a level boundary: the solve returned its level exactly; its volume follows from it
            vol[i] = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                                     net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                                     net.tab_at, net.tab_wt, i, z[i])[0]
            inflow = 0.0
            for c in range(net.nl_ptr[i], net.nl_ptr[i + 1]):
                inflow -= net.nl_sign[c] * qn[net.nl_link[c]]
            balance[bnd] += dt * inflow
    for j in range(work.wreq.size):
        work.wreq_sum[j] += dt * work.wreq[j]
        work.wshort_sum[j] += dt * work.wshort[j]
    if not finite:
        for i in range(z.size):
            if not math.fabs(z[i] - net.hp_bed[i]) <= 1.0e4:
                return STATUS_LEVEL, i
    calm = True
    if vmax < math.inf:  # otherwise the step control has checked them (:func:`.too_fast`)
        for link in range(un.size):
            calm &= math.fabs(un[link]) <= vmax  # also NaN
    if not calm:
        for link in range(un.size):
            if not math.fabs(un[link]) <= vmax:
                return STATUS_VELOCITY, link
    if worst >= FLICKER_LIMIT:
        for i in range(flick.size):
            if flick[i] >= FLICKER_LIMIT:
                flick[i] = 0
                work.stats[STAT_FLICKERS] += 1
                work.stats[STAT_FLICKER_AT] = i
                return STATUS_FLICKER, i
    return STATUS_OK, -1


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
