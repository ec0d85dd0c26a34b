"""How far a time step can trust the scheme's explicit upwind depth: the step control's forecast.

The flux of a channel link is A(h_up^n) u^{n+1}: the flow area comes from the upwind depth at the start of
the step (reference note §A; Stelling & Duinmeijer 2003). A point whose level stands δh too high at time n
sends W |u| δh more water (m³/s, W the flow width) through every link that leaves it; the implicit part of
the step answers through the point's storage and its links' conductances, the diagonal of the level system,
w/Δt + Σ θ A f (m²/s). Their ratio,

    a_i = Σ_out W |u| / (w_i/Δt + Σ θ A f),

is the share of a level error that the explicit depth passes on to the next step. Where it exceeds about one
the step-to-step (2Δt) mode grows: the flow is too fast for the step (a steep reach at Courant numbers
u Δt/Δx above about 2). Short links between large pools have large conductances and stay far below one at any
Courant number; a friction-dominated steep reach does not. The time loop divides a step whose largest a_i
exceeds ``AMP_RISE`` (:mod:`.timeloop`). Links that may be free overfalls (``net.dl_link``) or reach a free
outfall (``net.of_link``) do not count: their flux areas follow the Picard iterate (:mod:`.overfall`,
:mod:`.outfall`).

:func:`explicit_amplification` runs only when some wet channel link is crossed in less than a step (the
largest |u|/Δx, which :func:`.momentum.channel_coefficients` finds on its way, times Δt above one).
"""

from __future__ import annotations

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import LINK_CHANNEL
from rivercal.engine.kernels.lookup import hp_volume_width_piece

__all__ = ["explicit_amplification"]


@kernel
def explicit_amplification(net, work, z, u, dt, theta, min_depth):
    """The largest a_i of the module docstring over the points (not level boundaries), for a step of ``dt`` s.

    From the channel links' flux areas (m²) and coefficients f (1/s) of :func:`.momentum.channel_coefficients`
    for this step, the velocities ``u`` (m/s) and levels ``z`` (m AD) at its start, and each point's storage
    area (m²) at ``z`` (the piece of its volume curve that holds ``z``, looked up here where the last one does
    not, as :func:`.assemble.assemble` does: the result depends on the state alone).
    """
    num, den = work.anum, work.aden
    zlo, zhi = work.zlo, work.zhi
    for i in range(num.size):
        if not zlo[i] <= z[i] <= zhi[i]:  # the storage area at z itself, whatever was looked up before
            zlo[i], zhi[i], work.p_z[i], work.p_v[i], work.p_w[i] = hp_volume_width_piece(
                net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin, net.tab_off, net.tab_n,
                net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top, net.tab_at, net.tab_wt, i, z[i])
        num[i] = 0.0
        den[i] = work.p_w[i] / dt
    area, fco, lk_type = work.area, work.fco, net.lk_type
    for link in range(area.size):
        a = area[link]
        if a <= 0.0 or lk_type[link] != LINK_CHANNEL:
            continue
        k1 = np.uint64(net.lk_k1[link])
        k2 = np.uint64(net.lk_k2[link])
        c = theta * a * fco[link]
        den[k1] += c
        den[k2] += c
        u0 = u[link]
        if u0 > 0.0:
            num[k1] += a / max(z[k1] - net.lk_b1[link], min_depth) * u0
        elif u0 < 0.0:
            num[k2] -= a / max(z[k2] - net.lk_b2[link], min_depth) * u0
    for j in range(net.dl_link.size + net.of_link.size):  # overfalls and outfalls: flux areas of the iterate
        link = np.uint64(net.dl_link[j] if j < net.dl_link.size else net.of_link[j - net.dl_link.size])
        a = area[link]
        if a <= 0.0:
            continue
        u0 = u[link]
        if u0 > 0.0:
            k1 = np.uint64(net.lk_k1[link])
            num[k1] -= a / max(z[k1] - net.lk_b1[link], min_depth) * u0
        elif u0 < 0.0:
            k2 = np.uint64(net.lk_k2[link])
            num[k2] += a / max(z[k2] - net.lk_b2[link], min_depth) * u0
    worst = 0.0
    for i in range(num.size):
        if not work.fixed[i] and num[i] > 0.0:
            worst = max(worst, num[i] / den[i])
    return worst
