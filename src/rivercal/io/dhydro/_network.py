"""The network of a D-Flow FM model as case tables: nodes, branches, profiles, friction, stations, initial state.

D-Flow FM → case:

- network nodes → ``[[nodes]]`` (with storage from the storage-node file);
- network branches → ``[[branches]]`` with the chainages of the net file's branch length, the geometry,
  and D-Flow FM's calculation points (``points``), so that the case's grid is D-Flow FM's;
- cross-section definitions → ``[[profiles]]`` (yz, zw, zwRiver, circle, rectangle), cross-section
  locations → ``branches[].cross_sections`` with bed level = the definition's lowest level + shift (``_profiles``);
- roughness files → ``[[friction_groups]]`` (global value, branch values), referred to by the profiles
  (``_friction``);
- observation points and cross-sections → ``[[stations]]`` (``_stations``);
- initial water depth or level → ``[initial]`` (``_initial``).

:func:`convert_network` runs these in turn; the nodes, branches and storage nodes are converted here.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np

from rivercal.errors import CaseError
from rivercal.io.dhydro._context import Context, unquote
from rivercal.io.dhydro._friction import FRICTION_TYPES, MAIN, branch_friction_entries, friction_groups, friction_of
from rivercal.io.dhydro._initial import _initial
from rivercal.io.dhydro._profiles import (
    _borrowed_section,
    _cross_sections,
    _sections_across_nodes,
    profile_of_definition,
)
from rivercal.io.dhydro._stations import _stations

__all__ = ["FRICTION_TYPES", "MAIN", "convert_network", "friction_of", "profile_of_definition"]


def convert_network(ctx: Context) -> None:
    """Fill ``ctx.case`` with friction groups, profiles, nodes, branches, stations and the initial state."""
    friction_groups(ctx)
    _nodes_and_branches(ctx)
    _storage_nodes(ctx)
    _stations(ctx)
    _initial(ctx)


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
    taken: dict[str, Any] = {}  # the storage node block that gave each node its storage
    sources = ctx.model.sources
    for s in blocks.objects:
        sid = unquote(s.id)
        target = s.nodeid or s.manholeid
        node = nodes.get(ctx.id("node", target)) if target and ctx.ids["node"].known(target) else None
        if node is None:
            ctx.ledger.refused("storage node", sid, f"its node {target!r} is not a connection node of the network")
            continue
        first = taken.setdefault(node["id"], s)
        if first is not s:
            # which of the two D-Flow FM would take, or whether it would add them, is not for the import to guess
            ctx.ledger.error(sources.where(s) or ctx.model.mdu.name,
                             f"storage node {sid!r} is a second storage node on node {unquote(target)!r}; the first, "
                             f"{unquote(first.id)!r}, is at {sources.where(first) or 'an earlier block'}: give one "
                             "storage node per node (one table that holds both)")
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
        given = np.maximum(np.asarray(areas, dtype=float), 0.0)
        areas = list(np.maximum.accumulate(given))
        if np.any(given < areas):
            notes.append(_narrowing_note(levels, given, np.asarray(areas)))
        if areas[-1] <= 0:
            ctx.ledger.refused("storage node", sid, "the storage area is 0 at every level", hydraulic=False)
            continue
        node["storage_table"] = {"levels": levels, "areas": areas}
        ctx.source("nodes", node["id"], s)
        node.pop("storage_area", None)
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("storage node", sid, "; ".join(notes))


def _narrowing_note(levels: list[float], given: np.ndarray, kept: np.ndarray) -> str:
    """What keeping a narrowing storage table at its widest changes: where, and the extra volume (m³).

    A case's storage area cannot shrink as the water rises (``nodes[].storage_table``); D-Flow FM interpolates
    the table as given. The extra volume is the integral of the difference of the areas up to the table's top
    (linear between levels, as both interpolate); above it both hold their last area.
    """
    z = np.asarray(levels, dtype=float)
    k = int(np.argmax(given < kept))
    extra = float(np.sum(0.5 * (np.diff(z)) * ((kept - given)[1:] + (kept - given)[:-1])))
    volume = float(np.sum(0.5 * np.diff(z) * (given[1:] + given[:-1])))
    share = f" ({100 * extra / volume:.0f} % of the table's {volume:.4g} m³)" if volume > 0 else ""
    return (f"the storage area narrows upward (to {given[k]:g} m² at {z[k]:g} m AD); a case's storage cannot shrink "
            f"as the water rises, so it is kept at {kept[k]:g} m² from there: {extra:.4g} m³ more storage up to "
            f"{z[-1]:g} m AD{share}, and {kept[-1] - given[-1]:g} m² more area above it — the node fills slower "
            "and its level rises less there than in D-Flow FM")


def _block_to_linear(levels: list[float], areas: list[float]) -> tuple[list[float], list[float]]:
    lv, ar = [levels[0]], [areas[0]]
    for k in range(1, len(levels)):
        lv.append(levels[k])
        ar.append(areas[k - 1])
        lv.append(levels[k] + 0.001)
        ar.append(areas[k])
    return lv, ar
