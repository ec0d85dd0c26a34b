"""Cross-sections of a SOBEK 3 model as case profiles and as the cross-sections of its branches.

``CrossSectionDefinitions.ini`` → ``[[profiles]]``: ``tabulated`` → ``zw`` (flow and total widths, the main channel
and floodplains as friction sections, the summer dike ``sd_*``; closed when no width is left at its top),
``rectangle``, ``trapezium``, ``circle`` (also when written with a table), ``yz``;
``CrossSectionLocations.ini`` → ``branches[].cross_sections`` with bed level = the definition's lowest level + shift.
:func:`add_profile` also serves the structures that name a definition.
"""

from __future__ import annotations

import itertools
from collections import defaultdict

import numpy as np

from rivercal.io._summer_dike import summer_dike
from rivercal.io.sobek3._context import Context
from rivercal.io.sobek3._ini import Section

__all__ = ["SECTION_NAMES", "add_profile", "profile_of", "unused_definitions"]

#: Default names of the friction sections of a profile (SOBEK 3 uses them when a definition names none).
SECTION_NAMES = ["Main", "FloodPlain1", "FloodPlain2"]
#: A flow width below this is no section at all, m (SOBEK 3's Preissmann-slot threshold).
_NO_WIDTH = 1e-3


def _cross_sections(ctx: Context) -> None:
    ctx.reserve("profile", ctx.model.blocks("crossDefFile", "definition"), "id")
    for s in ctx.model.blocks("crossDefFile", "definition"):
        did = s.text("id")
        if did in ctx.definitions:
            raise s.error("id", f"cross-section definition {did!r} is defined twice")
        ctx.definitions[did] = s
    per_branch: dict[str, list[tuple[float, dict, str]]] = defaultdict(list)
    for s in ctx.model.blocks("crossLocFile", "crosssection"):
        cid = ctx.claim("cross-section", s)
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
    if (kind == "egg" or (kind == "circle" and not s.has("diameter"))) and s.has("numLevels"):
        kind = "tabulated"  # DeltaShell writes the table of such a shape too; a circle keeps its diameter
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
    # closed when no width is left at the top: flow1d's readTabulatedCS closes a table whose top total width is no
    # wider than its Preissmann slot (a culvert's pipe or egg given as a table); an open one may narrow in its flow
    # width only (the rest stores)
    closed = len(levels) > 1 and total[-1] < _NO_WIDTH
    if not closed and any(b < a for a, b in itertools.pairwise(total)):
        notes.append("total widths that narrow upward held at their largest value below (an open profile's storage "
                     "cannot shrink)")
        total = list(np.maximum.accumulate(total))
    if len(levels) < 2:
        levels, flow, total = [levels[0], levels[0] + 0.01], flow * 2, total * 2
        notes.append("a single level: taken as vertical walls")
    if max(flow) <= 0:
        return None, 0.0, "every flow width is 0: the profile conveys no water"
    if not closed and flow[-1] <= 0:
        notes.append(f"the flow width closes at the top of an open table (its total width does not): the top keeps "
                     f"{_NO_WIDTH * 1000:g} mm of flow width")
        flow = [*flow[:-1], _NO_WIDTH]
    if s.flag("groundlayerUsed", default=False) and s.number("groundlayer", default=0.0) > 0:
        return None, 0.0, "a ground layer (groundlayerUsed) is not converted"
    bottom = levels[0]
    prof: dict = {"id": pid, "type": "zw", "heights": [v - bottom for v in levels], "flow_widths": flow}
    if total != flow:
        prof["total_widths"] = total
    if closed:
        prof["closed"] = True
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
