"""Cross-sections of a D-Flow FM model as case profiles and as the cross-sections of its branches.

Definitions become ``[[profiles]]`` (yz, zw, zwRiver, circle, rectangle), locations ``branches[].cross_sections``; a
branch of an order without any takes those D-Flow FM carries across the nodes into it.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from rivercal.io._summer_dike import summer_dike
from rivercal.io.dhydro._context import Context, _numbers, unquote
from rivercal.io.dhydro._friction import MAIN, friction_of

__all__ = ["CLOSED_WIDTH", "SUMMER_DIKE_TRANSITION", "add_profile", "profile_of_definition"]

#: A zw table whose top width is narrower than this is a closed conduit, m.
CLOSED_WIDTH = 1.0e-3
#: D-Flow FM's transition height of a summer dike (``summerDikeTransitionHeight``), m.
SUMMER_DIKE_TRANSITION = 0.5


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
