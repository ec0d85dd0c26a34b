"""Structures written in the linear link form ``u = r - f (z2 - z1)`` (Picard-linearised).

Each law returns, for one link, the flux area A (m²) and the coefficients ``f`` (1/s) and
``r`` (m/s) of ``u = r - f (z2 - z1)``, evaluated at the current iterate of the levels. With A,
u_s and the flow regime taken from the iterate, the level system stays symmetric;
at convergence the link reproduces the discharge formula exactly (reference note §A, after
D-Flow FM ``weir.f90``):

- weir, submerged (h1 - zs ≤ 1.5 (h2 - zs)): Q = c_e c_w W √(2g(h1 - h2)) (h2 - zs);
- weir, free: Q = c_e c_w W (2/3) √((2/3) g) (h1 - zs)^1.5 (thesis Eq. 3-4);
- culvert: Q = A(d) √(2g ΔE / ξ) with ξ = ξ_in + 2gL/(C²R) + ξ_out, where d and ΔE are the
  critical depth min(2/3 H1, D) and H1 - d in free flow, the downstream depth min(H2, D) and
  H1 - H2 when submerged or pressurised.
"""

from __future__ import annotations

import math

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import (
    CULVERT_RECTANGULAR,
    FLOW_BOTH,
    FLOW_NEGATIVE,
    FLOW_POSITIVE,
    FRICTION_MANNING,
    FRICTION_STRICKLER,
    LINK_WEIR,
)

__all__ = [
    "G",
    "culvert_area_perimeter",
    "culvert_link",
    "direction_allowed",
    "friction_c2r",
    "structure_coefficients",
    "switch_pumps",
    "weir_link",
]

G = 9.81


@kernel
def direction_allowed(code, sign):
    """Whether flow with ``sign`` (+1 branch direction, -1 against) passes a structure with ``code``."""
    if code == FLOW_BOTH:
        return True
    if code == FLOW_POSITIVE:
        return sign > 0
    if code == FLOW_NEGATIVE:
        return sign < 0
    return False


@kernel
def friction_c2r(ftype, value, r, r43):
    """C² R (m²/s²) for hydraulic radius ``r`` (m) and r43 = R^(4/3): Strickler, Manning or Chézy."""
    if ftype == FRICTION_STRICKLER:
        return value * value * r43
    if ftype == FRICTION_MANNING:
        return r43 / (value * value)
    return value * value * r


@kernel
def weir_link(z1, z2, crest, width, cmu, dircode, length, u_old, dt):
    """Flux area (m²), f and r of a weir link for levels z1, z2 (m AD) at its two ends."""
    if z1 >= z2:
        smax, smin, sign = z1, z2, 1.0
    else:
        smax, smin, sign = z2, z1, -1.0
    h1 = smax - crest
    if h1 <= 0.0 or not direction_allowed(dircode, sign):
        return 0.0, 0.0, 0.0
    h2 = smin - crest
    if h1 > 1.5 * h2:  # free flow
        area = cmu * width * (2.0 / 3.0) * h1
        us = math.sqrt((2.0 / 3.0) * G * h1)
        cu = G / (1.5 * length)
        extra = cu * (smin - crest)
    else:  # submerged
        area = cmu * width * h2
        us = math.sqrt(2.0 * G * (smax - smin))
        cu = 2.0 * G / length
        extra = 0.0
    b = 1.0 / dt + us / length
    return area, cu / b, (u_old / dt + sign * extra) / b


@kernel
def culvert_area_perimeter(shape, width, height, d):
    """Flow area (m²) and wetted perimeter (m) of a culvert barrel at depth ``d`` (m)."""
    if d <= 0.0:
        return 0.0, 0.0
    if shape == CULVERT_RECTANGULAR:
        if d >= height:
            return width * height, 2.0 * (width + height)
        return width * d, width + 2.0 * d
    radius = 0.5 * width
    if d >= width:
        return math.pi * radius * radius, math.pi * width
    theta = 2.0 * math.acos(1.0 - 2.0 * d / width)
    return radius * radius * 0.5 * (theta - math.sin(theta)), radius * theta


@kernel
def culvert_link(z1, z2, shape, width, height, invert, clen, xin, xout, ftype, fval, dircode, length, u_old, dt):
    """Flux area (m²), f and r of a culvert link for levels z1, z2 (m AD) at its two ends."""
    if z1 >= z2:
        smax, smin, sign = z1, z2, 1.0
    else:
        smax, smin, sign = z2, z1, -1.0
    h1 = smax - invert
    if h1 <= 0.0 or not direction_allowed(dircode, sign):
        return 0.0, 0.0, 0.0
    h2 = max(smin - invert, 0.0)
    dcrit = min((2.0 / 3.0) * h1, height)
    free = h2 < dcrit
    d = dcrit if free else min(h2, height)
    area, per = culvert_area_perimeter(shape, width, height, d)
    if area <= 0.0:
        return 0.0, 0.0, 0.0
    radius = area / per
    xi = xin + xout + 2.0 * G * clen / friction_c2r(ftype, fval, radius, radius * np.cbrt(radius))
    head = (h1 - d) if free else (h1 - h2)
    us = math.sqrt(2.0 * G * max(head, 0.0) / xi)
    cu = 2.0 * G / (xi * length)
    extra = cu * (smin - invert - d) if free else 0.0
    b = 1.0 / dt + us / length
    return area, cu / b, (u_old / dt + sign * extra) / b


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
def structure_coefficients(net, work, zk, u, crest, dt):
    """Weir and culvert links linearised at the levels ``zk`` (m AD) of the current iterate."""
    for link in work.struct_links:
        s = net.lk_sidx[link]
        k1 = net.lk_k1[link]
        k2 = net.lk_k2[link]
        z1 = zk[k1]
        z2 = zk[k2]
        if net.lk_type[link] == LINK_WEIR:
            a, f, r = weir_link(z1, z2, crest[s], net.w_width[s], net.w_cmu[s], net.w_dir[s], net.lk_len[link],
                                u[link], dt)
        else:
            a, f, r = culvert_link(z1, z2, net.c_shape[s], net.c_width[s], net.c_height[s], net.c_invert[s],
                                   net.c_length[s], net.c_xin[s], net.c_xout[s], net.c_ftype[s], net.c_fval[s],
                                   net.c_dir[s], net.lk_len[link], u[link], dt)
        work.area[link] = a
        work.fco[link] = f
        work.rco[link] = r
