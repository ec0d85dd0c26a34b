"""Free overfalls: a channel link whose bed steps down at its end carries at most the critical flow there.

Where the bed of a channel link ends above the bed of the point it flows into (a drop in the bed: a
culvert outlet or a ditch above a deeper watercourse, a D-Flow FM junction whose node lies at the lowest
bed of its branches), the water leaving the link falls freely once the level downstream is below the
critical level over the brink. The momentum equation of the link would then feel the whole fall (the
level below the brink) and accelerate the flow without bound; the flow that actually leaves is the
critical flow over the brink (Chow 1959, *Open-channel hydraulics*, §3-4 and §15-1: the brink depth of a
free overfall is close to the critical depth), and the upstream level is governed by it.

:func:`overfall_coefficients` runs in every Picard iteration after the structures, for the links with such
a step (``net.dl_link``): when the level downstream (in the flow direction, at the iterate) lies below the
brink ``crest`` (the higher of the link's two end beds) plus two thirds of the upstream depth above it, and
the link's channel law would carry more at the iterate than the brink's critical discharge, the link is written
like a free weir without losses (:func:`.structures.weir_link`): flux area A(d_c) of the link's profile at the
critical depth d_c = (2/3) h1 and velocity √(g d_c), so that at convergence Q = A(d_c) √(g d_c), the critical
discharge of a rectangular section with upstream head h1 above the brink. Otherwise the link keeps its channel
coefficients (:mod:`.momentum`), which are saved in the first iteration and restored when an iterate leaves the
overfall.

The brink limits the flow; it never raises it. Where the channel carries less than the brink could pass — a
flat pipe leaving a deep manhole above its bottom, its outfall low — the brink is no control. Judged by the
levels alone, such a pipe switched between its channel law (whose steady state lies on the free side of the
limit) and the brink's law (whose steady state lies on the drowned side) every few steps, and its levels swung
for as long as the flow lasted (tests/verification/test_overfall_entry.py).
"""

from __future__ import annotations

import math

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.lookup import flow_geometry
from rivercal.engine.kernels.structures import G

__all__ = ["overfall_coefficients"]


@kernel
def overfall_coefficients(net, work, zk, u, dt, first):
    """Free-overfall flux area (m²) and coefficients f (1/s), r (m/s) of the links in ``net.dl_link`` at iterate ``zk``.

    ``u`` is the velocity at time n (m/s); ``first`` marks the first Picard iteration of a (sub-)step, in
    which the channel coefficients of these links are saved (``work.ovf``).
    """
    area, fco, rco, saved = work.area, work.fco, work.rco, work.ovf
    for j in range(net.dl_link.size):
        link = np.uint64(net.dl_link[j])
        if first:
            saved[0, j] = area[link]
            saved[1, j] = fco[link]
            saved[2, j] = rco[link]
        k1 = np.uint64(net.lk_k1[link])
        k2 = np.uint64(net.lk_k2[link])
        crest = max(net.lk_b1[link], net.lk_b2[link])
        if zk[k1] >= zk[k2]:
            z_up, z_down, sign, prof = zk[k1], zk[k2], 1.0, net.lk_p1[link]
        else:
            z_up, z_down, sign, prof = zk[k2], zk[k1], -1.0, net.lk_p2[link]
        h1 = z_up - crest
        a_ch, f_ch, r_ch = saved[0, j], saved[1, j], saved[2, j]
        area[link] = a_ch
        fco[link] = f_ch
        rco[link] = r_ch
        if h1 <= 0.0 or z_down >= crest + (2.0 / 3.0) * h1:  # no flow over the brink, or drowned: a channel
            continue
        d_c = (2.0 / 3.0) * h1
        a_c = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af, net.tab_pf,
                            net.tab_flow, prof, d_c)[0]
        length = net.lk_len[link]
        u_c = math.sqrt(G * d_c)
        if sign * a_ch * (r_ch - f_ch * (zk[k2] - zk[k1])) <= a_c * u_c:  # the channel carries less: no control
            continue
        cu = G / (1.5 * length)
        b = 1.0 / dt + u_c / length
        area[link] = a_c
        fco[link] = cu / b
        rco[link] = (u[link] / dt + sign * cu * (z_down - crest)) / b
