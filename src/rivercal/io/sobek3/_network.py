"""The network of a SOBEK 3 model as case tables: nodes, branches, profiles, friction, stations, initial levels.

SOBEK 3 → case:

- ``NetworkDefinition.ini`` ``[Node]`` → ``[[nodes]]``; ``[Branch]`` → ``[[branches]]`` with its geometry, its
  grid points as the case's calculation points (``points``) and its ``order``;
- ``CrossSectionDefinitions.ini`` → ``[[profiles]]``: ``tabulated`` → ``zw`` (flow and total widths, the main
  channel and floodplains as friction sections, the summer dike ``sd_*``), ``rectangle``, ``trapezium``,
  ``circle``, ``yz``; ``CrossSectionLocations.ini`` → ``branches[].cross_sections`` with bed level = the
  definition's lowest level + shift;
- ``roughness-*.ini`` → one ``[[friction_groups]]`` per roughness section (``Main``, ``FloodPlain1``, ...) with its
  global law and value, and per branch its law and its values: constant, along the branch (``[Definition]`` at
  chainages) or as a function of the water level (``functionType = 2``);
- ``ObservationPoints.ini`` → ``[[stations]]`` (level and discharge);
- ``InitialWaterLevel.ini`` → ``branches[].initial_levels``; the md1d's global initial level and depth →
  ``[initial]``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections import defaultdict

import numpy as np

from rivercal.errors import CaseError
from rivercal.io._summer_dike import summer_dike
from rivercal.io.sobek3._context import Context
from rivercal.io.sobek3._ini import Section
from rivercal.network import FRICTION_RANGES

__all__ = ["LAWS", "convert_network", "law_of", "profile_of", "unused_definitions"]

#: SOBEK 3's roughness type codes (roughness files of version 1, culverts and bridges) → (case law, note).
LAWS = {0: "chezy", 1: "chezy", 4: "manning", 5: "stricklernikuradse", 6: "strickler", 7: "white-colebrook",
        8: "engelund", 9: "bosbijkerk"}
_LAW_NAMES = {"chezy": "chezy", "manning": "manning", "strickler": "strickler", "stricklerks": "strickler",
              "stricklerkn": "stricklernikuradse", "stricklernikuradse": "stricklernikuradse",
              "whitecolebrook": "white-colebrook", "nikuradse": "white-colebrook", "engelund": "engelund",
              "bosbijkerk": "bosbijkerk", "debosbijkerk": "bosbijkerk", "debosenbijkerk": "bosbijkerk"}
#: Default names of the friction sections of a profile (SOBEK 3 uses them when a definition names none).
SECTION_NAMES = ["Main", "FloodPlain1", "FloodPlain2"]
#: A flow width below this is no section at all, m (SOBEK 3's Preissmann-slot threshold).
_NO_WIDTH = 1e-3


def law_of(code: str) -> str | None:
    """The case's friction law of a SOBEK 3 roughness type (a code or a name); None when unknown.

    ``stricklernikuradse`` (k_n) is converted by :func:`convert_value`; ``engelund`` and ``bosbijkerk`` have no
    counterpart in a case.
    """
    text = str(code).strip()
    try:
        return LAWS.get(int(float(text)))
    except ValueError:
        return _LAW_NAMES.get(re.sub(r"[^a-z]", "", text.lower()))


def convert_value(law: str, value: float) -> tuple[str, float]:
    """A coefficient of a SOBEK 3 law as the case's law and value.

    Strickler with the Nikuradse roughness k_n, C = 25 (R / k_n)^(1/6) (SOBEK 3 technical reference, roughness
    formulas; flow1d's GetChezy), is Strickler with k_s = 25 k_n^(-1/6).
    """
    if law == "stricklernikuradse":
        return "strickler", 25.0 * value ** (-1.0 / 6.0)
    return law, value


def convert_network(ctx: Context) -> None:
    """Fill ``ctx.case`` with nodes, branches, profiles, friction groups, stations and the initial state."""
    _nodes_and_branches(ctx)
    _friction_groups(ctx)
    _cross_sections(ctx)
    _stations(ctx)
    _initial(ctx)
    _retention(ctx)


# -- nodes and branches ---------------------------------------------------------------------------------


def _nodes_and_branches(ctx: Context) -> None:
    blocks = ctx.model.blocks("networkFile")
    nodes: list[dict] = []
    node_ids: dict[str, dict] = {}
    for s in blocks:
        if s.kind != "node":
            continue
        nid = s.text("id")
        if nid in node_ids:
            raise s.error("id", f"node {nid!r} is defined twice")
        node = {"id": ctx.id("node", nid)}
        if s.has("x") and s.has("y"):
            node["x"], node["y"] = s.number("x"), s.number("y")
        nodes.append(node)
        node_ids[nid] = node
        ctx.ledger.exact("node", nid)
    branches: list[dict] = []
    for s in blocks:
        if s.kind != "branch":
            continue
        bid = s.text("id")
        if ctx.known("branch", bid):
            raise s.error("id", f"branch {bid!r} is defined twice")
        ends = []
        for key in ("fromNode", "toNode"):
            nid = s.text(key)
            if nid not in node_ids:
                raise s.error(key, f"node {nid!r} is not a [Node] of the network")
            ends.append(node_ids[nid]["id"])
        if ends[0] == ends[1]:
            raise s.error("toNode", f"the branch starts and ends at node {s.text('toNode')!r}")
        geometry = _linestring(s)
        offsets = s.numbers("gridPointOffsets", "gridPointChainages", default=None)
        if offsets is not None and s.has("gridPointsCount") and s.integer("gridPointsCount") != len(offsets):
            raise s.error("gridPointOffsets", f"{len(offsets)} grid point offsets for gridPointsCount = "
                                              f"{s.integer('gridPointsCount')}")
        geo_length = None if geometry is None else float(np.hypot(*np.diff(np.asarray(geometry), axis=0).T).sum())
        if s.has("length"):
            length = s.number("length")
        elif offsets:
            length = float(offsets[-1])
        elif geo_length is not None:
            length = geo_length
        else:
            raise s.error("geometry", "the branch has neither grid points nor a geometry to give its length")
        if not length > 0:
            raise s.error("gridPointOffsets", f"the branch is {length:g} m long")
        branch: dict = {"id": ctx.id("branch", bid), "from_node": ends[0], "to_node": ends[1], "length": length}
        notes = []
        if offsets is not None:
            pts = np.asarray(offsets, dtype=float)
            if np.any(np.diff(pts) < 0):
                bad = int(np.flatnonzero(np.diff(pts) < 0)[0]) + 1
                raise s.error("gridPointOffsets", f"grid point offsets must increase, but {pts[bad]:g} m follows "
                                                  f"{pts[bad - 1]:g} m (position {bad})")
            if abs(pts[0]) > 1e-3 or abs(pts[-1] - length) > 1e-3 * max(1.0, length):
                raise s.error("gridPointOffsets", f"grid points must run from 0 to the branch length ({length:g} m), "
                                                  f"got {pts[0]:g}-{pts[-1]:g} m")
            keep = np.concatenate([[True], np.diff(pts) > 1e-3])
            if not keep.all():
                notes.append(f"{int((~keep).sum())} grid point(s) within 1 mm of the one before dropped")
                pts = pts[keep]
            pts[0], pts[-1] = 0.0, length
            if pts.size >= 2:
                branch["points"] = [float(p) for p in pts]
        if "points" not in branch:
            branch["dx"] = min(length, 100.0)
            notes.append("no grid points: calculation points every 100 m")
        if geometry is not None:
            branch["geometry"] = geometry
            if offsets is None and geo_length is not None and abs(geo_length - length) > 1e-3 * length:
                notes.append(f"the geometry is {geo_length:.1f} m long, the branch {length:g} m")
        order = s.integer("order", default=None)
        if order is not None and order > 0:
            branch["order"] = order
        branches.append(branch)
        ctx.branches[branch["id"]] = branch
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("branch", bid, "; ".join(notes))
    if not branches:
        raise CaseError("the network has no [Branch]", file=str(ctx.model.files["networkFile"][0]))
    used = {n for b in branches for n in (b["from_node"], b["to_node"])}
    for n in nodes:
        if n["id"] not in used:
            ctx.ledger.refused("node", n["id"], "no branch joins it", hydraulic=False)
    ctx.case["nodes"] = [n for n in nodes if n["id"] in used]
    ctx.case["branches"] = branches


def _linestring(s: Section) -> list[list[float]] | None:
    item = s.find("geometry")
    if item is None or not item.value:
        return None
    match = re.fullmatch(r"\s*LINESTRING\s*(?:Z\s*)?\((.*)\)\s*", item.value, flags=re.I)
    if not match:
        raise s.error("geometry", f"{item.value[:60]!r} is not a WKT LINESTRING", item)
    points = []
    for pair in match.group(1).split(","):
        parts = pair.split()
        try:
            points.append([float(parts[0]), float(parts[1])])
        except (ValueError, IndexError):
            raise s.error("geometry", f"{pair.strip()!r} is not a point 'x y [z]'", item) from None
    if len(points) < 2:
        raise s.error("geometry", "a branch geometry needs at least two points", item)
    return points


# -- friction ------------------------------------------------------------------------------------------


def _plausible(ctx: Context, law: str, values: list[float], where: str, *, table: bool = False) -> list[float]:
    """Values in the plausible range of their law: constants clamped into it, a table's largest value into it."""
    low, high, unit = FRICTION_RANGES[law]
    if table:
        top = max(values)
        if low <= top <= high:
            return values
        ctx.ledger.approximated("friction on a branch", where, f"its largest {law} coefficient {top:g} {unit} lies "
                                f"outside the plausible range {low:g}-{high:g} {unit}; the values are clamped to it")
        return [min(max(v, low), high) for v in values]
    out = [min(max(v, low), high) for v in values]
    changed = sum(1 for a, b in zip(values, out, strict=True) if a != b)
    if changed:
        ctx.ledger.approximated("friction on a branch", where, f"{changed} {law} coefficient(s) outside the plausible "
                                f"range {low:g}-{high:g} {unit} clamped to it (from {min(values):g}-{max(values):g})")
    return out


def _friction_groups(ctx: Context) -> None:
    groups: list[dict] = []
    seen: dict[str, str] = {}
    for path, sections in zip(ctx.model.files.get("roughnessFile", []), ctx.model.sections.get("roughnessFile", []),
                              strict=True):
        content = next((s for s in sections if s.kind == "content"), None)
        if content is None:
            version = next((s for s in sections if s.kind == "general"), None)
            if any(s.kind == "global" for s in sections):
                raise (version or sections[0]).error(None, "a roughness file of D-Flow FM's later format ([Global] "
                                                           "blocks); import the model with 'rivercal import dhydro'")
            ctx.ledger.warn(f"{path.name}: no [Content] section; the file is not read")
            continue
        sid = content.text("sectionId")
        direction = content.flag("flowDirection", default=False)
        if direction:
            ctx.ledger.refused("friction group", f"{sid} (negative flow)", f"{path.name}: roughness for flow against "
                               "the branch direction; a case has one roughness for both directions (the positive "
                               "direction's is used)")
            continue
        if sid in seen:
            raise content.error("sectionId", f"roughness section {sid!r} is also defined in {seen[sid]}")
        seen[sid] = path.name
        gid = ctx.id("friction group", sid)
        glaw = law_of(content.text("globalType", default="1"))
        gvalue = content.number("globalValue", default=45.0)
        if glaw in (None, "engelund", "bosbijkerk"):
            raise content.error("globalType", f"roughness type {content.text('globalType')!r} has no counterpart in "
                                              "a case (Chézy 1, Manning 4, Strickler k_n 5, Strickler k_s 6, "
                                              "White-Colebrook 7)")
        glaw, gvalue = convert_value(glaw, gvalue)
        gvalue = _plausible(ctx, glaw, [gvalue], f"{sid} (global value)")[0]
        group: dict = {"id": gid, "type": glaw, "value": gvalue, "branches": []}
        interpolate = content.flag("interpolate", default=True)
        properties: dict[str, Section] = {}
        for s in sections:
            if s.kind == "branchproperties":
                bid = s.text("branchId")
                if bid in properties:
                    raise s.error("branchId", f"branch {bid!r} has two [BranchProperties] in this file")
                properties[bid] = s
        definitions: dict[str, list[Section]] = defaultdict(list)
        for s in sections:
            if s.kind == "definition":
                definitions[s.text("branchId")].append(s)
        for bid in [*properties, *[b for b in definitions if b not in properties]]:
            where = f"{sid} on {bid}"
            if not ctx.known("branch", bid):
                ctx.ledger.refused("friction on a branch", where, f"{path.name}: branch {bid!r} is not in the network",
                                   hydraulic=False)
                continue
            entry = _branch_entry(ctx, group, properties.get(bid), definitions.get(bid, []), interpolate, where)
            if entry is not None:
                entry["branch"] = ctx.id("branch", bid)
                group["branches"].append(entry)
        if not group["branches"]:
            del group["branches"]
        groups.append(group)
        ctx.ledger.exact("friction group", sid, f"{path.name}: global {glaw} {gvalue:g}")
    ctx.case["friction_groups"] = groups


def _branch_entry(ctx: Context, group: dict, props: Section | None, defs: list[Section], interpolate: bool,
                  where: str) -> dict | None:
    """The group's entry for one branch (``BranchFriction``), or None when the branch keeps the group's value."""
    law = group["type"]
    function = 0
    levels = None
    raw_law = law
    if props is not None:
        code = props.text("roughnessType", default="1")
        raw_law = law_of(code)
        if raw_law is None:
            raise props.error("roughnessType", f"unknown roughness type {code!r}")
        if raw_law in ("engelund", "bosbijkerk"):
            ctx.ledger.refused("friction on a branch", where, f"roughness type {raw_law} has no counterpart in a case "
                               "(its coefficient depends on the flow); the branch takes the group's value")
            return None
        function = props.integer("functionType", default=0)
        if function == 1:
            ctx.ledger.refused("friction on a branch", where, "roughness as a function of the discharge "
                               "(functionType = 1) is not converted; the branch takes the group's value")
            return None
        if function not in (0, 2):
            raise props.error("functionType", f"functionType {function} is none of 0 (constant), 1 (discharge), "
                                              "2 (water level)")
        if function == 2:
            count = props.integer("numLevels", default=None)
            levels = props.numbers("levels", count=count)
            if len(levels) < 1 or any(b <= a for a, b in itertools.pairwise(levels)):
                raise props.error("levels", "the levels of a water-level dependent roughness must increase strictly")
    defs = sorted(defs, key=lambda s: s.number("chainage"))
    chainages: list[float] = []
    rows: list[list[float]] = []
    for s in defs:
        chainage = s.number("chainage")
        if chainages and abs(chainage - chainages[-1]) < 1e-6:
            ctx.ledger.approximated("friction on a branch", where, f"two definitions at chainage {chainage:g} m; the "
                                    f"first is kept ({s.where()})")
            continue
        if function == 2:
            values = s.numbers("values", count=len(levels)) if s.has("values") else [s.number("value")] * len(levels)
        else:
            values = [s.number("value")] if s.has("value") else s.numbers("values")[:1]
        if any(not v > 0 for v in values):
            raise s.error("values" if s.has("values") else "value", "roughness values must be positive")
        chainages.append(chainage)
        rows.append(values)
    if not rows:  # the branch's law with the group's global value (SOBEK 3 fills a branch without data so)
        if raw_law == group["type"] or props is None:
            return None
        rows, chainages, function = [[group["value"]]], [0.0], 0
    converted = [[convert_value(raw_law, v)[1] for v in row] for row in rows]
    case_law = convert_value(raw_law, 1.0)[0]
    if not interpolate and len(chainages) > 1:  # values held from one definition to the next: steps of 1 mm
        steps_c, steps_r = [chainages[0]], [converted[0]]
        for c, r in zip(chainages[1:], converted[1:], strict=True):
            steps_c += [max(c - 0.001, steps_c[-1] + 1e-6), c]
            steps_r += [steps_r[-1], r]
        chainages, converted = steps_c, steps_r
        ctx.ledger.approximated("friction on a branch", where, "values held between the definitions (interpolate = "
                                "0): steps of 1 mm")
    entry: dict = {}
    if case_law != group["type"]:
        entry["type"] = case_law
    if function == 2:
        flat = _plausible(ctx, case_law, [v for row in converted for v in row], where, table=True)
        n = len(levels)
        entry.update(function="waterlevel", levels=[float(v) for v in levels],
                     table=[flat[i * n:(i + 1) * n] for i in range(len(converted))])
        if len(chainages) > 1:
            entry["chainages"] = chainages
        ctx.ledger.exact("friction on a branch", where, f"{case_law} as a function of the water level "
                         f"({len(levels)} levels) at {len(chainages)} chainage(s)")
        return entry
    values = _plausible(ctx, case_law, [row[0] for row in converted], where)
    if len(values) == 1:
        entry["value"] = values[0]
    else:
        entry["chainages"] = chainages
        entry["values"] = values
    ctx.ledger.exact("friction on a branch", where, f"{case_law} along the branch" if len(values) > 1 else "")
    return entry


# -- cross-sections ------------------------------------------------------------------------------------


def _cross_sections(ctx: Context) -> None:
    for s in ctx.model.blocks("crossDefFile", "definition"):
        did = s.text("id")
        if did in ctx.definitions:
            raise s.error("id", f"cross-section definition {did!r} is defined twice")
        ctx.definitions[did] = s
    per_branch: dict[str, list[tuple[float, dict, str]]] = defaultdict(list)
    for s in ctx.model.blocks("crossLocFile", "crosssection"):
        cid = s.text("id")
        bid = s.text("branchId", "branchid")
        did = s.text("definitionId", "definition")
        if not ctx.known("branch", bid):
            ctx.ledger.refused("cross-section", cid, f"its branch {bid!r} is not in the network", hydraulic=False)
            continue
        if did not in ctx.definitions:
            raise s.error("definition" if s.has("definition") else "definitionId",
                          f"cross-section definition {did!r} is not in the definitions file")
        pid, bottom = add_profile(ctx, did)
        if pid is None:
            ctx.ledger.refused("cross-section", cid, f"its definition {did!r} was refused")
            continue
        branch = ctx.branches[ctx.id("branch", bid)]
        chainage = s.number("chainage")
        if chainage < -1e-6 or chainage > branch["length"] + 1e-3:
            raise s.error("chainage", f"chainage {chainage:g} m lies outside branch {bid!r} (0-{branch['length']:g} m)")
        chainage = min(max(chainage, 0.0), branch["length"])
        per_branch[branch["id"]].append((chainage, {"chainage": chainage, "profile": pid,
                                                    "bed_level": bottom + s.number("shift", default=0.0)}, cid))
    for branch in ctx.case["branches"]:
        items = sorted(per_branch.get(branch["id"], []), key=lambda c: c[0])
        sections = []
        for chainage, cs, cid in items:
            if sections and chainage <= sections[-1]["chainage"] + 1e-9:
                ctx.ledger.approximated("cross-section", cid, f"at the same chainage ({chainage:g} m) as another on "
                                        f"branch {branch['id']}; the first one is kept")
                continue
            sections.append(cs)
            ctx.ledger.exact("cross-section", cid)
        branch["cross_sections"] = sections
    empty = [b for b in ctx.case["branches"] if not b["cross_sections"]]
    for b in empty:
        ctx.ledger.refused("branch", b["id"], "no cross-section on the branch")
    ctx.case["branches"] = [b for b in ctx.case["branches"] if b["cross_sections"]]


def unused_definitions(ctx: Context) -> None:
    """Account for the cross-section definitions that no cross-section or structure uses."""
    for did in ctx.definitions:
        if did not in ctx.used_definitions:
            ctx.ledger.refused("profile", did, "not used by any cross-section or structure", hydraulic=False)


def add_profile(ctx: Context, did: str) -> tuple[str | None, float]:
    """The case profile of a definition (added once) and its lowest level (m AD, before shift); None if refused."""
    if did not in ctx.profiles:
        ctx.used_definitions.add(did)
        prof, bottom, note = profile_of(ctx, ctx.definitions[did])
        ctx.profiles[did] = (prof, bottom, note)
        if prof is None:
            ctx.ledger.refused("profile", did, note)
        else:
            ctx.case.setdefault("profiles", []).append(prof)
            (ctx.ledger.approximated if note else ctx.ledger.exact)("profile", did, note)
    prof, bottom, _ = ctx.profiles[did]
    return (prof["id"] if prof is not None else None), bottom


def profile_of(ctx: Context, s: Section) -> tuple[dict | None, float, str]:
    """A case profile of a SOBEK 3 cross-section definition, its lowest level (m AD, before shift), a note.

    The note is empty when the conversion is exact; a ``None`` profile means refused (the note says why).
    """
    did = s.text("id")
    pid = ctx.id("profile", did)
    kind = s.text("type").lower()
    names = s.words("roughnessNames", default=None)
    if kind in ("circle", "egg") and s.has("numLevels"):
        kind = "tabulated"
    if kind == "tabulated":
        return _tabulated(ctx, s, pid, names)
    if s.flag("groundlayerUsed", default=False) and s.number("groundlayer", default=0.0) > 0:
        return None, 0.0, "a ground layer (groundlayerUsed) is not converted"
    if kind == "rectangle":
        width = s.number("width")
        if not width > 0:
            raise s.error("width", f"the width must be positive, got {width:g} m")
        prof: dict = {"id": pid, "type": "rectangular", "width": width}
        if s.flag("closed", default=False):
            prof.update(closed=True, height=s.number("height"))
        elif s.has("height"):
            prof["height"] = s.number("height")
        return _with_friction(prof, names, 1), 0.0, ""
    if kind == "trapezium":
        bottom, top, slope = s.number("bottomWidth"), s.number("maximumFlowWidth"), s.number("slope")
        if not slope > 0 or top < bottom or bottom < 0:
            raise s.error("slope", f"a trapezium needs slope > 0 and maximumFlowWidth ({top:g} m) >= bottomWidth "
                                   f"({bottom:g} m) >= 0, got slope {slope:g}")
        height = (top - bottom) * 0.5 / slope
        if height <= 0:
            prof = {"id": pid, "type": "rectangular", "width": top}
        else:  # SOBEK 3 makes it a table of two levels, with vertical walls above the maximum flow width
            prof = {"id": pid, "type": "zw", "heights": [0.0, height], "flow_widths": [max(bottom, 0.0), top]}
        return _with_friction(prof, names, 1), 0.0, ""
    if kind == "circle":
        diameter = s.number("diameter")
        if not diameter > 0:
            raise s.error("diameter", f"the diameter must be positive, got {diameter:g} m")
        return _with_friction({"id": pid, "type": "circular", "diameter": diameter}, names, 1), 0.0, ""
    if kind == "yz":
        return _yz(s, pid, names)
    return None, 0.0, f"cross-section type {kind!r} has no counterpart in a case"


def _with_friction(prof: dict, names: list[str] | None, sections: int) -> dict:
    ids = (names or SECTION_NAMES)[:sections]
    if len(ids) < sections:
        ids = ids + SECTION_NAMES[len(ids):sections]
    prof["friction"] = ids
    return prof


def _tabulated(ctx: Context, s: Section, pid: str, names: list[str] | None) -> tuple[dict | None, float, str]:
    count = s.integer("numLevels", default=None)
    levels = s.numbers("levels", count=count)
    flow = s.numbers("flowWidths", count=len(levels))
    total = s.numbers("totalWidths", count=len(levels)) if s.has("totalWidths") else list(flow)
    notes = []
    if any(b < a for a, b in itertools.pairwise(levels)):
        raise s.error("levels", "the levels of a tabulated profile must not decrease")
    keep = [0] + [i for i in range(1, len(levels)) if levels[i] > levels[i - 1] + 1e-9]
    if len(keep) < len(levels):
        notes.append(f"{len(levels) - len(keep)} repeated level(s) dropped")
        levels, flow, total = ([v[i] for i in keep] for v in (levels, flow, total))
    for name, widths in (("flowWidths", flow), ("totalWidths", total)):
        if any(w < 0 for w in widths):
            raise s.error(name, "widths must not be negative")
    if any(t < f - 1e-9 for t, f in zip(total, flow, strict=True)):
        notes.append("total widths below the flow widths raised to them")
        total = [max(t, f) for t, f in zip(total, flow, strict=True)]
    if any(b < a for a, b in itertools.pairwise(total)):
        notes.append("total widths that narrow upward held at their largest value below (an open profile's storage "
                     "cannot shrink)")
        total = list(np.maximum.accumulate(total))
    if len(levels) < 2:
        levels, flow, total = [levels[0], levels[0] + 0.01], flow * 2, total * 2
        notes.append("a single level: taken as vertical walls")
    if max(flow) <= 0:
        return None, 0.0, "every flow width is 0: the profile conveys no water"
    if flow[-1] <= 0:
        return None, 0.0, "the flow width at the top is 0: a closed profile, which a tabulated river profile is not"
    if s.flag("groundlayerUsed", default=False) and s.number("groundlayer", default=0.0) > 0:
        return None, 0.0, "a ground layer (groundlayerUsed) is not converted"
    bottom = levels[0]
    prof: dict = {"id": pid, "type": "zw", "heights": [v - bottom for v in levels], "flow_widths": flow}
    if total != flow:
        prof["total_widths"] = total
    sections = _sections(s, flow)
    if len(sections) > 1:
        prof["section_widths"] = sections
    _with_friction(prof, names, len(sections))
    dike, note = _summer_dike(ctx, s, bottom)
    if dike is not None:
        prof["summer_dike"] = dike
    if note:
        notes.append(note)
    return prof, bottom, "; ".join(notes)


def _sections(s: Section, flow: list[float]) -> list[float]:
    """Widths of the main channel and floodplains, as SOBEK 3 makes them consistent with the top flow width.

    SOBEK 3 (flow1d's readTabulatedCS_v100): with ``main``, ``floodPlain1`` and ``floodPlain2`` summing to at least
    the flow width at the top of the table, the main channel is cut to it when wider, else the first floodplain,
    else the second takes the rest. The case's last section is unbounded, so it also covers a wider flow width
    lower in the table.
    """
    top = flow[-1]
    main = s.number("main", default=0.0)
    fp1 = s.number("floodPlain1", default=0.0)
    fp2 = s.number("floodPlain2", default=0.0)
    if top < _NO_WIDTH or main + fp1 + fp2 < top - 1e-3 or (fp1 <= 0 and fp2 > 0):
        if main + fp1 + fp2 > 0 and top >= _NO_WIDTH:
            if main + fp1 + fp2 < top - 1e-3:
                raise s.error("main", f"the sections main + floodPlain1 + floodPlain2 = {main + fp1 + fp2:g} m are "
                                      f"narrower than the flow width at the top, {top:g} m")
            raise s.error("floodPlain2", "a second floodplain needs a first")
        return [max(flow)]
    if main + fp1 + fp2 < top:
        main += 0.001
    if main >= top:
        widths = [top]
    elif main + fp1 >= top:
        widths = [main, top - main]
    else:
        widths = [main, fp1, top - main - fp1]
    if sum(widths) < max(flow):  # a flow width wider lower in the table: the last section takes it
        widths[-1] += max(flow) - sum(widths)
    return widths


def _summer_dike(ctx: Context, s: Section, bottom: float) -> tuple[dict | None, str]:
    if not s.has("sd_crest"):
        return None, ""
    crest = s.number("sd_crest")
    flow = s.number("sd_flowArea", default=0.0)
    total = s.number("sd_totalArea", default=0.0)
    base = s.number("sd_baseLevel", default=crest)
    if flow <= 1e-5 and total <= 1e-5:  # SOBEK 3 takes no summer dike then
        return None, ""
    if flow < 0 or total < 0:
        raise s.error("sd_flowArea" if flow < 0 else "sd_totalArea", "a summer dike's areas must not be negative")
    transition = ctx.model.number("AdvancedOptions", "TransitionHeightSD", default=0.5) or 0.5
    dike, notes = summer_dike(crest=crest, base=base, flow_area=flow, total_area=total, bottom=bottom,
                              transition=transition, kernel="SOBEK 3")
    return dike, "; ".join(notes)


def _yz(s: Section, pid: str, names: list[str] | None) -> tuple[dict | None, float, str]:
    count = s.integer("yzCount", "xyzCount", default=None)
    y = s.numbers("yValues", "yCoordinates", count=count)
    z = s.numbers("zValues", "zCoordinates", count=len(y))
    if any(b < a for a, b in itertools.pairwise(y)):
        return None, 0.0, "y values decrease: not a single-valued profile"
    bottom = min(z)
    prof: dict = {"id": pid, "type": "yz", "y": y, "z": [v - bottom for v in z]}
    n_sections = s.integer("sectionCount", default=1)
    positions = s.numbers("roughnessPositions", "frictionPositions", default=None)
    if positions is not None and n_sections > 1:
        if len(positions) != n_sections + 1:
            raise s.error("roughnessPositions", f"{len(positions)} positions for {n_sections} sections; give "
                                                "sectionCount + 1")
        if abs(positions[0] - y[0]) > 1e-6 or abs(positions[-1] - y[-1]) > 1e-6:
            shift = positions[-1] - y[-1]
            if abs(positions[0]) < 1e-9 and abs(positions[-1] - (y[-1] - y[0])) < 1e-6:
                positions = [p - shift for p in positions]  # given from 0 (an import from SOBEK 2), as flow1d shifts
            else:
                raise s.error("roughnessPositions", f"the sections must run from the first y ({y[0]:g} m) to the "
                                                    f"last ({y[-1]:g} m)")
        prof["friction_positions"] = positions
    else:
        n_sections = 1
    return _with_friction(prof, names, n_sections), bottom, ""


# -- stations ------------------------------------------------------------------------------------------


def _stations(ctx: Context) -> None:
    stations = []
    for s in ctx.model.blocks("obsPointsFile", "observationpoint"):
        oid = s.text("id")
        bid = s.text("branchId", "branchid", default=None)
        if bid is None or not ctx.known("branch", bid) or ctx.id("branch", bid) not in ctx.branches:
            ctx.ledger.refused("observation point", oid, f"not on a branch of the network ({bid!r})", hydraulic=False)
            continue
        branch = ctx.branches[ctx.id("branch", bid)]
        chainage = s.number("chainage")
        if chainage < -1e-6 or chainage > branch["length"] + 1e-3:
            raise s.error("chainage", f"chainage {chainage:g} m lies outside branch {bid!r} (0-{branch['length']:g} m)")
        sid = ctx.id("station", oid)
        stations.append({"id": sid, "branch": branch["id"], "chainage": min(max(chainage, 0.0), branch["length"]),
                         "quantities": ["h", "Q"]})
        ctx.origins[sid] = ("observation point", oid)
        ctx.ledger.exact("observation point", oid)
    ctx.case["stations"] = stations


# -- initial state -------------------------------------------------------------------------------------


def _initial(ctx: Context) -> None:
    level = ctx.model.number("GlobalValues", "InitialWaterLevel", default=None)
    depth = ctx.model.number("GlobalValues", "InitialWaterDepth", default=None)
    spatial = {}
    for key, quantity in (("initialWaterLevelFile", "level"), ("initialWaterDepthFile", "depth")):
        defs = ctx.model.blocks(key, "definition")
        if defs:
            content = next((s for s in ctx.model.blocks(key) if s.kind == "content"), None)
            spatial[quantity] = (defs, content)
    initial: dict = {"depth": max(depth or 0.0, 0.0)}
    if level is not None and "depth" not in spatial:
        initial["level"] = level
    if "level" in spatial:
        _along(ctx, *spatial["level"], "level")
        if "depth" in spatial:
            ctx.ledger.refused("initial field", "InitialWaterDepth", "both an initial level and an initial depth field "
                               "are given; the levels are used", hydraulic=False)
    elif "depth" in spatial:
        _along(ctx, *spatial["depth"], "depth")
    ctx.case["initial"] = initial
    ctx.ledger.exact("setting", "GlobalValues", f"initial level {level if level is not None else 'none'}, depth "
                     f"{depth or 0.0:g} m where no initial field covers a branch")
    for key in ("initialDischargeFile",):
        defs = ctx.model.blocks(key, "definition")
        glob = ctx.model.number("GlobalValues", "InitialDischarge", default=0.0)
        if defs or glob:
            ctx.ledger.approximated("initial field", "InitialDischarge", "the case starts at rest; the flow builds up "
                                    "in the first time steps (SOBEK 3 starts from the given discharge)")


def _along(ctx: Context, defs: list[Section], content: Section | None, quantity: str) -> None:
    interpolate = content.flag("interpolate", default=True) if content is not None else True
    per_branch: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for s in defs:
        bid = s.text("branchId", "branchid")
        if not ctx.known("branch", bid) or ctx.id("branch", bid) not in ctx.branches:
            ctx.ledger.refused("initial field", f"{quantity} on {bid}", "the branch is not in the network",
                               hydraulic=False)
            continue
        per_branch[ctx.id("branch", bid)].append((s.number("chainage"), s.number("value")))
    name = "InitialWaterLevel" if quantity == "level" else "InitialWaterDepth"
    for bid, pairs in per_branch.items():
        branch = ctx.branches[bid]
        pairs = sorted(dict(pairs).items())
        chainages = [c for c, _ in pairs]
        values = [v for _, v in pairs]
        notes = []
        if quantity == "depth":  # at the definitions: the bed there plus the depth
            ch = [c["chainage"] for c in branch["cross_sections"]]
            beds = [c["bed_level"] for c in branch["cross_sections"]]
            values = [float(np.interp(c, ch, beds)) + v for c, v in zip(chainages, values, strict=True)]
            notes.append("initial depths turned into levels at their chainages (linear between them)")
        if not interpolate and len(chainages) > 1:
            steps_c, steps_v = [chainages[0]], [values[0]]
            for c, v in zip(chainages[1:], values[1:], strict=True):
                steps_c += [max(c - 0.001, steps_c[-1] + 1e-6), c]
                steps_v += [steps_v[-1], v]
            chainages, values = steps_c, steps_v
            notes.append("values held between the definitions (interpolate = 0): steps of 1 mm")
        branch["initial_levels"] = {"chainages": [float(c) for c in chainages], "levels": [float(v) for v in values]}
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("initial field", f"{name} on {bid}", "; ".join(notes))


# -- retention areas -------------------------------------------------------------------------------------


def _retention(ctx: Context) -> None:
    nodes = {n["id"]: n for n in ctx.case["nodes"]}
    for s in ctx.model.blocks("retentionFile", "retention"):
        rid = s.text("id")
        nid = s.text("nodeId", default=None)
        if nid is None or not ctx.known("node", nid) or ctx.id("node", nid) not in nodes:
            ctx.ledger.refused("retention", rid, "a retention area on a branch (not on a connection node) is not "
                               "converted: a case stores water at nodes only")
            continue
        if s.has("levels"):
            count = s.integer("numLevels", default=None)
            levels = s.numbers("levels", count=count)
            areas = s.numbers("storageArea", "areas", count=len(levels))
        else:
            bed = s.number("bedLevel")
            area = s.number("area", "storageArea")
            levels, areas = [bed, bed + 1.0], [area, area]
        if len(levels) < 2:
            levels, areas = [levels[0], levels[0] + 1.0], [areas[0], areas[0]]
        if any(b <= a for a, b in itertools.pairwise(levels)):
            raise s.error("levels", "retention levels must increase strictly")
        notes = []
        if any(b < a for a, b in itertools.pairwise(areas)) or min(areas) < 0:
            notes.append("areas that shrink upward held at their largest value below")
            areas = list(np.maximum.accumulate(np.maximum(areas, 0.0)))
        if not math.isfinite(areas[-1]) or areas[-1] <= 0:
            ctx.ledger.refused("retention", rid, "its storage area is 0 at every level", hydraulic=False)
            continue
        node = nodes[ctx.id("node", nid)]
        node["storage_table"] = {"levels": [float(v) for v in levels], "areas": [float(v) for v in areas]}
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("retention", rid, "; ".join(notes))
