"""Roughness of a SOBEK 3 model as case friction groups: laws, values along a branch or of the water level.

``roughness-*.ini`` → one ``[[friction_groups]]`` per roughness section (``Main``, ``FloodPlain1``, ...) with its
global law and value, and per branch its law and its values: constant, along the branch (``[Definition]`` at
chainages) or as a function of the water level (``functionType = 2``). :func:`law_of` and :func:`convert_value`
also serve the culverts and bridges.
"""

from __future__ import annotations

import itertools
import re
from collections import defaultdict

from rivercal.io.sobek3._context import Context
from rivercal.io.sobek3._ini import Section
from rivercal.network import FRICTION_RANGES

__all__ = ["DEFAULT_CHEZY", "LAWS", "convert_value", "law_of"]

#: SOBEK 3's default roughness, Chézy m^(1/2)/s: a section without a roughness file, and a stand-in in a partial
#: import for a global roughness type a case cannot take.
DEFAULT_CHEZY = 45.0

#: SOBEK 3's roughness type codes (roughness files of version 1, culverts and bridges) → (case law, note).
LAWS = {0: "chezy", 1: "chezy", 4: "manning", 5: "stricklernikuradse", 6: "strickler", 7: "white-colebrook",
        8: "engelund", 9: "bosbijkerk"}
_LAW_NAMES = {"chezy": "chezy", "manning": "manning", "strickler": "strickler", "stricklerks": "strickler",
              "stricklerkn": "stricklernikuradse", "stricklernikuradse": "stricklernikuradse",
              "whitecolebrook": "white-colebrook", "nikuradse": "white-colebrook", "engelund": "engelund",
              "bosbijkerk": "bosbijkerk", "debosbijkerk": "bosbijkerk", "debosenbijkerk": "bosbijkerk"}


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
        gvalue = content.number("globalValue", default=DEFAULT_CHEZY)
        if glaw is None:
            raise content.error("globalType", f"roughness type {content.text('globalType')!r} is none of SOBEK 3's "
                                              "(Chézy 1, Manning 4, Strickler k_n 5, Strickler k_s 6, "
                                              "White-Colebrook 7, Engelund 8, Bos-Bijkerk 9)")
        if glaw in ("engelund", "bosbijkerk"):
            ctx.ledger.refused("friction group", sid, f"{path.name}: global roughness type {glaw} has no counterpart "
                               "in a case (its coefficient depends on the flow); where a branch gives no roughness "
                               f"of its own, a partial import takes Chézy {DEFAULT_CHEZY:g} m^(1/2)/s, SOBEK 3's "
                               "default roughness")
            glaw, gvalue = "chezy", DEFAULT_CHEZY
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
