"""Compound structures of a SOBEK 3 model as parallel branches of the case, as the D-HYDRO import sets them.

SOBEK 3 puts the members of a compound (``compound = 1`` with one ``compoundName`` in ``Structures.ini``) side by
side on one flow link between two grid points; their discharges add up. A case gives each structure a stretch of
its own, so the stretch around the compound becomes one parallel branch per member, each of 1/n of its length
with its cross-sections: :mod:`rivercal.io.dhydro._compound` does the cutting (its docstring gives the reasons and
the expected effect), and this module adapts a SOBEK 3 import to it and carries over what a SOBEK 3 branch holds
along its length that a D-HYDRO one does not: its initial levels and its friction along the branch (values or
water-level tables at chainages), which each piece and each parallel branch takes for the part of the branch it
stands for.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from rivercal.io.dhydro._compound import place_compounds as _place
from rivercal.io.sobek3._context import Context

__all__ = ["place_compounds"]


@dataclass
class _Cutting:
    """What :func:`rivercal.io.dhydro._compound.place_compounds` reads and writes of an import's context."""

    case: dict
    ledger: object
    compounds: list[tuple[str, list[str]]]
    branch_length: dict[str, float] = field(default_factory=dict)
    branch_nodes: dict[str, tuple[str, str]] = field(default_factory=dict)
    blocks: dict = field(default_factory=dict)
    pieces: dict[str, list[str]] = field(default_factory=dict)
    parallel: set[str] = field(default_factory=set)

    def source(self, table: str, case_id: str, obj) -> None:
        self.blocks[(table, case_id)] = obj


def place_compounds(ctx: Context) -> None:
    """Set the members of each compound of ``ctx.compounds`` side by side as parallel branches.

    ``ctx.compounds`` holds, per compound, its name and its members' case ids, all on one branch at one chainage
    between two grid points, one compound per branch (:func:`rivercal.io.sobek3._structures.convert_structures`
    refuses the others). Afterwards ``ctx.pieces`` maps each cut branch to its pieces and ``ctx.parallel`` holds the
    branches added beside a stretch.
    """
    if not ctx.compounds:
        return
    originals = {b["id"]: copy.deepcopy(b) for b in ctx.case["branches"]}
    entries = {(g["id"], e["branch"]): copy.deepcopy(e) for g in ctx.case.get("friction_groups", [])
               for e in g.get("branches", [])}
    spans = {}
    for _, members in ctx.compounds:
        item = _item(ctx, members[0])
        spans[item["branch"]] = (_stretch(originals[item["branch"]], item["chainage"]), len(members))
    cutting = _Cutting(case=ctx.case, ledger=ctx.ledger, compounds=ctx.compounds,
                       branch_length={b["id"]: b["length"] for b in ctx.case["branches"]},
                       branch_nodes={b["id"]: (b["from_node"], b["to_node"]) for b in ctx.case["branches"]})
    _place(cutting)
    ctx.ledger.entries[:] = [dataclasses.replace(e, note=e.note.replace("D-Flow FM", "SOBEK 3"))
                             if e.kind == "compound" else e for e in ctx.ledger.entries]  # flow1d is the same code
    ctx.pieces.update(cutting.pieces)
    ctx.parallel.update(cutting.parallel)
    branches = {b["id"]: b for b in ctx.case["branches"]}
    for bid, ((pa, pb), n) in spans.items():
        original = originals[bid]
        edges = [0.0, *[c for c in (pa, pb) if 1e-9 < c < original["length"] - 1e-9], original["length"]]
        pieces = cutting.pieces.get(bid, [bid])
        parts = {pid: (lo, hi, 1.0 / n if abs(lo - pa) < 1e-9 else 1.0)
                 for pid, lo, hi in zip(pieces, edges[:-1], edges[1:], strict=True)}
        stretch = next(pid for pid, (lo, _, _) in parts.items() if abs(lo - pa) < 1e-9)
        ends = (branches[stretch]["from_node"], branches[stretch]["to_node"])
        for other in cutting.parallel:
            if (branches[other]["from_node"], branches[other]["to_node"]) == ends:
                parts[other] = (pa, pb, 1.0 / n)
        for pid, (lo, hi, scale) in parts.items():
            _along(branches[pid], original, entries, bid, lo, hi, scale, ctx)


def _item(ctx: Context, case_id: str) -> dict:
    return next(i for t in ("weirs", "culverts", "pumps", "orifices", "universal_weirs", "bridges")
                for i in ctx.case.get(t, []) if i["id"] == case_id)


def _stretch(branch: dict, chainage: float) -> tuple[float, float]:
    """The grid points around a chainage of a branch, m (as the D-HYDRO import's cut finds them)."""
    points = np.asarray(branch.get("points") or [0.0, branch["length"]], dtype=float)
    j = int(np.clip(np.searchsorted(points, chainage, side="right") - 1, 0, points.size - 2))
    return float(points[j]), float(points[j + 1])


def _along(piece: dict, original: dict, entries: dict, bid: str, lo: float, hi: float, scale: float,
           ctx: Context) -> None:
    """Give a piece (or a parallel branch) the initial levels and friction of the part lo-hi of its branch."""
    if "initial_levels" in original:
        init = original["initial_levels"]
        chainages, (levels,) = _part(init["chainages"], [init["levels"]], lo, hi, scale)
        piece["initial_levels"] = {"chainages": chainages, "levels": levels}
    for group in ctx.case.get("friction_groups", []):
        entry = entries.get((group["id"], bid))
        kept = [e for e in group.get("branches", []) if e["branch"] != piece["id"]]
        if entry is None:
            if "branches" in group:
                group["branches"] = kept
            continue
        new = {**copy.deepcopy(entry), "branch": piece["id"]}
        if "chainages" in entry:
            columns = [entry["values"]] if "values" in entry else [list(c) for c in zip(*entry["table"], strict=True)]
            chainages, columns = _part(entry["chainages"], columns, lo, hi, scale)
            new["chainages"] = chainages
            if "values" in entry:
                new["values"] = columns[0]
            else:
                new["table"] = [list(row) for row in zip(*columns, strict=True)]
        group["branches"] = [*kept, new]


def _part(chainages: list[float], columns: list[list[float]], lo: float, hi: float,
          scale: float) -> tuple[list[float], list[list[float]]]:
    """Values given at chainages of a branch, for its part lo-hi, at chainages from the part's start times scale."""
    c = np.asarray(chainages, dtype=float)
    at = np.array([lo, *c[(c > lo + 1e-9) & (c < hi - 1e-9)], hi])
    return ([float(v) for v in (at - lo) * scale],
            [[float(v) for v in np.interp(at, c, np.asarray(col, dtype=float))] for col in columns])
