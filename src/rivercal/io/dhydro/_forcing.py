"""Boundaries, laterals and the time series of a D-Flow FM model, and the DIMR exchange files.

D-Flow FM → case: ``waterlevelbnd`` → a level boundary; ``dischargebnd`` → a discharge boundary;
``qhbnd`` → a rating boundary; a level boundary at −999 m (D-Flow FM's free outfall, whose level lies
below any bed) → a rating boundary with the critical-flow discharge of the end cross-section. Laterals
keep their node or branch and chainage. Values: a constant, a ``.bc`` time series (its own time unit),
a ``.tim`` file (minutes since the reference date), or ``realtime`` — supplied at run time by a
coupled model, taken from a DIMR exchange file when one is given.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.io._blockwise import block_steps
from rivercal.io.dhydro._context import Context, unquote

__all__ = ["FREE_OUTFALL_LEVEL", "convert_forcing", "forcing_series", "held_series", "read_exchange"]

#: A level boundary at or below this level (m AD) is D-Flow FM's free outfall.
FREE_OUTFALL_LEVEL = -998.0
BOUNDARY_FILE = "boundaries.csv"
LATERAL_FILE = "laterals.csv"
G = 9.81


# -- DIMR exchange files -------------------------------------------------------------------------------


def read_exchange(path: Path, refdate: pd.Timestamp) -> dict[str, pd.Series]:
    """The series of a DIMR exchange file, by D-Flow FM quantity (``laterals/<id>/water_discharge``).

    An exchange file holds ``item<k>_values`` whose ``long_name`` is ``"<source> -> <target>"``; the side
    that names a D-Flow FM quantity (``laterals/``, ``weirs/``, ``pumps/``, ``observations/``, ...) is the
    key. ``time_offset`` counts seconds from the model's reference date.
    """
    import xarray as xr

    out: dict[str, pd.Series] = {}
    with xr.open_dataset(path, decode_times=False) as ds:
        if "time_offset" not in ds.coords and "time_offset" not in ds:
            raise ValueError(f"{path}: no time_offset: not a DIMR exchange file")
        seconds = np.asarray(ds["time_offset"].values, dtype=float)
        if seconds.ndim != 1 or not np.all(np.isfinite(seconds)) or np.any(np.diff(seconds) <= 0) or \
                np.any(np.abs(seconds) > 3.2e9):
            raise ValueError("time_offset: times that are not finite, increasing seconds from the reference date")
        index = refdate + pd.to_timedelta(seconds, unit="s")
        for name, var in ds.data_vars.items():
            long_name = str(var.attrs.get("long_name", ""))
            if not name.endswith("_values") or "->" not in long_name:
                continue
            key = _flow_side(long_name)
            if key is None:
                continue
            values = np.asarray(var.values, dtype=float).reshape(len(index), -1)[:, 0]
            if not np.all(np.isfinite(values)):
                raise ValueError(f"{name} ({long_name}): values that are not finite numbers")
            out[key] = pd.Series(values, index=index, name=key)
    return out


_FLOW_PREFIXES = ("laterals/", "weirs/", "pumps/", "orifices/", "culverts/", "observations/", "generalStructures/",
                  "gates/", "boundaries/", "universalWeirs/")


def _flow_side(long_name: str) -> str | None:
    for side in (s.strip() for s in long_name.split("->")):
        if side.startswith(_FLOW_PREFIXES):
            return side
    return None


# -- .bc and .tim series -----------------------------------------------------------------------------------


_SINCE = re.compile(r"^\s*(seconds|minutes|hours|days)\s+since\s+(.+?)\s*$", re.I)


def _time_unit(unit: str) -> tuple[float, pd.Timestamp]:
    """Seconds per unit and the reference time (UTC) of a ``.bc`` time unit ``<unit> since <date> [<offset>]``.

    A date without an offset is GMT (UTC) whatever the MDU's ``Tzone``, as D-Flow FM's EC module reads a ``.bc``
    file: ``ecSupportTimestringToUnitAndRefdate`` takes the zone 0 when the unit names none, and
    ``ecSupportTimeToTimesteps`` moves a source time by ``k_timezone - ec_timezone`` (the model's ``Tzone``
    minus the file's zone) into model time (Deltares delft3d, ``ec_support.f90``; the MDU's own comment: "Data
    Sources in GMT are interrogated with time in minutes since refdat-Tzone*60"). A date with an offset
    (``+01:00``, ``+0100``) is in that zone. A ``.tim`` file and an exchange file count from ``RefDate`` in
    ``Tzone`` instead (``Context.refdate``).
    """
    m = _SINCE.match(unit)
    if not m:
        raise ValueError(f"time unit {unit!r} is not '<seconds|minutes|hours|days> since <date>'")
    factor = {"seconds": 1.0, "minutes": 60.0, "hours": 3600.0, "days": 86400.0}[m.group(1).lower()]
    try:
        base = pd.Timestamp(m.group(2).strip())
    except (ValueError, OverflowError):
        base = pd.NaT
    if base is pd.NaT:
        raise ValueError(f"time unit {unit!r}: {m.group(2).strip()!r} is not a date")
    base = base.tz_localize("UTC") if base.tzinfo is None else base.tz_convert("UTC")
    return factor, base


def forcing_series(ctx: Context, value: Any, *, name: str) -> pd.Series:
    """A constant, ``.bc`` block or ``.tim`` file as a UTC series covering the simulated period.

    Raises
    ------
    ValueError
        For a function the case cannot express (harmonic, astronomic, ...), a missing block, or values
        that cannot be used (these are also recorded as errors at their line).
    """
    kind = type(value).__name__
    if isinstance(value, int | float):
        return _constant(ctx, float(value))
    if kind == "TimModel":
        t = np.array([r.time for r in value.timeseries], dtype=float)
        v = np.array([r.data[0] if r.data else np.nan for r in value.timeseries], dtype=float)
        where = ctx.model.sources.rel(_source_path(ctx, value))
        if t.size == 0 or not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))) or np.any(np.abs(t) > 5e7) or \
                np.any(np.abs(v) > _LARGEST):
            ctx.ledger.error(where, "a time or value that is not a finite number of a plausible size")
            raise ValueError(f"{where}: unusable values (see the errors)")
        return _cover(ctx, pd.Series(v, index=ctx.refdate + pd.to_timedelta(t * 60.0, unit="s")))
    if kind == "ForcingModel":
        block = _block(value, name, ctx)
        return block_series(ctx, block, value)
    if kind == "DiskOnlyFileModel":
        raise ValueError(f"the forcing file {getattr(value, 'filepath', None)} could not be validated by hydrolib-core")
    raise ValueError(f"a value of type {kind} cannot be converted")


#: Largest magnitude of a value of a forcing series (a level in m AD, a discharge in m³/s, a width in m).
_LARGEST = 1.0e7


def _source_path(ctx: Context, model: Any) -> Path:
    path = Path(getattr(model, "filepath", None) or "")
    return path if path.is_absolute() else ctx.model.mdu.parent / path


def _block(model: Any, name: str, ctx: Context | None = None) -> Any:
    for f in model.forcing:
        if unquote(f.name) == unquote(name):
            return f
    if ctx is not None:
        for path, failures in ctx.model.sources.forcing_failures.items():
            if ctx.model.sources.rel(path) == str(getattr(model, "filepath", "")) and unquote(name) in failures:
                raise ValueError(f"its forcing block {unquote(name)!r} in {getattr(model, 'filepath', '?')} cannot be "
                                 f"read: {failures[unquote(name)]}")
    raise ValueError(f"no forcing block named {name!r} in {getattr(model, 'filepath', '?')}")


def _bc_where(ctx: Context, model: Any, block: Any, row: int | None) -> str:
    """``file, line N`` of a block of a ``.bc`` file (of one of its data rows when given)."""
    path = _source_path(ctx, model) if model is not None else None
    rel = ctx.model.sources.rel(path) if path is not None else "the forcing file"
    try:
        index = ctx.model.sources.ini(path, datablocks=True) if path is not None else None
    except OSError:
        index = None
    if index is None:
        return rel
    section = next((s for s in index.of("forcing") if s.block_id == unquote(block.name)), None)
    if section is None:
        return rel
    if row is not None and row < len(section.rows):
        return f"{rel}, line {section.rows[row][0]}"
    return f"{rel}, line {section.line}"


def block_series(ctx: Context, block: Any, model: Any = None) -> pd.Series:
    """A ``.bc`` constant or time-series block as a UTC series covering the period.

    Raises
    ------
    ValueError
        For a function the case cannot express, or values that cannot be used (also recorded as errors with
        the file and line).
    """
    kind = type(block).__name__
    name = unquote(block.name)

    def bad(row: int | None, problem: str) -> ValueError:
        ctx.ledger.error(_bc_where(ctx, model, block, row), f"forcing {name!r}: {problem}")
        return ValueError(f"forcing {name!r}: {problem} (see the errors)")

    try:
        rows = np.asarray(block.datablock, dtype=float)
    except (TypeError, ValueError):
        raise bad(None, "a table whose rows are not all numbers of the same count") from None
    if rows.ndim != 2 or rows.shape[0] == 0:
        raise bad(None, "an empty table")
    finite = np.isfinite(rows).all(axis=1)
    if not finite.all():
        raise bad(int(np.argmin(finite)), "a value that is not a finite number")
    large = (np.abs(rows) > _LARGEST * (86400.0 * 36525 if kind == "TimeSeries" else 1.0)).any(axis=1)
    if large.any():
        raise bad(int(np.argmax(large)), "a value beyond any plausible size")
    factor_value, offset = float(block.factor if block.factor is not None else 1.0), float(block.offset or 0.0)
    if not (np.isfinite(factor_value) and np.isfinite(offset)) or abs(factor_value) > _LARGEST or \
            abs(offset) > _LARGEST:
        raise bad(None, f"factor {block.factor} or offset {block.offset} is not a finite number of a plausible size")
    if kind == "Constant":
        return _constant(ctx, float(rows.ravel()[0]) * factor_value + offset)
    if kind != "TimeSeries":
        raise ValueError(f"forcing function {block.function!r} of {name!r} has no counterpart in a "
                         "case (constant and time series only)")
    if rows.shape[1] < 2:
        raise bad(0, "a time series needs a time and a value on every row")
    try:
        factor, base = _time_unit(block.quantityunitpair[0].unit)
    except ValueError as exc:
        raise bad(None, str(exc)) from None
    seconds = rows[:, 0] * factor
    if np.any(np.abs(seconds) > 3.2e9):
        raise bad(int(np.argmax(np.abs(seconds) > 3.2e9)), "a time more than a century from the reference date")
    steps = np.diff(seconds)
    if np.any(steps < 0):
        raise bad(int(np.argmax(steps < 0)) + 1, "times that go back (a time series runs forward)")
    values = rows[:, 1] * factor_value + offset
    try:
        index = base + pd.to_timedelta(seconds, unit="s")
    except (OverflowError, ValueError):
        raise bad(None, "times that do not fit a calendar (years 1677-2262)") from None
    series = pd.Series(values, index=index)
    interp = str(getattr(block.timeinterpolation, "value", block.timeinterpolation) or "linear").lower()
    if interp != "linear":
        series = block_steps(series, interp)
    return _cover(ctx, series)


def _constant(ctx: Context, value: float) -> pd.Series:
    return pd.Series([value, value], index=pd.DatetimeIndex([ctx.start, ctx.end]))


def _cover(ctx: Context, series: pd.Series) -> pd.Series:
    """The series on the period: values held beyond its ends, cut to the period with interpolated ends."""
    series = series[~series.index.duplicated(keep="last")].sort_index()
    t = (series.index - ctx.start).total_seconds().to_numpy()
    v = series.to_numpy(dtype=float)
    span = (ctx.end - ctx.start).total_seconds()
    inside = (t > 0) & (t < span)
    times = np.concatenate([[0.0], t[inside], [span]])
    values = np.interp(times, t, v)
    return pd.Series(values, index=ctx.start + pd.to_timedelta(times, unit="s"))


def held_series(ctx: Context, series: pd.Series) -> pd.Series:
    """An exchange series (a value per coupling time, held until the next) as change points with 1 s ramps.

    DIMR hands a coupled model's value to D-Flow FM at each coupling time and D-Flow FM keeps it until the next
    one: each value holds from its time to the next (a case interpolates linearly, hence the ramp of a second
    before each change). Beyond the series' ends its first and last values hold over the period.
    """
    values = series.to_numpy(dtype=float)
    times = series.index
    changes = np.flatnonzero(values[1:] != values[:-1]) + 1  # each time whose value differs from the one before
    at = times[changes].as_unit("ns")
    ramp_t = np.empty(2 * changes.size, dtype=np.int64)
    ramp_t[0::2], ramp_t[1::2] = (at - pd.Timedelta(seconds=1)).asi8, at.asi8  # ns since 1970 (UTC)
    ramp_v = np.empty(2 * changes.size)
    ramp_v[0::2], ramp_v[1::2] = values[changes - 1], values[changes]
    ramps = pd.DatetimeIndex(ramp_t.view("datetime64[ns]"))
    keep_t = [times[0], *(ramps.tz_localize("UTC").tz_convert(times.tz) if times.tz is not None else ramps)]
    keep_v = [values[0], *ramp_v.tolist()]
    if keep_t[-1] < ctx.end:
        keep_t.append(ctx.end)
        keep_v.append(keep_v[-1])
    if keep_t[0] > ctx.start:
        keep_t.insert(0, ctx.start)
        keep_v.insert(0, keep_v[0])
    return pd.Series(keep_v, index=pd.DatetimeIndex(keep_t))


# -- boundaries ----------------------------------------------------------------------------------------


def convert_forcing(ctx: Context) -> None:
    """Fill ``[[boundaries]]`` and ``[[laterals]]`` of ``ctx.case``."""
    ext = ctx.model.ext
    degree: dict[str, int] = {}
    for a, b in ctx.branch_nodes.values():
        degree[a] = degree.get(a, 0) + 1
        degree[b] = degree.get(b, 0) + 1
    boundaries: list[dict] = []
    laterals: list[dict] = []
    if ext is not None:
        for header, bid, reason in ext.failed:
            kind = {"boundary": "boundary", "lateral": "lateral"}.get(header.lower(), header)
            ctx.ledger.refused(kind, bid, reason, hydraulic=header.lower() in ("boundary", "lateral"))
        for bnd in _once(ctx, ext.boundary, "boundary", "at node", lambda b: b.nodeid):
            item = _boundary(ctx, bnd, degree)
            if item is not None:
                boundaries.append(item)
        for lat in _once(ctx, ext.lateral, "lateral", "with id", lambda b: b.id):
            item = _lateral(ctx, lat)
            if item is not None:
                laterals.append(item)
        for name in ("meteo", "sourcesink"):
            for block in getattr(ext, name, None) or []:
                ctx.ledger.refused(name, str(getattr(block, "quantity", None) or getattr(block, "id", "?")),
                                   "meteo forcing and 2D sources/sinks have no counterpart in a 1D case")
    old = ctx.model.fm.external_forcing.extforcefile
    if old is None and ("external_forcing", "extforcefile") in ctx.model.sources.dropped:
        old = "ExtForceFile"
    if old is not None:
        ctx.ledger.refused("forcing file", str(getattr(old, "filepath", old)),
                           "old-format external forcing file (.ext with .tim/.cmp): not read")
    ctx.case["boundaries"] = boundaries
    ctx.case["laterals"] = laterals


def _once(ctx: Context, blocks: list[Any], what: str, by: str, key: Any) -> list[Any]:
    """The blocks whose key (a boundary's node, a lateral's id) no earlier block has; each repeat is an error.

    A case holds one boundary per node and one lateral per id, and which of two blocks D-Flow FM would take
    (or whether it would add them) is not something an import should guess: the error names both blocks.
    """
    seen: dict[str, Any] = {}
    kept = []
    for block in blocks:
        name = key(block)
        if name is None:
            kept.append(block)
            continue
        name = unquote(name)
        first = seen.get(name)
        if first is None:
            seen[name] = block
            kept.append(block)
            continue
        sources = ctx.model.sources
        here = sources.where(block) or ctx.model.mdu.name
        ctx.ledger.error(here, f"a second [{_header(sources, block, what)}] block {by} {name!r}; the first is at "
                         f"{sources.where(first) or 'an earlier block'}: a {what} {by} {name!r} may be given once "
                         "(remove or rename one of them)")
    return kept


def _header(sources: Any, block: Any, default: str) -> str:
    found = sources.section_of(block)
    return found[1].header if found is not None else default


def _boundary(ctx: Context, bnd: Any, degree: dict[str, int]) -> dict | None:
    name = unquote(bnd.nodeid or "?")
    quantity = str(bnd.quantity).lower()
    if bnd.nodeid is None:
        ctx.ledger.refused("boundary", name, "given by a polyline (a 2D boundary), not at a node")
        return None
    if not ctx.ids["node"].known(bnd.nodeid) or ctx.id("node", bnd.nodeid) not in degree:
        ctx.ledger.refused("boundary", name, "its node is not a connection node of the network")
        return None
    node = ctx.id("node", bnd.nodeid)
    ctx.source("boundaries", ctx.id("boundary", name), bnd)
    if degree[node] != 1:
        ctx.ledger.refused("boundary", name, f"its node joins {degree[node]} branches; a case boundary sits at an end "
                           "node (D-Flow FM's AllowBndAtBifurcation)")
        return None
    bid = ctx.id("boundary", name)
    try:
        if quantity == "qhbnd":
            block = _block(bnd.forcingfile, bnd.nodeid, ctx)
            return _rating(ctx, bid, node, name, block, bnd.forcingfile)
        if quantity not in ("waterlevelbnd", "dischargebnd"):
            ctx.ledger.refused("boundary", name, f"boundary quantity {bnd.quantity!r} has no counterpart in a case "
                               "(level, discharge and Q(h) only)")
            return None
        series = forcing_series(ctx, bnd.forcingfile, name=bnd.nodeid)
    except ValueError as exc:
        ctx.ledger.refused("boundary", name, str(exc))
        return None
    kind = "level" if quantity == "waterlevelbnd" else "discharge"
    if kind == "level" and float(series.max()) <= FREE_OUTFALL_LEVEL:
        return _free_outfall(ctx, bid, node, name, float(series.max()))
    item: dict = {"id": bid, "node": node, "type": kind}
    if series.nunique() == 1:
        item["value"] = float(series.iloc[0])
    else:
        item["series"] = ctx.add_series(BOUNDARY_FILE, bid, series)
    ctx.ledger.exact("boundary", name)
    return item


def _rating(ctx: Context, bid: str, node: str, name: str, block: Any, model: Any = None) -> dict | None:
    names = [str(q.quantity).lower() for q in block.quantityunitpair]
    qcol = next((k for k, n in enumerate(names) if "discharge" in n), None)
    hcol = next((k for k, n in enumerate(names) if "waterlevel" in n), None)
    try:
        rows = np.asarray(block.datablock, dtype=float)
    except (TypeError, ValueError):
        rows = np.empty((0, 0))
    if qcol is None or hcol is None or rows.ndim != 2 or rows.shape[0] < 2 or rows.shape[1] <= max(qcol, hcol):
        ctx.ledger.error(_bc_where(ctx, model, block, None), f"forcing {unquote(block.name)!r}: a Q(h) table needs a "
                         "discharge and a water level column and at least two rows")
        return None
    bad = ~np.isfinite(rows).all(axis=1) | (np.abs(rows) > _LARGEST).any(axis=1)
    if bad.any():
        ctx.ledger.error(_bc_where(ctx, model, block, int(np.argmax(bad))), f"forcing {unquote(block.name)!r}: a value "
                         "that is not a finite number of a plausible size")
        return None
    q, h = rows[:, qcol], rows[:, hcol]
    order = np.argsort(h)
    q, h = q[order], h[order]
    notes = []
    if np.any(np.diff(q) < 0) or np.any(np.diff(h) <= 0):
        ctx.ledger.refused("boundary", name, "the Q(h) table is not monotone")
        return None
    if q[0] > 0:
        slope = (h[1] - h[0]) / (q[1] - q[0]) if len(q) > 1 and q[1] > q[0] else 0.0
        h0 = h[0] - slope * q[0] if slope > 0 else h[0] - 1.0
        notes.append(f"the Q(h) table starts at {q[0]:g} m³/s; extended linearly to 0 m³/s at {h0:g} m AD")
        q, h = np.concatenate([[0.0], q]), np.concatenate([[h0], h])
    item = {"id": bid, "node": node, "type": "rating", "rating": {"levels": h.tolist(), "discharges": q.tolist()}}
    notes.append("D-Flow FM imposes the level of the table at the discharge through the boundary; the case takes "
                 "the discharge of the table at the level (the same relation, solved the other way)")
    ctx.ledger.approximated("boundary", name, "; ".join(notes))
    return item


def _free_outfall(ctx: Context, bid: str, node: str, name: str, level: float) -> dict | None:
    table = _critical_rating(ctx, node)
    if table is None:
        ctx.ledger.refused("boundary", name, f"level {level:g} m AD (a free outfall) and no profile at the node to "
                           "compute its critical flow from")
        return None
    levels, discharges = table
    ctx.ledger.approximated("boundary", name,
                            f"level {level:g} m AD: D-Flow FM's free outfall (the level lies below any bed). Taken "
                            "as a rating boundary that lets out the critical discharge Q = A sqrt(g A / B) of the "
                            "end cross-section at the node's level, the most a free overfall can pass")
    return {"id": bid, "node": node, "type": "rating", "rating": {"levels": levels, "discharges": discharges}}


def _critical_rating(ctx: Context, node: str) -> tuple[list[float], list[float]] | None:
    """Levels (m AD) and critical discharges (m³/s) of the cross-section of the branch end at ``node``."""
    for b in ctx.case["branches"]:
        if node not in (b["from_node"], b["to_node"]):
            continue
        cs = b["cross_sections"][0] if b["from_node"] == node else b["cross_sections"][-1]
        prof = next(p for p in ctx.case["profiles"] if p["id"] == cs["profile"])
        depths, areas, widths = _area_width(prof)
        levels, discharges = [cs["bed_level"]], [0.0]
        for d, a, w in zip(depths[1:], areas[1:], widths[1:], strict=True):
            q = a * math.sqrt(G * a / w) if w > 1e-6 else discharges[-1]
            if d > 0 and q >= discharges[-1]:
                levels.append(cs["bed_level"] + float(d))
                discharges.append(float(q))
        return (levels, discharges) if len(levels) > 2 else None
    return None


def _area_width(prof: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Depths (m), flow areas (m²) and top widths (m) of a case profile dict, on 40 depths."""
    kind = prof["type"]
    if kind == "circular":
        top = prof["diameter"]
    elif kind in ("rectangular", "trapezoidal"):
        top = prof.get("height") or 3.0
    elif kind == "zw":
        top = prof["heights"][-1]
    else:
        top = max(prof["z"][0], prof["z"][-1])
    depths = np.linspace(0.0, top, 41)
    widths = np.array([_width(prof, d) for d in depths])
    areas = np.concatenate([[0.0], np.cumsum(0.5 * (widths[1:] + widths[:-1]) * np.diff(depths))])
    return depths, areas, np.maximum(widths, 1e-9)


def _width(prof: dict, d: float) -> float:
    kind = prof["type"]
    if kind == "rectangular":
        return prof["width"]
    if kind == "trapezoidal":
        return prof["bottom_width"] + 2 * prof["side_slope"] * d
    if kind == "circular":
        r = 0.5 * prof["diameter"]
        return 2 * math.sqrt(max(r * r - (r - d) ** 2, 0.0))
    if kind == "zw":
        return float(np.interp(d, prof["heights"], prof["flow_widths"]))
    y, z = np.asarray(prof["y"]), np.asarray(prof["z"])
    width = 0.0
    for k in range(len(y) - 1):
        lo, hi = sorted((z[k], z[k + 1]))
        if d <= lo:
            continue
        frac = 1.0 if d >= hi or hi == lo else (d - lo) / (hi - lo)
        width += frac * (y[k + 1] - y[k])
    return width


# -- laterals ------------------------------------------------------------------------------------------


def _lateral(ctx: Context, lat: Any) -> dict | None:
    name = unquote(lat.id)
    lid = ctx.id("lateral", name)
    item: dict = {"id": lid}
    ctx.source("laterals", lid, lat)
    notes: list[str] = []
    if lat.nodeid is not None:
        if not ctx.ids["node"].known(lat.nodeid):
            ctx.ledger.refused("lateral", name, f"its node {unquote(lat.nodeid)!r} is not in the network")
            return None
        item["node"] = ctx.id("node", lat.nodeid)
    elif lat.branchid is not None and lat.chainage is not None:
        if not ctx.ids["branch"].known(lat.branchid) or ctx.id("branch", lat.branchid) not in ctx.branch_length:
            ctx.ledger.refused("lateral", name, f"its branch {unquote(lat.branchid)!r} is not in the network")
            return None
        branch = ctx.id("branch", lat.branchid)
        length = ctx.branch_length[branch]
        if float(lat.chainage) > length + max(1.0, 0.01 * length):  # the tolerance of a structure's chainage
            sources = ctx.model.sources
            ctx.ledger.error(sources.where(lat, sources.key_of(lat, "chainage")) or ctx.model.mdu.name,
                             f"lateral {name!r}: chainage {float(lat.chainage):g} m lies beyond the end of branch "
                             f"{unquote(lat.branchid)} ({length:g} m long)")
            return None
        item["branch"] = branch
        item["chainage"] = min(max(float(lat.chainage), 0.0), length)
    else:
        ctx.ledger.refused("lateral", name, "given by x, y coordinates or a polygon (a 2D source), not on the network")
        return None
    discharge = lat.discharge
    key = f"laterals/{name}/water_discharge"
    if isinstance(discharge, str) or str(getattr(discharge, "value", "")) == "realtime":
        if key in ctx.exchange:
            ctx.exchange_used.add(key)
            series = _cover(ctx, held_series(ctx, ctx.exchange[key]))
            item["series"] = ctx.add_series(LATERAL_FILE, lid, series)
            notes.append("realtime: the inflow of the exchange file, each value held from its coupling time to the "
                         "next, as D-HYDRO's coupler hands it over")
        elif ctx.options.realtime_lateral is not None:
            item["value"] = float(ctx.options.realtime_lateral)
            notes.append(f"realtime (supplied at run time by a coupled model, not in the files): a constant "
                         f"{ctx.options.realtime_lateral:g} m³/s as the import was told")
        else:
            ctx.ledger.refused("lateral", name, "realtime inflow (supplied by a coupled model at run time): give an "
                               "exchange file (--realtime) or a constant (--realtime-lateral)")
            return None
    elif str(getattr(discharge, "filepath", "") or "").lower().endswith(".tim"):
        ctx.ledger.refused("lateral", name, f"discharge = {getattr(discharge, 'filepath', '')} is a .tim file; a "
                           "[Lateral]'s discharge is a number, realtime or a .bc file (hydrolib-core's "
                           "Lateral.discharge, D-Flow FM's new external forcing format): write the series as a "
                           f"[forcing] block named {name!r} in a .bc file")
        return None
    else:
        try:
            series = forcing_series(ctx, discharge, name=lat.id)
        except ValueError as exc:
            ctx.ledger.refused("lateral", name, str(exc))
            return None
        if series.nunique() == 1:
            item["value"] = float(series.iloc[0])
        else:
            item["series"] = ctx.add_series(LATERAL_FILE, lid, series)
    (ctx.ledger.approximated if notes else ctx.ledger.exact)("lateral", name, "; ".join(notes))
    return item
