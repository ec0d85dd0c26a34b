"""The network of a SOBEK 3 model as case tables: nodes, branches, profiles, friction, stations, initial levels.

SOBEK 3 → case:

- ``NetworkDefinition.ini`` ``[Node]`` → ``[[nodes]]``; ``[Branch]`` → ``[[branches]]`` with its geometry, its
  grid points as the case's calculation points (``points``) and its ``order``;
- ``CrossSectionDefinitions.ini`` → ``[[profiles]]``, ``CrossSectionLocations.ini`` →
  ``branches[].cross_sections`` (``_profiles``);
- ``roughness-*.ini`` → ``[[friction_groups]]`` (``_friction``);
- ``ObservationPoints.ini`` → ``[[stations]]`` (level and discharge);
- ``InitialWaterLevel.ini`` → ``branches[].initial_levels``; the md1d's global initial level and depth →
  ``[initial]``;
- retention areas on connection nodes → ``nodes[].storage_table``.

:func:`convert_network` runs these in turn; the nodes, branches, stations, initial state and retention areas are
converted here.
"""

from __future__ import annotations

import itertools
import math
import re
from collections import defaultdict

import numpy as np

from rivercal.errors import CaseError
from rivercal.io.sobek3._context import Context
from rivercal.io.sobek3._friction import LAWS, _friction_groups, convert_value, law_of
from rivercal.io.sobek3._ini import Section
from rivercal.io.sobek3._profiles import _cross_sections, profile_of, unused_definitions

__all__ = ["LAWS", "convert_network", "convert_value", "law_of", "profile_of", "unused_definitions"]


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
    ctx.reserve("node", [s for s in blocks if s.kind == "node"], "id")
    ctx.reserve("branch", [s for s in blocks if s.kind == "branch"], "id")
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


# -- stations ------------------------------------------------------------------------------------------


def _stations(ctx: Context) -> None:
    stations = []
    ctx.reserve("station", ctx.model.blocks("obsPointsFile", "observationpoint"), "id")
    for s in ctx.model.blocks("obsPointsFile", "observationpoint"):
        oid = ctx.claim("observation point", s)
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
        rid = ctx.claim("retention", s)
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
