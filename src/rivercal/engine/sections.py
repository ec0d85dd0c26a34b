"""Conveyance of cross-sections with friction sections, as D-Flow FM computes it for its profile types.

A profile is tabulated on a uniform grid of depths above its lowest point: flow area A (m²), total
(storage) area A_t (m²), wetted perimeter P (m), and the *conveyance shapes*

    S23(h) = Σ_i w_i A_i R_i^(2/3)   and   S12(h) = Σ_i w_i A_i R_i^(1/2)   (m³ per unit of coefficient),

so that the conveyance K = c S23 for a Strickler (c = k_s) or Manning (c = 1/n) law and K = c S12 for
Chézy (c = C). The sum runs over the parts the profile's conveyance is computed for:

- a **segmented yz** profile: every piece of bed between two survey points, with its own wetted area and
  perimeter (D-Flow FM user manual, "yz profiles, conveyance segmented"): a shallow bank does not lower
  the hydraulic radius of the deep channel;
- a **lumped yz** profile, and a **zw profile with sections** (main channel and floodplains, "zwRiver"):
  every friction section as a whole, R = A/P of the section;
- any other profile: the profile as a whole, R = A/P (then S23/A = R^(2/3), the plain law).

``w_i`` is the coefficient of the part's friction group relative to the profile's first section (1 when
they are alike), so that one coefficient per profile carries a calibration: K = c_first · S. The engine's
kernels read R^(4/3)_eff = (S23/A)² for Strickler and Manning and R_eff = (S12/A)² for Chézy, so a
table of this module drops into the kernels' look-up in place of the plain (A/P)^(4/3) and A/P.

Closed profiles (pipes, box culverts, egg shapes) hold no flow width above their crown: the flow area and
perimeter stay those of the full conduit. Open profiles continue with vertical walls above their table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rivercal.network import (
    CircularProfile,
    RectangularProfile,
    TrapezoidalProfile,
    YZProfile,
    ZWProfile,
)

__all__ = ["SectionTable", "interpolate_tables", "section_table"]

#: Depth grid cells per table (as the engine's other tables).
CELLS = 2000
#: Minimum height of a table, m.
MIN_TOP = 10.0
#: Points on which a circle is resolved for its widths (its area and perimeter are exact).
_CIRCLE_LEVELS = 256


@dataclass(frozen=True)
class SectionTable:
    """A profile on a uniform depth grid (depth 0 = its lowest point).

    Attributes
    ----------
    depth
        Depths, m (``CELLS + 1`` values from 0 to ``top``).
    area, total, perimeter
        Flow area (m²), total (storage) area (m²) and wetted perimeter (m) at each depth.
    s23, s12
        Conveyance shapes Σ w A R^(2/3) (m^(8/3)) and Σ w A R^(1/2) (m^(5/2)) at each depth.
    flow_width_top, total_width_top
        Flow and total width above ``top``, m (0 for a closed profile).
    closed
        Whether the profile is a closed conduit.
    """

    depth: np.ndarray
    area: np.ndarray
    total: np.ndarray
    perimeter: np.ndarray
    s23: np.ndarray
    s12: np.ndarray
    flow_width_top: float
    total_width_top: float
    closed: bool

    @property
    def top(self) -> float:
        """Depth of the top of the table, m."""
        return float(self.depth[-1])

    def r43(self) -> np.ndarray:
        """Effective R^(4/3) = (S23 / A)² at each depth, m^(4/3) (0 where dry)."""
        return np.divide(self.s23, self.area, out=np.zeros_like(self.area), where=self.area > 0) ** 2

    def radius_chezy(self) -> np.ndarray:
        """Effective R = (S12 / A)² at each depth, m (0 where dry)."""
        return np.divide(self.s12, self.area, out=np.zeros_like(self.area), where=self.area > 0) ** 2


def section_table(profile, weights: list[float] | None = None) -> SectionTable:
    """Tabulate a profile (see the module docstring).

    Parameters
    ----------
    profile
        A rectangular, trapezoidal, circular, zw or yz profile of :mod:`rivercal.network`.
    weights
        Coefficient of each friction section relative to the first (default all 1).
    """
    if isinstance(profile, YZProfile):
        return _yz(profile, weights)
    if isinstance(profile, CircularProfile):
        return _circle(profile.diameter)
    h, wf, wt, closed, sections = _zw_widths(profile)
    return _zw(h, wf, wt, closed, sections, weights)


def interpolate_tables(a: SectionTable, b: SectionTable, weight: float) -> SectionTable:
    """The table ``(1 - weight) a + weight b``, depth by depth (the profile between two cross-sections)."""
    top = max(a.top, b.top)
    depth = np.linspace(0.0, top, CELLS + 1)

    def at(t: SectionTable, values: np.ndarray, width_top: float) -> np.ndarray:
        inside = np.interp(depth, t.depth, values)
        return np.where(depth > t.top, values[-1] + width_top * (depth - t.top), inside)

    def perimeter(t: SectionTable) -> np.ndarray:
        inside = np.interp(depth, t.depth, t.perimeter)
        return np.where(depth > t.top, t.perimeter[-1] + (0.0 if t.closed else 2.0) * (depth - t.top), inside)

    def shapes(t: SectionTable) -> tuple[np.ndarray, np.ndarray]:
        area, per = at(t, t.area, t.flow_width_top), perimeter(t)
        s23, s12 = np.interp(depth, t.depth, t.s23), np.interp(depth, t.depth, t.s12)
        above = depth > t.top
        if above.any() and t.area[-1] > 0:  # the walls above add their part as a whole: scale with A R^x
            r_top = t.area[-1] / max(t.perimeter[-1], 1e-12)
            r = area[above] / np.maximum(per[above], 1e-12)
            s23[above] = t.s23[-1] * (area[above] / t.area[-1]) * (r / r_top) ** (2.0 / 3.0)
            s12[above] = t.s12[-1] * (area[above] / t.area[-1]) * (r / r_top) ** 0.5
        return s23, s12

    sa, sb = shapes(a), shapes(b)
    w0, w1 = 1.0 - weight, weight
    return SectionTable(
        depth=depth,
        area=w0 * at(a, a.area, a.flow_width_top) + w1 * at(b, b.area, b.flow_width_top),
        total=w0 * at(a, a.total, a.total_width_top) + w1 * at(b, b.total, b.total_width_top),
        perimeter=w0 * perimeter(a) + w1 * perimeter(b),
        s23=w0 * sa[0] + w1 * sb[0],
        s12=w0 * sa[1] + w1 * sb[1],
        flow_width_top=w0 * a.flow_width_top + w1 * b.flow_width_top,
        total_width_top=w0 * a.total_width_top + w1 * b.total_width_top,
        closed=a.closed and b.closed,
    )


# -- zw-like profiles ------------------------------------------------------------------------------------


def _zw_widths(profile) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, list[float] | None]:
    """Heights (m), flow and total widths (m), closed, section widths of a rectangular, trapezoidal or zw profile."""
    if isinstance(profile, RectangularProfile):
        if profile.closed:
            h = np.array([0.0, float(profile.height)])
            w = np.array([profile.width, profile.width], dtype=float)
            return h, w, w.copy(), True, None
        top = max(profile.height or 0.0, MIN_TOP)
        w = np.array([profile.width, profile.width], dtype=float)
        return np.array([0.0, top]), w, w.copy(), False, None
    if isinstance(profile, TrapezoidalProfile):
        top = max(profile.height or 0.0, MIN_TOP)
        w = np.array([profile.bottom_width, profile.bottom_width + 2.0 * profile.side_slope * top])
        return np.array([0.0, top]), w, w.copy(), False, None
    if not isinstance(profile, ZWProfile):
        raise TypeError(f"not a profile: {type(profile).__name__}")
    h = np.asarray(profile.heights, dtype=float)
    return (h, np.asarray(profile.flow_widths, dtype=float), np.asarray(profile.storage_widths, dtype=float),
            bool(profile.closed), list(profile.section_widths) if profile.section_widths else None)


def _zw(h: np.ndarray, wf: np.ndarray, wt: np.ndarray, closed: bool, sections: list[float] | None,
        weights: list[float] | None) -> SectionTable:
    top = max(float(h[-1]), MIN_TOP)
    if closed:
        # no width above the crown: extend with zero widths so that area and perimeter stay constant
        h = np.append(h, [h[-1] * (1 + 1e-12) + 1e-9, top]) if h[-1] < top else h
        wf = np.append(wf, [0.0, 0.0])[: h.size]
        wt = np.append(wt, [0.0, 0.0])[: h.size]
    elif h[-1] < top:
        h, wf, wt = np.append(h, top), np.append(wf, wf[-1]), np.append(wt, wt[-1])
    depth = np.linspace(0.0, top, CELLS + 1)
    # per level: perimeter of the part below it (bottom width plus the two banks), exact for linear widths
    dz = np.diff(h)
    bank = np.sqrt(dz**2 + (0.5 * np.diff(wf)) ** 2)
    if closed:  # walls of a closed profile above the crown have no width, and so no wetted length
        bank = np.where((wf[:-1] == 0) & (wf[1:] == 0) & (np.arange(dz.size) > 0), 0.0, bank)
    p_nodes = wf[0] + np.concatenate([[0.0], np.cumsum(2.0 * bank)])
    if closed:  # the roof closes the perimeter: the top width at the crown is added when the pipe runs full
        pass
    area = _integrate(depth, h, wf)
    total = _integrate(depth, h, wt)
    perimeter = np.interp(depth, h, p_nodes)
    if sections is None:
        radius = np.divide(area, perimeter, out=np.zeros_like(area), where=perimeter > 0)
        s23, s12 = area * radius ** (2.0 / 3.0), area * np.sqrt(radius)
    else:
        s23, s12 = _sections_zw(depth, h, wf, perimeter, area, sections, weights)
    wtop_f = 0.0 if closed else float(wf[-1])
    wtop_t = 0.0 if closed else float(wt[-1])
    return SectionTable(depth, area, total, perimeter, s23, s12, wtop_f, wtop_t, closed)


def _sections_zw(depth, h, wf, perimeter, area, sections, weights):
    """Conveyance shapes of a zw profile split into main channel and floodplains (flow width filled in order)."""
    weights = weights or [1.0] * len(sections)
    edges = np.concatenate([[0.0], np.cumsum(sections)])
    s23 = np.zeros_like(depth)
    s12 = np.zeros_like(depth)
    fine = np.linspace(0.0, depth[-1], 8 * (depth.size - 1) + 1)
    width = np.interp(fine, h, wf)
    per_fine = np.interp(fine, depth, perimeter)
    for k in range(len(sections)):
        part = np.clip(width - edges[k], 0.0, sections[k] if k < len(sections) - 1 else np.inf)
        a_part = np.concatenate([[0.0], np.cumsum(0.5 * (part[1:] + part[:-1]) * np.diff(fine))])
        # the wetted perimeter that appears while this section is filling belongs to it
        dp = np.diff(per_fine)
        grows = (width[1:] > edges[k] + 1e-12) & ((k == len(sections) - 1) | (width[:-1] < edges[k + 1] - 1e-12))
        if k == 0:
            grows = grows | (width[1:] <= edges[1] + 1e-12)
        p_part = np.concatenate([[wf[0] if k == 0 else 0.0], (wf[0] if k == 0 else 0.0) + np.cumsum(dp * grows)])
        a_s = np.interp(depth, fine, a_part)
        p_s = np.interp(depth, fine, p_part)
        r = np.divide(a_s, p_s, out=np.zeros_like(a_s), where=p_s > 0)
        s23 += weights[k] * a_s * r ** (2.0 / 3.0)
        s12 += weights[k] * a_s * np.sqrt(r)
    return s23, s12


def _integrate(d: np.ndarray, h: np.ndarray, w: np.ndarray) -> np.ndarray:
    """∫_0^d w(z) dz for widths linear between the heights h (exact)."""
    seg = np.clip(np.searchsorted(h, d, side="right") - 1, 0, len(h) - 2)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(h))])
    slope = np.diff(w) / np.diff(h)
    x = d - h[seg]
    return cum[seg] + w[seg] * x + 0.5 * slope[seg] * x**2


# -- circle --------------------------------------------------------------------------------------------


def _circle(diameter: float) -> SectionTable:
    r = 0.5 * diameter
    top = max(diameter, MIN_TOP)
    depth = np.linspace(0.0, top, CELLS + 1)
    d = np.minimum(depth, diameter)
    theta = 2.0 * np.arccos(np.clip(1.0 - 2.0 * d / diameter, -1.0, 1.0))
    area = 0.5 * r * r * (theta - np.sin(theta))
    perimeter = r * theta
    radius = np.divide(area, perimeter, out=np.zeros_like(area), where=perimeter > 0)
    return SectionTable(depth, area, area.copy(), perimeter, area * radius ** (2.0 / 3.0), area * np.sqrt(radius),
                        0.0, 0.0, True)


# -- yz ------------------------------------------------------------------------------------------------


def _yz(profile: YZProfile, weights: list[float] | None) -> SectionTable:
    y = np.asarray(profile.y, dtype=float)
    z = np.asarray(profile.z, dtype=float)
    positions = list(profile.friction_positions) if profile.friction_positions else [y[0], y[-1]]
    weights = weights or [1.0] * (len(positions) - 1)
    # split the survey line at the section boundaries
    for p in positions[1:-1]:
        if not np.any(np.isclose(y, p)):
            k = int(np.searchsorted(y, p))
            zp = np.interp(p, y, z)
            y, z = np.insert(y, k, p), np.insert(z, k, zp)
    top = max(float(z.max()), MIN_TOP)
    depth = np.linspace(0.0, top, CELLS + 1)
    n_pieces = y.size - 1
    area = np.zeros((n_pieces, depth.size))
    wet = np.zeros((n_pieces, depth.size))
    for i in range(n_pieces):
        area[i], wet[i] = _piece(y[i], z[i], y[i + 1], z[i + 1], depth)
    # vertical walls above the end points (D-Flow FM extends a yz profile upward at its ends)
    wall_left = np.clip(depth - z[0], 0.0, None)
    wall_right = np.clip(depth - z[-1], 0.0, None)
    mid = 0.5 * (y[:-1] + y[1:])
    section = np.clip(np.searchsorted(positions, mid, side="right") - 1, 0, len(positions) - 2)
    total_area = area.sum(axis=0)
    perimeter = wet.sum(axis=0) + wall_left + wall_right
    s23 = np.zeros_like(depth)
    s12 = np.zeros_like(depth)
    if profile.conveyance == "segmented":
        for i in range(n_pieces):
            p = wet[i] + (wall_left if i == 0 else 0.0) + (wall_right if i == n_pieces - 1 else 0.0)
            r = np.divide(area[i], p, out=np.zeros_like(p), where=p > 0)
            s23 += weights[section[i]] * area[i] * r ** (2.0 / 3.0)
            s12 += weights[section[i]] * area[i] * np.sqrt(r)
    else:
        for s in range(len(positions) - 1):
            pieces = np.flatnonzero(section == s)
            if pieces.size == 0:
                continue
            a = area[pieces].sum(axis=0)
            p = wet[pieces].sum(axis=0)
            if pieces[0] == 0:
                p = p + wall_left
            if pieces[-1] == n_pieces - 1:
                p = p + wall_right
            r = np.divide(a, p, out=np.zeros_like(p), where=p > 0)
            s23 += weights[s] * a * r ** (2.0 / 3.0)
            s12 += weights[s] * a * np.sqrt(r)
    width_top = float(y[-1] - y[0])
    return SectionTable(depth, total_area, total_area.copy(), perimeter, s23, s12, width_top, width_top, False)


def _piece(y0: float, z0: float, y1: float, z1: float, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wetted area (m²) and wetted bed length (m) of the bed piece from (y0, z0) to (y1, z1) at each depth."""
    dy = y1 - y0
    lo, hi = min(z0, z1), max(z0, z1)
    length = math.hypot(dy, z1 - z0)
    if dy <= 0.0:  # a vertical wall inside the profile: wetted, without area
        return np.zeros_like(depth), np.clip(depth - lo, 0.0, hi - lo)
    full = depth >= hi
    part = (depth > lo) & ~full
    area = np.zeros_like(depth)
    wet = np.zeros_like(depth)
    area[full] = dy * (depth[full] - 0.5 * (z0 + z1))
    wet[full] = length
    if hi > lo:
        frac = (depth[part] - lo) / (hi - lo)
        area[part] = 0.5 * frac * dy * (depth[part] - lo)
        wet[part] = frac * length
    return area, wet
