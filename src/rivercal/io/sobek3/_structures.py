"""Structures of a SOBEK 3 model (``Structures.ini``) as case tables.

SOBEK 3 → case (key names of SOBEK 3's structure file, flow1d's readStructures of the Delft3D 4 source tree):

- ``weir`` (crestLevel, crestWidth, dischargeCoeff, latDisCoeff, allowedFlowDir) → ``[[weirs]]``: the same
  simple-weir formula with its free/submerged switch at two thirds of the upstream head;
- ``universalWeir`` (levelsCount, yValues, zValues as heights above their lowest, crestLevel, dischargeCoeff) →
  ``[[universal_weirs]]``;
- ``orifice``/``gate`` (crestLevel, crestWidth, openLevel, contractionCoeff, latContrCoeff, flow limits) →
  ``[[orifices]]`` with the coefficient μ c_w;
- ``culvert`` and ``invertedSiphon`` (csDefId, leftLevel, rightLevel, length, loss coefficients, bed friction) →
  ``[[culverts]]`` with the definition as their profile;
- ``bridge`` (csDefId, bedLevel, length, loss coefficients, bed friction) → ``[[bridges]]``;
- ``pump`` with one stage controlled on its suction side → ``[[pumps]]``;
- the members of a compound (``compound = 1``, one ``compoundName``) side by side as parallel branches
  (:mod:`rivercal.io.sobek3._compound`);
- ``siphon`` (with its own switch-on levels), ``bridgePillar``, ``riverWeir``, ``advancedWeir``,
  ``generalStructure``, ``extraResistance`` and a valve in a culvert are refused: a case has no counterpart.

``allowedFlowDir`` is 0 (both), 1 (positive), 2 (negative) or 3 (none). Every structure gets a station with the
levels either side and its discharge, as SOBEK 3 reports them.
"""

from __future__ import annotations

import itertools

from rivercal.io.sobek3._context import Context
from rivercal.io.sobek3._friction import convert_value, law_of
from rivercal.io.sobek3._ini import Section
from rivercal.io.sobek3._profiles import add_profile
from rivercal.network import FRICTION_RANGES

__all__ = ["convert_structures"]

_DIRECTIONS = {0: "both", 1: "positive", 2: "negative", 3: "none"}
_TABLES = ("weirs", "universal_weirs", "orifices", "culverts", "bridges", "pumps")
#: Opening given to a closed orifice, m: a case's gate must lie above its crest; no flow passes either way.
CLOSED_OPENING = 1e-3


def _direction(s: Section) -> str:
    item = s.find("allowedFlowDir")
    if item is None or not item.value:
        return "both"
    text = item.value.strip().lower()
    if text in _DIRECTIONS.values():
        return text
    try:
        return _DIRECTIONS[int(float(text))]
    except (ValueError, KeyError):
        raise s.error("allowedFlowDir", f"{item.value!r} is none of 0 (both), 1 (positive), 2 (negative), "
                                        "3 (none)", item) from None


def _friction(s: Section, type_key: str, value_key: str) -> tuple[dict, str]:
    code = s.text(type_key, default="1")
    law = law_of(code)
    if law is None or law in ("engelund", "bosbijkerk"):
        raise s.error(type_key, f"roughness type {code!r} has no counterpart in a case")
    law, value = convert_value(law, s.number(value_key))
    low, high, unit = FRICTION_RANGES[law]
    if not low <= value <= high:
        return {"type": law, "value": min(max(value, low), high)}, (
            f"{law} {value:g} {unit} outside the plausible range, clamped to it")
    return {"type": law, "value": value}, ""


def convert_structures(ctx: Context) -> None:
    """Fill the structure tables of ``ctx.case`` from the model's structure file."""
    tables: dict[str, list[dict]] = {t: [] for t in _TABLES}
    compounds: dict[str, list[tuple[str, dict, Section]]] = {}
    ctx.reserve("structure", ctx.model.blocks("structureFile", "structure"), "id")
    for s in ctx.model.blocks("structureFile", "structure"):
        sid = ctx.claim("structure", s)
        kind = s.text("type").strip()
        bid = s.text("branchId", "branchid", default=None)
        if bid is None or not ctx.known("branch", bid) or ctx.id("branch", bid) not in ctx.branches:
            ctx.ledger.refused(kind, sid, f"its branch {bid!r} is not in the network")
            continue
        branch = ctx.branches[ctx.id("branch", bid)]
        chainage = s.number("chainage")
        if chainage < -1e-6 or chainage > branch["length"] + 1e-3:
            raise s.error("chainage", f"chainage {chainage:g} m lies outside branch {bid!r} (0-{branch['length']:g} m)")
        base = {"id": ctx.id("structure", sid), "branch": branch["id"],
                "chainage": min(max(chainage, 0.0), branch["length"])}
        handler = _HANDLERS.get(kind.lower())
        if handler is None:
            ctx.ledger.refused(kind, sid, f"structure type {kind!r} has no counterpart in a case")
            continue
        table, item, notes, refusal = handler(ctx, s, base)
        if refusal:
            ctx.ledger.refused(kind, sid, refusal)
            continue
        tables[table].append(item)
        ctx.origins[item["id"]] = (kind, sid)
        ctx.places[item["id"]] = s.where(s.find("id"))
        if s.flag("compound", default=False):
            compounds.setdefault(s.text("compoundName", default=sid), []).append((table, item, s))
        (ctx.ledger.approximated if notes else ctx.ledger.exact)(kind, sid, "; ".join(notes))
    _compounds(ctx, compounds, tables)
    for table, items in tables.items():
        if items:
            ctx.case[table] = items
    taken = {st["id"] for st in ctx.case["stations"]}
    for items in tables.values():
        for item in items:
            sid = item["id"] if item["id"] not in taken else f"{item['id']}_structure"
            sid = sid.replace(".", "_")
            taken.add(sid)
            ctx.case["stations"].append({"id": sid, "structure": item["id"], "quantities": ["h_up", "h_down", "Q"]})


def _compounds(ctx: Context, compounds: dict[str, list[tuple[str, dict, Section]]],
               tables: dict[str, list[dict]]) -> None:
    """The compound structures (``compound = 1``, one ``compoundName``) to set side by side, or refuse.

    SOBEK 3 sets the members of a compound side by side on one flow link, between the same two grid points, their
    discharges adding up; :func:`rivercal.io.sobek3._compound.place_compounds` makes them parallel branches. A
    compound of one member is that structure alone. Refused (each member, naming the compound and where its first
    member is): members at different places, a branch without grid points or without coordinates to place the cut
    at, a second compound on a branch.
    """
    nodes = {n["id"]: n for n in ctx.case["nodes"]}
    holding: set[str] = set()
    for name, members in compounds.items():
        if len(members) < 2:
            continue
        first = members[0][1]
        branch = ctx.branches[first["branch"]]
        why = ""
        if any(i["branch"] != first["branch"] or abs(i["chainage"] - first["chainage"]) > 1e-6
               for _, i, _ in members[1:]):
            why = "its members do not lie at one branch and chainage"
        elif "points" not in branch:
            why = f"its branch {branch['id']!r} has no grid points to cut it at"
        elif "geometry" not in branch and not all("x" in nodes[n] for n in (branch["from_node"], branch["to_node"])):
            why = f"its branch {branch['id']!r} has neither a geometry nor nodes with coordinates to cut it at"
        elif branch["id"] in holding:
            why = f"a second compound on branch {branch['id']!r} (the import sets one per branch side by side)"
        if not why:
            holding.add(branch["id"])
            ctx.compounds.append((name, [item["id"] for _, item, _ in members]))
            continue
        s = members[0][2]
        ids = ", ".join(repr(ctx.origins[item["id"]][1]) for _, item, _ in members)
        for table, item, _ in members:
            tables[table].remove(item)
            kind, sid = ctx.origins[item["id"]]
            ctx.ledger.refused(kind, sid, f"a member of compound structure {name!r} ({s.where(s.find('id'))}; "
                               f"members {ids}), whose members SOBEK 3 sets side by side between the same two grid "
                               f"points: {why}")


def _weir(ctx: Context, s: Section, base: dict):
    item = {**base, "crest_level": s.number("crestLevel"), "crest_width": s.number("crestWidth"),
            "discharge_coefficient": s.number("dischargeCoeff", default=1.0),
            "lateral_contraction": s.number("latDisCoeff", default=1.0), "allowed_flow": _direction(s)}
    if not item["crest_width"] > 0:
        raise s.error("crestWidth", f"the crest width must be positive, got {item['crest_width']:g} m")
    for key, name in (("dischargeCoeff", "discharge_coefficient"), ("latDisCoeff", "lateral_contraction")):
        if not 0 < item[name] <= (2.0 if name == "discharge_coefficient" else 1.0):
            raise s.error(key, f"{item[name]:g} lies outside the range of a {key} (above 0, at most "
                               f"{2.0 if name == 'discharge_coefficient' else 1.0:g})")
    return "weirs", item, [], ""


def _universal_weir(ctx: Context, s: Section, base: dict):
    """A universal weir: its crest at ``crestLevel``, its shape the z values above their lowest.

    SOBEK 3's reader (flow1d's ``readUniversalWeir``) takes the z values as heights relative to the crest and
    shifts them so that the lowest is 0; the crest is ``crestLevel`` (raised to the bed where it lies below it,
    as ``ComputeUniversalWeir`` takes the highest of the crest and the bed levels either side).
    """
    count = s.integer("levelsCount", "numLevels", default=None)
    y = s.numbers("yValues", count=count)
    z = s.numbers("zValues", count=len(y))
    crest = s.number("crestLevel")
    if any(b < a for a, b in itertools.pairwise(y)):
        raise s.error("yValues", "the y values of a universal weir must not decrease")
    low = min(z)
    notes = []
    factor = s.number("freeSubmergedFactor", default=0.667)
    if abs(factor - 0.667) > 1e-3:
        notes.append(f"freeSubmergedFactor {factor:g}: the case switches to submerged flow at 2/3")
    item = {**base, "y": y, "z": [v - low for v in z], "crest_level": crest,
            "discharge_coefficient": s.number("dischargeCoeff", default=1.0), "allowed_flow": _direction(s)}
    return "universal_weirs", item, notes, ""


def _orifice(ctx: Context, s: Section, base: dict):
    if s.has("crestLevel"):
        crest, width, gate = s.number("crestLevel"), s.number("crestWidth"), s.number("openLevel",
                                                                                     "gateLowerEdgeLevel")
    else:  # SOBEK 3's older form: a bottom level and an area, a square opening
        crest, area = s.number("bottomLevel"), s.number("area")
        width = area**0.5
        gate = crest + width
    if not width >= 1e-3:
        key = "crestWidth" if s.has("crestLevel") else "area"
        raise s.error(key, f"the opening must be at least 1 mm wide, got {width:g} m")
    mu = s.number("contractionCoeff", default=0.63) * s.number("latContrCoeff", default=1.0)
    if not 0 < mu <= 2.0:
        raise s.error("contractionCoeff", f"contractionCoeff times latContrCoeff is {mu:g}; it must lie above 0 and "
                                          "at most 2")
    item = {**base, "crest_level": crest, "crest_width": width, "gate_lower_edge_level": gate,
            "discharge_coefficient": mu, "allowed_flow": _direction(s)}
    notes = ["contraction coefficient times lateral contraction as the orifice's discharge coefficient"]
    if not gate > crest:  # flow1d's ComputeOrifice: no flow when the opening (gate - crest) is not positive
        item.update(gate_lower_edge_level=crest + CLOSED_OPENING, allowed_flow="none")
        notes.append(f"closed: the gate's lower edge ({gate:g} m AD) is not above the crest ({crest:g} m AD), so "
                     "SOBEK 3 lets no water through; taken as a closed orifice (allowed_flow = 'none')")
    for use, key, name in (("useLimitFlowPos", "limitFlowPos", "max_flow_positive"),
                           ("useLimitFlowNeg", "limitFlowNeg", "max_flow_negative")):
        if s.flag(use, default=False):
            item[name] = s.number(key)
            if item[name] < 0:
                raise s.error(key, f"a largest discharge must not be negative, got {item[name]:g} m³/s")
    return "orifices", item, notes, ""


def _culvert(ctx: Context, s: Section, base: dict, *, siphon: bool = False):
    did = s.text("csDefId")
    if did not in ctx.definitions:
        raise s.error("csDefId", f"cross-section definition {did!r} is not in the definitions file")
    if s.flag("valveOnOff", default=False):
        return "culverts", None, [], "a culvert with a valve: the valve's losses are not converted"
    pid, _ = add_profile(ctx, did)
    if pid is None:
        return "culverts", None, [], f"its cross-section definition {did!r} was refused"
    friction, note = _friction(s, "bedFrictionType", "bedFriction")
    item = {**base, "shape": "profile", "profile": pid, "invert_level": s.number("leftLevel"),
            "invert_level_end": s.number("rightLevel"), "length": s.number("length"),
            "inlet_loss": s.number("inletLossCoeff", default=0.5), "outlet_loss": s.number("outletLossCoeff",
                                                                                          default=1.0),
            "friction": friction, "allowed_flow": _direction(s)}
    if siphon:
        item["bend_loss"] = s.number("bendLossCoeff", default=0.0)
    return "culverts", item, [note] if note else [], ""


def _bridge(ctx: Context, s: Section, base: dict):
    did = s.text("csDefId")
    if did not in ctx.definitions:
        raise s.error("csDefId", f"cross-section definition {did!r} is not in the definitions file")
    pid, _ = add_profile(ctx, did)
    if pid is None:
        return "bridges", None, [], f"its cross-section definition {did!r} was refused"
    friction, note = _friction(s, "bedFrictionType", "bedFriction")
    item = {**base, "profile": pid, "bed_level": s.number("bedLevel"), "length": s.number("length"),
            "inlet_loss": s.number("inletLossCoeff", default=0.5), "outlet_loss": s.number("outletLossCoeff",
                                                                                          default=1.0),
            "friction": friction, "allowed_flow": _direction(s)}
    return "bridges", item, [note] if note else [], ""


def _pump(ctx: Context, s: Section, base: dict):
    direction = s.integer("direction", default=1)
    stages = s.integer("nrStages", "numStages", default=1)
    if abs(direction) not in (1, 2, 3) or direction == 0:
        raise s.error("direction", f"direction {direction} is none of ±1 (suction side), ±2 (delivery side), "
                                   "±3 (both sides)")
    if abs(direction) != 1:
        return "pumps", None, [], "a pump controlled on its delivery side; a case's pump switches on its suction side"
    if stages != 1:
        return "pumps", None, [], f"a pump of {stages} stages; a case's pump has one"
    capacity = s.numbers("capacity", count=1)[0]
    start = s.numbers("startLevelSuctionSide", count=1)[0]
    stop = s.numbers("stopLevelSuctionSide", count=1)[0]
    notes = []
    if s.has("reductionFactor"):
        factors = s.numbers("reductionFactor")
        if any(abs(f - 1.0) > 1e-9 for f in factors):
            notes.append("the reduction of the capacity with the head is not converted (full capacity)")
    item = {**base, "capacity": capacity, "start_level": start, "stop_level": stop,
            "direction": "positive" if direction > 0 else "negative"}
    if not capacity > 0:
        return "pumps", None, [], f"capacity {capacity:g} m³/s: the pump never pumps"
    if stop >= start:
        raise s.error("stopLevelSuctionSide", f"the stop level {stop:g} m AD is not below the start level "
                                              f"{start:g} m AD")
    return "pumps", item, notes, ""


def _refuse(why: str):
    def handler(ctx: Context, s: Section, base: dict):
        return "weirs", None, [], why
    return handler


_HANDLERS = {
    "weir": _weir,
    "universalweir": _universal_weir,
    "orifice": _orifice,
    "gate": _orifice,
    "culvert": _culvert,
    "invertedsiphon": lambda ctx, s, base: _culvert(ctx, s, base, siphon=True),
    "bridge": _bridge,
    "pump": _pump,
    "siphon": _refuse("a siphon with its own switch-on and switch-off levels has no counterpart in a case"),
    "bridgepillar": _refuse("a pillar bridge (pillar width and form factor) has no counterpart in a case"),
    "riverweir": _refuse("a river weir (its reduction tables) has no counterpart in a case"),
    "advancedweir": _refuse("an advanced weir (piers, design head) has no counterpart in a case"),
    "generalstructure": _refuse("a general structure has no exact counterpart in a case"),
    "extraresistance": _refuse("an extra resistance has no counterpart in a case"),
}
