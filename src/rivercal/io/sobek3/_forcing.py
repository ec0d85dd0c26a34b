"""Boundaries and laterals of a SOBEK 3 model as case tables, with their series.

SOBEK 3 → case:

- ``BoundaryLocations.ini`` ``[Boundary]`` (``type`` 1: water level, 2: discharge) with its ``.bc`` block of the
  same name: a ``timeseries`` → a ``level`` or ``discharge`` boundary with a series, a ``constant`` → a value, a
  ``qhtable`` → a ``rating`` boundary. SOBEK 3 writes the discharges of a Q(h) table at a downstream end
  negative (out of the model) and takes the level from the discharge, holding the table's end levels beyond it
  (as its own results show at the Waal model's downstream end); the case's rating is the outflow as a function
  of the level, so the table is turned around, and beyond its ends the outflow falls to 0 (below) or rises
  steeply (above) within 1 cm, which holds the level there as SOBEK 3 does;
- ``LateralDischargeLocations.ini`` ``[LateralDischarge]`` with its ``.bc`` block → ``[[laterals]]``;
- a series' ``time-interpolation``: ``linear``, ``block-from`` and ``block-to`` (steps whose changes take 1 s in the
  case's linear series); ``periodic = true``: the series repeated over the simulated period;
- the model-wide meteorology of the ``.bc`` file: wind that is not zero is refused (a case has no wind); air
  temperature, humidity and cloudiness only drive the temperature model and are not read.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from rivercal.io._blockwise import STEP_SECONDS, block_steps
from rivercal.io.sobek3._context import Context
from rivercal.io.sobek3._ini import Section
from rivercal.network import MAX_DISCHARGE

__all__ = ["bc_blocks", "bc_series", "convert_forcing"]

BOUNDARY_FILE = "boundaries.csv"
LATERAL_FILE = "laterals.csv"
_UNITS = {"seconds": 1.0, "second": 1.0, "s": 1.0, "minutes": 60.0, "minute": 60.0, "min": 60.0, "hours": 3600.0,
          "hour": 3600.0, "h": 3600.0, "days": 86400.0, "day": 86400.0, "d": 86400.0}
#: Height over which a rating continues beyond the ends of a SOBEK 3 Q(h) table, m (see the module docstring).
RATING_EDGE = 0.01


def bc_blocks(ctx: Context) -> dict[str, list[Section]]:
    """The blocks of the boundary-condition files by name (lower case)."""
    out: dict[str, list[Section]] = {}
    for s in ctx.model.blocks("boundCondFile"):
        if s.kind in ("general",):
            continue
        name = s.text("name", default=None)
        if name is None:
            raise s.error("name", f"a [{s.name}] block of a boundary-condition file needs a name")
        out.setdefault(name.lower(), []).append(s)
    return out


def _quantities(s: Section) -> list[tuple[str, str, int]]:
    """The (quantity, unit, line of the unit) columns of a .bc block, in order."""
    qs, us = s.all("quantity"), s.all("unit")
    if len(qs) != len(us):
        raise s.error("unit", f"{len(qs)} quantities but {len(us)} units: give a unit after each quantity")
    return [(q.value.strip().lower(), u.value.strip(), u.line) for q, u in zip(qs, us, strict=True)]


def _rows(s: Section, columns: int) -> np.ndarray:
    values = []
    for line, text in s.rows:
        parts = text.split()
        if len(parts) != columns:
            raise s.error_at(line, f"the data row has {len(parts)} value(s) but the block's {columns} quantities "
                                   f"need {columns}: {text[:60]!r}")
        try:
            row = [float(p.replace("d", "e").replace("D", "e")) for p in parts]
        except ValueError:
            raise s.error_at(line, f"the data row {text[:60]!r} holds something that is not a number") from None
        if not all(np.isfinite(row)):
            raise s.error_at(line, f"the data row {text[:60]!r} holds a value that is not finite")
        values.append(row)
    if not values:
        raise s.error("function", f"the [{s.name}] block {s.text('name')!r} has no data rows")
    return np.asarray(values, dtype=float)


def bc_series(ctx: Context, s: Section, quantity: str) -> tuple[pd.Series | float, str]:
    """The series (UTC index) or constant of a ``timeseries``/``constant`` .bc block, and a note if approximated."""
    function = s.text("function", default="timeseries").lower()
    cols = _quantities(s)
    names = [q for q, _, _ in cols]
    if quantity not in names:
        raise s.error("quantity", f"the block {s.text('name')!r} has no quantity {quantity!r} (it has "
                                  f"{', '.join(names)})")
    if function == "constant":
        data = _rows(s, len(cols))
        return float(data[0, names.index(quantity)]), ""
    if function != "timeseries":
        raise s.error("function", f"function {function!r} where a time series or a constant is expected")
    if "time" not in names:
        raise s.error("quantity", "a time series needs a 'time' quantity")
    _, unit, unit_line = cols[names.index("time")]
    match = re.fullmatch(r"\s*(\w+)\s+since\s+(.+?)\s*", unit)
    if not match or match.group(1).lower() not in _UNITS:
        raise s.error_at(unit_line, f"time unit {unit!r} is not '<seconds|minutes|hours|days> since <date>'", "unit")
    try:
        ref = pd.Timestamp(match.group(2).strip())
    except ValueError:
        raise s.error_at(unit_line, f"{match.group(2)!r} is not a date", "unit") from None
    ref = ref.tz_localize("UTC") if ref.tzinfo is None else ref.tz_convert("UTC")
    data = _rows(s, len(cols))
    seconds = data[:, names.index("time")] * _UNITS[match.group(1).lower()]
    if np.any(np.diff(seconds) <= 0):
        k = int(np.flatnonzero(np.diff(seconds) <= 0)[0]) + 1
        raise s.error_at(s.rows[k][0], f"the times must increase, but {data[k, names.index('time')]:g} does not "
                                       f"follow {data[k - 1, names.index('time')]:g}")
    values = data[:, names.index(quantity)]
    index = ref + pd.to_timedelta(np.round(seconds * 1000.0).astype(np.int64), unit="ms")
    series = pd.Series(values, index=index)
    notes = []
    interpolation = _interpolation(s)
    if interpolation != "linear" and len(series) > 1:
        series = block_steps(series, interpolation)
        notes.append(f"{interpolation} series taken as steps (each change over {STEP_SECONDS:g} s)")
    if s.flag("periodic", default=False) and len(series) > 1:
        series, note = _periodic(ctx, series, interpolation)
        notes.append(note)
    series, note = _cover(ctx, series)
    if note:
        notes.append(note)
    return series, "; ".join(notes)


def _interpolation(s: Section) -> str:
    """``linear``, ``block-from`` or ``block-to``: a .bc block's time interpolation, however it is spelled.

    The .bc format (hydrolib-core's ``TimeInterpolation``; DeltaShell) writes ``linear``, ``block-from`` and
    ``block-to``; SOBEK 3 also writes ``linear-extrapolate`` and older files ``blockFrom``/``blockTo``. The words
    are compared without case, blanks and hyphens.
    """
    item = s.find("time-interpolation", "timeInterpolation")
    if item is None or not item.value:
        return "linear"
    word = re.sub(r"[^a-z]", "", item.value.lower())
    found = _INTERPOLATIONS.get(word)
    if found is None:
        raise s.error(item.key, f"{item.value!r} is none of linear, block-from, block-to", item)
    return found


_INTERPOLATIONS = {"linear": "linear", "linearextrapolate": "linear", "blockfrom": "block-from",
                   "blockto": "block-to"}


def _periodic(ctx: Context, series: pd.Series, interpolation: str) -> tuple[pd.Series, str]:
    """A periodic series (``periodic = true``) repeated over the simulated period, and the ledger's note.

    ``series`` is one period as the case takes it (block-wise series already as steps). The period is its span,
    from its first time to its last (DeltaShell's periodic extrapolation of a time series); each repeat starts
    again at the first value at the end of the one before (a change over 1 s where the last value differs; a
    ``block-from`` series' last value, which would hold from the end of the period on, is never reached).
    """
    t0, period = series.index[0], series.index[-1] - series.index[0]
    first = int(np.floor((ctx.start - t0) / period))
    last = max(int(np.ceil((ctx.end - t0) / period)), first + 1)
    one = series.iloc[:-1]
    if interpolation != "block-from" and series.iloc[-1] != series.iloc[0]:
        ramp = min(pd.Timedelta(seconds=STEP_SECONDS), (series.index[-1] - series.index[-2]) / 2)
        one = pd.concat([one, pd.Series([series.iloc[-1]], index=[series.index[-1] - ramp])])
        one = one[~one.index.duplicated(keep="first")]
    shifted = [pd.Series(one.to_numpy(), index=one.index + k * period) for k in range(first, last)]
    end = series.iloc[[0]]
    shifted.append(pd.Series(end.to_numpy(), index=end.index + last * period))
    out = pd.concat(shifted)
    note = f"periodic: repeated every {_duration(period)} over the simulated period"
    if series.iloc[-1] != series.iloc[0] and interpolation != "block-from":
        note += (f" (its last value {series.iloc[-1]:g} differs from its first, {series.iloc[0]:g}: each repeat "
                 "starts again at the first, over 1 s)")
    return out, note


def _duration(delta: pd.Timedelta) -> str:
    seconds = delta.total_seconds()
    for unit, size in (("day", 86400.0), ("hour", 3600.0), ("minute", 60.0)):
        if seconds >= size and seconds % size == 0:
            n = int(seconds // size)
            return f"{n} {unit}{'s' if n != 1 else ''}"
    return f"{seconds:g} s"


def _cover(ctx: Context, series: pd.Series) -> tuple[pd.Series, str]:
    """The series extended with its end values so that it covers the simulated period."""
    notes = []
    if series.index[0] > ctx.start:
        series = pd.concat([pd.Series([series.iloc[0]], index=[ctx.start]), series])
        notes.append("starts after the simulated period; its first value held before")
    if series.index[-1] < ctx.end:
        series = pd.concat([series, pd.Series([series.iloc[-1]], index=[ctx.end])])
        notes.append("ends before the simulated period; its last value held after")
    return series, "; ".join(notes)


def convert_forcing(ctx: Context) -> None:
    """Fill the boundaries and laterals of ``ctx.case``."""
    blocks = bc_blocks(ctx)
    used: set[str] = set()
    degree: dict[str, int] = {}
    for b in ctx.case["branches"]:
        for n in (b["from_node"], b["to_node"]):
            degree[n] = degree.get(n, 0) + 1
    boundaries = []
    ctx.reserve("boundary", ctx.model.blocks("boundLocFile", "boundary"), "nodeId")
    ctx.reserve("lateral", ctx.model.blocks("latDischargeLocFile", "lateraldischarge"), "id")
    for s in ctx.model.blocks("boundLocFile", "boundary"):
        nid = ctx.claim("boundary", s, "nodeId")
        code = s.integer("type", default=None)
        if not ctx.known("node", nid) or degree.get(ctx.id("node", nid), 0) == 0:
            ctx.ledger.refused("boundary", nid, f"node {nid!r} is not in the network", hydraulic=False)
            continue
        node = ctx.id("node", nid)
        if degree[node] != 1:
            ctx.ledger.refused("boundary", nid, f"node {nid!r} joins {degree[node]} branches; a boundary sits at an "
                               "end node")
            continue
        found = blocks.get(nid.lower(), [])
        used.add(nid.lower())
        if not found:
            ctx.ledger.refused("boundary", nid, "no block of this name in the boundary-condition file")
            continue
        if len(found) > 1:
            raise found[1].error("name", f"boundary {nid!r} has {len(found)} blocks in the boundary-condition file")
        bc = found[0]
        item, note = _boundary(ctx, bc, node, code)
        if item is None:
            ctx.ledger.refused("boundary", nid, note)
            continue
        item["id"] = ctx.id("boundary", nid)
        boundaries.append(item)
        (ctx.ledger.approximated if note else ctx.ledger.exact)("boundary", nid, note)
    ctx.case["boundaries"] = boundaries
    laterals = []
    for s in ctx.model.blocks("latDischargeLocFile", "lateraldischarge"):
        lid = ctx.claim("lateral", s)
        notes = []
        nid = s.text("nodeId", "nodeid", default=None)
        if nid is not None:
            if not ctx.known("node", nid) or degree.get(ctx.id("node", nid), 0) == 0:
                ctx.ledger.refused("lateral", lid, f"its node {nid!r} is not in the network")
                continue
            lat = {"id": ctx.id("lateral", lid), "node": ctx.id("node", nid)}
        else:
            bid = s.text("branchId", "branchid")
            if not ctx.known("branch", bid) or ctx.id("branch", bid) not in ctx.branches:
                ctx.ledger.refused("lateral", lid, f"its branch {bid!r} is not in the network")
                continue
            branch = ctx.branches[ctx.id("branch", bid)]
            chainage = s.number("chainage")
            length = s.number("length", default=0.0)
            if length > 0:
                chainage += 0.5 * length
                notes.append(f"spread over {length:g} m in SOBEK 3; the case puts it at the middle")
            if chainage < -1e-6 or chainage > branch["length"] + 1e-3:
                raise s.error("chainage", f"chainage {chainage:g} m lies outside branch {bid!r} "
                                          f"(0-{branch['length']:g} m)")
            lat = {"id": ctx.id("lateral", lid), "branch": branch["id"],
                   "chainage": min(max(chainage, 0.0), branch["length"])}
        found = blocks.get(lid.lower(), [])
        used.add(lid.lower())
        if not found:
            ctx.ledger.refused("lateral", lid, "no block of this name in the boundary-condition file")
            continue
        if len(found) > 1:
            raise found[1].error("name", f"lateral {lid!r} has {len(found)} blocks in the boundary-condition file")
        function = found[0].text("function", default="timeseries").lower()
        if function not in ("timeseries", "constant"):
            ctx.ledger.refused("lateral", lid, f"a lateral given as {function!r} (a case takes a time series or a "
                               "constant)")
            continue
        value, note = bc_series(ctx, found[0], "water_discharge")
        if isinstance(value, float):
            lat["value"] = value
        else:
            lat["series"] = ctx.add_series(LATERAL_FILE, lat["id"], value)
        if note:
            notes.append(note)
        laterals.append(lat)
        (ctx.ledger.approximated if notes else ctx.ledger.exact)("lateral", lid, "; ".join(notes))
    ctx.case["laterals"] = laterals
    for name, found in blocks.items():
        if name in used:
            continue
        if name == "model_wide":
            _meteo(ctx, found)
            continue
        ctx.ledger.warn(f"{found[0].where()}: block {found[0].text('name')!r} matches no boundary or lateral and was "
                        "not used")


def _boundary(ctx: Context, bc: Section, node: str, code: int | None) -> tuple[dict | None, str]:
    function = bc.text("function", default="timeseries").lower()
    if function not in ("timeseries", "constant", "qhtable"):
        return None, f"a boundary given as {function!r} (a case takes a time series, a constant or a Q(h) table)"
    names = [q for q, _, _ in _quantities(bc)]
    if function == "qhtable":
        if code not in (None, 1):
            return None, f"a Q(h) table at a boundary of type {code} (type 1, a water level, expected)"
        item, note = _rating(bc, names)
        if item is not None:
            item["node"] = node
        return item, note
    if "water_level" in names:
        kind, quantity = "level", "water_level"
    elif "water_discharge" in names:
        kind, quantity = "discharge", "water_discharge"
    else:
        return None, f"quantities {', '.join(names)}: neither a water level nor a discharge"
    expected = {1: "level", 2: "discharge"}.get(code)
    if expected is not None and expected != kind:
        return None, f"the location file says {expected} (type {code}) but the block gives a {kind}"
    value, note = bc_series(ctx, bc, quantity)
    item: dict = {"node": node, "type": kind}
    if isinstance(value, float):
        item["value"] = value
    else:
        item["series"] = ctx.add_series(BOUNDARY_FILE, ctx.id("boundary", bc.text("name")), value)
    return item, note


def _rating(bc: Section, names: list[str]) -> tuple[dict | None, str]:
    if "water_level" not in names or "water_discharge" not in names:
        raise bc.error("quantity", "a qhtable needs the quantities water_level and water_discharge")
    data = _rows(bc, len(names))
    levels = data[:, names.index("water_level")]
    q = data[:, names.index("water_discharge")]
    order = np.argsort(levels, kind="stable")
    levels, q = levels[order], q[order]
    if np.any(np.diff(levels) <= 0):
        raise bc.error_at(bc.rows[0][0], "the water levels of the Q(h) table must differ from row to row")
    notes = []
    if np.all(q <= 0):
        out = -q  # SOBEK 3's convention: out of the model is negative
    elif np.all(q >= 0):
        out = q
        notes.append("discharges written positive: taken as the outflow (a Q(h) boundary at an end node lets water "
                     "out)")
    else:
        return None, "the Q(h) table's discharges change sign; neither an outflow nor an inflow table"
    if np.any(np.diff(out) < 0):
        return None, "the outflow of the Q(h) table falls as the level rises"
    lv, qv = list(levels), list(out)
    if qv[0] > 0:
        lv.insert(0, lv[0] - RATING_EDGE)
        qv.insert(0, 0.0)
    if qv[-1] < MAX_DISCHARGE:
        lv.append(lv[-1] + RATING_EDGE)
        qv.append(MAX_DISCHARGE)
    notes.append(f"the level follows the table; beyond it the level is held within {RATING_EDGE * 100:g} cm of the "
                 f"table's ends ({levels[0]:g} and {levels[-1]:g} m AD), as SOBEK 3 holds it there")
    return {"node": "", "type": "rating", "rating": {"levels": lv, "discharges": qv}}, "; ".join(notes)


def _meteo(ctx: Context, blocks: list[Section]) -> None:
    for bc in blocks:
        names = [q for q, _, _ in _quantities(bc)]
        data = _rows(bc, len(names))
        for k, quantity in enumerate(names):
            if quantity == "time":
                continue
            if quantity == "wind_speed":
                if np.any(data[:, k] != 0):
                    ctx.ledger.refused("setting", "wind", "wind over the water is not modelled by a case")
                else:
                    ctx.ledger.exact("setting", "wind", "no wind")
            elif quantity != "wind_from_direction":
                ctx.ledger.refused("setting", quantity, "drives SOBEK 3's temperature model only; not read",
                                   hydraulic=False)
