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
from rivercal.io.dhydro._context import Context, unquote
from rivercal.io.dhydro._source import is_file

__all__ = ["FRICTION_TYPES", "MAIN", "convert_network", "friction_of", "profile_of_definition"]

#: D-Flow FM's default friction group: profiles without a friction id use it.
MAIN = "Main"
#: Farthest a location given by x, y may lie from a branch to be snapped onto it, m.
SNAP_DISTANCE = 100.0

#: hydrolib-core's friction types → the case's, with the note for the ones that are converted approximately.
FRICTION_TYPES = {"chezy": "chezy", "manning": "manning", "strickler": "strickler", "whitecolebrook": "white-colebrook"}


def friction_of(kind: object, value: float) -> tuple[dict | None, str]:
    """A case friction ``{type, value}`` for a D-Flow FM friction type and value, and a note if approximated.

    Returns ``(None, why)`` when the law has no counterpart.
    """
    name = str(getattr(kind, "value", kind)).lower().replace("-", "").replace("_", "")
    if name in FRICTION_TYPES:
        return {"type": FRICTION_TYPES[name], "value": float(value)}, ""
    if name == "stricklernikuradse":
        # C = 25 (R / k_n)^(1/6) is Strickler with k_s = 25 k_n^(-1/6) (D-Flow FM user manual, roughness formulas)
        return {"type": "strickler", "value": 25.0 * float(value) ** (-1.0 / 6.0)}, ""
    if name == "walllawnikuradse":
        return ({"type": "white-colebrook", "value": float(value)},
                "wall-law Nikuradse roughness taken as White-Colebrook with the same k_n (both are rough-turbulent "
                "logarithmic laws; C differs by a few %)")
    return None, f"friction type {kind!r} has no counterpart in a case"


def convert_network(ctx: Context) -> None:
    """Fill ``ctx.case`` with friction groups, profiles, nodes, branches, stations and the initial state."""
    _friction_groups(ctx)
    _nodes_and_branches(ctx)
    _storage_nodes(ctx)
    _stations(ctx)
    _initial(ctx)


# -- friction ----------------------------------------------------------------------------------------


def _friction_groups(ctx: Context) -> None:
    physics = ctx.model.fm.physics
    kind = {0: "chezy", 1: "manning", 2: "whitecolebrook", 3: "whitecolebrook"}.get(int(physics.uniffricttype), None)
    value = physics.uniffrictcoef1d if physics.uniffrictcoef1d is not None else physics.uniffrictcoef
    glob, _ = friction_of(kind, value) if kind and value else (None, "")
    if glob is not None:
        try:
            from rivercal.network import Friction

            Friction.model_validate(glob)
            ctx.case["friction"] = glob
            ctx.ledger.exact("setting", "UnifFrictType/UnifFrictCoef1D",
                             "global friction of profiles without a friction group")
        except ValueError as exc:
            ctx.ledger.approximated("setting", "UnifFrictCoef1D", f"uniform friction {value} ({kind}) is outside "
                                    f"the plausible range ({exc}); the case keeps its default global friction")
    groups: list[dict] = []
    branch_values: dict[str, dict[str, float]] = defaultdict(dict)
    main_laws: dict[str, dict] = {}
    for blocks in ctx.model.frictions:
        for _, bid, reason in blocks.failed:
            ctx.ledger.refused("friction group", bid, reason)
        group_id = None
        for obj in blocks.objects:
            if type(obj).__name__ == "FrictGlobal":
                gid = ctx.id("friction group", obj.frictionid)
                fr, note = friction_of(obj.frictiontype, obj.frictionvalue)
                if fr is None:
                    ctx.ledger.refused("friction group", gid, note)
                    continue
                groups.append({"id": gid, **fr, "branches": []})
                ctx.source("friction_groups", gid, obj)
                group_id = gid
                (ctx.ledger.approximated if note else ctx.ledger.exact)("friction group", gid, note)
        for obj in blocks.objects:
            if type(obj).__name__ != "FrictBranch":
                continue
            where = f"{unquote(obj.branchid)} in {blocks.path.name}"
            if group_id is None:
                ctx.ledger.refused("friction on a branch", where, "the file has no [Global] friction group")
                continue
            fr, note = friction_of(obj.frictiontype, 1.0)
            group = next(g for g in groups if g["id"] == group_id)
            if fr is not None and group_id == MAIN and fr["type"] != group["type"]:
                values = [float(v) for v in (obj.frictionvalues or [])]
                if values:
                    main_laws[unquote(obj.branchid)] = friction_of(obj.frictiontype, float(np.mean(values)))[0]
                    (ctx.ledger.approximated if len(set(values)) > 1 else ctx.ledger.exact)(
                        "friction on a branch", where, "values along the branch replaced by their mean"
                        if len(set(values)) > 1 else "")
                continue
            if fr is None or fr["type"] != group["type"]:
                ctx.ledger.refused("friction on a branch", where,
                                   f"friction type {obj.frictiontype} differs from the group's {group['type']}; a "
                                   "group has one law")
                continue
            values = [float(v) for v in (obj.frictionvalues or [])]
            if not values:
                ctx.ledger.refused("friction on a branch", where, "no friction values", hydraulic=False)
                continue
            function = str(getattr(obj.functiontype, "value", obj.functiontype) or "constant").lower()
            value = float(np.mean(values))
            if function != "constant" or len(set(values)) > 1:
                ctx.ledger.approximated("friction on a branch", where,
                                        f"{function} friction varying {min(values):g}-{max(values):g} along the "
                                        f"branch or with level/discharge; the case takes its mean {value:g}")
            else:
                ctx.ledger.exact("friction on a branch", where)
            if fr["type"] == "strickler" and str(obj.frictiontype).lower().startswith("stricklernik"):
                value = friction_of(obj.frictiontype, value)[0]["value"]
            branch_values[group_id][unquote(obj.branchid)] = value
    main = next((g for g in groups if g["id"] == MAIN), None)
    if main is not None:  # D-Flow FM's default group: the case's global friction and the branches' own
        ctx.case["friction"] = {"type": main["type"], "value": main["value"]}
        for branch, value in branch_values.get(MAIN, {}).items():
            main_laws.setdefault(branch, {"type": main["type"], "value": value})
        ctx.ledger.exact("setting", "friction group Main", "D-Flow FM's default friction group: the case's global "
                         "friction ([friction]) and the branches' own (branches[].friction)")
    ctx.case["friction_groups"] = groups
    ctx._branch_friction = branch_values  # type: ignore[attr-defined]  # resolved once branch ids are known
    ctx._main_branches = main_laws  # type: ignore[attr-defined]


def _finish_friction_groups(ctx: Context) -> None:
    for b in ctx.case["branches"]:
        name = next((k for k in ctx._main_branches if ctx.id("branch", k) == b["id"]), None)  # type: ignore[attr-defined]
        if name is not None:
            b["friction"] = ctx._main_branches[name]  # type: ignore[attr-defined]
    for g in ctx.case["friction_groups"]:
        for branch, value in ctx._branch_friction.get(g["id"], {}).items():  # type: ignore[attr-defined]
            if ctx.ids.get("branch") is None or not ctx.ids["branch"].known(branch):
                ctx.ledger.refused("friction on a branch", branch, "the branch is not in the network", hydraulic=False)
                continue
            g["branches"].append({"branch": ctx.id("branch", branch), "value": value})
        if not g["branches"]:
            del g["branches"]


# -- profiles ----------------------------------------------------------------------------------------


def _section_friction(ctx: Context, d: Any, sections: int) -> tuple[list[str] | None, str]:
    """Friction group ids of a definition's sections (inline friction becomes a group of its own)."""
    ids = getattr(d, "frictionids", None)
    if ids is None and getattr(d, "frictionid", None):
        ids = [d.frictionid]
    groups = {g["id"] for g in ctx.case["friction_groups"]}
    if ids:
        ids = [unquote(i) for i in ids]
        out = [ctx.id("friction group", i) for i in ids]
        if all(i == MAIN for i in out) and MAIN in groups:
            return None, ""  # the case's global and branch friction
        missing = [i for i, o in zip(ids, out, strict=True) if o not in groups]
        if missing:
            return None, f"friction group(s) {', '.join(missing)} not defined; the profile takes the global friction"
        if len(out) > sections:  # ids of sections of zero width (an absent floodplain)
            out = out[:sections]
        elif len(out) < sections:
            return [out[0]] * sections, (f"{len(out)} friction ids for {sections} sections; all sections take "
                                         f"{out[0]}")
        return out, ""
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
        closed = any(b < a for a, b in itertools.pairwise(flow)) or flow[-1] == 0
        if total is not None and not closed:
            total = list(np.maximum.accumulate(total))
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
            if any(float(getattr(d, name, 0) or 0) > 0 for name in ("leveeflowarea", "leveetotalrea")):
                notes.append("summer dike (levee) areas ignored: the floodplain behind it takes part in the flow "
                             "from its own level up")
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
    edges = arrays["edges"]
    on_branch = arrays["on_branch"]
    offsets = arrays["offsets"]
    lengths = arrays["lengths"]
    geometries = arrays["geometry"]
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
        if not sections:
            pending.append((branch, name, notes))
            continue
        branch["cross_sections"] = sections
        ctx.branch_nodes[bid] = (branch["from_node"], branch["to_node"])
        ctx.branch_length[bid] = length
        ctx.__dict__.setdefault("_points", {})[bid] = points
        branches.append(branch)
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("branch", name, "; ".join(notes))
    for branch, name, notes in pending:
        section = _borrowed_section(branches, branch)
        if section is None:
            ctx.ledger.refused("branch", name, "no cross-section on the branch or on a branch next to it")
            continue
        branch["cross_sections"] = [section]
        notes.append(f"no cross-section (a branch that carries a structure): it borrows profile {section['profile']!r} "
                     f"at bed {section['bed_level']:g} m AD from the end of a branch next to it; it holds only "
                     "the little storage of its own length")
        ctx.branch_nodes[branch["id"]] = (branch["from_node"], branch["to_node"])
        ctx.branch_length[branch["id"]] = branch["length"]
        branches.append(branch)
        ctx.ledger.approximated("branch", name, "; ".join(notes))
    ctx.case["branches"] = branches
    _finish_friction_groups(ctx)
    referenced = {g for prof in ctx.case.get("profiles", []) for g in prof.get("friction", [])}
    ctx.case["friction_groups"] = [g for g in ctx.case["friction_groups"] if g["id"] != MAIN or MAIN in referenced]
    used = {n for b in branches for n in (b["from_node"], b["to_node"])}
    ctx.case["nodes"] = [n for n in nodes if n["id"] in used]


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
        values = ([glob] if glob is not None else []) + list(per_branch.values())
        if not values:
            ctx.ledger.exact("initial field", quantity, f"{sources.rel(data.path)} holds no [Global] value and no "
                             "[Branch] values: D-Flow FM applies none either, and the initial state comes from the MDU")
            continue
        value = glob if glob is not None else float(np.median(values))
        if quantity == "waterdepth" and value < 0:
            ctx.ledger.error(sources.rel(data.path), f"the initial water depth {value:g} m is negative")
            continue
        note = ""
        if per_branch:
            note = (f"values per branch ({min(values):g}-{max(values):g}); the case takes one value, {value:g}, "
                    "everywhere (affects the first hours only)")
        if quantity == "waterdepth":
            initial = {"depth": value}
        else:
            initial = {"depth": 0.0, "level": value}
        found = True
        (ctx.ledger.approximated if note else ctx.ledger.exact)("initial field", quantity, note)
    if not found and level_ini is not None:
        initial = {"depth": 0.0, "level": float(level_ini)}
        ctx.ledger.exact("setting", "WaterLevIni", "initial level where no initial field is given")
    ctx.case["initial"] = initial
    if index is not None:
        ctx.source("initial", "initial", f"{sources.rel(index.path)}")


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


def _one_d_field(ctx: Context, index) -> tuple[float | None, dict[str, float]]:
    """The [Global] value and the mean value per [Branch] of a 1dField file; non-numbers are errors with their line."""
    sources = ctx.model.sources
    glob = None
    per_branch: dict[str, float] = {}
    for section in index.sections:
        header = section.header.lower()
        if header not in ("global", "branch"):
            continue
        raw = section.first("value" if header == "global" else "values")
        if raw is None or raw.value is None:
            ctx.ledger.error(f"{sources.rel(index.path)}, line {section.line}", f"[{section.header}] has no "
                             f"{'value' if header == 'global' else 'values'}")
            continue
        try:
            values = [float(v) for v in raw.value.split()]
        except ValueError:
            values = []
        if not values or not all(np.isfinite(values)) or any(abs(v) > 1e4 for v in values):
            ctx.ledger.error(f"{sources.rel(index.path)}, line {raw.line}",
                             f"{raw.key} = {raw.value}: not finite numbers of a plausible size")
            continue
        if header == "global":
            glob = values[0]
        else:
            per_branch[section.value("branchId") or "?"] = float(np.mean(values))
    return glob, per_branch
