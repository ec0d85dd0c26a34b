"""Compound structures of D-Flow FM as parallel branches of the case.

D-Flow FM puts the members of a ``compound`` side by side on one flow link: every member sees the
levels of the two calculation points around it, and their discharges add up. A case gives each
structure a stretch of its own between two calculation points, so the members are set side by side
as branches in parallel between those two points:

- the branch that holds the compound is cut at the two calculation points around it (where one of
  them is an end node, it is not cut there), which become connection nodes;
- the stretch of length L between them becomes n parallel branches of length L/n, one per member,
  each with the stretch's cross-sections. Together they hold the stretch's storage, each member sees
  the levels of the two points, and a culvert's exit loss the same downstream channel.

D-Flow FM's structure link has the inertia of its length L (``u = r - f Δz`` with ``1/Δt + u/L``, after
``weir.f90``); a member on a branch of L/n has 1/n of it. Steady flows are the same; after a change of
levels the flow through the members settles a little faster than in D-Flow FM. The alternative, a
branch of length L per member, would multiply the storage of the stretch by n for as long as the
model runs.

Cutting a branch keeps everything on it (cross-sections, calculation points, structures, laterals,
stations, its own friction) on the piece it lies on. A cut between two cross-sections of the same
definition is exact (the bed is interpolated); between two different definitions the cut takes the
nearer one, an approximation of the interpolated shape over half a stretch, noted in ``import.md``.
"""

from __future__ import annotations

import numpy as np

from rivercal.io.dhydro._context import Context

__all__ = ["place_compounds"]

_TABLES = ("weirs", "culverts", "pumps", "orifices", "universal_weirs", "bridges")


def place_compounds(ctx: Context) -> None:
    """Set the members of each compound side by side: the stretch around it becomes one parallel branch per member."""
    for cid, members in ctx.compounds:
        items = [found for found in (_item(ctx, m) for m in members) if found is not None]
        if len(items) < 2:
            continue
        first = items[0][1]
        if any(i["branch"] != first["branch"] or abs(i["chainage"] - first["chainage"]) > 1e-6 for _, i in items[1:]):
            ctx.ledger.warn(f"compound {cid!r}: its members do not lie at one branch and chainage; each is placed "
                            "where it lies")
            continue
        branch = next(b for b in ctx.case["branches"] if b["id"] == first["branch"])
        stretch, notes = _cut_around(ctx, branch, first["chainage"])
        n = len(items)
        share = stretch["length"] / n
        scaled = [{**cs, "chainage": cs["chainage"] / n} for cs in stretch["cross_sections"]]
        stretch.update(length=share, points=[0.0, share], cross_sections=scaled)
        ctx.branch_length[stretch["id"]] = share
        first["chainage"] = 0.5 * share
        for _, item in items[1:]:
            bid = _unique(ctx, f"{item['id']}_beside")
            new = {**{k: v for k, v in stretch.items() if k != "geometry"}, "id": bid,
                   "cross_sections": [dict(cs) for cs in scaled]}
            if "friction" in stretch:
                new["friction"] = dict(stretch["friction"])
            ctx.case["branches"].append(new)
            ctx.parallel.add(bid)
            ctx.branch_nodes[bid] = (new["from_node"], new["to_node"])
            ctx.branch_length[bid] = share
            ctx.source("branches", bid, ctx.blocks.get(("branches", branch["id"]), ""))
            item["branch"] = bid
            item["chainage"] = 0.5 * share
        note = (f"{n} structures side by side, as D-Flow FM sets them: the stretch of {n * share:g} m between the "
                f"calculation points around the compound becomes {n} parallel branches of {share:g} m with its "
                f"cross-sections, one per member (the same storage; each member's flow link is 1/{n} as long as "
                "D-Flow FM's, which changes only how fast the flow through it follows a change of levels)")
        ctx.ledger.approximated("compound", cid, "; ".join([note, *notes]))


def _item(ctx: Context, case_id: str) -> tuple[str, dict] | None:
    for table in _TABLES:
        for item in ctx.case.get(table, []):
            if item["id"] == case_id:
                return table, item
    return None


def _unique(ctx: Context, base: str) -> str:
    taken = {b["id"] for b in ctx.case["branches"]} | {n["id"] for n in ctx.case["nodes"]}
    new, k = base[:64], 2
    while new in taken:
        new = f"{base[:60]}_{k}"
        k += 1
    return new


def _cut_around(ctx: Context, branch: dict, chainage: float) -> tuple[dict, list[str]]:
    """Cut a branch at the calculation points around a chainage; the stretch between them, and notes.

    The members of the compound move with the rest of the branch onto the stretch (their chainage there).
    """
    length = branch["length"]
    points = np.asarray(branch.get("points") or [0.0, length], dtype=float)
    j = int(np.clip(np.searchsorted(points, chainage, side="right") - 1, 0, points.size - 2))
    pa = float(points[j])
    cuts = [c for c in (pa, float(points[j + 1])) if 1e-9 < c < length - 1e-9]
    if not cuts:
        return branch, []
    pieces, notes = _split(ctx, branch, cuts)
    stretch = next(p for p in pieces if abs(p["_start"] - pa) < 1e-9)
    for p in pieces:
        del p["_start"]
    return stretch, notes


def _split(ctx: Context, branch: dict, cuts: list[float]) -> tuple[list[dict], list[str]]:
    """Cut ``branch`` at ``cuts`` (m, inside it); everything on it moves to its piece. The first piece keeps the id."""
    bid = branch["id"]
    edges = [0.0, *cuts, branch["length"]]
    nodes = [branch["from_node"]]
    for c in cuts:
        x, y = _xy(ctx, branch, c)
        nid = _unique(ctx, f"{bid}_at_{c:.0f}")
        ctx.case["nodes"].append({"id": nid, "x": x, "y": y})
        nodes.append(nid)
    nodes.append(branch["to_node"])
    notes: list[str] = []
    pieces = []
    for k in range(len(edges) - 1):
        lo, hi = edges[k], edges[k + 1]
        pid = bid if k == 0 else _unique(ctx, f"{bid}_{k + 1}")
        piece = {**{key: v for key, v in branch.items() if key not in ("points", "geometry", "cross_sections")},
                 "id": pid, "from_node": nodes[k], "to_node": nodes[k + 1], "length": hi - lo, "_start": lo}
        points = [p - lo for p in (branch.get("points") or [0.0, branch["length"]]) if lo - 1e-9 <= p <= hi + 1e-9]
        piece["points"] = [0.0, *[p for p in points if 1e-9 < p < hi - lo - 1e-9], hi - lo]
        if branch.get("geometry"):
            piece["geometry"] = _geometry(branch, lo, hi)
        sections = []
        for end in (lo, hi):
            cs, note = _interpolated(ctx, branch, end)
            if note:
                notes.append(note)
            sections.append({**cs, "chainage": end - lo})
        inside = [{**cs, "chainage": cs["chainage"] - lo} for cs in branch["cross_sections"]
                  if lo + 1e-9 < cs["chainage"] < hi - 1e-9]
        piece["cross_sections"] = [sections[0], *inside, sections[1]]
        pieces.append(piece)
        ctx.branch_nodes[pid] = (piece["from_node"], piece["to_node"])
        ctx.branch_length[pid] = piece["length"]
        if pid != bid:
            ctx.source("branches", pid, ctx.blocks.get(("branches", bid), ""))
    index = ctx.case["branches"].index(branch)
    ctx.case["branches"][index:index + 1] = pieces
    ctx.pieces.setdefault(bid, [bid])
    ctx.pieces[bid] = [p["id"] for p in pieces]
    _move_things(ctx, bid, pieces)
    for group in ctx.case.get("friction_groups", []):
        for entry in list(group.get("branches", [])):
            if entry["branch"] == bid:
                group["branches"] += [{**entry, "branch": p["id"]} for p in pieces[1:]]
    return pieces, notes


def _move_things(ctx: Context, bid: str, pieces: list[dict]) -> None:
    """Structures, laterals and stations on a cut branch to the piece they lie on, with their chainage there."""
    things = [*(i for t in _TABLES for i in ctx.case.get(t, [])), *ctx.case.get("laterals", []),
              *ctx.case.get("stations", [])]
    for item in things:
        if item.get("branch") != bid:
            continue
        c = item["chainage"]
        piece = next((p for p in pieces if p["_start"] - 1e-9 <= c < p["_start"] + p["length"] - 1e-9), pieces[-1])
        item["branch"] = piece["id"]
        item["chainage"] = min(max(c - piece["_start"], 0.0), piece["length"])


def _interpolated(ctx: Context, branch: dict, chainage: float) -> tuple[dict, str]:
    """The cross-section of a branch at a chainage: its profile and the interpolated bed, and a note if approximated."""
    sections = branch["cross_sections"]
    ch = np.array([c["chainage"] for c in sections])
    bed = float(np.interp(chainage, ch, [c["bed_level"] for c in sections]))
    right = int(np.clip(np.searchsorted(ch, chainage), 0, len(sections) - 1))
    left = max(right - 1, 0)
    near = left if abs(chainage - ch[left]) <= abs(ch[right] - chainage) else right
    note = ""
    if sections[left]["profile"] != sections[right]["profile"] and not (
            abs(chainage - ch[left]) < 1e-9 or abs(chainage - ch[right]) < 1e-9) and ch[left] < chainage < ch[right]:
        note = (f"branch {branch['id']} is cut at {chainage:g} m between two different cross-section definitions: "
                f"the cut takes the nearer one, {sections[near]['profile']!r}, with the interpolated bed")
    return {"profile": sections[near]["profile"], "bed_level": bed}, note


def _xy(ctx: Context, branch: dict, chainage: float) -> tuple[float, float]:
    geo = np.asarray(branch.get("geometry") or [], dtype=float)
    if geo.shape[0] < 2:
        nodes = {n["id"]: n for n in ctx.case["nodes"]}
        a, b = nodes[branch["from_node"]], nodes[branch["to_node"]]
        geo = np.array([[a["x"], a["y"]], [b["x"], b["y"]]], dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(geo, axis=0).T))])
    f = chainage / branch["length"] * s[-1]
    return float(np.interp(f, s, geo[:, 0])), float(np.interp(f, s, geo[:, 1]))


def _geometry(branch: dict, lo: float, hi: float) -> list[list[float]]:
    geo = np.asarray(branch["geometry"], dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(geo, axis=0).T))])
    scale = s[-1] / branch["length"] if branch["length"] > 0 else 1.0
    a, b = lo * scale, hi * scale
    inner = [list(map(float, p)) for p, d in zip(geo, s, strict=True) if a < d < b]
    start = [float(np.interp(a, s, geo[:, 0])), float(np.interp(a, s, geo[:, 1]))]
    end = [float(np.interp(b, s, geo[:, 0])), float(np.interp(b, s, geo[:, 1]))]
    return [start, *inner, end]
