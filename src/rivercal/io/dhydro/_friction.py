"""Roughness files → ``[friction]``, ``[[friction_groups]]`` and the branches' own friction.

D-Flow FM's roughness (Deltares delft3d, flow1d library: ``m_read_roughness.scan_roughness_input`` reads a
file, ``getFrictionValue`` evaluates it):

- a ``[Global]`` block names a friction id (a group) with its law and value;
- a ``[Branch]`` block gives the group other values on one branch, in a law of its own (``frictionType`` of the
  block, kept per branch), at ``numLocations`` chainages (linear between them, constant beyond the first and
  the last) and, for ``functionType = waterLevel``, at ``numLevels`` water levels (linear between them,
  constant beyond): ``frictionValues`` holds ``numLocations`` values for each level in turn (level by level,
  ``setTableMatrix``); the coefficient is interpolated in chainage and level (``interpolateTableMatrix``);
- a branch without a ``[Branch]`` block takes the group's own law and value.

Each ``[Branch]`` block becomes a :class:`rivercal.network.BranchFriction` of its group with its own law,
chainages and level table, exactly. A block of ``functionType = absDischarge`` (the coefficient as a function of
the discharge) or ``timeSeries`` is refused: the case cannot hold a coefficient that depends on the discharge or
on time.

The default group ``Main`` is the case's global friction (``[friction]``). When every one of its ``[Branch]``
blocks gives one value along the branch, those become the branches' own friction (``branches[].friction``,
calibration targets ``friction:branch:<id>``), as before. When one of them varies along its branch or with the
level, ``Main`` stays a friction group that every profile which uses it names (``friction:group:Main``); a
profile without a friction id then names ``Main`` too, as D-Flow FM's default.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from typing import Any

import numpy as np

from rivercal.io.dhydro._context import Context, unquote

__all__ = ["FRICTION_TYPES", "MAIN", "branch_friction_entries", "friction_groups", "friction_of"]

#: D-Flow FM's default friction group: profiles without a friction id use it.
MAIN = "Main"

#: hydrolib-core's friction types → the case's.
FRICTION_TYPES = {"chezy": "chezy", "manning": "manning", "strickler": "strickler", "whitecolebrook": "white-colebrook"}

#: Spacing of chainages or levels that a file gives twice (a step), m.
STEP = 0.001


def _law_name(kind: object) -> str:
    return str(getattr(kind, "value", kind)).lower().replace("-", "").replace("_", "")


def friction_of(kind: object, value: float) -> tuple[dict | None, str]:
    """A case friction ``{type, value}`` for a D-Flow FM friction type and value, and a note if approximated.

    Returns ``(None, why)`` when the law has no counterpart.
    """
    name = _law_name(kind)
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


def friction_groups(ctx: Context) -> None:
    """``ctx.case['friction']`` and ``['friction_groups']`` from the MDU's uniform friction and the roughness files.

    The ``[Branch]`` blocks are kept by D-Flow FM branch id in ``ctx.friction_entries`` and put on their groups by
    :func:`branch_friction_entries` once the branches are known.
    """
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
    entries: dict[str, dict[str, dict]] = defaultdict(dict)
    for blocks in ctx.model.frictions:
        for _, bid, reason in blocks.failed:
            ctx.ledger.refused("friction group", bid, reason)
        group = None
        for obj in blocks.objects:
            if type(obj).__name__ == "FrictGlobal":
                gid = ctx.id("friction group", obj.frictionid)
                fr, note = friction_of(obj.frictiontype, obj.frictionvalue)
                if fr is None:
                    ctx.ledger.refused("friction group", gid, note)
                    continue
                group = {"id": gid, **fr, "branches": []}
                groups.append(group)
                ctx.source("friction_groups", gid, obj)
                (ctx.ledger.approximated if note else ctx.ledger.exact)("friction group", gid, note)
        globals_ = [o for o in blocks.objects if type(o).__name__ == "FrictGlobal"]
        branch_blocks = [o for o in blocks.objects if type(o).__name__ == "FrictBranch"]
        if len(globals_) > 1 and branch_blocks:
            ctx.ledger.error(ctx.model.sources.rel(blocks.path), f"{len(globals_)} [Global] blocks and [Branch] blocks "
                             "in one roughness file: D-Flow FM allows [Branch] blocks only beside a single [Global] "
                             "block (the group they belong to); give each group a file of its own")
            continue
        for obj in branch_blocks:
            where = f"{unquote(obj.branchid)} in {blocks.path.name}"
            if group is None:
                ctx.ledger.refused("friction on a branch", where, "the file has no [Global] friction group")
                continue
            entry = _branch_entry(ctx, obj, group, where)
            if entry is not None:
                entries[group["id"]][unquote(obj.branchid)] = entry
    ctx.friction_entries = entries
    ctx.main_group = False
    main = next((g for g in groups if g["id"] == MAIN), None)
    if main is not None:  # D-Flow FM's default group: the case's global friction
        ctx.case["friction"] = {"type": main["type"], "value": main["value"]}
        varying = sorted(b for b, e in entries.get(MAIN, {}).items() if "value" not in e)
        if varying:
            ctx.main_group = True
            ctx.ledger.exact("setting", "friction group Main", "D-Flow FM's default friction group varies along "
                             f"branch(es) {', '.join(varying[:5])}{' ...' if len(varying) > 5 else ''} or with the "
                             "level: it stays a friction group (friction:group:Main) that every profile using it "
                             "names; its value is also the case's global friction ([friction])")
        else:
            ctx.ledger.exact("setting", "friction group Main", "D-Flow FM's default friction group: the case's global "
                             "friction ([friction]) and the branches' own (branches[].friction)")
    ctx.case["friction_groups"] = groups


def branch_friction_entries(ctx: Context) -> None:
    """Put the ``[Branch]`` blocks on their groups (and, for ``Main``, on the branches) once branch ids are known."""
    entries: dict[str, dict[str, dict]] = ctx.friction_entries
    known = ctx.ids.get("branch")
    in_case = {b["id"] for b in ctx.case["branches"]}
    resolved: dict[str, dict[str, dict]] = defaultdict(dict)
    for gid, per_branch in entries.items():
        for name, entry in per_branch.items():
            if known is None or not known.known(name) or ctx.id("branch", name) not in in_case:
                ctx.ledger.refused("friction on a branch", f"{name} (group {gid})", "the branch is not in the network",
                                   hydraulic=False)
                continue
            resolved[gid][ctx.id("branch", name)] = entry
    groups = {g["id"]: g for g in ctx.case["friction_groups"]}
    if MAIN in groups and not ctx.main_group:
        law = groups[MAIN]["type"]
        for b in ctx.case["branches"]:
            entry = resolved.get(MAIN, {}).get(b["id"])
            if entry is not None:
                b["friction"] = {"type": entry.get("type", law), "value": entry["value"]}
    for g in ctx.case["friction_groups"]:
        g["branches"] = [{"branch": bid, **entry} for bid, entry in resolved.get(g["id"], {}).items()]
        if not g["branches"]:
            del g["branches"]


def _branch_entry(ctx: Context, obj: Any, group: dict, where: str) -> dict | None:
    """The group's entry for one ``[Branch]`` block (a ``BranchFriction`` without its branch), or None (refused)."""
    sources = ctx.model.sources

    def at(field: str) -> str:
        return sources.where(obj, sources.key_of(obj, field)) or where

    fr, note = friction_of(obj.frictiontype, 1.0)
    if fr is None:
        ctx.ledger.refused("friction on a branch", where, note)
        return None
    law = fr["type"]
    function = _law_name(obj.functiontype or "constant")
    if function == "absdischarge":
        ctx.ledger.refused("friction on a branch", where, "its coefficient is a function of the discharge "
                           "(functionType = absDischarge), which a case cannot express (friction may vary along a "
                           "branch and with the water level, not with the discharge); import with --allow-partial to "
                           "give the branch the group's value instead")
        return None
    if function == "timeseries":
        ctx.ledger.refused("friction on a branch", where, "its coefficient follows a time series (functionType = "
                           "timeSeries), which a case cannot express; import with --allow-partial to give the branch "
                           "the group's value instead")
        return None
    if function not in ("constant", "waterlevel"):
        ctx.ledger.error(at("functiontype"), f"[Branch] {unquote(obj.branchid)!r}: functionType = {obj.functiontype} "
                         "is none of constant, waterLevel, absDischarge, timeSeries")
        return None
    values = [float(v) for v in (obj.frictionvalues or [])]
    n_loc = int(obj.numlocations or 0)
    n_lev = int(obj.numlevels or 0)
    chain = [float(c) for c in (obj.chainage or [])] if n_loc > 0 else [0.0]
    levels = [float(v) for v in (obj.levels or [])] if n_lev > 0 else [0.0]
    expected = len(chain) * len(levels)
    if len(chain) != max(n_loc, 1):
        ctx.ledger.error(at("chainage"), f"[Branch] {unquote(obj.branchid)!r}: numLocations = {n_loc} but "
                         f"{len(chain)} chainage(s)")
        return None
    if len(levels) != max(n_lev, 1):
        ctx.ledger.error(at("levels"), f"[Branch] {unquote(obj.branchid)!r}: numLevels = {n_lev} but {len(levels)} "
                         "level(s)")
        return None
    if len(values) != expected:
        ctx.ledger.error(at("frictionvalues"), f"[Branch] {unquote(obj.branchid)!r}: {len(values)} frictionValues "
                         f"for numLocations = {n_loc} and numLevels = {n_lev}; give numLocations values for each "
                         "level (one when numLocations is 0)")
        return None
    notes: list[str] = []
    chain, keep_c, problem = _rising(chain, "chainage")
    if problem:
        ctx.ledger.error(at("chainage"), f"[Branch] {unquote(obj.branchid)!r}: {problem}")
        return None
    levels, keep_l, problem = _rising(levels, "levels")
    if problem:
        ctx.ledger.error(at("levels"), f"[Branch] {unquote(obj.branchid)!r}: {problem}")
        return None
    # frictionValues: numLocations values for each level in turn (D-Flow FM's setTableMatrix)
    matrix = np.asarray(values, dtype=float).reshape(len(keep_l), len(keep_c)).T  # rows: chainages, columns: levels
    if len(set(keep_c)) < len(keep_c):
        notes.append(f"chainages given twice: the step there is spread over {STEP * 1000:g} mm")
    if function == "waterlevel" and len(set(keep_l)) < len(keep_l):
        notes.append(f"levels given twice: the step there is spread over {STEP * 1000:g} mm")
    if function == "constant" and len(levels) > 1:
        # a constant function with a level table: D-Flow FM interpolates the table at level 0
        matrix = np.array([[float(np.interp(0.0, levels, row))] for row in matrix])
        levels = [0.0]
        notes.append("a level table with functionType = constant: D-Flow FM reads it at level 0, and so does the "
                     "case")
    if _law_name(obj.frictiontype) == "stricklernikuradse":
        matrix = 25.0 * matrix ** (-1.0 / 6.0)
        if matrix.size > 1 and np.ptp(matrix) > 0:
            notes.append("Strickler-Nikuradse roughness heights converted to Strickler k_s = 25 k_n^(-1/6) value by "
                         "value: the case interpolates k_s between them where D-Flow FM interpolates k_n (a fraction "
                         "of a % apart)")
    elif _law_name(obj.frictiontype) == "walllawnikuradse":
        notes.append(friction_of(obj.frictiontype, 1.0)[1])
    entry: dict = {}
    if law != group["type"]:
        entry["type"] = law
    level_dependent = function == "waterlevel" and len(levels) > 1
    if level_dependent:
        entry["function"] = "waterlevel"
        entry["levels"] = levels
        if len(chain) > 1:
            entry["chainages"] = chain
        entry["table"] = [[float(v) for v in row] for row in matrix]
    elif len(chain) > 1 and np.ptp(matrix[:, 0]) > 0:
        entry["chainages"] = chain
        entry["values"] = [float(v) for v in matrix[:, 0]]
    else:
        entry["value"] = float(matrix[0, 0])
    problem = _check_entry(entry, law)
    if problem:
        ctx.ledger.error(at("frictionvalues"), f"[Branch] {unquote(obj.branchid)!r} of friction group "
                         f"{group['id']!r}: {problem}")
        return None
    what = [law if law != group["type"] else ""]
    if level_dependent:
        what.append(f"a function of the water level ({len(levels)} levels)")
    if len(chain) > 1 and ("chainages" in entry):
        what.append(f"along the branch ({len(chain)} chainages)")
    description = ", ".join(w for w in what if w)
    if notes:
        ctx.ledger.approximated("friction on a branch", where, "; ".join([description, *notes]) if description
                                else "; ".join(notes))
    else:
        ctx.ledger.exact("friction on a branch", where, description)
    return entry


def _rising(values: list[float], name: str) -> tuple[list[float], list[float], str]:
    """Values made strictly increasing (a value given twice moves up by :data:`STEP`), the values as read, a problem.

    D-Flow FM interpolates between a value given twice as a step there (``findInterpolationInterval``); a case needs
    strictly increasing values, so the second of two equal values moves up by 1 mm. Values that go down are a
    problem.
    """
    for i, (a, b) in enumerate(itertools.pairwise(values), start=1):
        if b < a:
            return values, values, f"{name} must increase, but {b:g} (position {i + 1}) follows {a:g}"
    out = list(values)
    for i in range(1, len(out)):
        if out[i] <= out[i - 1]:
            out[i] = out[i - 1] + STEP
    return out, list(values), ""


def _check_entry(entry: dict, law: str) -> str:
    """What the case's rules reject in a branch entry (a coefficient out of the plausible range of its law), or ''."""
    from pydantic import ValidationError

    from rivercal.errors import FieldProblem
    from rivercal.network import BranchFriction

    try:
        BranchFriction.model_validate({"branch": "b", **entry}).check_range(law)
    except FieldProblem as exc:
        return str(exc)
    except (ValidationError, ValueError) as exc:
        if isinstance(exc, ValidationError):
            err = exc.errors(include_url=False)[0]
            return " ".join(str(err.get("msg", "")).split())
        return " ".join(str(exc).split())
    return ""
