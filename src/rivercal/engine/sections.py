"""Conveyance of cross-sections with friction sections, as D-Flow FM and SOBEK 3 compute it for their profile types.

A profile is tabulated on a uniform grid of depths above its lowest point (:class:`SectionTable`): flow area A
(m²), total (storage) area A_t (m²) and wetted perimeter P (m), and per *friction section* (main channel,
floodplains, the friction sections of a yz profile) its flow area A_s, wetted perimeter P_s and *conveyance
shapes*

    S23_s(h) = Σ_i A_i R_i^(2/3)   and   S12_s(h) = Σ_i A_i R_i^(1/2)   (m^(8/3) and m^(5/2)),

summed over the parts the conveyance is computed for:

- a **segmented yz** profile: every piece of bed between two survey points, with its own wetted area and
  perimeter (D-Flow FM user manual, "yz profiles, conveyance segmented"): a shallow bank does not lower
  the hydraulic radius of the deep channel;
- a **lumped yz** profile, and a **zw profile with sections** (main channel and floodplains, D-Flow FM's
  "zwRiver", SOBEK 3's "tabulated" profile with ``main``/``floodPlain1``/``floodPlain2``): every friction
  section as a whole, R_s = A_s / P_s (a *lumped* table);
- any other profile: the profile as a whole, R = A/P.

The friction is applied afterwards, per section, with a coefficient that may vary with the depth (a friction
that depends on the water level, evaluated at the level of the depth over the bed where the table is used):
:meth:`SectionTable.conveyance` gives K(h) = Σ_s K_s(h) with K_s = k_s S23_s (Strickler), S23_s / n (Manning),
C S12_s (Chézy) or A_s C(R_s) √R_s with C = 18 log10(12 R_s / k_n) (White-Colebrook). :func:`kernel_columns`
turns K(h) into the look-up columns of the kernels for the link's own friction law and coefficient c: the
kernels read R^(4/3)_eff = (K / (c' A))² for Strickler and Manning (c' = k_s or 1/n) and a hydraulic radius
R_eff for Chézy and White-Colebrook (K = A C(R_eff) √R_eff), so the kernels' friction term reproduces K(h)
exactly while a calibration still scales one coefficient per friction slot.

Between two cross-sections (:func:`interpolate_tables`) the tables are combined at equal depth, as D-Flow FM 1D
and SOBEK 3 do: a lumped table's section areas and perimeters are interpolated and its conveyance recomputed
from them; a segmented yz profile's conveyance shapes are interpolated.

A summer dike (:class:`rivercal.network.SummerDike`) is kept beside the table (:class:`DikeShape`), not in it,
because SOBEK 3 interpolates a summer dike between two cross-sections by its crest, base and areas, not by its
curves (flow1d's ``interpolateSummerDike``): :func:`flow_view` adds its flow area to the highest wet friction
section (without wetted perimeter), from 0 at the crest to full at the transition height above it; its storage
is not in the table's total area but a storage contribution of its own (:func:`dike_storage`), whose curve
depends on whether the level last reached the full height or fell to the base (SOBEK 3's hysteresis).

Closed profiles (pipes, box culverts, egg shapes) hold no flow width above their crown: the flow area and
perimeter stay those of the full conduit. Open profiles continue with vertical walls above their table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from rivercal.network import (
    CircularProfile,
    RectangularProfile,
    TrapezoidalProfile,
    YZProfile,
    ZWProfile,
)

__all__ = [
    "DikeShape",
    "SectionTable",
    "dike_storage",
    "flow_view",
    "interpolate_tables",
    "kernel_columns",
    "law_conveyance",
    "section_table",
]

#: Depth grid cells per table (as the engine's other tables).
CELLS = 2000
#: Minimum height of a table, m.
MIN_TOP = 10.0
#: Height above the top of an open profile up to which its table reaches, m: above a table the kernels see
#: vertical walls of one friction law, so the table holds the sections and their friction well beyond the top.
HEADROOM = 5.0
#: Points on which a circle is resolved for its widths (its area and perimeter are exact).
_CIRCLE_LEVELS = 256
#: A summer dike's flow area joins the highest friction section whose flow area exceeds this, m² (SOBEK 3's
#: ThresholdForSummerDike).
SUMMER_DIKE_THRESHOLD = 0.4
#: Smallest Chézy coefficient a White-Colebrook section gets, m^(1/2)/s (the engine's kernels: 1).
_MIN_CHEZY = 1.0
#: Depth step of a summer dike's storage tables, m (at least ``DIKE_MIN_CELLS`` cells, at most ``CELLS``).
DIKE_STEP = 0.005
DIKE_MIN_CELLS = 64


@dataclass(frozen=True)
class DikeShape:
    """A summer dike of a table, its heights relative to the table's depth 0 (the profile's lowest point).

    Attributes
    ----------
    crest, base
        Height of the crest and of the floodplain behind it, m (base ≤ crest).
    flow_area, total_area
        Flow and total (storage) area behind the dike when full, m².
    transition
        Height over which it fills above the crest, m.
    """

    crest: float
    base: float
    flow_area: float
    total_area: float
    transition: float

    @property
    def full(self) -> float:
        """Height at and above which the dike is full, m."""
        return self.crest + self.transition


@dataclass(frozen=True)
class SectionTable:
    """A profile on a uniform depth grid (depth 0 = its lowest point), without its friction.

    Attributes
    ----------
    depth
        Depths, m (``CELLS + 1`` values from 0 to ``top``).
    area, total, perimeter
        Flow area (m²), total (storage) area (m²) and wetted perimeter (m) at each depth.
    part_area, part_perimeter
        Per friction section (rows), its flow area (m²) and wetted perimeter (m) at each depth.
    part_s23, part_s12
        Per friction section, its conveyance shapes Σ A R^(2/3) (m^(8/3)) and Σ A R^(1/2) (m^(5/2)).
    part_width_top
        Per friction section, its flow width above ``top``, m.
    lumped
        Whether each section's conveyance follows from its own area and perimeter (R_s = A_s / P_s), so that it
        is recomputed after an interpolation; a segmented yz profile is not lumped.
    flow_width_top, total_width_top
        Flow and total width above ``top``, m (0 for a closed profile).
    closed
        Whether the profile is a closed conduit.
    dike
        A summer dike, kept beside the table (:func:`flow_view` adds its flow area, :func:`dike_storage` makes its
        storage), or None.
    """

    depth: np.ndarray
    area: np.ndarray
    total: np.ndarray
    perimeter: np.ndarray
    part_area: np.ndarray
    part_perimeter: np.ndarray
    part_s23: np.ndarray
    part_s12: np.ndarray
    part_width_top: np.ndarray
    lumped: bool
    flow_width_top: float
    total_width_top: float
    closed: bool
    dike: DikeShape | None = None

    @property
    def top(self) -> float:
        """Depth of the top of the table, m."""
        return float(self.depth[-1])

    @property
    def sections(self) -> int:
        """Number of friction sections."""
        return int(self.part_area.shape[0])

    @property
    def s23(self) -> np.ndarray:
        """Σ over the sections of S23_s (all sections of one coefficient), m^(8/3)."""
        return self.part_s23.sum(axis=0)

    @property
    def s12(self) -> np.ndarray:
        """Σ over the sections of S12_s (all sections of one coefficient), m^(5/2)."""
        return self.part_s12.sum(axis=0)

    def conveyance(self, laws: list[str], coefficients: list) -> np.ndarray:
        """Conveyance K (m³/s) at each depth with a friction law and coefficient per section.

        Parameters
        ----------
        laws
            Friction law of each section (``strickler``, ``manning``, ``chezy``, ``white-colebrook``).
        coefficients
            Coefficient of each section in the unit of its law: a number, or an array on the depth grid (a
            friction that depends on the water level).
        """
        k = np.zeros_like(self.depth)
        for s in range(self.sections):
            k += law_conveyance(laws[s], coefficients[s], self.part_area[s], self.part_perimeter[s],
                                self.part_s23[s], self.part_s12[s])
        return k


def law_conveyance(law: str, c, area: np.ndarray, perimeter: np.ndarray, s23: np.ndarray,
                   s12: np.ndarray) -> np.ndarray:
    """Conveyance (m³/s) of one friction section with coefficient ``c`` (unit of ``law``; number or array)."""
    if law == "strickler":
        return c * s23
    if law == "manning":
        return s23 / c
    if law == "chezy":
        return c * s12
    if law == "white-colebrook":
        radius = np.divide(area, perimeter, out=np.zeros_like(area), where=perimeter > 0)
        chezy = np.maximum(18.0 * np.log10(np.maximum(12.0 * radius / c, 1.0)), _MIN_CHEZY)
        return area * chezy * np.sqrt(radius)
    raise ValueError(f"unknown friction law {law!r}")


def _lumped_shapes(area: np.ndarray, perimeter: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    radius = np.divide(area, perimeter, out=np.zeros_like(area), where=perimeter > 0)
    return area * radius ** (2.0 / 3.0), area * np.sqrt(radius)


def _table(depth, area, total, perimeter, part_area, part_perimeter, part_width_top, lumped, flow_top, total_top,
           closed, part_s23=None, part_s12=None, dike=None) -> SectionTable:
    part_area = np.atleast_2d(part_area)
    part_perimeter = np.atleast_2d(part_perimeter)
    if part_s23 is None:
        shapes = [_lumped_shapes(a, p) for a, p in zip(part_area, part_perimeter, strict=True)]
        part_s23 = np.array([s[0] for s in shapes])
        part_s12 = np.array([s[1] for s in shapes])
    return SectionTable(depth, area, total, perimeter, part_area, part_perimeter, np.atleast_2d(part_s23),
                        np.atleast_2d(part_s12), np.atleast_1d(np.asarray(part_width_top, dtype=float)), lumped,
                        float(flow_top), float(total_top), closed, dike)


def section_table(profile) -> SectionTable:
    """Tabulate a profile (see the module docstring).

    Parameters
    ----------
    profile
        A rectangular, trapezoidal, circular, zw or yz profile of :mod:`rivercal.network`.
    """
    if isinstance(profile, YZProfile):
        return _yz(profile)
    if isinstance(profile, CircularProfile):
        return _circle(profile.diameter)
    h, wf, wt, closed, sections = _zw_widths(profile)
    table = _zw(h, wf, wt, closed, sections)
    dike = getattr(profile, "summer_dike", None)
    if dike is not None and (dike.flow_area > 0 or dike.total_area > 0):
        table = replace(table, dike=DikeShape(float(dike.crest), float(dike.floor), float(dike.flow_area),
                                              float(dike.total_area), float(dike.transition)))
    return table


def _resampled(t: SectionTable, depth: np.ndarray) -> SectionTable:
    """The table on another depth grid that starts at 0: interpolated inside, continued with its walls above."""
    if t.depth.size == depth.size and t.top == float(depth[-1]):
        return t
    above = depth > t.top
    extra = np.where(above, depth - t.top, 0.0)

    def inside(values: np.ndarray) -> np.ndarray:
        return np.interp(depth, t.depth, values)

    wall = 0.0 if t.closed else 2.0
    area = np.where(above, t.area[-1] + t.flow_width_top * extra, inside(t.area))
    total = np.where(above, t.total[-1] + t.total_width_top * extra, inside(t.total))
    perimeter = np.where(above, t.perimeter[-1] + wall * extra, inside(t.perimeter))
    part_area = np.array([np.where(above, a[-1] + w * extra, inside(a)) for a, w in zip(t.part_area, t.part_width_top,
                                                                                        strict=True)])
    wet = [s for s in range(t.sections) if t.part_area[s, -1] > 0]
    last = wet[-1] if wet else 0
    part_perimeter = np.array([np.where(above, p[-1] + (wall * extra if s == last else 0.0), inside(p))
                               for s, p in enumerate(t.part_perimeter)])
    if t.lumped:
        return _table(depth, area, total, perimeter, part_area, part_perimeter, t.part_width_top, True,
                      t.flow_width_top, t.total_width_top, t.closed)
    s23 = np.array([inside(s) for s in t.part_s23])
    s12 = np.array([inside(s) for s in t.part_s12])
    if above.any():  # the walls above add their part as a whole: scale with A R^x of the section
        for s in range(t.sections):
            a_top, p_top = t.part_area[s, -1], t.part_perimeter[s, -1]
            if a_top <= 0 or p_top <= 0:
                continue
            r_top = a_top / p_top
            r = part_area[s, above] / np.maximum(part_perimeter[s, above], 1e-12)
            s23[s, above] = t.part_s23[s, -1] * (part_area[s, above] / a_top) * (r / r_top) ** (2.0 / 3.0)
            s12[s, above] = t.part_s12[s, -1] * (part_area[s, above] / a_top) * (r / r_top) ** 0.5
    return _table(depth, area, total, perimeter, part_area, part_perimeter, t.part_width_top, False,
                  t.flow_width_top, t.total_width_top, t.closed, s23, s12)


def _padded(values: np.ndarray, sections: int) -> np.ndarray:
    if values.shape[0] == sections:
        return values
    pad = np.zeros((sections - values.shape[0], *values.shape[1:]))
    return np.concatenate([values, pad])


def interpolate_tables(a: SectionTable, b: SectionTable, weight: float) -> SectionTable:
    """The table ``weight`` of the way from cross-section ``a`` to ``b``, depth by depth.

    Lumped tables (zw profiles with or without sections, lumped yz, circles) interpolate their sections' areas
    and perimeters and recompute the conveyance from them (D-Flow FM 1D and SOBEK 3 for tabulated profiles);
    otherwise the sections' conveyance shapes are interpolated. Section ``s`` of one table meets section ``s``
    of the other (a table with fewer sections has empty ones).
    """
    top = max(a.top, b.top)
    depth = np.linspace(0.0, top, CELLS + 1)
    ta, tb = _resampled(a, depth), _resampled(b, depth)
    n = max(ta.sections, tb.sections)
    w0, w1 = 1.0 - weight, weight

    def mix(name: str) -> np.ndarray:
        return w0 * _padded(getattr(ta, name), n) + w1 * _padded(getattr(tb, name), n)

    lumped = ta.lumped and tb.lumped
    common = dict(depth=depth, area=w0 * ta.area + w1 * tb.area, total=w0 * ta.total + w1 * tb.total,
                  perimeter=w0 * ta.perimeter + w1 * tb.perimeter, part_area=mix("part_area"),
                  part_perimeter=mix("part_perimeter"), part_width_top=mix("part_width_top"), lumped=lumped,
                  flow_top=w0 * ta.flow_width_top + w1 * tb.flow_width_top,
                  total_top=w0 * ta.total_width_top + w1 * tb.total_width_top, closed=ta.closed and tb.closed,
                  dike=_interpolated_dike(a.dike, b.dike, weight))
    if lumped:
        return _table(**common)
    return _table(**common, part_s23=mix("part_s23"), part_s12=mix("part_s12"))


def _interpolated_dike(a: DikeShape | None, b: DikeShape | None, weight: float) -> DikeShape | None:
    """The summer dike ``weight`` of the way from ``a`` to ``b``: crest, base and areas interpolated.

    SOBEK 3's rule (flow1d ``interpolateSummerDike``): heights and areas are interpolated; where only one of the
    two cross-sections has a dike, the other counts as one of no area with its crest and base at its lowest point.
    """
    if a is None and b is None:
        return None
    w0, w1 = 1.0 - weight, weight
    a = a or DikeShape(0.0, 0.0, 0.0, 0.0, b.transition)  # type: ignore[union-attr]
    b = b or DikeShape(0.0, 0.0, 0.0, 0.0, a.transition)
    return DikeShape(w0 * a.crest + w1 * b.crest, w0 * a.base + w1 * b.base, w0 * a.flow_area + w1 * b.flow_area,
                     w0 * a.total_area + w1 * b.total_area, w0 * a.transition + w1 * b.transition)


def kernel_columns(t: SectionTable, conveyance: np.ndarray, law: str, coefficient: float,
                   plain_white_colebrook: bool = False) -> tuple:
    """A table and its conveyance as the kernels' columns (af, pf, at, r43, flow width above, total width above, top).

    The kernels compute the friction of a link from its law and coefficient (``law``, ``coefficient``: the
    friction slot's) and from the table's R^(4/3) (Strickler, Manning) or hydraulic radius R = af / pf (Chézy,
    White-Colebrook). The columns are chosen so that this reproduces ``conveyance`` (m³/s) at every depth:
    R^(4/3)_eff = (K / (c' A))² with c' = k_s or 1/n; for Chézy and White-Colebrook pf = A / R_eff with
    A C(R_eff) √R_eff = K. ``plain_white_colebrook`` keeps the plain R = A/P of a White-Colebrook link whose
    sections all share its coefficient (the conveyance is then the law's own).
    """
    area = t.area
    wet = area > 0
    pf = t.perimeter.copy()
    if law in ("strickler", "manning"):
        c = coefficient if law == "strickler" else 1.0 / coefficient
        r23 = np.divide(conveyance, c * area, out=np.zeros_like(area), where=wet)
        r43 = r23 * r23
    elif law == "chezy":
        root = np.divide(conveyance, coefficient * area, out=np.zeros_like(area), where=wet)
        radius = root * root
        pf = np.where(radius > 0, np.divide(area, radius, out=np.zeros_like(area), where=radius > 0), pf)
        r43 = radius ** (4.0 / 3.0)
    elif law == "white-colebrook":
        if plain_white_colebrook:
            radius = np.divide(area, t.perimeter, out=np.zeros_like(area), where=t.perimeter > 0)
        else:
            radius = _white_colebrook_radius(area, conveyance, coefficient)
            pf = np.where(radius > 0, np.divide(area, radius, out=np.zeros_like(area), where=radius > 0), pf)
        r43 = radius ** (4.0 / 3.0)
    else:
        raise ValueError(f"unknown friction law {law!r}")
    if t.depth.size != CELLS + 1 or t.top < MIN_TOP - 1e-9:
        raise ValueError("a section table must have the engine's depth grid")
    return (area, pf, t.total, r43, t.flow_width_top, t.total_width_top, t.top)


def _white_colebrook_radius(area: np.ndarray, conveyance: np.ndarray, k_n: float) -> np.ndarray:
    """The radius R (m) with A C(R) √R = K, C = max(18 log10(max(12 R / k_n, 1)), 1) (the kernels' law)."""
    wet = (area > 0) & (conveyance > 0)
    target = np.divide(conveyance, area, out=np.zeros_like(area), where=wet)  # C(R) √R, increasing in R
    lo = np.full(area.shape, 1e-12)
    hi = np.maximum(target**2, 1.0) * 1e3
    for _ in range(200):  # bisection on a log scale: each halves the ratio's exponent
        mid = np.sqrt(lo * hi)
        chezy = np.maximum(18.0 * np.log10(np.maximum(12.0 * mid / k_n, 1.0)), _MIN_CHEZY)
        below = chezy * np.sqrt(mid) < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
        if np.all(hi / lo < 1.0 + 1e-13):
            break
    return np.where(wet, np.sqrt(lo * hi), 0.0)


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


def _zw(h: np.ndarray, wf: np.ndarray, wt: np.ndarray, closed: bool, sections: list[float] | None) -> SectionTable:
    top = max(float(h[-1]) + (0.0 if closed else HEADROOM), MIN_TOP)
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
    area = _integrate(depth, h, wf)
    total = _integrate(depth, h, wt)
    perimeter = np.interp(depth, h, p_nodes)
    wtop_f = 0.0 if closed else float(wf[-1])
    wtop_t = 0.0 if closed else float(wt[-1])
    if sections is None:
        return _table(depth, area, total, perimeter, area[None, :], perimeter[None, :], [wtop_f], True, wtop_f,
                      wtop_t, closed)
    part_area, part_perimeter = _sections_zw(depth, h, wf, perimeter, sections)
    edges = np.concatenate([[0.0], np.cumsum(sections)])
    part_top = [float(np.clip(wtop_f - edges[k], 0.0, sections[k] if k < len(sections) - 1 else np.inf))
                for k in range(len(sections))]
    return _table(depth, area, total, perimeter, part_area, part_perimeter, part_top, True, wtop_f, wtop_t, closed)


def _sections_zw(depth, h, wf, perimeter, sections) -> tuple[np.ndarray, np.ndarray]:
    """Area (m²) and perimeter (m) of each section of a zw profile split into main channel and floodplains.

    The flow width is filled in order: main channel first, then the floodplains (D-Flow FM's zwRiver, SOBEK 3's
    tabulated profile). The wetted perimeter that appears while a section is filling belongs to it.
    """
    edges = np.concatenate([[0.0], np.cumsum(sections)])
    fine = np.linspace(0.0, depth[-1], 8 * (depth.size - 1) + 1)
    width = np.interp(fine, h, wf)
    per_fine = np.interp(fine, depth, perimeter)
    dp = np.diff(per_fine)
    areas, perimeters = [], []
    for k in range(len(sections)):
        part = np.clip(width - edges[k], 0.0, sections[k] if k < len(sections) - 1 else np.inf)
        a_part = np.concatenate([[0.0], np.cumsum(0.5 * (part[1:] + part[:-1]) * np.diff(fine))])
        grows = (width[1:] > edges[k] + 1e-12) & ((k == len(sections) - 1) | (width[:-1] < edges[k + 1] - 1e-12))
        if k == 0:
            grows = grows | (width[1:] <= edges[1] + 1e-12)
        p_part = np.concatenate([[wf[0] if k == 0 else 0.0], (wf[0] if k == 0 else 0.0) + np.cumsum(dp * grows)])
        areas.append(np.interp(depth, fine, a_part))
        perimeters.append(np.interp(depth, fine, p_part))
    return np.array(areas), np.array(perimeters)


def _integrate(d: np.ndarray, h: np.ndarray, w: np.ndarray) -> np.ndarray:
    """∫_0^d w(z) dz for widths linear between the heights h (exact)."""
    seg = np.clip(np.searchsorted(h, d, side="right") - 1, 0, len(h) - 2)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(h))])
    slope = np.diff(w) / np.diff(h)
    x = d - h[seg]
    return cum[seg] + w[seg] * x + 0.5 * slope[seg] * x**2


def summer_dike_fill(depth: np.ndarray, crest: float, transition: float) -> np.ndarray:
    """Fraction (0-1) of a summer dike's area in use at each depth (m): two parabolas over ``transition`` m.

    0 up to the crest, 2 x² for x = (d - crest) / transition up to 1/2, 1 - 2 (1 - x)² up to 1, then 1 (SOBEK 3's
    summer dike, whose width rises linearly to its peak at half the transition height and falls back to 0).
    """
    x = np.clip((depth - crest) / transition, 0.0, 1.0)
    return np.where(x <= 0.5, 2.0 * x * x, 1.0 - 2.0 * (1.0 - x) ** 2)


def flow_view(t: SectionTable) -> SectionTable:
    """The table with its summer dike's flow area in the highest wet friction section (the table itself without one).

    The flow area fills from 0 at the crest to full at the transition height above it, on the rising curve
    whichever way the level moves (SOBEK 3's GetSummerDikeFlow has no hysteresis); it goes to the highest section
    whose own flow area exceeds ``SUMMER_DIKE_THRESHOLD`` and adds no wetted perimeter. The total area is left
    as it is: the dike's storage is a contribution of its own (:func:`dike_storage`).
    """
    dike = t.dike
    if dike is None or dike.flow_area <= 0:
        return t
    flow = dike.flow_area * summer_dike_fill(t.depth, dike.crest, dike.transition)
    part_area = t.part_area.copy()
    target = np.zeros(t.depth.size, dtype=int)
    for s in range(t.sections):  # the highest section that carries more than the threshold takes the area
        target = np.where(t.part_area[s] > SUMMER_DIKE_THRESHOLD, s, target)
    for s in range(t.sections):
        part_area[s] += np.where(target == s, flow, 0.0)
    if t.lumped:  # the sections' conveyance follows from their areas and perimeters
        return _table(t.depth, t.area + flow, t.total, t.perimeter, part_area, t.part_perimeter, t.part_width_top,
                      True, t.flow_width_top, t.total_width_top, t.closed, dike=dike)
    s23, s12 = t.part_s23.copy(), t.part_s12.copy()
    for s in range(t.sections):  # a segmented section gains what the area adds to it as a whole
        after, before = _lumped_shapes(part_area[s], t.part_perimeter[s]), _lumped_shapes(t.part_area[s],
                                                                                          t.part_perimeter[s])
        s23[s] += after[0] - before[0]
        s12[s] += after[1] - before[1]
    return replace(t, area=t.area + flow, part_area=part_area, part_s23=s23, part_s12=s12)


def dike_storage(dike: DikeShape) -> tuple[tuple, tuple | None]:
    """A summer dike's storage as kernel tables from its base (rising curve, falling curve or None).

    Both are tables of total area only (flow area and perimeter 0; the columns of :func:`kernel_columns`) on a
    depth grid from the dike's base, ``DIKE_STEP`` apart, up to its full height; above it they hold the full total
    area. The rising curve is 0 up to the crest and fills over the transition height above it (SOBEK 3's
    GetSummerDikeTotal with its hysteresis flag set, the curve of the flow area); the falling curve fills over
    the whole height from the base to the full height, along the same two parabolas (the flag cleared). Both
    are full at and above the full height and empty at and below the base, so the storage keeps its volume when
    the engine changes curve there. Without a base below the crest there is no second curve (None).
    """
    top = dike.full - dike.base
    cells = int(min(max(math.ceil(top / DIKE_STEP), DIKE_MIN_CELLS), CELLS))
    depth = np.linspace(0.0, top, cells + 1)
    zero = np.zeros_like(depth)

    def table(total: np.ndarray) -> tuple:
        return (zero, zero, total, zero, 0.0, 0.0, top)

    rising = table(dike.total_area * summer_dike_fill(depth, dike.crest - dike.base, dike.transition))
    if dike.base >= dike.crest:
        return rising, None
    return rising, table(dike.total_area * summer_dike_fill(depth, 0.0, top))


# -- circle --------------------------------------------------------------------------------------------


def _circle(diameter: float) -> SectionTable:
    r = 0.5 * diameter
    top = max(diameter, MIN_TOP)
    depth = np.linspace(0.0, top, CELLS + 1)
    d = np.minimum(depth, diameter)
    theta = 2.0 * np.arccos(np.clip(1.0 - 2.0 * d / diameter, -1.0, 1.0))
    area = 0.5 * r * r * (theta - np.sin(theta))
    perimeter = r * theta
    return _table(depth, area, area.copy(), perimeter, area[None, :], perimeter[None, :], [0.0], True, 0.0, 0.0,
                  True)


# -- yz ------------------------------------------------------------------------------------------------


def _yz(profile: YZProfile) -> SectionTable:
    y = np.asarray(profile.y, dtype=float)
    z = np.asarray(profile.z, dtype=float)
    positions = list(profile.friction_positions) if profile.friction_positions else [y[0], y[-1]]
    # split the survey line at the section boundaries
    for p in positions[1:-1]:
        if not np.any(np.isclose(y, p)):
            k = int(np.searchsorted(y, p))
            zp = np.interp(p, y, z)
            y, z = np.insert(y, k, p), np.insert(z, k, zp)
    top = max(float(z.max()) + HEADROOM, MIN_TOP)
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
    n_sections = len(positions) - 1
    section = np.clip(np.searchsorted(positions, mid, side="right") - 1, 0, n_sections - 1)
    total_area = area.sum(axis=0)
    perimeter = wet.sum(axis=0) + wall_left + wall_right
    part_area = np.zeros((n_sections, depth.size))
    part_perimeter = np.zeros((n_sections, depth.size))
    part_s23 = np.zeros((n_sections, depth.size))
    part_s12 = np.zeros((n_sections, depth.size))
    part_top = np.zeros(n_sections)
    for i in range(n_pieces):
        p = wet[i] + (wall_left if i == 0 else 0.0) + (wall_right if i == n_pieces - 1 else 0.0)
        s = section[i]
        part_area[s] += area[i]
        part_perimeter[s] += p
        part_top[s] += y[i + 1] - y[i]
        if profile.conveyance == "segmented":
            r = np.divide(area[i], p, out=np.zeros_like(p), where=p > 0)
            part_s23[s] += area[i] * r ** (2.0 / 3.0)
            part_s12[s] += area[i] * np.sqrt(r)
    width_top = float(y[-1] - y[0])
    if profile.conveyance == "segmented":
        return _table(depth, total_area, total_area.copy(), perimeter, part_area, part_perimeter, part_top, False,
                      width_top, width_top, False, part_s23, part_s12)
    return _table(depth, total_area, total_area.copy(), perimeter, part_area, part_perimeter, part_top, True,
                  width_top, width_top, False)


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
