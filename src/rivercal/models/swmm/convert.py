"""A case's network as an EPA SWMM 5 input file (``.inp``), for the SWMM case and the cross-engine check.

The conversion keeps what both engines share and says what it changes:

- every branch becomes a chain of conduits of at most ``dx`` m between junctions at the branch's
  structures, stations and laterals; a structure closer than ``min_length`` to a branch end moves to
  that distance (a SWMM junction between an end and a structure alone has no storage and oscillates),
  laterals and stations that close to another junction share it; junction inverts are the bed levels
  (interpolated linearly along the branch; the junction below a structure and the conduit that leaves it
  start at the lowest bed within :data:`BASIN` m below it, so that a stilling basin is not smeared over
  the conduit); a connection node takes the lowest bed of the branches that meet there;
- cross-sections become SWMM ``TRAPEZOIDAL`` sections: a trapezoidal profile as it is; a ZW profile as
  the trapezoid of its main channel (bed width and the bank slope up to its bank height), continued
  up to the top of the table. The floodplain storage of a ZW profile above its banks is not carried
  over (SWMM conduits have one width for flow and storage);
- friction: Strickler k_s becomes Manning n = 1/k_s, Manning stays (Chézy is refused: its n depends on
  the depth); the conduits of a branch carry a ``[TAGS]`` entry with the branch id (a roughness group);
- a weir becomes a ``TRANSVERSE`` SWMM weir between the junctions ``<id>_up`` and ``<id>_dn`` with
  C_w = c_e c_w (2/3) √(2g/3) m^½/s, so that free flow gives the engine's Q = c_e c_w W (2/3) √((2/3) g) h^1.5
  (thesis Eq. 3-4; SWMM's submerged flow uses the Villemonte correction instead of Eq. 3-4's submerged
  branch); a flow direction ``positive`` gets a flap gate;
- a culvert becomes a closed conduit (circular or rectangular) with its entrance and exit losses;
- boundaries: a discharge becomes an external inflow, a level an outfall with a stage series, a Q(h)
  rating an ``OUTLET`` with a ``TABULAR/DEPTH`` curve to a free outfall, a critical boundary (a free
  outfall) SWMM's ``FREE`` outfall (the smaller of the critical and the normal depth of the conduit);
- laterals become external inflows at the nearest junction (several at one junction are summed);
- stations: ``h_up``/``h_down``/``Q`` of a structure become the heads of ``<id>_up``/``<id>_dn`` and the
  structure's flow; ``h``/``Q`` at a branch chainage the head of the junction there and the flow of the
  conduit that leaves it;
- the forcing series are written from ``start - spinup`` (held at their start values before ``start``,
  as the engine's spin-up does) to ``end``; junctions start ``depth`` m deep.

Pumps are not converted.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np
import pandas as pd

__all__ = ["SwmmExport", "case_to_inp", "weir_coefficient"]

G = 9.81
#: Length below a structure whose lowest bed the junction there takes (a stilling basin), m.
BASIN = 15.0


def weir_coefficient(discharge_coefficient: float = 1.0, lateral_contraction: float = 1.0) -> float:
    """SWMM's transverse-weir coefficient C_w (m^½/s) that equals the engine's free weir formula."""
    return discharge_coefficient * lateral_contraction * (2.0 / 3.0) * math.sqrt(2.0 * G / 3.0)


@dataclass
class SwmmExport:
    """What :func:`case_to_inp` made: the file's text and the names a ``model.toml`` needs.

    Attributes
    ----------
    text
        The ``.inp`` file.
    stations
        Observable ``<station>.<quantity>`` → ``node:<id>`` (head, m) or ``link:<id>`` (flow, m³/s).
    weirs
        Weir id → (inlet junction, crest level in m AD).
    junctions, conduits
        Numbers of junctions (incl. outfalls) and conduits.
    """

    text: str
    stations: dict[str, str] = field(default_factory=dict)
    weirs: dict[str, tuple[str, float]] = field(default_factory=dict)
    junctions: int = 0
    conduits: int = 0


def _bed(branch, chainage: float) -> float:
    xs = branch.cross_sections
    ch = [c.chainage for c in xs]
    return float(np.interp(chainage, ch, [c.bed_level for c in xs]))


def _profile_at(branch, chainage: float):
    xs = branch.cross_sections
    return min(xs, key=lambda c: abs(c.chainage - chainage)).profile


def _trapezoid(profile) -> tuple[float, float, float]:
    """(max depth, bottom width, side slope) of a profile as a SWMM trapezoid (module docstring)."""
    if profile.type == "trapezoidal":
        return max(profile.height or 10.0, 10.0), profile.bottom_width, profile.side_slope
    if profile.type == "rectangular":
        return max(profile.height or 10.0, 10.0), profile.width, 0.0
    if profile.type == "zw":
        h, w = profile.heights, profile.flow_widths
        k = h.index(profile.height) if profile.height in h else len(h) - 1
        k = max(k, 1)
        return float(h[-1]), float(w[0]), float((w[k] - w[0]) / (2.0 * h[k]))
    raise ValueError(f"profile {profile.id!r}: type {profile.type!r} is not converted to SWMM")


def _manning(friction) -> float:
    if friction.type == "strickler":
        return 1.0 / friction.value
    if friction.type == "manning":
        return friction.value
    raise ValueError(f"{friction.type} friction is not converted to SWMM (its Manning n depends on the depth)")


def _date(t: pd.Timestamp) -> tuple[str, str]:
    return t.strftime("%m/%d/%Y"), t.strftime("%H:%M:%S")


def case_to_inp(case, forcing: Mapping[str, pd.Series], *, dx: float = 500.0, min_length: float = 50.0,
                routing_step: float = 10.0, lengthening_step: float = 0.0,
                variable_step: float = 0.0, spinup: float | None = None, depth: float | None = None,
                start: pd.Timestamp | None = None, end: pd.Timestamp | None = None,
                title: str = "") -> SwmmExport:
    """Write ``case``'s network and ``forcing`` as a SWMM input file (module docstring).

    Parameters
    ----------
    case
        A loaded case (:class:`~rivercal.case.Case`).
    forcing
        Boundary and lateral series by key ``boundary:<id>`` / ``lateral:<id>`` (m³/s or m AD), e.g.
        ``EmbeddedModel.forcing`` (with the rainfall-runoff inflows).
    dx
        Longest conduit, m.
    min_length
        Shortest conduit beside a structure, m: a structure closer to a branch end moves to this
        distance; laterals and stations closer to another junction share it.
    routing_step
        SWMM's routing time step, s.
    variable_step
        SWMM's ``VARIABLE_STEP`` safety factor (0: fixed steps).
    lengthening_step
        SWMM's ``LENGTHENING_STEP``, s: conduits shorter than their Courant length at this step are
        lengthened (0: none).
    spinup, depth
        Hours of forcing held at its start value before ``start``, and the junctions' initial depth, m
        (default: the case's ``[initial]``).
    start, end
        Period of the file (default: the case's).
    title
        The ``[TITLE]`` text.

    Raises
    ------
    ValueError
        For pumps, Chézy friction, a profile type that is not converted, or controllers (``[[controllers]]``;
        no SWMM control rules are written, and fixed crests would not be the same model).
    """
    net = case.network
    spec = case.spec
    if spec.controllers:
        raise ValueError(f"case {case.name!r} has {len(spec.controllers)} controllers ([[controllers]]), which the "
                         "SWMM conversion does not write as control rules; convert a case without them")
    start = case.start if start is None else start
    end = case.end if end is None else end
    spinup = spec.initial.spinup if spinup is None else spinup
    depth = spec.initial.depth if depth is None else depth
    if net.pumps:
        raise ValueError(f"pumps ({', '.join(p.id for p in net.pumps)}) are not converted to SWMM")
    structures = {s.id: s for s in [*net.weirs, *net.culverts]}
    by_branch: dict[str, list] = {b.id: [] for b in net.branches}
    for s in structures.values():
        by_branch[s.branch].append(s)
    lat_at: dict[str, list[tuple[str, float]]] = {b.id: [] for b in net.branches}
    node_laterals: dict[str, list[str]] = {}
    for lat in net.laterals:
        if lat.branch is not None:
            lat_at[lat.branch].append((lat.id, float(lat.chainage)))
        else:
            node_laterals.setdefault(lat.node, []).append(lat.id)
    station_at: dict[str, list[tuple[str, float]]] = {b.id: [] for b in net.branches}
    for st in net.stations:
        if st.structure is None:
            station_at[st.branch].append((st.id, float(st.chainage)))

    # connection nodes: lowest bed of the branch ends that meet there
    node_invert: dict[str, float] = {}
    for b in net.branches:
        for nid, ch in ((b.from_node, 0.0), (b.to_node, b.length)):
            node_invert[nid] = min(node_invert.get(nid, math.inf), _bed(b, ch))
    junctions: dict[str, float] = dict(node_invert)
    # conduits: id, from node, to node, length, n, inlet offset, outlet offset, (depth, width, slope), tag
    conduits: list[tuple[str, str, str, float, float, float, float, tuple, str]] = []
    weirs, culverts = [], []
    lateral_node: dict[str, str] = {}
    stations: dict[str, str] = {}
    global_n = _manning(net.friction)
    for b in net.branches:
        n = _manning(b.friction) if b.friction is not None else global_n
        length = float(b.length)
        snap = min(min_length, 0.25 * length)
        stops = {0.0: [b.from_node, b.from_node, None], length: [b.to_node, b.to_node, None]}
        for s in sorted(by_branch[b.id], key=lambda s: s.chainage):
            # a structure keeps a conduit of at least ``snap`` to a branch end: a junction between an end
            # and a structure alone has no storage in SWMM and oscillates
            stops[min(max(float(s.chainage), snap), length - snap)] = [f"{s.id}_up", f"{s.id}_dn", s]

        def stop_near(c: float, stops=stops, b=b, snap=snap) -> float:
            nearest = min(stops, key=lambda at: abs(at - c))
            if abs(nearest - c) >= snap:
                stops[c] = [f"{b.id}_{c:g}", f"{b.id}_{c:g}", None]
                nearest = c
            return nearest

        lateral_stop = {lid: stop_near(ch) for lid, ch in lat_at[b.id]}
        station_stop = {sid: stop_near(ch) for sid, ch in station_at[b.id]}
        seq = sorted(stops.items())
        # the bed just below a structure (a stilling basin drops within metres): the downstream junction and
        # the conduit that leaves it start there, instead of smearing the drop over the whole conduit
        below = {dn: min(_bed(b, min(float(st.chainage) + x, length)) for x in np.linspace(0.0, BASIN, 11))
                 for _, (_, dn, st) in seq if st is not None}  # from where the structure is, also when moved
        for (c0, (_, a_dn, _)), (c1, (b_up, _, _)) in pairwise(seq):
            k = max(1, math.ceil((c1 - c0) / dx - 1e-9))
            chain = [a_dn] + [f"{b.id}_{c0 + (c1 - c0) * i / k:.0f}" for i in range(1, k)] + [b_up]
            for i, (u, v) in enumerate(pairwise(chain)):
                ca, cb = c0 + (c1 - c0) * i / k, c0 + (c1 - c0) * (i + 1) / k
                bed_a = below.get(u, _bed(b, ca))
                bed_b = _bed(b, cb)
                for nid, z in ((u, bed_a), (v, bed_b)):
                    if nid not in node_invert:
                        junctions[nid] = z
                o1 = bed_a - junctions[u]
                o2 = bed_b - junctions[v]
                prof = next(p for p in net.profiles if p.id == _profile_at(b, 0.5 * (ca + cb)))
                conduits.append((f"{b.id}_c{len(conduits)}", u, v, cb - ca, n, o1, o2, _trapezoid(prof), b.id))
        for c, (up, dn, s) in seq:
            if s is None:
                continue
            junctions.setdefault(up, _bed(b, c))
            junctions.setdefault(dn, below[dn])
            (weirs if hasattr(s, "crest_level") else culverts).append((s, up, dn))
        for lid, c in lateral_stop.items():
            lateral_node[lid] = stops[c][1]
        for sid, c in station_stop.items():
            here = stops[c][1]
            st = next(x for x in net.stations if x.id == sid)
            for q in st.quantities or ["h"]:
                if q == "h":
                    stations[f"{sid}.h"] = f"node:{here}"
                elif q == "Q":
                    leaving = next(x[0] for x in conduits if x[1] == here)
                    stations[f"{sid}.Q"] = f"link:{leaving}"
    for nid, lids in node_laterals.items():
        for lid in lids:
            lateral_node[lid] = nid
    for st in net.stations:
        if st.structure is not None:
            for q in st.quantities or ["h_up", "h_down"]:
                stations[f"{st.id}.{q}"] = {"h_up": f"node:{st.structure}_up", "h_down": f"node:{st.structure}_dn",
                                            "Q": f"link:{st.structure}"}[q]

    run_from = start - pd.Timedelta(hours=spinup)
    lines: list[str] = []

    def section(name: str, rows: list[str]) -> None:
        lines.append(f"[{name}]")
        lines.extend(rows)
        lines.append("")

    section("TITLE", [title or f"{case.name}: converted from rivercal case {case.name!r}"])
    d0, t0 = _date(run_from)
    d1, t1 = _date(end)
    section("OPTIONS", [
        "FLOW_UNITS CMS", "INFILTRATION HORTON", "FLOW_ROUTING DYNWAVE", "LINK_OFFSETS DEPTH",
        f"START_DATE {d0}", f"START_TIME {t0}", f"REPORT_START_DATE {d0}", f"REPORT_START_TIME {t0}",
        f"END_DATE {d1}", f"END_TIME {t1}", "SWEEP_START 01/01", "SWEEP_END 12/31", "DRY_DAYS 0",
        "REPORT_STEP 01:00:00", "WET_STEP 00:05:00", "DRY_STEP 01:00:00", f"ROUTING_STEP {routing_step:g}",
        "RULE_STEP 00:00:00", "ALLOW_PONDING NO", "INERTIAL_DAMPING PARTIAL", f"VARIABLE_STEP {variable_step:g}",
        f"LENGTHENING_STEP {lengthening_step:g}", "MIN_SURFAREA 1.0", "NORMAL_FLOW_LIMITED BOTH",
        "SKIP_STEADY_STATE NO",
        "FORCE_MAIN_EQUATION H-W", "SURCHARGE_METHOD EXTRAN", "MAX_TRIALS 8", "HEAD_TOLERANCE 0.0005",
        "SYS_FLOW_TOL 5", "LAT_FLOW_TOL 5", "MINIMUM_STEP 0.5", "THREADS 1"])

    bounds = {bd.node: bd for bd in net.boundaries}
    outfalls, junction_rows, outlets, curves = [], [], [], []
    series_rows: list[str] = []
    inflows: dict[str, pd.Series] = {}

    def extended(key: str) -> pd.Series:
        s = forcing[key].astype(float)
        s = s[(s.index >= start) & (s.index <= end)] if len(s) > 2 else s
        first = float(np.interp(0.0, (forcing[key].index - start).total_seconds(), forcing[key].to_numpy(float)))
        head = pd.Series([first, first], index=[run_from, start])
        return pd.concat([head, s[s.index > start]]).groupby(level=0).last()

    for nid, z in sorted(junctions.items()):
        bd = bounds.get(nid)
        if bd is not None and bd.type == "level":
            outfalls.append(f"{nid} {z:.4f} TIMESERIES ts_{bd.id} NO")
            series_rows += _series_rows(f"ts_{bd.id}", extended(f"boundary:{bd.id}"))
            continue
        if bd is not None and bd.type == "critical":
            outfalls.append(f"{nid} {z:.4f} FREE NO")
            continue
        junction_rows.append(f"{nid} {z:.4f} 20 {depth:g} 0 0")
        if bd is not None and bd.type == "discharge":
            inflows[nid] = _add(inflows.get(nid), extended(f"boundary:{bd.id}"))
        if bd is not None and bd.type == "rating":
            sink = f"{nid}_sink"
            low = min(z, bd.rating.levels[0]) - 1.0
            outfalls.append(f"{sink} {low:.4f} FREE NO")
            outlets.append(f"{bd.id} {nid} {sink} 0 TABULAR/DEPTH rating_{bd.id} NO")
            pts = [(lv - z, q) for lv, q in zip(bd.rating.levels, bd.rating.discharges, strict=True) if lv >= z]
            if not pts or pts[0][0] > 0:
                pts.insert(0, (0.0, 0.0))
            curves += [f"rating_{bd.id} Rating {pts[0][0]:.4f} {pts[0][1]:.4f}"]
            curves += [f"rating_{bd.id} {h:.4f} {q:.4f}" for h, q in pts[1:]]
    for lid, nid in lateral_node.items():
        inflows[nid] = _add(inflows.get(nid), extended(f"lateral:{lid}"))
    section("JUNCTIONS", [";Name Elevation MaxDepth InitDepth SurDepth Aponded", *junction_rows])
    section("OUTFALLS", [";Name Elevation Type Stage Gated", *outfalls])
    section("CONDUITS", [";Name From To Length Roughness InOffset OutOffset InitFlow MaxFlow",
                         *(f"{c[0]} {c[1]} {c[2]} {c[3]:.2f} {c[4]:.6g} {c[5]:.4f} {c[6]:.4f} 0 0" for c in conduits),
                         *(f"{s.id} {up} {dn} {s.length:g} {_manning(s.friction):.6g} "
                           f"{s.invert_level - junctions[up]:.4f} {s.invert_level - junctions[dn]:.4f} 0 0"
                           for s, up, dn in culverts)])
    section("OUTLETS", [";Name From To Offset Type Curve Gated", *outlets])
    section("WEIRS", [";Name From To Type CrestHt Qcoeff Gated EndCon EndCoeff Surcharge",
                      *(f"{w.id} {up} {dn} TRANSVERSE {w.crest_level - junctions[up]:.4f} "
                        f"{weir_coefficient(w.discharge_coefficient, w.lateral_contraction):.6f} "
                        f"{'YES' if w.allowed_flow == 'positive' else 'NO'} 0 0 NO" for w, up, dn in weirs)])
    xs_rows = [f"{c[0]} TRAPEZOIDAL {c[7][0]:g} {c[7][1]:g} {c[7][2]:g} {c[7][2]:g} 1" for c in conduits]
    for s, _, _ in culverts:
        if s.shape == "circular":
            xs_rows.append(f"{s.id} CIRCULAR {s.diameter:g} 0 0 0 1")
        else:
            xs_rows.append(f"{s.id} RECT_CLOSED {s.height:g} {s.width:g} 0 0 1")
    xs_rows += [f"{w.id} RECT_OPEN 20 {w.crest_width:g} 0 0" for w, _, _ in weirs]
    section("XSECTIONS", [";Link Shape Geom1 Geom2 Geom3 Geom4 Barrels", *xs_rows])
    section("LOSSES", [";Link Inlet Outlet Average FlapGate",
                       *(f"{s.id} {s.inlet_loss:g} {s.outlet_loss:g} 0 "
                         f"{'YES' if s.allowed_flow == 'positive' else 'NO'}" for s, _, _ in culverts)])
    section("CURVES", [";Name Type X Y", *curves])
    inflow_rows = []
    for nid, s in sorted(inflows.items()):
        inflow_rows.append(f'{nid} FLOW ts_in_{nid} FLOW 1.0 1.0')
        series_rows += _series_rows(f"ts_in_{nid}", s)
    section("INFLOWS", [";Node Constituent Series Type Mfactor Sfactor", *inflow_rows])
    section("TIMESERIES", [";Name Date Time Value", *series_rows])
    section("TAGS", [f"Link {c[0]} {c[8]}" for c in conduits])
    section("REPORT", ["INPUT NO", "CONTROLS NO", "NODES ALL", "LINKS ALL"])
    coords = [f"{nd.id} {nd.x:g} {nd.y:g}" for nd in net.nodes if nd.x is not None and nd.y is not None]
    section("COORDINATES", [";Node X Y", *coords])
    return SwmmExport(text="\n".join(lines), stations=stations,
                      weirs={w.id: (up, float(w.crest_level)) for w, up, _ in weirs},
                      junctions=len(junctions) + len([o for o in outfalls if "_sink" in o.split()[0]]),
                      conduits=len(conduits) + len(culverts))


def _add(a: pd.Series | None, b: pd.Series) -> pd.Series:
    """The sum of two series on the union of their times (each interpolated linearly in time)."""
    if a is None:
        return b
    index = a.index.union(b.index)
    t = (index - index[0]).total_seconds().to_numpy()

    def on(s: pd.Series) -> np.ndarray:
        return np.interp(t, (s.index - index[0]).total_seconds().to_numpy(), s.to_numpy(float))

    return pd.Series(on(a) + on(b), index=index)


def _series_rows(name: str, s: pd.Series) -> list[str]:
    """``[TIMESERIES]`` rows of a series (one per time; UTC times written as SWMM's local clock)."""
    idx = s.index.tz_convert("UTC") if s.index.tz is not None else s.index
    return [f"{name} {t:%m/%d/%Y %H:%M} {v:.6g}" for t, v in zip(idx, s.to_numpy(float), strict=True)]
