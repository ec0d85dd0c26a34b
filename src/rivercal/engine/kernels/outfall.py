"""Free outfalls: the last reach to a critical control as gradually varied flow, integrated inside the step.

Towards a free outfall (a ``critical`` boundary: the flow leaves over the end at critical depth) the water
surface of the last cells is far from straight: in a M2 drawdown the depth falls most steeply in the last
metres before the brink, and the friction slope there grows with the depth to the power -10/3. A scheme that
evaluates the last link's velocity and friction at one or two depths is off by decimetres with Δx = 100 m
(-180 mm 100 m above the brink before this module existed). Instead the link that reaches the outfall
(``net.of_link``) takes its discharge from the steady gradually-varied-flow equation over its length L,

    ds/dd = (1 - Fr²) / (S_f - S_0),   Fr² = Q² T / (g A³),   S_f = Q|Q| / (A² C² R),

integrated from the critical depth d_c at the brink (where Q = A √(g A / T)) up to the depth d_1 at the
link's upstream point (Chow 1959, *Open-channel hydraulics*, §9-1 and §10-1): the discharge is the one whose
drawdown reaches d_1 exactly L upstream of the brink. With the bed slope S_0 and the friction of the link
(its law and value, the cross-section at the brink), :func:`_drawdown_length` evaluates the integral by
8-point Gauss-Legendre quadrature in the depth; :func:`outfall_coefficients` finds d_c (so Q) by the Illinois
variant of regula falsi, and writes the link like a free weir (:func:`.structures.weir_link`): flux area
A(d_c), velocity Q / A(d_c), so that at convergence of the Picard iterations the link carries that Q. The
last reach is so treated as quasi-steady; the point at the brink keeps its storage and, with the critical
boundary's rating, the critical depth.
"""

from __future__ import annotations

import math

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import FLOW_WIDTH, NB_OUTFALL
from rivercal.engine.kernels.lookup import flow_geometry
from rivercal.engine.kernels.structures import G, friction_c2r_any

__all__ = ["outfall_coefficients"]

#: Gauss-Legendre nodes and weights on [-1, 1], 8 points.
_NODES = np.array([-0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
                   0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363])
_WEIGHTS = np.array([0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
                     0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763])
#: Regula-falsi iterations for the critical depth at the brink, at most.
_ITERATIONS = 40


@kernel
def _section(net, prof, d):
    """Flow area (m²), top width (m), wetted perimeter (m) and R^(4/3) (m^(4/3)) of profile ``prof`` at depth ``d``."""
    a, per, r43 = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af,
                                net.tab_pf, net.tab_flow, prof, d)
    off = net.tab_off[prof]
    n = net.tab_n[prof]
    j = int(d * net.tab_idd[prof])
    if j >= n - 1:
        width = net.tab_wf_top[prof]
    else:
        width = net.tab_flow[np.uint64(FLOW_WIDTH * (off + j) + 1)] * net.tab_idd[prof]
    return a, width, per, r43


@kernel
def _critical_flow(net, prof, d):
    """Critical discharge (m³/s) of profile ``prof`` at depth ``d`` (m): A √(g A / T)."""
    a, width, _, _ = _section(net, prof, d)
    if a <= 0.0 or width <= 0.0:
        return 0.0
    return a * math.sqrt(G * a / width)


@kernel
def _drawdown_length(net, prof, ftype, fvalue, slope, q, d_c, d_1):
    """Distance (m) over which the steady drawdown of discharge ``q`` rises from depth ``d_c`` to ``d_1`` (m).

    ``math.inf`` when it never gets there (the depth ``d_1`` lies at or above the normal depth of ``q`` on
    bed slope ``slope``). ``ftype``/``fvalue``: the link's friction law and value.
    """
    half = 0.5 * (d_1 - d_c)
    mid = 0.5 * (d_1 + d_c)
    total = 0.0
    for k in range(_NODES.size):
        d = mid + half * _NODES[k]
        a, width, per, r43 = _section(net, prof, d)
        if a <= 0.0:
            return math.inf
        c2r = friction_c2r_any(ftype, fvalue, a / per, r43)
        excess = q * q / (a * a * c2r) - slope
        if excess <= 0.0:
            return math.inf
        total += _WEIGHTS[k] * (1.0 - q * q * width / (G * a * a * a)) / excess
    return half * total


@kernel
def outfall_discharge(net, link, prof, ftype, fvalue, slope, length, d_1):
    """Discharge (m³/s) over the brink of an outfall reach of ``length`` m whose upstream depth is ``d_1`` m.

    Also returns the critical depth at the brink (m). Regula falsi (Illinois) on the critical depth d_c in
    (0, d_1): the drawdown from d_c reaches d_1 after more than ``length`` m for small d_c, after none at d_1.
    """
    lo, hi = 0.0, d_1
    f_lo, f_hi = math.inf, -length
    d_c = 0.5 * d_1
    side = 0
    for _ in range(_ITERATIONS):
        if math.isinf(f_lo):
            d_c = 0.5 * (lo + hi)
        else:
            d_c = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        f = _drawdown_length(net, prof, ftype, fvalue, slope, _critical_flow(net, prof, d_c), d_c, d_1) - length
        if f > 0.0:
            lo, f_lo = d_c, f
            if side == 1:
                f_hi *= 0.5
            side = 1
        else:
            hi, f_hi = d_c, f
            if side == -1 and not math.isinf(f_lo):
                f_lo *= 0.5
            side = -1
        if hi - lo <= 1.0e-7 * d_1:
            break
    return _critical_flow(net, prof, d_c), d_c


@kernel
def outfall_coefficients(net, work, zk, u, dt):
    """Flux area (m²) and coefficients f (1/s), r (m/s) of the links that reach a free outfall, at iterate ``zk``.

    ``u`` is the velocity at time n (m/s). A link whose upstream level does not stand above the brink, or
    whose flow runs away from the outfall, keeps its channel coefficients.
    """
    for j in range(net.of_link.size):
        link = np.uint64(net.of_link[j])
        k1 = np.uint64(net.lk_k1[link])
        k2 = np.uint64(net.lk_k2[link])
        if net.lk_nb2[link] == NB_OUTFALL:
            z_up, z_down, sign, bed_up, bed, prof = zk[k1], zk[k2], 1.0, net.lk_b1[link], net.lk_b2[link], \
                net.lk_p2[link]
        else:
            z_up, z_down, sign, bed_up, bed, prof = zk[k2], zk[k1], -1.0, net.lk_b2[link], net.lk_b1[link], \
                net.lk_p1[link]
        length = net.lk_len[link]
        d_1 = z_up - bed_up
        h1 = z_up - bed
        if d_1 <= 1.0e-6 or h1 <= 1.0e-6 or z_down > z_up:
            continue
        q, d_c = outfall_discharge(net, link, prof, net.lk_ftype[link], work.lfric[link], (bed_up - bed) / length,
                                   length, d_1)
        a_c = flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af, net.tab_pf,
                            net.tab_flow, prof, d_c)[0]
        if a_c <= 0.0 or q <= 0.0:
            continue
        u_s = q / a_c
        cu = u_s * u_s / (length * h1)
        b = 1.0 / dt + u_s / length
        work.area[link] = a_c
        work.fco[link] = cu / b
        work.rco[link] = (u[link] / dt + sign * cu * (z_down - bed)) / b
