"""Structures written in the linear link form ``u = r - f (z2 - z1)`` (Picard-linearised).

Each law returns, for one link, the flux area A (m²) and the coefficients ``f`` (1/s) and
``r`` (m/s) of ``u = r - f (z2 - z1)``, evaluated at the current iterate of the levels. With A,
u_s and the flow regime taken from the iterate, the level system stays symmetric;
at convergence the link reproduces the discharge formula exactly (reference note §A, after
D-Flow FM ``weir.f90``):

- weir, submerged (h1 - zs ≤ 1.5 (h2 - zs)): Q = c_e c_w W √(2g(h1 - h2)) (h2 - zs);
- weir, free: Q = c_e c_w W (2/3) √((2/3) g) (h1 - zs)^1.5 (thesis Eq. 3-4);
- culvert (and bridge): Q = A(d) √(2g ΔE / ξ) with ξ = ξ_in + ξ_bend + 2gL/(C²R) + ξ_out, where d
  and ΔE are the critical depth min(2/3 H1, D) and H1 - d in free flow, the downstream depth
  min(H2, D) and H1 - H2 when submerged or pressurised; H1 and H2 are measured from the downstream
  invert (a culvert may have two). With the expansion option the exit loss is ξ_out (1 - A/A_2)²,
  A_2 the flow area of the channel downstream (Borda–Carnot, as D-Flow FM's culvert);
- orifice (a crest under a gate of opening a = gate - z_s): weir flow as above (with μ for c_e c_w)
  while the flow depth over the crest (2/3 H1 free, H2 submerged) stays below a; gate flow above it,
  free Q = μ W a √(2g(H1 - μ a)) while H2 < μ a, submerged Q = μ W a √(2g(h1 - h2));
- universal weir: the weir law on each strip of its crest (flat pieces, sloping pieces in 8 strips),
  summed; the link carries their total area and the discharge-weighted velocity, so that at
  convergence Q = Σ Q_strip exactly.
"""

from __future__ import annotations

import math

import numpy as np

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import (
    C_EXPAND,
    C_INVERT2,
    C_PROF,
    CULVERT_PROFILE,
    CULVERT_RECTANGULAR,
    FLOW_BOTH,
    FLOW_NEGATIVE,
    FLOW_POSITIVE,
    FRICTION_MANNING,
    FRICTION_STRICKLER,
    FRICTION_WHITE_COLEBROOK,
    LINK_CULVERT,
    LINK_ORIFICE,
    LINK_WEIR,
    O_CREST,
    O_DIR,
    O_GATE,
    O_MU,
    O_QNEG,
    O_QPOS,
    O_SPAN,
    PUMP_DRY,
    STRIP_CREST,
    STRIP_SPAN,
    U_CE,
    U_DIR,
    U_END,
    U_FIRST,
)
from rivercal.engine.kernels.lookup import flow_geometry

__all__ = [
    "G",
    "apply_settings",
    "culvert_area_perimeter",
    "culvert_link",
    "culvert_link_ext",
    "direction_allowed",
    "extended_coefficients",
    "friction_c2r",
    "friction_c2r_any",
    "orifice_link",
    "reset_settings",
    "structure_coefficients",
    "switch_pumps",
    "universal_weir_link",
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
    """C² R (m²/s²) for hydraulic radius ``r`` (m) and r43 = R^(4/3): Strickler, Manning or Chézy.

    Cheap arithmetic only, so that the vectorised momentum loop stays vectorised; White-Colebrook links are
    never in that loop (:func:`friction_c2r_any`).
    """
    if ftype == FRICTION_STRICKLER:
        return value * value * r43
    if ftype == FRICTION_MANNING:
        return r43 / (value * value)
    return value * value * r


@kernel
def friction_c2r_any(ftype, value, r, r43):
    """C² R (m²/s²) as :func:`friction_c2r`, and for White-Colebrook (``value`` = k_n, m).

    White-Colebrook, rough turbulent: C = 18 log10(12 R / k_n), at least 1 m^(1/2)/s.
    """
    if ftype != FRICTION_WHITE_COLEBROOK:
        return friction_c2r(ftype, value, r, r43)
    c = max(18.0 * math.log10(max(12.0 * r / value, 1.0)), 1.0)
    return c * c * r


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
    """Flow area (m²) and wetted perimeter (m) of a rectangular or circular culvert barrel at depth ``d`` (m)."""
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
    """Flux area (m²), f and r of a culvert link for levels z1, z2 (m AD) at its two ends (one invert, m AD)."""
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
def culvert_link_ext(z1, z2, shape, width, height, inv1, inv2, clen, xin, xout, ftype, fval, dircode, length, u_old,
                     dt, prof, tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf, tab_flow, expand, a1, a2):
    """Flux area (m²), f and r of a culvert (or bridge) link with the D-HYDRO extensions, levels z1, z2 (m AD).

    ``inv1`` and ``inv2`` are the inverts (m AD) at the k1 and k2 end; depths are measured from the
    downstream one. A barrel of shape ``CULVERT_PROFILE`` reads area and perimeter from profile table
    ``prof`` (its ``height`` is its crown, or infinite for an open profile). With ``expand`` the exit loss
    is ``xout (1 - A / A_2)²``, A_2 the channel's flow area downstream (``a1``, ``a2`` at the k1, k2 end, m²).
    """
    if z1 >= z2:
        smax, smin, sign, inv_up, inv_dn, a_dn = z1, z2, 1.0, inv1, inv2, a2
    else:
        smax, smin, sign, inv_up, inv_dn, a_dn = z2, z1, -1.0, inv2, inv1, a1
    if smax - inv_up <= 0.0 or not direction_allowed(dircode, sign):
        return 0.0, 0.0, 0.0
    h1 = smax - inv_dn
    if h1 <= 0.0:
        return 0.0, 0.0, 0.0
    h2 = max(smin - inv_dn, 0.0)
    dcrit = min((2.0 / 3.0) * h1, height)
    free = h2 < dcrit
    d = dcrit if free else min(h2, height)
    if shape == CULVERT_PROFILE:
        area, per, _ = flow_geometry(tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf, tab_flow, prof, d)
    else:
        area, per = culvert_area_perimeter(shape, width, height, d)
    if area <= 0.0:
        return 0.0, 0.0, 0.0
    radius = area / per
    exit_loss = xout
    if expand:
        exit_loss = xout * max(1.0 - area / a_dn, 0.0) ** 2 if a_dn > 0.0 else xout
    xi = xin + exit_loss + 2.0 * G * clen / friction_c2r_any(ftype, fval, radius, radius * np.cbrt(radius))
    head = (h1 - d) if free else (h1 - h2)
    us = math.sqrt(2.0 * G * max(head, 0.0) / xi)
    cu = 2.0 * G / (xi * length)
    extra = cu * (smin - inv_dn - d) if free else 0.0
    b = 1.0 / dt + us / length
    return area, cu / b, (u_old / dt + sign * extra) / b


@kernel
def orifice_link(z1, z2, crest, width, gate, mu, dircode, qpos, qneg, length, u_old, dt):
    """Flux area (m²), f and r of an orifice link (a crest under a gate) for levels z1, z2 (m AD).

    ``qpos``/``qneg`` cap the discharge in each direction (m³/s; infinite: no cap).
    """
    if z1 >= z2:
        smax, smin, sign, cap = z1, z2, 1.0, qpos
    else:
        smax, smin, sign, cap = z2, z1, -1.0, qneg
    h1 = smax - crest
    if h1 <= 0.0 or not direction_allowed(dircode, sign):
        return 0.0, 0.0, 0.0
    h2 = smin - crest
    opening = gate - crest
    if h1 > 1.5 * h2 and (2.0 / 3.0) * h1 <= opening:  # free weir flow under a gate out of the water
        area = mu * width * (2.0 / 3.0) * h1
        us = math.sqrt((2.0 / 3.0) * G * h1)
        cu = G / (1.5 * length)
        extra = cu * (smin - crest)
    elif h1 <= 1.5 * h2 and h2 <= opening:  # submerged weir flow
        area = mu * width * h2
        us = math.sqrt(2.0 * G * (smax - smin))
        cu = 2.0 * G / length
        extra = 0.0
    elif h2 < mu * opening:  # free gate flow
        area = mu * width * opening
        us = math.sqrt(2.0 * G * max(h1 - mu * opening, 0.0))
        cu = 2.0 * G / length
        extra = cu * (smin - crest - mu * opening)
    else:  # submerged gate flow
        area = mu * width * opening
        us = math.sqrt(2.0 * G * (smax - smin))
        cu = 2.0 * G / length
        extra = 0.0
    if area <= 0.0:
        return 0.0, 0.0, 0.0
    if area * us > cap:  # the discharge limit: a fixed discharge
        return area, 0.0, sign * cap / area
    b = 1.0 / dt + us / length
    return area, cu / b, (u_old / dt + sign * extra) / b


@kernel
def universal_weir_link(z1, z2, u_strip, lo, hi, ce, dircode, length, u_old, dt):
    """Flux area (m²), f and r of a universal weir: the weir law on its crest strips ``lo..hi``, summed.

    Each strip is a row of ``u_strip``: its width (m) and crest (m AD). The link carries the total flow
    area and the discharge-weighted velocity (see the module docstring).
    """
    if z1 >= z2:
        smax, smin, sign = z1, z2, 1.0
    else:
        smax, smin, sign = z2, z1, -1.0
    if not direction_allowed(dircode, sign):
        return 0.0, 0.0, 0.0
    area = 0.0
    flow = 0.0
    flow_us = 0.0
    cu_sum = 0.0
    extra_sum = 0.0
    for k in range(lo, hi):
        crest = u_strip[k, STRIP_CREST]
        h1 = smax - crest
        if h1 <= 0.0:
            continue
        h2 = smin - crest
        if h1 > 1.5 * h2:
            a = ce * u_strip[k, STRIP_SPAN] * (2.0 / 3.0) * h1
            us = math.sqrt((2.0 / 3.0) * G * h1)
            cu = G / (1.5 * length)
            extra = cu * (smin - crest)
        else:
            a = ce * u_strip[k, STRIP_SPAN] * h2
            us = math.sqrt(2.0 * G * (smax - smin))
            cu = 2.0 * G / length
            extra = 0.0
        area += a
        flow += a * us
        flow_us += a * us * us
        cu_sum += a * cu
        extra_sum += a * extra
    if area <= 0.0 or flow <= 0.0:
        return 0.0, 0.0, 0.0
    us_eff = flow_us / flow
    b = 1.0 / dt + us_eff / length
    return area, (cu_sum / area) / b, (u_old / dt + sign * extra_sum / area) / b


@kernel
def switch_pumps(net, work, z, pump_on):
    """Pump switches from the suction-side level at time n; a pump link carries a fixed flux ``rco``.

    The capacity is ``net.p_cap`` (m³/s), which a capacity series sets each step (:func:`apply_settings`). A pump
    cannot draw water that is not there: it stops when its suction point holds less than ``PUMP_DRY`` of water,
    whatever its stop level (a stop level at or below the bed), and starts again ``PUMP_DRY`` above that at the
    earliest. Returns how many pumps switched.
    """
    switched = 0
    for link in work.pump_links:
        s = net.lk_sidx[link]
        ksuc = net.lk_k1[link] if net.p_sign[s] > 0.0 else net.lk_k2[link]
        off = max(net.p_off[s], net.hp_bed[ksuc] + PUMP_DRY)
        on = max(net.p_on[s], off + PUMP_DRY)
        if pump_on[s] > 0.5 and z[ksuc] <= off:
            pump_on[s] = 0.0
            switched += 1
        elif pump_on[s] < 0.5 and z[ksuc] >= on:
            pump_on[s] = 1.0
            switched += 1
        work.area[link] = 0.0
        work.fco[link] = 0.0
        work.rco[link] = net.p_sign[s] * net.p_cap[s] * pump_on[s]
    return switched


@kernel
def _channel_area(net, p, bed, z):
    """Flow area (m²) of profile table ``p`` with its bed at ``bed`` (m AD) at level ``z`` (m AD)."""
    return flow_geometry(net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af, net.tab_pf,
                         net.tab_flow, p, z - bed)[0]


@kernel
def structure_coefficients(net, work, zk, u, crest, dt):
    """Weir and culvert links linearised at the levels ``zk`` (m AD) of the current iterate.

    The structures with D-HYDRO's extensions (orifices, universal weirs, culverts with two inverts, a profile
    barrel or the expansion loss, bridges) are done by :func:`extended_coefficients`.
    """
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


@kernel
def extended_coefficients(net, sx, work, zk, u, dt):
    """The links of ``sx.links`` (orifices, universal weirs, extended culverts and bridges) linearised at ``zk``."""
    for link in sx.links:
        s = net.lk_sidx[link]
        k1 = net.lk_k1[link]
        k2 = net.lk_k2[link]
        z1 = zk[k1]
        z2 = zk[k2]
        t = net.lk_type[link]
        if t == LINK_CULVERT:
            ex = sx.c_extra[s]
            expand = ex[C_EXPAND] > 0.0
            a1 = _channel_area(net, net.lk_p1[link], net.lk_b1[link], z1) if expand else 0.0
            a2 = _channel_area(net, net.lk_p2[link], net.lk_b2[link], z2) if expand else 0.0
            a, f, r = culvert_link_ext(z1, z2, net.c_shape[s], net.c_width[s], net.c_height[s], net.c_invert[s],
                                       ex[C_INVERT2], net.c_length[s], net.c_xin[s], net.c_xout[s], net.c_ftype[s],
                                       net.c_fval[s], net.c_dir[s], net.lk_len[link], u[link], dt, int(ex[C_PROF]),
                                       net.tab_off, net.tab_n, net.tab_idd, net.tab_top, net.tab_wf_top, net.tab_af,
                                       net.tab_pf, net.tab_flow, expand, a1, a2)
        elif t == LINK_ORIFICE:
            o = sx.o_par[s]
            a, f, r = orifice_link(z1, z2, o[O_CREST], o[O_SPAN], sx.ogate[s], o[O_MU], int(o[O_DIR]), o[O_QPOS],
                                   o[O_QNEG], net.lk_len[link], u[link], dt)
        else:
            w = sx.u_par[s]
            a, f, r = universal_weir_link(z1, z2, sx.u_strip, int(w[U_FIRST]), int(w[U_END]), w[U_CE],
                                          int(w[U_DIR]), net.lk_len[link], u[link], dt)
        work.area[link] = a
        work.fco[link] = f
        work.rco[link] = r


@kernel
def reset_settings(net, sx):
    """The orifice gates (m AD) and pump capacities (m³/s) of the structures themselves, before a run."""
    for s in range(sx.ogate.size):
        sx.ogate[s] = sx.o_par[s, O_GATE]
    for s in range(sx.pnom.size):
        net.p_cap[s] = sx.pnom[s]


@kernel
def apply_settings(net, sx, n, forcing, crest):
    """Structure settings that follow a series: weir crests (m AD), orifice gates (m AD), pump capacities (m³/s).

    ``sx.set_col`` holds the forcing column of each setting (-1: a constant), the weirs', the orifices' and
    the pumps' in that order; a pump's capacity of the step goes into ``net.p_cap``.
    """
    n_w = crest.size
    n_o = sx.ogate.size
    for k in range(sx.set_col.size):
        col = sx.set_col[k]
        if col < 0:
            continue
        if k < n_w:
            crest[k] = forcing[n, col]
        elif k < n_w + n_o:
            s = k - n_w
            sx.ogate[s] = max(forcing[n, col], sx.o_par[s, O_CREST])
        else:
            net.p_cap[k - n_w - n_o] = max(forcing[n, col], 0.0)
