"""Structures of a D-Flow FM model as case tables.

D-Flow FM → case: ``weir`` → ``[[weirs]]``; ``universalWeir`` → ``[[universal_weirs]]``; ``orifice`` →
``[[orifices]]``; ``culvert`` (also a siphon) → ``[[culverts]]``; ``bridge`` → ``[[bridges]]``; ``pump`` →
``[[pumps]]``; ``compound`` → its members, side by side (:mod:`._compound`); ``generalStructure`` and ``gate`` →
an orifice (approximated); ``dambreak`` and ``longCulvert`` are refused (on a branch as hydraulic refusals: they
carry water). Settings given as time series
(``.tim``/``.bc``) or supplied in real time (DIMR exchange files) become structure-setting series.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rivercal.io.dhydro._context import Context, unquote
from rivercal.io.dhydro._forcing import forcing_series, held_series
from rivercal.io.dhydro._friction import friction_of
from rivercal.io.dhydro._profiles import add_profile

__all__ = ["convert_structures"]

SETTINGS_FILE = "settings.csv"


def _direction(value: Any) -> str:
    name = str(getattr(value, "value", value) or "both").lower()
    return name if name in ("both", "positive", "negative", "none") else "both"


#: Why a long culvert on a branch is refused (a hydraulic refusal: it carries water between two places).
_LONG_CULVERT = ("a long culvert: D-Flow FM builds it as a conduit of flow links of its own along its polyline "
                 "(xCoordinates, yCoordinates, zCoordinates), with friction and no inlet or outlet losses, between the "
                 "places its ends connect; a case has no such conduit and the import does not guess where its ends "
                 "join the network. Model it as a [[culverts]] entry (width x height, inverts from zCoordinates) or a "
                 "branch of its own")
_DAMBREAK = ("a dam break: its breach deepens and widens in time (the Verheij-Van der Knaap growth formula, or a "
             "series of its levels and widths) between the places it connects; a case has no breach. Model the "
             "breach as a weir whose crest follows a series (crest_series), or leave the dam break out where it "
             "does not break in the simulated period")
#: Structure types on a branch that carry water and that a case cannot take: hydraulic refusals with their reason.
_REFUSED = {"longCulvert": _LONG_CULVERT, "dambreak": _DAMBREAK}


def convert_structures(ctx: Context) -> None:
    """Fill the structure tables of ``ctx.case`` from the model's structure files."""
    tables: dict[str, list[dict]] = {t: [] for t in ("weirs", "culverts", "pumps", "orifices", "universal_weirs",
                                                     "bridges")}
    objects = _once(ctx, [s for f in ctx.model.structures for s in f.objects])
    for f in ctx.model.structures:
        for kind, sid, reason in f.failed:
            ctx.ledger.refused(kind, unquote(sid), reason)
    by_id = {unquote(s.id): s for s in objects}
    compounds: list[tuple[str, list[str]]] = []
    for s in objects:
        if s.type != "compound":
            continue
        cid = unquote(s.id)
        members = [unquote(m) for m in (s.structureids or [])]
        missing = [m for m in members if m not in by_id]
        if missing:
            ctx.ledger.refused("compound", cid, f"member(s) {', '.join(missing)} not found", hydraulic=False)
        present = [m for m in members if m in by_id]
        if len(present) > 1:
            compounds.append((cid, present))
        else:
            ctx.ledger.exact("compound", cid, "one member: the member itself")
    for s in objects:
        if s.type == "compound":
            continue
        sid = unquote(s.id)
        if s.branchid is None or s.chainage is None:
            ctx.ledger.refused(s.type, sid, "located by x, y coordinates: a structure of the 2D part of a 1D2D "
                               "model, which a case leaves out", hydraulic=False)
            continue
        if not ctx.ids["branch"].known(s.branchid) or ctx.id("branch", s.branchid) not in ctx.branch_length:
            ctx.ledger.refused(s.type, sid, f"its branch {unquote(s.branchid)!r} is not in the network")
            continue
        branch = ctx.id("branch", s.branchid)
        length = ctx.branch_length[branch]
        if float(s.chainage) > length + max(1.0, 0.01 * length):
            ctx.ledger.error(ctx.model.sources.where(s, ctx.model.sources.key_of(s, "chainage")) or ctx.model.mdu.name,
                             f"{s.type} {sid!r}: chainage {float(s.chainage):g} m lies beyond the end of branch "
                             f"{unquote(s.branchid)} ({length:g} m long)")
            continue
        chainage = min(max(float(s.chainage), 0.0), length)
        base = {"id": ctx.id("structure", sid), "branch": branch, "chainage": chainage}
        handler = _HANDLERS.get(s.type)
        if s.type in _REFUSED:
            ctx.ledger.refused(s.type, sid, _REFUSED[s.type])
            continue
        if handler is None:
            ctx.ledger.refused(s.type, sid, f"structure type {s.type!r} has no counterpart in a case")
            continue
        table, item, notes, refusal = handler(ctx, s, base)
        if refusal:
            ctx.ledger.refused(s.type, sid, refusal)
            continue
        tables[table].append(item)
        ctx.origins[item["id"]] = (s.type, sid)
        ctx.source(table, item["id"], s)
        (ctx.ledger.approximated if notes else ctx.ledger.exact)(s.type, sid, "; ".join(notes))
    for table, items in tables.items():
        if items:
            ctx.case[table] = items
    converted = {i["id"] for items in tables.values() for i in items}
    for cid, members in compounds:
        ids = [ctx.id("structure", m) for m in members]
        kept = [i for i in ids if i in converted]
        if len(kept) > 1:
            ctx.compounds.append((cid, kept))
        elif kept:
            ctx.ledger.exact("compound", cid, "its other members were refused (see there): the one left is itself")
    # D-Flow FM reports every structure's levels either side and discharge: so does the case
    taken = {st["id"] for st in ctx.case["stations"]}
    for items in tables.values():
        for item in items:
            sid = item["id"] if item["id"] not in taken else f"{item['id']}_structure"
            sid = sid.replace(".", "_")
            taken.add(sid)
            ctx.case["stations"].append({"id": sid, "structure": item["id"], "quantities": ["h_up", "h_down", "Q"]})


def _once(ctx: Context, objects: list[Any]) -> list[Any]:
    """The structures whose id no earlier block has; each repeat is an error naming both blocks.

    D-Flow FM knows a structure by its id (its settings, exchange series and history output go by it), within a
    file and across the files of ``StructureFile``; which of two blocks it would take is not for the import to guess.
    """
    seen: dict[str, Any] = {}
    kept = []
    sources = ctx.model.sources
    for s in objects:
        sid = unquote(s.id)
        first = seen.get(sid)
        if first is None:
            seen[sid] = s
            kept.append(s)
            continue
        ctx.ledger.error(sources.where(s) or ctx.model.mdu.name,
                         f"a second structure with id {sid!r} ({s.type}); the first ({first.type}) is at "
                         f"{sources.where(first) or 'an earlier block'}: a structure id may be given once "
                         "(remove or rename one of them)")
    return kept


# -- settings that may be time series ------------------------------------------------------------------


def _setting(ctx: Context, s: Any, field: str, quantity: str, what: str, notes: list[str]) -> tuple[float | None,
                                                                                                     dict | None, str]:
    """A structure setting: constant value, series reference (from a file or an exchange file), or a refusal."""
    sid = unquote(s.id)
    key = f"{quantity}/{sid}/{field}"
    exchanged = ctx.exchange.get(key)
    value = getattr(s, field.lower())
    if exchanged is not None:
        ctx.exchange_used.add(key)
        series = held_series(ctx, exchanged)
        ref = ctx.add_series(SETTINGS_FILE, f"{sid}.{field}", series)
        notes.append(f"{what} follows its series in the exchange file (each value held until the next exchange "
                     "time); the value in the structure file is not used")
        constant = float(value) if isinstance(value, int | float) else float(series.iloc[0])
        return constant, ref, ""
    if isinstance(value, int | float):
        return float(value), None, ""
    if value is None:
        return None, None, f"{what} is missing"
    try:
        series = forcing_series(ctx, value, name=sid)
    except ValueError as exc:
        return None, None, f"{what}: {exc}"
    if series.nunique() == 1:
        return float(series.iloc[0]), None, ""
    ref = ctx.add_series(SETTINGS_FILE, f"{sid}.{field}", series)
    return float(series.iloc[0]), ref, ""


# -- one handler per type: (table, item, notes, refusal) -------------------------------------------------


def _weir(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    crest, ref, why = _setting(ctx, s, "crestLevel", "weirs", "the crest level", notes)
    if why:
        return "weirs", {}, notes, why
    width = s.crestwidth
    if width is None:
        width = _width_at(ctx, base["branch"], base["chainage"], crest)
        notes.append(f"no crest width: the flow width of the channel at the crest, {width:.3g} m, as D-Flow FM takes")
    item = {**base, "crest_level": crest, "crest_width": float(width),
            "discharge_coefficient": float(s.corrcoeff), "allowed_flow": _direction(s.allowedflowdir)}
    if ref:
        item["crest_series"] = ref
    if s.usevelocityheight:
        notes.append("the upstream velocity head is not added to the upstream level (useVelocityHeight); at the "
                     "velocities of a polder channel (< 0.5 m/s) it is below 1.3 cm")
    return "weirs", item, notes, ""


def _universal_weir(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    y = [float(v) for v in s.yvalues]
    z = [float(v) for v in s.zvalues]
    low = min(z)
    item = {**base, "y": y, "z": [v - low for v in z], "crest_level": float(s.crestlevel),
            "discharge_coefficient": float(s.dischargecoeff), "allowed_flow": _direction(s.allowedflowdir)}
    # D-Flow FM shifts the crest shape so that its lowest point lies at crestLevel: z relative to that point
    return "universal_weirs", item, [], ""


def _orifice(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    crest, cref, why = _setting(ctx, s, "crestLevel", "orifices", "the crest level", notes)
    if why:
        return "orifices", {}, notes, why
    if cref:
        return "orifices", {}, notes, "a crest level that varies in time (only the gate of an orifice may vary)"
    gate, gref, why = _setting(ctx, s, "gateLowerEdgeLevel", "orifices", "the gate's lower edge", notes)
    if why:
        return "orifices", {}, notes, why
    width = s.crestwidth
    if width is None:
        width = _width_at(ctx, base["branch"], base["chainage"], crest)
        notes.append(f"no crest width: the flow width of the channel at the crest, {width:.3g} m")
    item = {**base, "crest_level": crest, "crest_width": float(width),
            "discharge_coefficient": float(s.corrcoeff), "allowed_flow": _direction(s.allowedflowdir)}
    _gate_of(ctx, item, gate, gref, notes)
    if s.uselimitflowpos and s.limitflowpos is not None:
        item["max_flow_positive"] = float(s.limitflowpos)
    if s.uselimitflowneg and s.limitflowneg is not None:
        item["max_flow_negative"] = float(s.limitflowneg)
    if s.usevelocityheight:
        notes.append("the upstream velocity head is not added to the upstream level (useVelocityHeight)")
    return "orifices", item, notes, ""


def _general(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    crest, cref, why = _setting(ctx, s, "crestLevel", "generalStructures", "the crest level", notes)
    if why or cref:
        return "orifices", {}, notes, why or "a crest level that varies in time"
    gate, gref = None, None  # no gate: a weir
    if s.gateloweredgelevel is not None or f"generalStructures/{unquote(s.id)}/gateLowerEdgeLevel" in ctx.exchange:
        gate, gref, why = _setting(ctx, s, "gateLowerEdgeLevel", "generalStructures", "the gate's lower edge", notes)
        if why:
            return "orifices", {}, notes, why
    width = float(s.crestwidth or _width_at(ctx, base["branch"], base["chainage"], crest))
    coefficient = float(s.posfreegateflowcoeff or 1.0) * float(s.poscontrcoeffreegate or 1.0)
    notes.append("general structure taken as an orifice (weir under a gate) of the crest width, with the "
                 "positive free-gate flow coefficient x contraction as discharge coefficient; the approach "
                 "widths and levels and the separate drowned/negative coefficients are not used")
    if gref is None and (gate is None or gate > crest + 100):
        item = {**base, "crest_level": crest, "crest_width": width,
                "discharge_coefficient": min(float(s.posfreeweirflowcoeff or 1.0), 2.0),
                "allowed_flow": _direction(s.allowedflowdir)}
        notes[-1] = "general structure with its gate out of the water taken as a weir of the crest width"
        return "weirs", item, notes, ""
    item = {**base, "crest_level": crest, "crest_width": width,
            "discharge_coefficient": min(coefficient, 2.0), "allowed_flow": _direction(s.allowedflowdir)}
    _gate_of(ctx, item, gate, gref, notes)
    return "orifices", item, notes, ""


def _gate(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    crest, cref, why = _setting(ctx, s, "crestLevel", "gates", "the sill level", notes)
    if why or cref:
        return "orifices", {}, notes, why or "a sill level that varies in time"
    gate, gref, why = _setting(ctx, s, "gateLowerEdgeLevel", "gates", "the gate's lower edge", notes)
    if why:
        return "orifices", {}, notes, why
    width = float(s.crestwidth or _width_at(ctx, base["branch"], base["chainage"], crest))
    item = {**base, "crest_level": crest, "crest_width": width, "discharge_coefficient": 1.0}
    _gate_of(ctx, item, gate, gref, notes)
    notes.append("gate taken as an orifice of the sill width (the horizontal gate opening is not used)")
    return "orifices", item, notes, ""


def _gate_of(ctx: Context, item: dict, gate: float, gref: dict | None, notes: list[str]) -> None:
    """Set an orifice's gate: a constant level, or a series that may close it at some times and open it at others.

    A case's orifice needs its gate above the crest (``gate_lower_edge_level``); the engine takes a gate series'
    value at or below the crest as a closed gate (no flow), so a series carries its closed times as they are. Only
    a gate that is closed for the whole run (a constant, or a series never above the crest) becomes
    ``allowed_flow = "none"``. The constant beside a series is the series' first opening (it is what a spin-up
    without the series would take; the engine follows the series).
    """
    crest = item["crest_level"]
    if gref is None:
        if gate <= crest:
            item["gate_lower_edge_level"] = crest + 0.001
            item["allowed_flow"] = "none"
            notes.append(f"the gate ({gate:g} m AD) is down on the crest ({crest:g} m AD): closed, no flow")
        else:
            item["gate_lower_edge_level"] = gate
        return
    series = ctx.series[gref["file"]][gref["column"]]
    values = series.to_numpy(dtype=float)
    item["gate_series"] = gref
    open_values = values[values > crest]
    if open_values.size == 0:
        item["gate_lower_edge_level"] = crest + 0.001
        item["allowed_flow"] = "none"
        notes.append(f"the gate series never rises above the crest ({crest:g} m AD): closed all the time, no flow")
        return
    item["gate_lower_edge_level"] = float(gate) if gate > crest else float(open_values[0])


def _culvert(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    d = next((x for x in ctx.model.crossdefs.objects if unquote(x.id) == unquote(s.csdefid)), None)
    if d is None:
        return "culverts", {}, notes, f"its cross-section definition {unquote(s.csdefid)!r} is missing or unreadable"
    item: dict = {**base}
    kind = type(d).__name__
    ctx.used_definitions.add(unquote(s.csdefid))
    if kind == "CircleCrsDef":
        item.update(shape="circular", diameter=float(d.diameter))
        ctx.ledger.exact("profile", unquote(d.id), "the shape of a culvert (its diameter)")
    elif kind == "RectangleCrsDef" and d.closed:
        item.update(shape="rectangular", width=float(d.width), height=float(d.height))
        ctx.ledger.exact("profile", unquote(d.id), "the shape of a culvert (its width and height)")
    else:
        pid, _ = add_profile(ctx, s.csdefid, for_structure=True)
        if pid is None:
            return "culverts", {}, notes, f"its cross-section definition {unquote(s.csdefid)!r} was refused"
        item.update(shape="profile", profile=pid)
    left, right = float(s.leftlevel), float(s.rightlevel)
    item["invert_level"] = left
    if right != left:
        item["invert_level_end"] = right
    item["length"] = max(float(s.length), 0.001)
    item["inlet_loss"] = float(s.inletlosscoeff)
    item["outlet_loss"] = float(s.outletlosscoeff)
    item["outlet_expansion"] = True  # D-Flow FM's exit loss: outletLossCoeff (1 - A / A_downstream)²
    if s.bendlosscoeff:
        item["bend_loss"] = float(s.bendlosscoeff)
    if s.bedfrictiontype is not None and s.bedfriction is not None:
        fr, note = friction_of(s.bedfrictiontype, s.bedfriction)
        if fr is None:
            return "culverts", {}, notes, note
        if note:
            notes.append(note)
        item["friction"] = fr
    else:
        notes.append("no bed friction given: Manning n = 0.015 (concrete)")
    item["allowed_flow"] = _direction(s.allowedflowdir)
    if s.valveonoff:
        opening = s.valveopeningheight
        if not isinstance(opening, int | float):
            return "culverts", {}, notes, "a valve whose opening varies in time"
        notes.append(f"valve at {float(opening):g} m opening ignored: the culvert is taken fully open (its loss table "
                     "has no counterpart)")
    subtype = str(getattr(s.subtype, "value", s.subtype) or "culvert").lower()
    if subtype == "invertedsiphon":
        notes.append("an inverted siphon: a culvert with its two inverts and the bend loss")
    return "culverts", item, notes, ""


def _bridge(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    pid, bottom = add_profile(ctx, s.csdefid, for_structure=True)
    if pid is None:
        return "bridges", {}, notes, f"its cross-section definition {unquote(s.csdefid)!r} was refused"
    fr, note = friction_of(s.frictiontype, s.friction)
    if fr is None:
        return "bridges", {}, notes, note
    if note:
        notes.append(note)
    item = {**base, "profile": pid, "bed_level": bottom + float(s.shift), "length": max(float(s.length), 0.001),
            "inlet_loss": float(s.inletlosscoeff), "outlet_loss": float(s.outletlosscoeff), "friction": fr,
            "allowed_flow": _direction(s.allowedflowdir)}
    return "bridges", item, notes, ""


def _pump(ctx: Context, s: Any, base: dict) -> tuple[str, dict, list[str], str]:
    notes: list[str] = []
    capacity, cref, why = _setting(ctx, s, "capacity", "pumps", "the capacity", notes)
    if why:
        return "pumps", {}, notes, why
    side = str(getattr(s.controlside, "value", s.controlside) or "suctionSide").lower()
    stages = int(s.numstages or 1)
    if side not in ("suctionside",):
        return "pumps", {}, notes, f"control side {s.controlside!r}: a case pump switches on its suction side only"
    start, stop = s.startlevelsuctionside, s.stoplevelsuctionside
    if not start or not stop:
        return "pumps", {}, notes, "no start/stop levels on the suction side"
    if stages > 1:
        notes.append(f"{stages} stages: taken as one stage with the first stage's levels and the full capacity")
    item = {**base, "capacity": capacity, "start_level": float(start[0]), "stop_level": float(stop[0]),
            "direction": "negative" if str(getattr(s.orientation, "value", s.orientation)) == "negative"
            else "positive"}
    if cref:
        item["capacity_series"] = cref
        if capacity <= 0:
            item["capacity"] = float(getattr(s, "capacity", 0.0) or 0.0) if isinstance(s.capacity, int | float) else 0
    if item["capacity"] <= 0:
        if cref is None:
            return "pumps", {}, notes, "capacity 0: a pump that never runs (left out; it does not change the flow)"
        item["capacity"] = 1.0
        notes.append("nominal capacity 1 m³/s (the series sets the real one)")
    if s.numreductionlevels:
        notes.append("capacity reduction table (by head) ignored: the pump delivers its capacity at any head")
    return "pumps", item, notes, ""


def _width_at(ctx: Context, branch: str, chainage: float, level: float) -> float:
    """Flow width (m) of the channel at a chainage and level: D-Flow FM's width for a structure without one."""
    b = next(x for x in ctx.case["branches"] if x["id"] == branch)
    cs = min(b["cross_sections"], key=lambda c: abs(c["chainage"] - chainage))
    prof = next(p for p in ctx.case["profiles"] if p["id"] == cs["profile"])
    depth = max(level - cs["bed_level"], 0.0)
    if prof["type"] == "rectangular":
        return prof["width"]
    if prof["type"] == "trapezoidal":
        return prof["bottom_width"] + 2 * prof["side_slope"] * depth
    if prof["type"] == "circular":
        return prof["diameter"]
    if prof["type"] == "zw":
        return float(np.interp(depth, prof["heights"], prof["flow_widths"]))
    y, z = np.asarray(prof["y"]), np.asarray(prof["z"])
    wet = z <= depth
    return float(y[wet].max() - y[wet].min()) if wet.any() else 1.0


_HANDLERS = {"weir": _weir, "universalWeir": _universal_weir, "orifice": _orifice, "culvert": _culvert,
             "bridge": _bridge, "pump": _pump, "generalStructure": _general, "gate": _gate}
