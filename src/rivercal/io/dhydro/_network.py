"""The network of a D-Flow FM model as case tables: nodes, branches, profiles, friction, stations, initial state.

D-Flow FM → case:

- network nodes → ``[[nodes]]`` (with storage from the storage-node file);
- network branches → ``[[branches]]`` with the chainages of the net file's branch length, the geometry,
  and D-Flow FM's calculation points (``points``), so that the case's grid is D-Flow FM's;
- cross-section definitions → ``[[profiles]]`` (yz, zw, zwRiver, circle, rectangle), cross-section
  locations → ``branches[].cross_sections`` with bed level = the definition's lowest level + shift;
- roughness files → ``[[friction_groups]]`` (global value, branch values), referred to by the profiles;
- observation points and cross-sections → ``[[stations]]``;
- initial water depth or level → ``[initial]``.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from rivercal.errors import CaseError
from rivercal.io._summer_dike import summer_dike
from rivercal.io.dhydro._context import Context, unquote
from rivercal.io.dhydro._friction import FRICTION_TYPES, MAIN, branch_friction_entries, friction_groups, friction_of
from rivercal.io.dhydro._source import is_file

__all__ = ["FRICTION_TYPES", "MAIN", "convert_network", "friction_of", "profile_of_definition"]

#: Farthest a location given by x, y may lie from a branch to be snapped onto it, m.
SNAP_DISTANCE = 100.0
#: A zw table whose top width is narrower than this is a closed conduit, m.
CLOSED_WIDTH = 1.0e-3
#: D-Flow FM's transition height of a summer dike (``summerDikeTransitionHeight``), m.
SUMMER_DIKE_TRANSITION = 0.5


def convert_network(ctx: Context) -> None:
    """Fill ``ctx.case`` with friction groups, profiles, nodes, branches, stations and the initial state."""
    friction_groups(ctx)
    _nodes_and_branches(ctx)
    _storage_nodes(ctx)
    _stations(ctx)
    _initial(ctx)


# -- profiles ----------------------------------------------------------------------------------------


def _section_friction(ctx: Context, d: Any, sections: int) -> tuple[list[str] | None, str]:
    """Friction group ids of a definition's sections (inline friction becomes a group of its own)."""
    ids = getattr(d, "frictionids", None)
    if ids is None and getattr(d, "frictionid", None):
        ids = [d.frictionid]
    groups = {g["id"] for g in ctx.case["friction_groups"]}
    inline = getattr(d, "frictiontypes", None) or getattr(d, "frictiontype", None)
    note = ""
    if not ids and not inline and type(d).__name__ == "ZWRiverCrsDef" and sections > 1:
        # zwRiver without friction ids: D-Flow FM's defaults (hydrolib-core, ZWRiverCrsDef.frictionids)
        defaults = ["Main", "FloodPlain1", "FloodPlain2"][:sections]
        absent = [i for i in defaults[1:] if ctx.id("friction group", i) not in groups]
        ids = [i if i not in absent else MAIN for i in defaults]
        if absent:
            note = f"no friction ids and no roughness for {', '.join(absent)}: the floodplain(s) take Main"
    if not ids and not inline and ctx.main_group:
        return [MAIN] * sections, ""  # D-Flow FM's default group, kept as a group
    if ids:
        ids = [unquote(i) for i in ids]
        out = [ctx.id("friction group", i) for i in ids]
        if all(i == MAIN for i in out) and MAIN in groups:
            if ctx.main_group:
                return [MAIN] * sections, note
            return None, note  # the case's global and branch friction
        missing = [i for i, o in zip(ids, out, strict=True) if o not in groups]
        if missing:
            return None, f"friction group(s) {', '.join(missing)} not defined; the profile takes the global friction"
        if len(out) > sections:  # ids of sections of zero width (an absent floodplain)
            out = out[:sections]
        elif len(out) < sections:
            return [out[0]] * sections, (f"{len(out)} friction ids for {sections} sections; all sections take "
                                         f"{out[0]}")
        return out, note
    types = getattr(d, "frictiontypes", None) or ([d.frictiontype] if getattr(d, "frictiontype", None) else None)
    values = getattr(d, "frictionvalues", None) or ([d.frictionvalue] if getattr(d, "frictionvalue", None) else None)
    if types and values:
        out = []
        for k, (t, v) in enumerate(zip(types, values, strict=False)):
            fr, note = friction_of(t, v)
            if fr is None:
                return None, note
            gid = ctx.id("friction group", f"{unquote(d.id)}_friction{k + 1}" if len(types) > 1
                         else f"{unquote(d.id)}_friction")
            if gid not in groups:
                ctx.case["friction_groups"].append({"id": gid, **fr})
                groups.add(gid)
            out.append(gid)
        if len(out) != sections:
            out = [out[0]] * sections
        return out, ""
    return None, ""  # no friction id: D-Flow FM's default group Main, the case's global and branch friction


def profile_of_definition(ctx: Context, d: Any, *, for_structure: bool = False) -> tuple[dict | None, float, str]:
    """A case profile for a cross-section definition, the level of its lowest point (m AD, before shift), a note.

    The note is empty when the conversion is exact; a ``None`` profile means refused (the note says why).
    """
    kind = type(d).__name__
    pid = ctx.id("profile", d.id)
    notes: list[str] = []
    if kind == "CircleCrsDef":
        prof: dict = {"id": pid, "type": "circular", "diameter": float(d.diameter)}
        bottom = 0.0
        sections = 1
    elif kind == "RectangleCrsDef":
        prof = {"id": pid, "type": "rectangular", "width": float(d.width), "height": float(d.height)}
        if d.closed:
            prof["closed"] = True
        bottom = 0.0
        sections = 1
    elif kind in ("ZWCrsDef", "ZWRiverCrsDef"):
        levels = [float(v) for v in d.levels]
        flow = [float(v) for v in d.flowwidths]
        total = [float(v) for v in d.totalwidths] if d.totalwidths else None
        where = ctx.model.sources.where
        key = ctx.model.sources.key_of
        if not levels or len(flow) != len(levels) or (total is not None and len(total) != len(levels)):
            return None, 0.0, (f"{where(d, key(d, 'levels'))}: {len(levels)} levels, {len(flow)} flow widths"
                               + (f", {len(total)} total widths" if total is not None else "")
                               + ": one width of each per level")
        if any(b < a for a, b in itertools.pairwise(levels)):
            k = next(i for i in range(1, len(levels)) if levels[i] < levels[i - 1])
            ctx.ledger.error(where(d, key(d, "levels")), f"definition {unquote(d.id)!r}, {key(d, 'levels')}: "
                             f"{levels[k - 1]:g} is followed by the lower {levels[k]:g}; the levels of a zw table rise "
                             "from the bottom up")
            return None, 0.0, "levels that do not rise (see the errors)"
        keep = [0] + [i for i in range(1, len(levels)) if levels[i] > levels[i - 1]]
        if len(keep) < len(levels):
            notes.append(f"{len(levels) - len(keep)} repeated level(s) dropped")
        levels = [levels[i] for i in keep]
        flow = [flow[i] for i in keep]
        total = [total[i] for i in keep] if total else None
        if total is not None:
            short = [k for k, (t, f) in enumerate(zip(total, flow, strict=True)) if t < f - max(1e-3, 1e-6 * f)]
            if short:
                k = short[0]
                ctx.ledger.error(where(d, key(d, "totalwidths")),
                                 f"definition {unquote(d.id)!r}, {key(d, 'totalwidths')}: at level {levels[k]:g} m "
                                 f"the total width {total[k]:g} m is below the flow width {flow[k]:g} m (the total "
                                 "width holds the flow width and the storage beside it)")
                return None, 0.0, "total widths below the flow widths (see the errors)"
            if any(t < f for t, f in zip(total, flow, strict=True)):
                notes.append("total widths less than 1 mm below the flow widths (rounding) raised to them")
            total = [max(t, f) for t, f in zip(total, flow, strict=True)]
        # closed when no width is left at the top (D-Flow FM: a top total width no wider than its Preissmann slot,
        # readTabulatedCS); an open table may narrow: the flow width stops conveying and only stores
        closed = (total if total is not None else flow)[-1] < CLOSED_WIDTH
        if not closed:
            if total is None and any(b < a for a, b in itertools.pairwise(flow)):
                total = list(flow)
            if total is not None and any(b < a for a, b in itertools.pairwise(total)):
                k = next(i for i in range(1, len(total)) if total[i] < total[i - 1])
                notes.append(f"the total (storage) width narrows above level {levels[k - 1]:g} m ({total[k - 1]:g} m "
                             f"to {total[k]:g} m): the case keeps the widest width below as storage (an open profile's "
                             "storage cannot narrow), so it stores a little more water above that level")
                total = [float(v) for v in np.maximum.accumulate(total)]
            if flow[-1] <= 0:
                notes.append("the flow width closes at the top of an open table: the top keeps 1 mm of flow width")
                flow[-1] = CLOSED_WIDTH
                total = total if total is not None else [*flow[:-1], CLOSED_WIDTH]
        if len(levels) < 2:
            levels = [levels[0], levels[0] + 0.01]
            flow, total = flow * 2, (total * 2 if total else None)
            notes.append("a single level: taken as vertical walls")
        bottom = levels[0]
        prof = {"id": pid, "type": "zw", "heights": [lv - bottom for lv in levels], "flow_widths": flow}
        if total is not None and total != flow:
            prof["total_widths"] = total
        if closed:
            prof["closed"] = True
        sections = 1
        if kind == "ZWRiverCrsDef":
            widths = [float(w or 0.0) for w in (d.mainwidth, d.fp1width, d.fp2width)]
            if widths[0] <= 0:
                widths[0] = max(flow)
            while len(widths) > 1 and widths[-1] <= 0:
                widths.pop()
            if len(widths) > 1 or sum(widths) < max(flow):
                widths[-1] += max(0.0, max(flow) - sum(widths))
                prof["section_widths"] = widths
                sections = len(widths)
            dike, note = _summer_dike(ctx, d, bottom)
            if dike is not None and not closed:
                prof["summer_dike"] = dike
            if note:
                notes.append(note)
    elif kind in ("YZCrsDef", "XYZCrsDef"):
        y = [float(v) for v in d.ycoordinates] if kind == "YZCrsDef" else _along(d)
        z = [float(v) for v in d.zcoordinates]
        if any(b < a for a, b in itertools.pairwise(y)):
            if kind == "YZCrsDef":
                return None, 0.0, "y coordinates decrease: not a single-valued profile"
        bottom = min(z)
        prof = {"id": pid, "type": "yz", "y": y, "z": [v - bottom for v in z]}
        conveyance = str(getattr(d, "conveyance", "segmented") or "segmented").lower()
        if conveyance in ("lumped", "segmented"):
            prof["conveyance"] = conveyance
        else:
            notes.append(f"conveyance {conveyance!r} taken as segmented")
        positions = getattr(d, "frictionpositions", None)
        sections = 1
        if positions and len(positions) > 2:
            pos = [float(p) for p in positions]
            pos[0], pos[-1] = y[0], y[-1]
            pos = [p for k, p in enumerate(pos) if k in (0, len(pos) - 1) or y[0] < p < y[-1]]
            prof["friction_positions"] = pos
            sections = len(pos) - 1
        if kind == "XYZCrsDef":
            notes.append("xyz profile taken as a yz profile along its survey line")
    else:
        return None, 0.0, f"cross-section type {getattr(d, 'type', kind)!r} is not known"
    friction, note = _section_friction(ctx, d, sections)
    if friction is not None and not for_structure:
        prof["friction"] = friction
    if note:
        notes.append(note)
    return prof, bottom, "; ".join(notes)


def _summer_dike(ctx: Context, d: Any, bottom: float) -> tuple[dict | None, str]:
    """A zwRiver definition's levee as a case summer dike (heights above the table's lowest level), and a note.

    D-Flow FM takes a summer dike when the definition gives all four of ``leveeCrestLevel``, ``leveeBaseLevel``,
    ``leveeFlowArea`` and ``leveeTotalArea`` and one of the areas exceeds 1e-5 m² (Deltares delft3d, flow1d
    ``readTabulatedCS``). Its flow and total areas fill from the crest over a transition height of 0.5 m along two
    parabolas (``GetSummerDikeFlow``, ``GetSummerDikeTotal``: ``summerDikeTransitionHeight`` is 0.5 m in D-Flow FM),
    as the case's summer dike does. Once the level has reached crest + 0.5 m, D-Flow FM empties the storage behind
    the dike on a falling limb down to the base level, as the case does with its ``base``.
    """
    # read from the file as written: hydrolib-core 1.5 misses two of the four keys (its fields leveecrestLevel and
    # leveetotalrea match neither leveeCrestLevel nor leveeTotalArea)
    keys = {"leveecrestLevel": "leveeCrestLevel", "leveebaselevel": "leveeBaseLevel", "leveeflowarea": "leveeFlowArea",
            "leveetotalrea": "leveeTotalArea"}
    found = ctx.model.sources.section_of(d)
    given: dict[str, float] = {}
    for name, key in keys.items():
        raw = found[1].first(key) if found is not None else None
        text = raw.value if raw is not None else getattr(d, name, None)
        if text is None or str(text).strip() == "":
            continue
        numbers = _numbers(str(text))
        if len(numbers) != 1 or not np.isfinite(numbers[0]) or abs(numbers[0]) > 1e4 or (
                name in ("leveeflowarea", "leveetotalrea") and numbers[0] < 0):
            where = f"{ctx.model.sources.rel(found[0])}, line {raw.line}" if found is not None and raw is not None \
                else ctx.model.mdu.name
            ctx.ledger.error(where, f"definition {unquote(d.id)!r}, {key} = {text}: not a finite number of a "
                             "plausible size (areas not negative)")
            return None, "an unusable levee value (see the errors)"
        given[name] = numbers[0]
    if len(given) < 4:
        if given:
            return None, (f"levee keys incomplete ({', '.join(sorted(given))} given): D-Flow FM takes no summer dike "
                          "without all four of leveeCrestLevel, leveeBaseLevel, leveeFlowArea, leveeTotalArea, and "
                          "neither does the case")
        return None, ""
    crest, base = given["leveecrestLevel"], given["leveebaselevel"]
    flow, total = given["leveeflowarea"], given["leveetotalrea"]
    if not (flow > 1e-5 or total > 1e-5):
        return None, ""
    dike, notes = summer_dike(crest=crest, base=base, flow_area=flow, total_area=total, bottom=bottom,
                              transition=SUMMER_DIKE_TRANSITION, kernel="D-Flow FM")
    return dike, "; ".join(notes)


def _along(d: Any) -> list[float]:
    x = np.asarray(d.xcoordinates, dtype=float)
    y = np.asarray(d.ycoordinates, dtype=float)
    return [0.0, *np.cumsum(np.hypot(np.diff(x), np.diff(y))).tolist()]


def add_profile(ctx: Context, definition_id: str, *, for_structure: bool = False) -> tuple[str | None, float]:
    """Convert a definition once (by id) into ``ctx.case['profiles']``; its profile id and lowest level (m AD)."""
    key = unquote(definition_id)
    ctx.used_definitions.add(key)
    cache = ctx.__dict__.setdefault("_profiles", {})
    if key in cache:
        return cache[key]
    d = next((x for x in ctx.model.crossdefs.objects if unquote(x.id) == key), None)
    if d is None:
        failed = next((r for _, i, r in ctx.model.crossdefs.failed if unquote(i) == key), None)
        cache[key] = (None, 0.0)
        ctx.ledger.refused("profile", key, f"definition not readable: {failed}" if failed else "no such definition")
        return cache[key]
    prof, bottom, note = profile_of_definition(ctx, d, for_structure=for_structure)
    if prof is None:
        ctx.ledger.refused("profile", key, note)
        cache[key] = (None, 0.0)
        return cache[key]
    ctx.case.setdefault("profiles", []).append(prof)
    ctx.source("profiles", prof["id"], d)
    (ctx.ledger.approximated if note else ctx.ledger.exact)("profile", key, note)
    cache[key] = (prof["id"], bottom)
    return cache[key]


# -- nodes and branches ------------------------------------------------------------------------------


def _network_arrays(ctx: Context) -> dict[str, Any]:
    """The 1D network of the net file as plain arrays, checked; an error naming the net file when damaged.

    hydrolib-core reads a damaged or truncated NetCDF file partly, with masked or missing values; the
    numbers are checked here so that nothing downstream meets a hole.
    """
    net = ctx.model.net_path
    try:
        m1 = ctx.model.network._mesh1d
        arrays = {
            "node_ids": [str(v) for v in m1.network1d_node_id],
            "node_x": np.ma.filled(np.ma.asarray(m1.network1d_node_x, dtype=float), np.nan),
            "node_y": np.ma.filled(np.ma.asarray(m1.network1d_node_y, dtype=float), np.nan),
            "edges": np.ma.filled(np.ma.asarray(m1.network1d_edge_nodes), -1).astype(np.int64),
            "branch_ids": [str(v) for v in m1.network1d_branch_id],
            "lengths": np.ma.filled(np.ma.asarray(m1.network1d_branch_length, dtype=float), np.nan),
            "on_branch": np.ma.filled(np.ma.asarray(m1.mesh1d_node_branch_id), -1).astype(np.int64),
            "offsets": np.ma.filled(np.ma.asarray(m1.mesh1d_node_branch_offset, dtype=float), np.nan),
            "geometry": {str(k): np.asarray(v.geometry, dtype=float) for k, v in (m1.branches or {}).items()},
            "orders": np.ma.filled(np.ma.asarray(getattr(m1, "network1d_branch_order", np.empty(0))), -1)
            .astype(np.int64).ravel(),
        }
    except (AttributeError, TypeError, ValueError, KeyError, IndexError) as exc:
        raise CaseError(f"the network file is damaged or not a UGRID 1D network ({type(exc).__name__}: "
                        f"{' '.join(str(exc).split())[:200]})", file=str(net)) from None
    n_nodes, n_branches = len(arrays["node_ids"]), len(arrays["branch_ids"])
    problems = []
    if n_branches == 0:
        problems.append("it has no 1D branches")
    if arrays["edges"].shape != (n_branches, 2) or (arrays["edges"].size and (
            arrays["edges"].min() < 0 or arrays["edges"].max() >= n_nodes)):
        problems.append("its branches do not connect nodes of the network (network1d_edge_nodes)")
    if arrays["lengths"].shape != (n_branches,) or not np.all(np.isfinite(arrays["lengths"])) or np.any(
            arrays["lengths"] <= 0) or np.any(arrays["lengths"] > 1e7):
        problems.append("branch lengths that are missing, not positive or beyond 10,000 km (network1d_branch_length)")
    if arrays["node_x"].shape != (n_nodes,) or arrays["node_y"].shape != (n_nodes,) or not (
            np.all(np.isfinite(arrays["node_x"])) and np.all(np.isfinite(arrays["node_y"]))):
        problems.append("node coordinates that are missing or not finite (network1d_node_x/y)")
    if arrays["on_branch"].shape != arrays["offsets"].shape or (arrays["on_branch"].size and (
            arrays["on_branch"].min() < 0 or arrays["on_branch"].max() >= n_branches)) or not np.all(
            np.isfinite(arrays["offsets"])):
        problems.append("calculation points on branches that do not exist or at offsets that are not finite "
                        "(mesh1d_node_branch_id/offset)")
    if arrays["orders"].size not in (0, n_branches):
        problems.append("branch orders that are not one per branch (network1d_branch_order)")
    if any(not np.all(np.isfinite(g)) for g in arrays["geometry"].values()):
        problems.append("branch geometry with coordinates that are not finite")
    if len(set(arrays["node_ids"])) < n_nodes or len(set(arrays["branch_ids"])) < n_branches:
        problems.append("ids given to more than one node or branch")
    if problems:
        raise CaseError(f"the network file is damaged or inconsistent: {'; '.join(problems)}", file=str(net))
    return arrays


def _nodes_and_branches(ctx: Context) -> None:
    arrays = _network_arrays(ctx)
    net_where = ctx.model.sources.rel(ctx.model.net_path)
    node_ids = arrays["node_ids"]
    xs, ys = arrays["node_x"], arrays["node_y"]
    nodes = []
    for k, nid in enumerate(node_ids):
        nodes.append({"id": ctx.id("node", nid), "x": float(xs[k]), "y": float(ys[k])})
        ctx.source("nodes", nodes[-1]["id"], net_where)
        ctx.ledger.exact("node", unquote(nid))
    ctx.case["nodes"] = nodes
    locations: dict[str, list[Any]] = defaultdict(list)
    for loc in ctx.model.crosslocs.objects:
        if loc.branchid is None:
            ctx.ledger.refused("cross-section", unquote(loc.id), "located by x, y, not on a branch (a 2D or "
                               "unassigned cross-section)")
            continue
        locations[unquote(loc.branchid)].append(loc)
    known_branches = {unquote(b) for b in arrays["branch_ids"]}
    for name, locs in locations.items():
        if name not in known_branches:
            for loc in locs:
                ctx.ledger.refused("cross-section", unquote(loc.id), f"its branch {name!r} is not in the network")
    for _, cid, reason in ctx.model.crosslocs.failed:
        ctx.ledger.refused("cross-section", cid, reason)
    branches = []
    pending: list[tuple[dict, str, list[str]]] = []
    position: dict[str, int] = {}
    edges = arrays["edges"]
    on_branch = arrays["on_branch"]
    offsets = arrays["offsets"]
    lengths = arrays["lengths"]
    geometries = arrays["geometry"]
    orders = _case_orders(arrays["orders"], len(arrays["branch_ids"]))
    for k, raw in enumerate(arrays["branch_ids"]):
        name = unquote(raw)
        bid = ctx.id("branch", name)
        a, b = (node_ids[int(i)] for i in edges[k])
        length = float(lengths[k])
        geo = geometries.get(str(raw))
        points = np.unique(np.concatenate([[0.0, length], offsets[on_branch == k]]))
        points = points[(points >= 0.0) & (points <= length + 1e-3)]
        if points.size >= 2 and abs(points[0]) < 1e-6 and abs(points[-1] - length) < 1e-3 * max(1.0, length):
            points = np.concatenate([[0.0], points[1:-1], [length]])
        close = np.concatenate([[False], np.diff(points) < 1e-3])
        if close[-1]:  # keep the end point, drop the one before it
            close[-1], close[-2] = False, points.size > 2
        if close.any():
            ctx.ledger.warn(f"branch {name}: {int(close.sum())} calculation point(s) within 1 mm of the one before "
                            "dropped")
            points = points[~close]
            if points.size < 2:
                points = np.array([0.0, length])
        dx = float(np.max(np.diff(points))) if points.size > 1 else length
        branch: dict = {"id": bid, "from_node": ctx.id("node", a), "to_node": ctx.id("node", b), "length": length}
        if orders[k] is not None:
            branch["order"] = orders[k]
        if points.size >= 2 and abs(points[0]) < 1e-6 and abs(points[-1] - length) < 1e-3 * max(1.0, length):
            points[0], points[-1] = 0.0, length
            branch["points"] = [float(p) for p in points]
        else:
            branch["dx"] = max(dx, 0.1)
            ctx.ledger.warn(f"branch {name}: its calculation points do not run from 0 to its length; the case lays "
                            f"out its own at most {dx:g} m apart")
        if geo is not None and geo.ndim == 2 and geo.shape[1] == 2 and len(geo) >= 2:
            branch["geometry"] = [[float(x), float(y)] for x, y in geo]
        ctx.source("branches", bid, net_where)
        sections, notes = _cross_sections(ctx, name, locations.get(name, []), length)
        position[bid] = k
        if not sections:
            pending.append((branch, name, notes))
            continue
        branch["cross_sections"] = sections
        ctx.branch_nodes[bid] = (branch["from_node"], branch["to_node"])
        ctx.branch_length[bid] = length
        ctx.__dict__.setdefault("_points", {})[bid] = points
        branches.append(branch)
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("branch", name, "; ".join(notes))
    across = _sections_across_nodes(ctx, branches, [b for b, _, _ in pending], position)
    for branch, name, notes in pending:
        found = across.get(branch["id"])
        if found is not None:
            branch["cross_sections"], note = found
            notes = [*notes, note] if note else notes
            if notes:
                ctx.ledger.approximated("branch", name, "; ".join(notes))
            else:
                ctx.ledger.exact("branch", name, "no cross-section of its own: it takes those D-Flow FM continues into "
                                 "it from the branches of its order")
        else:
            section = _borrowed_section(branches, branch)
            if section is None:
                ctx.ledger.refused("branch", name, "no cross-section on the branch or on a branch next to it")
                continue
            branch["cross_sections"] = [section]
            notes.append(f"no cross-section (a branch that carries a structure): it borrows profile "
                         f"{section['profile']!r} at bed {section['bed_level']:g} m AD from the end of a branch next "
                         "to it; it holds only the little storage of its own length")
            ctx.ledger.approximated("branch", name, "; ".join(notes))
        ctx.branch_nodes[branch["id"]] = (branch["from_node"], branch["to_node"])
        ctx.branch_length[branch["id"]] = branch["length"]
        branches.append(branch)
    ordered = [b for b in branches if "order" in b]
    if ordered:
        branches.sort(key=lambda b: position[b["id"]])  # the net file's order: D-Flow FM looks for orders in it
        ctx.ledger.exact("setting", "branchOrder", f"{len(ordered)} branch(es) in {len({b['order'] for b in ordered})} "
                         "order(s): their cross-sections are interpolated across the connection nodes between branches "
                         "of one order, as D-Flow FM does (branches[].order)")
    ctx.case["branches"] = branches
    branch_friction_entries(ctx)
    referenced = {g for prof in ctx.case.get("profiles", []) for g in prof.get("friction", [])}
    ctx.case["friction_groups"] = [g for g in ctx.case["friction_groups"] if g["id"] != MAIN or MAIN in referenced]
    used = {n for b in branches for n in (b["from_node"], b["to_node"])}
    ctx.case["nodes"] = [n for n in nodes if n["id"] in used]


def _case_orders(raw: np.ndarray, n: int) -> list[int | None]:
    """The case's order of each branch from D-Flow FM's ``branchOrder`` (``network1d_branch_order``).

    D-Flow FM interpolates cross-sections across a connection node between branches of one order, every order but
    -1, the order of a branch that takes part in none (Deltares delft3d, flow1d ``useBranchOrdersCrs``: the
    cross-sections are sorted by order and every group after the first, that of -1, is continued across nodes).
    The case does so for positive orders, so an order of 0 or below -1 becomes a positive order that no other
    branch has.
    """
    if raw.size != n:
        return [None] * n
    values = [int(v) for v in raw]
    spare = max([v for v in values if v > 0], default=0) + 1
    mapped: dict[int, int] = {}
    out: list[int | None] = []
    for v in values:
        if v == -1:
            out.append(None)
        elif v > 0:
            out.append(v)
        else:
            if v not in mapped:
                mapped[v] = spare
                spare += 1
            out.append(mapped[v])
    return out


def _sections_across_nodes(ctx: Context, branches: list[dict], pending: list[dict],
                           position: dict[str, int]) -> dict[str, tuple[list[dict], str]]:
    """Cross-sections for branches of an order that have none: those D-Flow FM continues into them across nodes.

    D-Flow FM copies the first and last cross-section of a branch of an order onto the next branch of that order
    at the node, at the chainage seen from there, and a branch without cross-sections of its own passes it on
    (:func:`rivercal.engine.channels.extended_cross_sections`). Such a branch is given cross-sections at its two
    ends, interpolated (bed level) between the copies that reach it: the same bed levels along it and along its
    neighbours, and the same shapes when the copies have one profile (else the profile of the nearer copy at each
    end, approximated).
    """
    from types import SimpleNamespace

    from rivercal.engine.channels import extended_cross_sections

    wanted = [b for b in pending if "order" in b]
    if not wanted:
        return {}
    ids = [p["id"] for p in ctx.case.get("profiles", [])]
    everything = sorted([*branches, *wanted], key=lambda b: position[b["id"]])
    network = SimpleNamespace(
        profiles=[SimpleNamespace(id=i) for i in ids],
        branches=[SimpleNamespace(id=b["id"], from_node=b["from_node"], to_node=b["to_node"], length=b["length"],
                                  order=b.get("order"),
                                  cross_sections=[SimpleNamespace(**cs) for cs in b.get("cross_sections", [])])
                  for b in everything])
    extended = extended_cross_sections(network)
    out = {}
    for b in wanted:
        copies = extended.get(b["id"], [])
        if not copies:
            continue
        ch = np.array([c[0] for c in copies])
        beds = np.array([c[2] for c in copies])
        ends = [0.0, b["length"]] if b["length"] > 0 else [0.0]
        sections = []
        for end in ends:
            nearest = copies[int(np.argmin(np.abs(ch - end)))]
            sections.append({"chainage": end, "profile": ids[nearest[1]], "bed_level": float(np.interp(end, ch, beds))})
        if len(sections) == 2 and sections[0]["profile"] == sections[1]["profile"] and \
                abs(sections[0]["bed_level"] - sections[1]["bed_level"]) < 1e-12:
            sections = sections[:1]
        shapes = {c[1] for c in copies}
        note = ("" if len(shapes) == 1 else "no cross-section of its own; D-Flow FM interpolates the shapes of the "
                f"cross-sections of its order across it ({', '.join(sorted(ids[s] for s in shapes))}): the case "
                "gives each end the shape of the nearer one, with the bed levels interpolated")
        out[b["id"]] = (sections, note)
    return out


def _borrowed_section(branches: list[dict], branch: dict) -> dict | None:
    """The lowest end cross-section of the branches that share a node with ``branch``."""
    found = []
    for b in branches:
        for end, cs in ((b["from_node"], b["cross_sections"][0]), (b["to_node"], b["cross_sections"][-1])):
            if end in (branch["from_node"], branch["to_node"]):
                found.append(cs)
    if not found:
        return None
    low = min(found, key=lambda c: c["bed_level"])
    return {"chainage": 0.0, "profile": low["profile"], "bed_level": low["bed_level"]}


def _cross_sections(ctx: Context, branch: str, locations: list[Any], length: float) -> tuple[list[dict], list[str]]:
    out: list[dict] = []
    notes: list[str] = []
    for loc in sorted(locations, key=lambda c: float(c.chainage)):
        pid, bottom = add_profile(ctx, loc.definitionid)
        if pid is None:
            ctx.ledger.refused("cross-section", unquote(loc.id), f"its definition {unquote(loc.definitionid)!r} "
                               "was refused")
            continue
        chainage = float(loc.chainage)
        if chainage > length + max(1.0, 0.01 * length):
            ctx.ledger.error(ctx.model.sources.where(loc, ctx.model.sources.key_of(loc, "chainage")),
                             f"cross-section {unquote(loc.id)!r}: chainage {chainage:g} m lies beyond the end of "
                             f"branch {branch} ({length:g} m long)")
            continue
        if chainage > length:
            if chainage - length > 1e-3:
                notes.append(f"cross-section {unquote(loc.id)} at {chainage:g} m beyond the branch end ({length:g} m) "
                             "moved to the end")
            chainage = length
        if out and chainage <= out[-1]["chainage"]:
            ctx.ledger.approximated("cross-section", unquote(loc.id),
                                    f"at the same chainage ({chainage:g} m) as another on branch {branch}; the first "
                                    "one is kept")
            continue
        out.append({"chainage": chainage, "profile": pid, "bed_level": bottom + float(loc.shift or 0.0)})
        ctx.ledger.exact("cross-section", unquote(loc.id))
    return out, notes


# -- storage nodes ---------------------------------------------------------------------------------------


def _storage_nodes(ctx: Context) -> None:
    blocks = ctx.model.storage_nodes
    if blocks is None:
        return
    general = ctx.model.sources.ini(blocks.path).of("General")
    flag = general[0].value("useStreetStorage") if general else None
    general_street = str(flag).strip().lower() not in ("0", "false", "no") if flag is not None else True
    for _, sid, reason in blocks.failed:
        ctx.ledger.refused("storage node", sid, reason)
    nodes = {n["id"]: n for n in ctx.case["nodes"]}
    for s in blocks.objects:
        sid = unquote(s.id)
        target = s.nodeid or s.manholeid
        node = nodes.get(ctx.id("node", target)) if target and ctx.ids["node"].known(target) else None
        if node is None:
            ctx.ledger.refused("storage node", sid, f"its node {target!r} is not a connection node of the network")
            continue
        notes = []
        if s.usetable:
            levels = [float(v) for v in s.levels]
            areas = [float(v) for v in s.storagearea]
            if str(getattr(s.interpolate, "value", s.interpolate)).lower() == "block":
                levels, areas = _block_to_linear(levels, areas)
                notes.append("block-wise table taken as linear with 1 mm transitions")
        else:
            bed, area = float(s.bedlevel), float(s.area)
            street = float(s.streetlevel) if s.streetlevel is not None else None
            street_area = float(s.streetstoragearea or 0.0)
            storage = str(getattr(s.storagetype, "value", s.storagetype) or "reservoir").lower()
            levels, areas = [bed], [area]
            if street is not None and street > bed:
                levels.append(street)
                areas.append(area)
                if storage == "reservoir" and general_street and street_area > area:
                    levels.append(street + 0.001)
                    areas.append(street_area)
                    notes.append("the jump of the storage area at the street level is spread over 1 mm")
                elif storage == "closed":
                    notes.append("closed manhole: above the street level the case keeps the manhole's area "
                                 "(D-Flow FM: none, the manhole pressurises)")
                elif street_area < area:
                    notes.append("street storage smaller than the manhole: the manhole's area is kept above the street")
        if len(levels) < 2:
            levels, areas = [levels[0], levels[0] + 1.0], [areas[0], areas[0]]
        areas = list(np.maximum.accumulate(np.maximum(areas, 0.0)))
        if areas[-1] <= 0:
            ctx.ledger.refused("storage node", sid, "the storage area is 0 at every level", hydraulic=False)
            continue
        node["storage_table"] = {"levels": levels, "areas": areas}
        ctx.source("nodes", node["id"], s)
        node.pop("storage_area", None)
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("storage node", sid, "; ".join(notes))


def _block_to_linear(levels: list[float], areas: list[float]) -> tuple[list[float], list[float]]:
    lv, ar = [levels[0]], [areas[0]]
    for k in range(1, len(levels)):
        lv.append(levels[k])
        ar.append(areas[k - 1])
        lv.append(levels[k] + 0.001)
        ar.append(areas[k])
    return lv, ar


# -- stations ------------------------------------------------------------------------------------------


def _stations(ctx: Context) -> None:
    stations = []
    for blocks in ctx.model.observations:
        for _, oid, reason in blocks.failed:
            ctx.ledger.refused("observation point", oid, reason, hydraulic=False)
        for obs in blocks.objects:
            name = unquote(obs.name)
            where = _locate(ctx, obs.branchid, obs.chainage, obs.x, obs.y, obs)
            if where is None:
                ctx.ledger.refused("observation point", name, f"not on a branch of the network (none within "
                                   f"{SNAP_DISTANCE:g} m)", hydraulic=False)
                continue
            branch, chainage, note = where
            stations.append({"id": ctx.id("station", name), "branch": branch, "chainage": chainage,
                             "quantities": ["h"]})
            ctx.origins[stations[-1]["id"]] = ("observation point", name)
            ctx.source("stations", stations[-1]["id"], obs)
            (ctx.ledger.approximated if note else ctx.ledger.exact)("observation point", name, note)
    for blocks in ctx.model.cross_observations:
        for _, oid, reason in blocks.failed:
            ctx.ledger.refused("observation cross-section", oid, reason, hydraulic=False)
        for oc in blocks.objects:
            name = unquote(oc.name)
            where = _locate(ctx, oc.branchid, oc.chainage, None, None, oc)
            note = ""
            if where is None and getattr(oc, "xcoordinates", None):
                where = _crossing(ctx, oc)
                if where is not None:
                    note = where[2]
            if where is None:
                ctx.ledger.refused("observation cross-section", name, "not on a branch of the network (its branch "
                                   "is unknown, or its polyline crosses no branch)", hydraulic=False)
                continue
            branch, chainage, _ = where
            sid = ctx.id("station", name)
            same = next((st for st in stations if st["id"] == sid), None)
            if same is not None and same["branch"] == branch and abs(same["chainage"] - chainage) < 1e-6:
                same["quantities"].append("Q")  # an observation point and cross-section of one name at one place
                (ctx.ledger.approximated if note else ctx.ledger.exact)("observation cross-section", name, note)
                continue
            if same is not None:
                sid = ctx.id("station", f"{name}_discharge")
            stations.append({"id": sid, "branch": branch, "chainage": chainage, "quantities": ["Q"]})
            ctx.origins[stations[-1]["id"]] = ("observation cross-section", name)
            ctx.source("stations", stations[-1]["id"], oc)
            (ctx.ledger.approximated if note else ctx.ledger.exact)("observation cross-section", name, note)
    ctx.case["stations"] = stations


def _locate(ctx: Context, branch: Any, chainage: Any, x: Any, y: Any, obj: Any = None) -> tuple[str, float, str] | None:
    """Branch id and chainage of a location given on a branch or by x, y (snapped to the nearest branch)."""
    if branch is not None and chainage is not None:
        if not ctx.ids["branch"].known(branch) or ctx.id("branch", branch) not in ctx.branch_length:
            return None
        bid = ctx.id("branch", branch)
        length = ctx.branch_length[bid]
        if float(chainage) > length + max(1.0, 0.01 * length):
            where = ctx.model.sources.where(obj, ctx.model.sources.key_of(obj, "chainage")) if obj is not None else ""
            ctx.ledger.error(where or ctx.model.mdu.name, f"chainage {float(chainage):g} m lies beyond the end of "
                             f"branch {unquote(branch)} ({length:g} m long)")
            return None
        return bid, min(max(float(chainage), 0.0), length), ""
    if x is None or y is None:
        return None
    best = None
    for b in ctx.case["branches"]:
        geo = np.asarray(b.get("geometry") or [], dtype=float)
        if geo.shape[0] < 2:
            continue
        seg = np.diff(geo, axis=0)
        seglen = np.hypot(seg[:, 0], seg[:, 1])
        t = np.clip(((x - geo[:-1, 0]) * seg[:, 0] + (y - geo[:-1, 1]) * seg[:, 1]) / np.maximum(seglen**2, 1e-12),
                    0, 1)
        px, py = geo[:-1, 0] + t * seg[:, 0], geo[:-1, 1] + t * seg[:, 1]
        d = np.hypot(px - x, py - y)
        k = int(np.argmin(d))
        along = (np.concatenate([[0.0], np.cumsum(seglen)])[k] + t[k] * seglen[k]) / max(seglen.sum(), 1e-12)
        if best is None or d[k] < best[0]:
            best = (float(d[k]), b["id"], float(along * b["length"]))
    if best is None or best[0] > SNAP_DISTANCE:
        return None
    return best[1], best[2], f"given by x, y; snapped to the nearest branch {best[1]} ({best[0]:.1f} m away)"


def _crossing(ctx: Context, oc: Any) -> tuple[str, float, str] | None:
    """Where D-Flow FM places an observation cross-section given as a polyline: on the 1D flow link it crosses.

    D-Flow FM (Deltares delft3d, ``crosssections_on_flowgeom`` and ``crspath_on_singlelink`` with
    ``zork = 1``) observes every flow link whose segment between its two calculation points the polyline
    crosses. Where the polyline passes exactly through a calculation point it touches two links; D-Flow FM
    keeps the one the crossing's direction selects (at the link's end point when the cross product of
    polyline and link, −(x43·y21 − y43·x21), is negative, at its start point when it is positive), so that
    the point counts once. The station is put at the middle of the first link the polyline crosses (in the
    polyline's order), where the case reports that link's discharge.
    """
    xs = [float(v) for v in (oc.xcoordinates or [])]
    ys = [float(v) for v in (oc.ycoordinates or [])]
    if len(xs) < 2 or len(xs) != len(ys):
        return None
    poly = np.column_stack([xs, ys])
    found: list[tuple[float, str, float]] = []
    for b in ctx.case["branches"]:
        geo = np.asarray(b.get("geometry") or [], dtype=float)
        points = np.asarray(b.get("points") or [0.0, b["length"]], dtype=float)
        if geo.shape[0] < 2:
            continue
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(geo, axis=0).T))])
        scale = along[-1] / b["length"] if b["length"] > 0 else 1.0
        px = np.interp(points * scale, along, geo[:, 0])
        py = np.interp(points * scale, along, geo[:, 1])
        for k in range(points.size - 1):
            q1, q2 = np.array([px[k], py[k]]), np.array([px[k + 1], py[k + 1]])
            for j in range(len(poly) - 1):
                hit = _crosses(poly[j], poly[j + 1], q1, q2)
                if hit is not None:
                    found.append((j + hit, b["id"], 0.5 * (points[k] + points[k + 1])))
    if not found:
        return None
    found.sort()
    _, branch, chainage = found[0]
    links = {(f[1], f[2]) for f in found}
    note = (f"given by a polyline: placed on the flow link it crosses, as D-Flow FM places it (the middle of the link, "
            f"{chainage:g} m on branch {branch})")
    if len(links) > 1:
        note += (f"; the polyline crosses {len(links)} links, whose discharges D-Flow FM adds up; the station "
                 "reports the first")
    return branch, float(chainage), note


def _crosses(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> float | None:
    """Where polyline segment p1-p2 crosses link q1-q2 (a fraction of p1-p2) by D-Flow FM's rule, or None."""
    x21, y21 = p2 - p1
    x43, y43 = q2 - q1
    x31, y31 = q1 - p1
    det = x43 * y21 - y43 * x21
    eps = max(1e-12 * max(abs(x21), abs(y21), abs(x43), abs(y43), abs(x31), abs(y31)), 1e-300)
    if abs(det) < eps:
        return None
    sm = (y31 * x21 - x31 * y21) / det
    sl = (sm * x43 + x31) / x21 if abs(x21) > eps else (sm * y43 + y31) / y21 if abs(y21) > eps else 0.0
    tol = 1e-9
    if not (-tol <= sm <= 1 + tol and -tol <= sl <= 1 + tol):
        return None
    crp = -det
    if abs(sm - 1.0) <= tol and crp > 0:
        return None
    if abs(sm) <= tol and crp < 0:
        return None
    return float(min(max(sl, 0.0), 1.0))


# -- initial state -------------------------------------------------------------------------------------


def _initial(ctx: Context) -> None:
    """``[initial]`` from the initial-field file (1dField water depth or level) or the MDU's WaterLevIni."""
    fm = ctx.model.fm
    sources = ctx.model.sources
    initial: dict = {"depth": 0.0}
    level_ini = getattr(fm.geometry, "waterlevini", None)
    found = False
    path = _ini_field_path(ctx)
    index = _readable(ctx, path, "initial fields", f"{ctx.model.mdu.name}, iniFieldFile") if path is not None else None
    for section in (index.sections if index is not None else []):
        header = section.header.lower()
        if header == "general":
            continue
        quantity = (section.value("quantity") or "?").lower()
        where = f"{sources.rel(index.path)}, line {section.line}"
        if header == "parameter":
            ctx.ledger.refused("initial field", f"{quantity} ({where})", "a [Parameter] field (a spatially varying "
                               "model parameter) is not read", hydraulic=True)
            continue
        if header != "initial":
            ctx.ledger.warn(f"{where}: a [{section.header}] block in an initial-field file is not read")
            continue
        if quantity not in ("waterdepth", "waterlevel"):
            ctx.ledger.refused("initial field", quantity, "only the initial water depth or level is used",
                               hydraulic=False)
            continue
        kind = (section.value("dataFileType") or "").lower()
        if kind != "1dfield":
            ctx.ledger.refused("initial field", quantity, f"data file type {kind!r} (2D samples or polygons) is not "
                               "read; the initial state comes from the other settings", hydraulic=False)
            continue
        name = section.value("dataFile")
        if not name:
            ctx.ledger.error(where, f"[Initial] {quantity}: no dataFile")
            continue
        data = _readable(ctx, _relative(ctx, Path(name), index.path), f"initial {quantity}",
                         f"{where}, dataFile = {name}")
        if data is None:
            continue
        glob, per_branch = _one_d_field(ctx, data)
        if glob is None and not per_branch:
            ctx.ledger.exact("initial field", quantity, f"{sources.rel(data.path)} holds no [Global] value and no "
                             "[Branch] values: D-Flow FM applies none either, and the initial state comes from the MDU")
            continue
        if glob is not None:
            if quantity == "waterdepth" and glob < 0:
                ctx.ledger.error(sources.rel(data.path), f"the initial water depth {glob:g} m is negative")
                continue
            initial = {"depth": glob} if quantity == "waterdepth" else {"depth": 0.0, "level": glob}
            found = True
            ctx.ledger.exact("initial field", quantity)
        for branch, (chainages, values, where_branch) in per_branch.items():
            _branch_initial(ctx, quantity, branch, chainages, values, where_branch)
    if not found and level_ini is not None:
        initial = {"depth": 0.0, "level": float(level_ini)}
        ctx.ledger.exact("setting", "WaterLevIni", "initial level where no initial field is given")
    ctx.case["initial"] = initial
    if index is not None:
        ctx.source("initial", "initial", f"{sources.rel(index.path)}")


def _branch_initial(ctx: Context, quantity: str, branch: str, chainages: list[float], values: list[float],
                    where: str) -> None:
    """A [Branch] block of an initial field as the branch's ``initial_levels``.

    Levels are taken as they are (exact); a depth is added to the bed level interpolated between the
    cross-sections at every chainage where either changes slope (approximated: D-Flow FM adds it to the bed level
    of each calculation point, the lowest of its links).
    """
    what = f"{quantity} on {branch}"
    target = None
    if ctx.ids.get("branch") is not None and ctx.ids["branch"].known(branch):
        target = next((b for b in ctx.case["branches"] if b["id"] == ctx.id("branch", branch)), None)
    if target is None:
        ctx.ledger.refused("initial field", what, f"{where}: the branch is not in the network", hydraulic=False)
        return
    if quantity == "waterlevel":
        target["initial_levels"] = {"chainages": chainages, "levels": values}
        ctx.ledger.exact("initial field", what, "initial levels along the branch (branches[].initial_levels)")
        return
    if any(v < 0 for v in values):
        ctx.ledger.error(where, f"[Branch] {branch!r}: a negative initial water depth")
        return
    cs = target["cross_sections"]
    ch = [c["chainage"] for c in cs]
    beds = [c["bed_level"] for c in cs]
    at = sorted({*chainages, *ch, 0.0, float(target["length"])})
    target["initial_levels"] = {"chainages": at, "levels": [float(np.interp(c, ch, beds) + np.interp(c, chainages,
                                                                                                       values))
                                                            for c in at]}
    ctx.ledger.approximated("initial field", what, "initial depths along the branch become initial levels: the depth "
                            "plus the bed level interpolated between the cross-sections (D-Flow FM adds it to the bed "
                            "level of each calculation point, the lowest of its links; affects the first hours only)")


def _ini_field_path(ctx: Context) -> Path | None:
    from rivercal.io.dhydro._read import _dropped_paths

    if ("geometry", "inifieldfile") in ctx.model.sources.dropped:
        found = _dropped_paths(ctx.model.sources.ini(ctx.model.mdu), "geometry", "inifieldfile")
        return _relative(ctx, found[0], ctx.model.mdu) if found else None
    ini = ctx.model.fm.geometry.inifieldfile
    name = getattr(ini, "filepath", None)
    return None if name is None else _relative(ctx, Path(name), ctx.model.mdu)


def _relative(ctx: Context, path: Path, referring: Path) -> Path:
    """A file name as D-Flow FM resolves it: relative to the MDU's folder, or to its own file's folder."""
    if path.is_absolute():
        return path
    if bool(getattr(ctx.model.fm.general, "pathsrelativetoparent", False)):
        return referring.parent / path
    return ctx.model.mdu.parent / path


def _readable(ctx: Context, path: Path, what: str, named_at: str):
    """The line index of a file the initial state needs, or a refusal saying why not and where the file is named."""
    sources = ctx.model.sources
    reason = None
    if not sources.inside(path):
        reason = f"it lies outside the model folder {sources.root} (the import reads no file outside it)"
    elif not is_file(path):
        reason = "the file does not exist"
    if reason is None:
        try:
            index = sources.ini(path)
        except OSError as exc:
            reason = f"the file cannot be read ({exc.strerror or exc})"
        else:
            if not index.sections:
                reason = "not a D-Flow FM INI file (no [section])"
            else:
                for line, text in index.stray[:5]:
                    ctx.ledger.error(f"{sources.rel(path)}, line {line}", f"{text[:60]!r} is not INI text")
                return index
    ctx.ledger.refused("file", sources.rel(path), f"named at {named_at}: {reason}; the {what} it holds are missing, "
                       "which changes the initial state", hydraulic=True)
    return None


def _one_d_field(ctx: Context, index) -> tuple[float | None, dict[str, tuple[list[float], list[float], str]]]:
    """The [Global] value and, per [Branch], its chainages, values and place of a 1dField file.

    Non-numbers, a count that does not match ``numLocations`` and chainages that go down are errors with their line.
    A branch with ``numLocations = 0`` has one value along it (chainage 0).
    """
    sources = ctx.model.sources
    glob = None
    per_branch: dict[str, tuple[list[float], list[float], str]] = {}
    for section in index.sections:
        header = section.header.lower()
        if header not in ("global", "branch"):
            continue
        raw = section.first("value" if header == "global" else "values")
        if raw is None or raw.value is None:
            ctx.ledger.error(f"{sources.rel(index.path)}, line {section.line}", f"[{section.header}] has no "
                             f"{'value' if header == 'global' else 'values'}")
            continue
        values = _numbers(raw.value)
        if not values or not all(np.isfinite(values)) or any(abs(v) > 1e4 for v in values):
            ctx.ledger.error(f"{sources.rel(index.path)}, line {raw.line}",
                             f"{raw.key} = {raw.value}: not finite numbers of a plausible size")
            continue
        if header == "global":
            glob = values[0]
            continue
        where = f"{sources.rel(index.path)}, line {section.line}"
        count = _numbers(section.value("numLocations") or "0")
        n = int(count[0]) if count and count[0] >= 0 else -1
        chain_raw = section.first("chainage")
        chainages = _numbers(chain_raw.value) if chain_raw is not None and chain_raw.value else []
        if n <= 0:
            chainages, values = [0.0], values[:1]
        if n < 0 or len(chainages) != len(values) or (n > 0 and len(values) != n):
            ctx.ledger.error(where, f"[Branch] {section.value('branchId')!r}: {len(values)} values and "
                             f"{len(chainages)} chainages for numLocations = {section.value('numLocations')}")
            continue
        if not all(np.isfinite(chainages)) or any(b < a for a, b in itertools.pairwise(chainages)) or chainages[0] < 0:
            ctx.ledger.error(f"{sources.rel(index.path)}, line {chain_raw.line if chain_raw else section.line}",
                             f"[Branch] {section.value('branchId')!r}: chainages must be finite, not negative and "
                             "increasing")
            continue
        for i in range(1, len(chainages)):  # a chainage given twice: a step, spread over 1 mm
            if chainages[i] <= chainages[i - 1]:
                chainages[i] = chainages[i - 1] + 0.001
        per_branch[section.value("branchId") or "?"] = (chainages, values, where)
    return glob, per_branch


def _numbers(text: str) -> list[float]:
    """The numbers of a value written as numbers separated by spaces; [] when one is not a number."""
    try:
        return [float(v) for v in text.split()]
    except ValueError:
        return []
