"""Cross-section look-ups on the uniform-depth tables of :mod:`rivercal.engine.geometry`.

The helpers take the arrays they read explicitly (not the network namedtuple) and are inlined:
passing a namedtuple of ~70 arrays into a small function costs ~0.5 µs of reference counting per
call, 50 times the look-up itself.
"""

from __future__ import annotations

import math

import numpy as np

from rivercal.engine.kernels._jit import entry, kernel
from rivercal.engine.kernels.codes import FLOW_WIDTH

__all__ = [
    "PIECE_MARGIN",
    "flow_geometry",
    "hp_volume_width",
    "hp_volume_width_piece",
    "storage_area_width",
]


@entry
def flow_geometry(tab_off, tab_n, tab_idd, tab_top, tab_wf_top, tab_af, tab_pf, tab_flow, p, d):
    """Flow area (m²), wetted perimeter (m) and R^(4/3) (m^(4/3)) of profile ``p`` at depth ``d`` (m).

    ``tab_idd`` holds the inverse depth step of each table, 1/m. The cell is read from ``tab_flow``, one
    cache line per cell: af, pf and r43, each followed by its increment to the next cell
    (:func:`rivercal.engine.geometry.flow_records`); above the table the walls are vertical.
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
    k = np.uint64(FLOW_WIDTH * (off + j))  # unsigned, and no slice: no wraparound or slice-bounds code
    return (tab_flow[k] + f * tab_flow[k + np.uint64(1)], tab_flow[k + np.uint64(2)] + f * tab_flow[k + np.uint64(3)],
            tab_flow[k + np.uint64(4)] + f * tab_flow[k + np.uint64(5)])


@entry
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


@entry
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


#: Margin (m) by which :func:`hp_volume_width_piece` narrows the interval it returns, so that within the
#: interval every table index comes out the same as at the look-up (far above the round-off of a level).
PIECE_MARGIN = 1.0e-9


@kernel
def hp_volume_width_piece(sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin,
                          tab_off, tab_n, tab_dd, tab_idd, tab_top, tab_wt_top, tab_at, tab_wt, i, z):
    """The piece of h-point ``i``'s volume curve that holds level ``z`` (m AD), on which the volume is linear.

    Returns (low m AD, high m AD, reference level m AD, its volume m³, storage area m²): within
    [low, high] every storage contribution stays in the table cell it is read from at ``z`` (or below
    its bed, or above its table), so ``V(z') = volume + area (z' - reference)`` there. The reference
    level is the low end of the piece (the high end, or the bed, when the piece is unbounded below):
    it depends on the piece only, not on ``z``, so the linear form is the same whichever level in the
    piece it was made at.
    """
    width = hp_amin[i]
    lo = -math.inf
    hi = math.inf
    for c in range(sc_ptr[i], sc_ptr[i + 1]):
        p = sc_prof[c]
        bed = sc_bed[c]
        d = z - bed
        length = sc_len[c]
        if d <= 0.0:
            hi = min(hi, bed - PIECE_MARGIN)
            continue
        off = tab_off[p]
        n = tab_n[p]
        j = int(d * tab_idd[p])
        if j >= n - 1:
            width += length * tab_wt_top[p]
            lo = max(lo, bed + tab_top[p] + PIECE_MARGIN)
            continue
        dd = tab_dd[p]
        width += length * tab_wt[off + j]
        lo = max(lo, bed + j * dd + PIECE_MARGIN)
        hi = min(hi, bed + (j + 1) * dd - PIECE_MARGIN)
    if lo > -math.inf:
        ref = lo
    elif hi < math.inf:
        ref = hi
    else:
        ref = hp_bed[i]
    vol = hp_volume_width(sc_ptr, sc_prof, sc_bed, sc_len, hp_bed, hp_amin, tab_off, tab_n, tab_dd, tab_idd, tab_top,
                          tab_wt_top, tab_at, tab_wt, i, ref)[0]
    return lo, hi, ref, vol, width
