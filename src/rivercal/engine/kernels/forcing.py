"""The forcing of a time step: boundary discharges and levels, laterals, and the rating-boundary law.

Per (sub-)step :func:`apply_forcing` writes the sources (m³/s) of discharge boundaries and laterals
(withdrawals limited to the water present), the imposed levels (m AD) of level boundaries, and the lateral
inflow per unit length (m²/s) that the momentum equation of the channel links sees. :func:`rating_flow` is the
Q(h) law of a rating boundary, which the assembly linearises at each iterate.
"""

from __future__ import annotations

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import BOUNDARY_DISCHARGE, BOUNDARY_LEVEL

__all__ = ["apply_forcing", "rating_flow"]


@kernel
def apply_forcing(net, work, n, forcing, edges, dt, vol, z, weight, start, end):
    """Sources (m³/s), Dirichlet levels (m AD) and lateral inflow per unit length (m²/s) of a step of ``n``.

    ``dt`` (s) is the length of the (sub-)step, which covers the fractions ``start`` to ``end`` of the step. A
    level boundary reaches its level for the end of step ``n`` over the rest of the step: its level moves from
    ``z`` (m AD, the current level) by the share ``weight`` of the way (1 for a whole step, or for the last
    sub-step of one). A whole step takes the step-mean discharges of ``forcing``; a sub-step, where ``edges`` holds
    the forcing's course within each step (two rows per step, :meth:`~rivercal.engine.Simulator.forcing_edges`),
    the mean over the sub-step of the discharge that moves linearly from the step's start to its end
    (:func:`_discharge`): a divided step then follows the forcing's own course and its levels bend no more at the
    step's start than within it (with the step's mean in every sub-step, an hourly flood wave divided into 128
    sub-steps bent its upstream level by centimetres at every hour, and the step control kept dividing). The
    sub-steps of a step take its mean volume, to round-off.

    Withdrawals (a negative discharge of a boundary or a lateral) take at most half of the water present
    at their point per (sub-)step: what they ask beyond that is not delivered. Per boundary, then per
    lateral, ``work.wreq`` gets the withdrawal asked and ``work.wshort`` what is not delivered (m³/s), and
    ``work.bq`` each discharge boundary's delivered discharge (m³/s). Only the entries of forced points
    are written: the others stay as :func:`run` set them at its start (no source, no lateral inflow, not
    fixed). Returns the total of the laterals (m³/s).
    """
    src, fixed, fixed_val, qlat = work.src, work.fixed, work.fixed_val, work.qlat
    b_hp, b_type, b_col = net.b_hp, net.b_type, net.b_col
    n_b = b_hp.size
    for bnd in range(n_b):
        src[b_hp[bnd]] = 0.0
    for lat in range(net.lat_hp.size):
        src[net.lat_hp[lat]] = 0.0
        qlat[net.lat_hp[lat]] = 0.0
    whole = end - start >= 1.0 or edges.shape[0] <= 2 * n + 1
    for bnd in range(n_b):
        i = b_hp[bnd]
        if b_type[bnd] == BOUNDARY_DISCHARGE:
            qb = _withdrawal(work, bnd, _discharge(forcing, edges, n, b_col[bnd], whole, start, end), vol[i], dt)
            work.bq[bnd] = qb
            src[i] += qb
        elif b_type[bnd] == BOUNDARY_LEVEL:
            fixed[i] = True
            target = forcing[n, b_col[bnd]]
            fixed_val[i] = target if weight == 1.0 else z[i] + weight * (target - z[i])
    total = 0.0
    for lat in range(net.lat_hp.size):
        i = net.lat_hp[lat]
        ql = _withdrawal(work, n_b + lat, _discharge(forcing, edges, n, net.lat_col[lat], whole, start, end), vol[i],
                         dt)
        if ql > 0.0:
            qlat[i] += ql * net.hp_ilen[i]  # an extraction leaves with the flow's velocity: no momentum change
        src[i] += ql
        total += ql
    return total


@kernel
def _discharge(forcing, edges, n, col, whole, start, end):
    """Discharge (m³/s) of forcing column ``col`` in step ``n``: its mean, or its mean from ``start`` to ``end``.

    Within the step the discharge moves linearly from ``edges[2n, col]`` to ``edges[2n + 1, col]``; the mean over
    the fractions ``start`` to ``end`` of the step is its value at their middle.
    """
    if whole:
        return forcing[n, col]
    q0 = edges[2 * n, col]
    return q0 + (edges[2 * n + 1, col] - q0) * (0.5 * (start + end))


@kernel
def _withdrawal(work, j, q, vol, dt):
    """Discharge ``q`` (m³/s) of forcing ``j``, a withdrawal limited to half the volume ``vol`` (m³) per ``dt`` (s).

    Records the withdrawal asked and its shortfall (m³/s) in ``work.wreq[j]`` and ``work.wshort[j]``.
    """
    if q >= 0.0:
        work.wreq[j] = 0.0
        work.wshort[j] = 0.0
        return q
    limited = max(q, -0.5 * max(vol, 0.0) / dt)
    work.wreq[j] = -q
    work.wshort[j] = limited - q
    return limited


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
