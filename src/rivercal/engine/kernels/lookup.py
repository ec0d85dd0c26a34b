"""Cross-section look-ups on the uniform-depth tables of :mod:`rivercal.engine.geometry`.

The helpers take the arrays they read explicitly (not the network namedtuple) and are inlined:
passing a namedtuple of ~70 arrays into a small function costs ~0.5 µs of reference counting per
call, 50 times the look-up itself.
"""

from __future__ import annotations

from rivercal.engine.kernels._jit import kernel

__all__ = ["flow_geometry", "hp_volume_width", "storage_area_width"]


@kernel
def flow_geometry(tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf, tab_r43, p, d):
    """Flow area (m²), wetted perimeter (m) and R^(4/3) (m^(4/3)) of profile ``p`` at depth ``d`` (m).

    ``tab_idd`` holds the inverse depth step of each table, 1/m.
    """
    if d <= 0.0:
        return 0.0, 0.0, 0.0
    off = tab_off[p]
    n = tab_n[p]
    x = d * tab_idd[p]
    j = int(x)
    if j >= n - 1:
        extra = d - tab_top[p]
        area = tab_af[off + n - 1] + tab_wf_top[p] * extra
        per = tab_pf[off + n - 1] + 2.0 * extra
        radius = area / per
        return area, per, radius * radius ** (1.0 / 3.0)
    f = x - j
    k = off + j
    return (tab_af[k] + f * (tab_af[k + 1] - tab_af[k]), tab_pf[k] + f * (tab_pf[k + 1] - tab_pf[k]),
            tab_r43[k] + f * (tab_r43[k + 1] - tab_r43[k]))


@kernel
def storage_area_width(tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt, p, d):
    """Total area (m²) and storage width (m) of profile ``p`` at depth ``d`` (m).

    The width ``tab_wt`` is the slope of the total area on each table cell, so that area and width
    are exactly consistent.
    """
    if d <= 0.0:
        return 0.0, 0.0
    off = tab_off[p]
    n = tab_n[p]
    j = int(d * tab_idd[p])
    if j >= n - 1:
        w = tab_wt_top[p]
        return tab_at[off + n - 1] + w * (d - tab_top[p]), w
    k = off + j
    w = tab_wt[k]
    return tab_at[k] + (d - j * tab_dd[p]) * w, w


@kernel
def hp_volume_width(sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin,
                    tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt, i, z):
    """Volume (m³) and storage area (m²) of h-point ``i`` at level ``z`` (m AD).

    The sum of its storage contributions (channel half-segments and node storage) plus the
    minimum storage area, which extends below the bed so that the volume stays a strictly
    increasing function of the level.
    """
    amin = hp_amin[i]
    vol = amin * (z - hp_bed[i])
    width = amin
    for c in range(sc_ptr[i], sc_ptr[i + 1]):
        a, w = storage_area_width(tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt,
                                  sc_prof[c], z - sc_bed[c])
        vol += sc_len[c] * a
        width += sc_len[c] * w
    return vol, width
