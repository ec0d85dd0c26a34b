"""Tabulated cross-section geometry for the kernels.

Every profile (and every node storage) becomes a table on a uniform depth grid: flow area A_f (m²),
wetted perimeter P_f (m) and total (storage) area A_t (m²) per metre of channel, at depths
0, δ, 2δ, … up to the top of the table, with vertical walls above. The kernels interpolate
linearly, so a look-up costs O(1), and the storage width they use is the slope of A_t on the grid
cell, which keeps volume and width exactly consistent (mass conservation does not depend on the
table resolution).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rivercal.engine.kernels.codes import FLOW_WIDTH
from rivercal.network import RectangularProfile, StorageTable, TrapezoidalProfile, ZWProfile

__all__ = ["ProfileTables", "build_tables", "flow_records", "storage_zw", "zw_of"]

#: Depth grid cells per table; δ = top / CELLS.
CELLS = 2000
#: Minimum height of a table, m; deeper water sees vertical walls.
MIN_TOP = 10.0


@dataclass(frozen=True)
class ProfileTables:
    """Flat tables of all profiles (kernel input).

    Attributes
    ----------
    off, n
        Offset and number of depth levels of each table in the flat arrays.
    dd
        Depth step of each table, m.
    af, pf, at
        Flow area (m²), wetted perimeter (m) and total area (m²) at each level.
    wt
        Storage width on each cell: the slope of ``at`` between two levels, m (last entry of each
        table: the width above it).
    r43
        Hydraulic radius to the power 4/3 at each level, m^(4/3) (friction without a cube root
        in the time loop).
    wf_top, wt_top
        Flow and total width above the top of each table, m.
    top
        Depth of the top of each table, m.
    """

    off: np.ndarray
    n: np.ndarray
    dd: np.ndarray
    af: np.ndarray
    pf: np.ndarray
    at: np.ndarray
    wt: np.ndarray
    r43: np.ndarray
    wf_top: np.ndarray
    wt_top: np.ndarray
    top: np.ndarray


def zw_of(profile: RectangularProfile | TrapezoidalProfile | ZWProfile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heights above the bed (m), flow widths (m) and total widths (m) of a profile as a ZW table."""
    if isinstance(profile, RectangularProfile):
        top = max(profile.height or 0.0, MIN_TOP)
        h = np.array([0.0, top])
        w = np.array([profile.width, profile.width])
        return h, w, w.copy()
    if isinstance(profile, TrapezoidalProfile):
        top = max(profile.height or 0.0, MIN_TOP)
        h = np.array([0.0, top])
        w = np.array([profile.bottom_width, profile.bottom_width + 2.0 * profile.side_slope * top])
        return h, w, w.copy()
    h = np.asarray(profile.heights, dtype=float)
    return h, np.asarray(profile.flow_widths, dtype=float), np.asarray(profile.storage_widths, dtype=float)


def storage_zw(table: StorageTable) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A node's level-area table as a storage-only ZW table (per metre = 1 m) and its bottom level."""
    levels = np.asarray(table.levels, dtype=float)
    areas = np.asarray(table.areas, dtype=float)
    h = levels - levels[0]
    return h, np.zeros_like(areas), areas, float(levels[0])


def _tabulate(h: np.ndarray, wf: np.ndarray, wt: np.ndarray) -> tuple[np.ndarray, ...]:
    top = max(float(h[-1]), MIN_TOP)
    if h[-1] < top:  # extend with vertical walls to the common minimum top
        h = np.append(h, top)
        wf = np.append(wf, wf[-1])
        wt = np.append(wt, wt[-1])
    d = np.linspace(0.0, top, CELLS + 1)
    # Exact integrals of the piecewise-linear widths, evaluated at the grid depths.
    af = _integrate_width(d, h, wf)
    at = _integrate_width(d, h, wt)
    # Perimeter: bottom width plus both banks, each bank rising dz while moving dw/2 sideways.
    dz = np.diff(h)
    bank = 2.0 * np.sqrt(dz**2 + (0.5 * np.diff(wf)) ** 2)
    p_nodes = wf[0] + np.concatenate([[0.0], np.cumsum(bank)])
    pf = np.interp(d, h, p_nodes)
    radius = np.divide(af, pf, out=np.zeros_like(af), where=pf > 0)
    return af, pf, at, radius ** (4.0 / 3.0), float(wf[-1]), float(wt[-1]), top


def _integrate_width(d: np.ndarray, h: np.ndarray, w: np.ndarray) -> np.ndarray:
    seg = np.searchsorted(h, d, side="right") - 1
    seg = np.clip(seg, 0, len(h) - 2)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(h))])
    slope = np.diff(w) / np.diff(h)
    x = d - h[seg]
    return cum[seg] + w[seg] * x + 0.5 * slope[seg] * x**2


def build_tables(zw: list[tuple]) -> ProfileTables:
    """Tabulate a list of ZW tables (heights, flow widths, total widths) for the kernels.

    An entry may also be a table already on a uniform depth grid (``CELLS + 1`` levels from 0 to its top, or fewer
    for a table of storage only): (af, pf, at, r43, flow width above, total width above, top), e.g. from
    :mod:`rivercal.engine.sections`.
    """
    off, n, dd, wft, wtt, tops = [], [], [], [], [], []
    af_all, pf_all, at_all, wt_all, r43_all = [], [], [], [], []
    pos = 0
    for entry in zw:
        af, pf, at, r43, wf_top, wt_top, top = _tabulate(*entry) if len(entry) == 3 else entry
        step = top / (af.size - 1)  # top / CELLS but for the shorter tables of a summer dike's storage
        off.append(pos)
        n.append(af.size)
        dd.append(step)
        wft.append(wf_top)
        wtt.append(wt_top)
        tops.append(top)
        af_all.append(af)
        pf_all.append(pf)
        at_all.append(at)
        wt_all.append(np.append(np.diff(at) / step, wt_top))
        r43_all.append(r43)
        pos += af.size
    return ProfileTables(
        off=np.asarray(off, dtype=np.int64),
        n=np.asarray(n, dtype=np.int64),
        dd=np.asarray(dd, dtype=float),
        af=np.concatenate(af_all),
        pf=np.concatenate(pf_all),
        at=np.concatenate(at_all),
        wt=np.concatenate(wt_all),
        r43=np.concatenate(r43_all),
        wf_top=np.asarray(wft, dtype=float),
        wt_top=np.asarray(wtt, dtype=float),
        top=np.asarray(tops, dtype=float),
    )


def _aligned_empty(n: int, align: int = 64) -> np.ndarray:
    """A float64 array of ``n`` zeros whose data starts on an ``align``-byte boundary (a cache line)."""
    raw = np.zeros(n + align // 8)
    start = (-raw.ctypes.data % align) // 8
    return raw[start : start + n]


def flow_records(tables: ProfileTables) -> np.ndarray:
    """The flow tables as one cache-line record per cell: a look-up reads one line, not six values in three arrays.

    The increments are the differences the interpolation takes (``af[k + 1] - af[k]``, computed the same way), so
    the interpolated values are bit-identical; the last cell of each table, never interpolated from, has none.
    """
    n = tables.af.size
    rec = _aligned_empty(n * FLOW_WIDTH).reshape(n, FLOW_WIDTH)
    last = np.zeros(n, dtype=bool)
    last[tables.off + tables.n - 1] = True
    for col, values in enumerate((tables.af, tables.pf, tables.r43)):
        rec[:, 2 * col] = values
        inc = np.zeros(n)
        inc[:-1] = values[1:] - values[:-1]
        inc[last] = 0.0
        rec[:, 2 * col + 1] = inc
    return rec.ravel()
