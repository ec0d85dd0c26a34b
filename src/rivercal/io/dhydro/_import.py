"""``import_dhydro``: a D-Flow FM 1D model (MDU and the files it names) → a case folder with ``import.md``."""

from __future__ import annotations

import logging
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case.load import load_case
from rivercal.errors import CaseError, StructureOverlap
from rivercal.io.dhydro._context import Context, ImportOptions, unquote
from rivercal.io.dhydro._forcing import convert_forcing, read_exchange
from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._network import convert_network
from rivercal.io.dhydro._read import load_fm_model
from rivercal.io.dhydro._structures import convert_structures
from rivercal.network import Branch, Bridge, Culvert, Orifice, Pump, UniversalWeir, Weir
from rivercal.network.grid import branch_layout

__all__ = ["ImportResult", "import_dhydro"]

log = logging.getLogger(__name__)

#: Longest time step an import gives a case, s.
MAX_DT = 60.0
STRUCTURE_LENGTH = 10.0
_KINDS = {"weirs": Weir, "culverts": Culvert, "pumps": Pump, "orifices": Orifice, "universal_weirs": UniversalWeir,
          "bridges": Bridge}


@dataclass(frozen=True)
class ImportResult:
    """What an import produced.

    Attributes
    ----------
    folder
        The case folder (``case.toml``, the CSV series, ``import.md``).
    summary
        Counts: branches, points (calculation points of the case's grid), profiles, structures by type,
        boundaries, laterals, stations, approximated, refused.
    ledger
        The full account (also in ``import.md``).
    """

    folder: Path
    summary: dict
    ledger: Ledger


def import_dhydro(mdu: Path | str, out: Path | str, options: ImportOptions | None = None) -> ImportResult:
    """Convert a D-Flow FM 1D model into a case folder.

    Parameters
    ----------
    mdu
        The model's ``.mdu`` file.
    out
        The case folder to write (created; files of an earlier import are replaced).
    options
        :class:`ImportOptions` (exchange files for realtime values, partial imports, time step).

    Returns
    -------
    ImportResult
        The folder, the summary and the ledger.

    Raises
    ------
    CaseError
        When the model cannot be read, or when objects that change the hydraulics were refused and
        partial imports are not allowed (the message lists them; ``import.md`` is written all the same).
    """
    options = options or ImportOptions()
    mdu, out = Path(mdu), Path(out)
    ledger = Ledger()
    model = load_fm_model(mdu, ledger)
    refdate, start, end = _period(model.fm)
    ctx = Context(model=model, options=options, ledger=ledger, start=start, end=end, refdate=refdate)
    for path in options.realtime:
        try:
            found = read_exchange(Path(path), refdate)
        except (OSError, ValueError) as exc:
            raise CaseError(f"cannot read the exchange file: {' '.join(str(exc).split())}", file=str(path)) from None
        ctx.exchange.update(found)
    ctx.case["case"] = {"name": mdu.stem, "description": f"imported from D-Flow FM model {mdu.name}",
                        "start": start.isoformat().replace("+00:00", "Z"),
                        "end": end.isoformat().replace("+00:00", "Z")}
    convert_network(ctx)
    convert_structures(ctx)
    convert_forcing(ctx)
    _engine(ctx)
    _fit_the_grid(ctx)
    _other_settings(ctx)
    unused = sorted(k for k in ctx.exchange if k not in ctx.exchange_used and not k.startswith("observations/")
                    and not k.endswith("/water_level"))
    for key in unused:
        ledger.warn(f"exchange series {key} matches no object of the model and was not used")
    out.mkdir(parents=True, exist_ok=True)
    (out / "import.md").write_text(ledger.markdown(model=str(mdu), case_folder=str(out),
                                                   partial=options.allow_partial), encoding="utf-8")
    if ledger.blocking and not options.allow_partial:  # no case that would run without these objects
        groups: dict[tuple[str, str], list[str]] = {}
        for e in ledger.blocking:
            groups.setdefault((e.kind, e.note), []).append(e.id)
        shown = "; ".join(f"{kind} {ids[0]!r}" + (f" and {len(ids) - 1} more" if len(ids) > 1 else "") + f": {note}"
                          for (kind, note), ids in list(groups.items())[:4])
        more = f" (and {len(groups) - 4} more reasons)" if len(groups) > 4 else ""
        raise CaseError(f"{len(ledger.blocking)} object(s) that change the hydraulics cannot be converted: "
                        f"{shown}{more}; no case was written"
                        f"; see {out / 'import.md'}, or import with --allow-partial to leave them out", file=str(mdu))
    _write(ctx, out)
    try:
        case = load_case(out)
    except CaseError as exc:
        raise CaseError(f"the imported case does not validate, which is a bug of the import: {exc}",
                        file=str(mdu)) from None
    return ImportResult(folder=out, summary=_summary(ctx, case), ledger=ledger)


def _period(fm) -> tuple[pd.Timestamp, pd.Timestamp, pd.Timestamp]:
    t = fm.time
    refdate = pd.Timestamp(str(int(t.refdate)), tz="UTC")
    shift = pd.Timedelta(hours=float(t.tzone or 0.0))
    unit = {"D": 86400.0, "H": 3600.0, "M": 60.0, "S": 1.0}[str(t.tunit or "S").upper()]
    if t.startdatetime and t.stopdatetime:
        start = pd.Timestamp(str(t.startdatetime), tz="UTC") - shift
        end = pd.Timestamp(str(t.stopdatetime), tz="UTC") - shift
    else:
        start = refdate + pd.to_timedelta(float(t.tstart or 0.0) * unit, unit="s") - shift
        end = refdate + pd.to_timedelta(float(t.tstop) * unit, unit="s") - shift
    return refdate - shift, start, end


def _engine(ctx: Context) -> None:
    fm = ctx.model.fm
    span = (ctx.end - ctx.start).total_seconds()
    his = fm.output.hisinterval
    interval = float(his[0]) if his and float(his[0]) > 0 else float(fm.time.dtuser or 3600.0)
    if span % interval:
        interval = math.gcd(int(span), int(interval)) or span
    dt_max = min(float(fm.time.dtmax or MAX_DT), MAX_DT)
    dt = ctx.options.dt or max(d for d in range(1, int(dt_max) + 1) if interval % d == 0)
    engine = {"dt": float(dt), "output_interval": float(interval), "structure_length": STRUCTURE_LENGTH,
              "cross_sections": "interpolated"}
    ctx.case["engine"] = engine
    from rivercal.io.dhydro._export import SETTINGS_FILE, read_engine_settings

    exported = read_engine_settings(ctx.model.mdu.parent)
    if exported:
        engine.update(exported)
        ctx.ledger.exact("setting", SETTINGS_FILE, "engine settings written by rivercal's export (cross-section "
                         "placement, numerics) taken over")
    ctx.ledger.approximated("setting", "DtMax/DtUser", f"D-Flow FM adapts its time step to a Courant limit (at most "
                            f"DtMax = {fm.time.dtmax:g} s); the case steps {dt:g} s (implicit, no Courant limit), "
                            f"output every {interval:g} s (the his interval)")


def _fit_the_grid(ctx: Context) -> None:
    """Make the case's grid rules hold: structure segments, crests above the bed, stations beside structures."""
    beds = {b["id"]: (np.array([c["chainage"] for c in b["cross_sections"]]),
                      np.array([c["bed_level"] for c in b["cross_sections"]])) for b in ctx.case["branches"]}
    on_branch: dict[str, list[tuple[str, dict]]] = defaultdict(list)
    for table in _KINDS:
        for item in ctx.case.get(table, []):
            on_branch[item["branch"]].append((table, item))
    length = ctx.case["engine"]["structure_length"]
    for bid, items in on_branch.items():
        ch, zb = beds[bid]
        for table, item in items:
            bed = float(np.interp(item["chainage"], ch, zb))
            for name in ("crest_level",):
                if name in item and item[name] < bed:
                    ctx.ledger.approximated(*ctx.origin(item["id"], table),
                                            f"the crest {item[name]:g} m AD lies below the bed ({bed:.3f} m AD): "
                                            "raised to the bed (D-Flow FM lets the channel bed govern there too)")
                    item[name] = bed
            if table == "culverts" and "invert_level_end" not in item and item["invert_level"] < bed:
                item["invert_level_end"] = item["invert_level"]
            if table == "pumps" and item["stop_level"] <= bed:
                ctx.ledger.approximated(*ctx.origin(item["id"], "pump"),
                                        f"the stop level {item['stop_level']:g} m AD is not above "
                                        f"the bed ({bed:.3f} m AD): raised to 1 cm above it")
                item["stop_level"] = bed + 0.01
                item["start_level"] = max(item["start_level"], bed + 0.02)
    branches = {b["id"]: b for b in ctx.case["branches"]}
    layouts = {}
    for bid, b in branches.items():
        branch = Branch.model_validate(b)
        structures = [_KINDS[t].model_validate(i) for t, i in on_branch.get(bid, [])]
        while True:
            try:
                layouts[bid] = branch_layout(branch, structures, length)
                break
            except StructureOverlap as exc:
                table, item = next((t, i) for t, i in on_branch[bid] if i["id"] == exc.structure.id)
                ctx.case[table].remove(item)
                structures = [s for s in structures if s.id != exc.structure.id]
                ctx.ledger.refused(*ctx.origin(item["id"], table),
                                   f"it lies between the same two calculation points as {exc.previous.id!r}; each "
                                   "structure needs a stretch of its own")
    for st in ctx.case["stations"]:
        if "h" not in st["quantities"]:
            continue
        for seg in layouts[st["branch"]]:
            if seg.structure is not None and seg.a + 1e-9 < st["chainage"] < seg.b - 1e-9:
                end = seg.a if st["chainage"] - seg.a <= seg.b - st["chainage"] else seg.b
                ctx.ledger.approximated(*ctx.origin(st["id"], "station"),
                                        f"at {st['chainage']:g} m it lies between the calculation "
                                        f"points around structure {seg.structure.id!r}; moved to the nearer point "
                                        f"({end:g} m), whose level D-Flow FM reports there too")
                st["chainage"] = end
    level_nodes = {b["node"]: b["id"] for b in ctx.case["boundaries"] if b["type"] == "level"}
    kept = []
    for lat in ctx.case["laterals"]:
        node = lat.get("node")
        if node is None:
            b = branches[lat["branch"]]
            from rivercal.network.grid import chainages

            chain = chainages(layouts[lat["branch"]])
            k = int(np.argmin(np.abs(chain - lat["chainage"])))
            node = b["from_node"] if k == 0 else b["to_node"] if k == chain.size - 1 else None
        if node in level_nodes:
            ctx.ledger.refused("lateral", lat["id"], f"it lands on node {node!r}, whose level boundary "
                               f"{level_nodes[node]!r} imposes the level: the inflow leaves the model at once "
                               "(in D-Flow FM too)", hydraulic=False)
            continue
        kept.append(lat)
    ctx.case["laterals"] = kept


def _other_settings(ctx: Context) -> None:
    fm = ctx.model.fm
    geometry = fm.geometry
    if getattr(geometry, "dxdoubleat1dendnodes", False):
        ctx.ledger.approximated("setting", "dxDoubleAt1DEndNodes", "D-Flow FM gives the end nodes of the network "
                                "the storage of a full cell instead of half a cell; the case keeps half a cell (the "
                                "extra storage at a dead end is small)")
    two_d = getattr(ctx.model.network, "_mesh2d", None)
    if two_d is not None and getattr(two_d, "mesh2d_node_x", np.empty(0)).size:
        ctx.ledger.refused("2D mesh", "mesh2d", "the 2D part of a 1D2D model is left out (a case is 1D)",
                           hydraulic=False)
    ctx.ledger.approximated("setting", "numerics", "rivercal's engine discretises the same equations (the staggered "
                            "Delft scheme) on D-Flow FM's calculation points, with its own upwinding and structure "
                            "linearisation; D-Flow FM's numerical settings (Teta0, advection type, limiters) are not "
                            "carried over")
    used = ctx.used_definitions
    for d in ctx.model.crossdefs.objects:
        if unquote(d.id) not in used:
            ctx.ledger.refused("profile", unquote(d.id), "not used by any cross-section or structure", hydraulic=False)
    for _, did, reason in ctx.model.crossdefs.failed:
        if did not in used:
            ctx.ledger.refused("profile", did, reason, hydraulic=False)


def _write(ctx: Context, out: Path) -> None:
    import tomli_w

    for old in out.glob("*.csv"):
        old.unlink()
    for file, columns in ctx.series.items():
        index = _without_gaps(sorted(set().union(*(s.index for s in columns.values()))))
        frame = pd.DataFrame({name: np.interp((pd.DatetimeIndex(index) - ctx.start).total_seconds(),
                                              (s.index - ctx.start).total_seconds(), s.to_numpy(dtype=float))
                              for name, s in columns.items()}, index=pd.DatetimeIndex(index))
        frame.index = frame.index.strftime("%Y-%m-%dT%H:%M:%SZ")
        frame.index.name = "time"
        frame.to_csv(out / file)  # shortest text that reads back as the same number
    order = ["case", "engine", "initial", "friction", "friction_groups", "profiles", "nodes", "branches", "weirs",
             "universal_weirs", "orifices", "culverts", "bridges", "pumps", "boundaries", "laterals", "stations"]
    data = {k: ctx.case[k] for k in order if ctx.case.get(k) not in (None, [], {})}
    (out / "case.toml").write_text(tomli_w.dumps(_clean(data)), encoding="utf-8")


def _without_gaps(times: list[pd.Timestamp]) -> pd.DatetimeIndex:
    """Times with the gaps of a mostly regular series filled at its regular step.

    A case rejects a regular series with a gap (a missing line is usually a mistake); a D-Flow FM series
    may skip times on purpose (a value held for days). The values at the inserted times are interpolated
    linearly, which is how both programs read the series between its points.
    """
    index = pd.DatetimeIndex(times)
    if index.size < 3:
        return index
    steps = np.diff(index).astype("timedelta64[ms]").astype(np.int64)
    values, counts = np.unique(steps, return_counts=True)
    step = int(values[np.argmax(counts)])
    if counts.max() < 0.9 * steps.size or not (steps > step).any():
        return index
    extra = [pd.date_range(a, b, freq=pd.Timedelta(step, unit="ms"), inclusive="neither")
             for a, b, d in zip(index[:-1], index[1:], steps, strict=True) if d > step]
    return index.append(extra).sort_values().unique()


def _clean(value):
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _summary(ctx: Context, case) -> dict:
    from rivercal.network.grid import chainages

    net = case.network
    by_branch: dict[str, list] = defaultdict(list)
    for s in net.structures:
        by_branch[s.branch].append(s)
    points = {n.id for n in net.nodes}
    n_points = len(points)
    for b in net.branches:
        n_points += len(chainages(branch_layout(b, by_branch[b.id], case.spec.engine.structure_length))) - 2
    structures = {}
    for table in _KINDS:
        count = len(getattr(net, table))
        if count:
            structures[table.rstrip("s").replace("_", " ") if table != "bridges" else "bridge"] = count
    return {
        "branches": len(net.branches),
        "points": n_points,
        "profiles": len(net.profiles),
        "structures": structures,
        "boundaries": len(net.boundaries),
        "laterals": len(net.laterals),
        "stations": len(net.stations),
        "approximated": ctx.ledger.counts("approximated"),
        "refused": ctx.ledger.counts("refused"),
    }
