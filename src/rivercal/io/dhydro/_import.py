"""``import_dhydro``: a D-Flow FM 1D model (MDU and the files it names) → a case folder with ``import.md``."""

from __future__ import annotations

import logging
import math
import os
import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError, StructureOverlap
from rivercal.io._calibration import write_parameters
from rivercal.io.dhydro._compound import place_compounds
from rivercal.io.dhydro._context import Context, ImportOptions, unquote
from rivercal.io.dhydro._forcing import convert_forcing, read_exchange
from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._network import convert_network
from rivercal.io.dhydro._read import load_fm_model
from rivercal.io.dhydro._structures import convert_structures
from rivercal.io.ledger import conclude
from rivercal.network import Branch, Bridge, Culvert, Orifice, Pump, UniversalWeir, Weir
from rivercal.network.grid import branch_layout

__all__ = ["ImportResult", "import_dhydro"]

log = logging.getLogger(__name__)

#: Longest time step an import gives a case, s.
MAX_DT = 60.0
STRUCTURE_LENGTH = 10.0
#: The INI section headers (lower case) of the blocks of each kind of the ledger; a structure's kind is its type.
_HEADERS = {"lateral": ("lateral",), "boundary": ("boundary",), "storage node": ("storagenode",),
            "profile": ("definition",), "cross-section": ("crosssection",), "friction group": ("global",),
            "observation point": ("observationpoint",), "observation cross-section": ("observationcrosssection",)}
_STRUCTURES = {"weir", "universalWeir", "orifice", "gate", "generalStructure", "culvert", "bridge", "pump",
               "compound", "dambreak", "longCulvert"}
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
    # the model folder by its real path: hydrolib-core opens the files it references by their real paths, which the
    # confinement to the model folder would otherwise take for files outside a folder reached through a link
    mdu, out = Path(os.path.realpath(Path(mdu).parent)) / Path(mdu).name, Path(out)
    _check_options(options)
    _check_out(out)
    ledger = Ledger()
    model = load_fm_model(mdu, ledger)
    refdate, start, end = _period(model)
    end = _whole_intervals(model, ledger, start, end)
    ctx = Context(model=model, options=options, ledger=ledger, start=start, end=end, refdate=refdate)
    for path in options.realtime:
        try:
            found = read_exchange(Path(path), refdate)
        except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
            raise CaseError(f"cannot read the exchange file: {' '.join(str(exc).split())[:300]}",
                            file=str(path)) from None
        ctx.exchange.update(found)
    ctx.case["case"] = {"name": _case_name(mdu), "description": f"imported from D-Flow FM model {mdu.name}",
                        "start": start.isoformat().replace("+00:00", "Z"),
                        "end": end.isoformat().replace("+00:00", "Z")}
    for stage in (convert_network, convert_structures, convert_forcing, place_compounds, _engine, _validate_items,
                  _fit_the_grid, _end_node_storage, _other_settings, _parameters):
        if ledger.errors:
            break
        stage(ctx)
    if not ledger.errors and not ctx.case.get("branches"):
        ledger.refused("network", mdu.name, "no branch could be converted (see the refusals): nothing is left to "
                       "make a case of")
    unused = sorted(k for k in ctx.exchange if k not in ctx.exchange_used and not k.startswith("observations/")
                    and not k.endswith("/water_level"))
    for key in unused:
        ledger.warn(f"exchange series {key} matches no object of the model and was not used")
    def where(kind: str, ident: str) -> str:
        if kind == "file":
            return ""
        return model.sources.find_block(ident, _HEADERS.get(kind, ("structure",) if kind in _STRUCTURES else None))

    case = conclude(ledger, out, mdu, allow_partial=options.allow_partial, write=lambda: _write(ctx, out),
                    locate=where, nothing_left=not ctx.case.get("branches"))
    return ImportResult(folder=out, summary=_summary(ctx, case), ledger=ledger)


def _case_name(mdu: Path) -> str:
    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", mdu.stem)[:64]
    return name or "imported"


def _check_options(options: ImportOptions) -> None:
    from rivercal.network import MAX_DISCHARGE

    q = options.realtime_lateral
    if q is not None and (not math.isfinite(q) or abs(q) > MAX_DISCHARGE):
        raise CaseError(f"{q}: the constant inflow of realtime laterals must be a finite discharge within "
                        f"±{MAX_DISCHARGE:g} m³/s", field="--realtime-lateral")
    dt = options.dt
    if dt is not None and (not math.isfinite(dt) or not 0 < dt <= 86400):
        raise CaseError(f"{dt}: the time step must be a finite number of seconds in (0, 86400]", field="--dt")


def _check_out(out: Path) -> None:
    """The case folder: new, empty, or the folder of an earlier import (whose case files are replaced)."""
    if out.exists() and not out.is_dir():
        raise CaseError("exists and is not a folder: give a new folder for the case", field="--out",
                        file=str(out))
    if out.is_dir() and any(out.iterdir()) and not (out / "import.md").is_file():
        raise CaseError("is a folder with other files in it and not the folder of an earlier import: give a new or "
                        "empty folder (an import replaces the case files it finds)", field="--out", file=str(out))


def _period(model) -> tuple[pd.Timestamp, pd.Timestamp, pd.Timestamp]:
    """Reference date, start and end (UTC) from the MDU's [time] section; an error naming the key when unusable."""
    from rivercal.io.dhydro._mdu import mdu_line

    fm, mdu = model.fm, model.mdu
    index = model.sources.ini(mdu)
    t = fm.time

    def bad(name: str, problem: str) -> CaseError:
        return CaseError(f"{mdu_line(index, 'time', name)}: {problem}", file=str(mdu))

    text = str(t.refdate).strip()
    try:
        if not (text.isdigit() and len(text) == 8):
            raise ValueError(text)
        refdate = pd.Timestamp(f"{text[:4]}-{text[4:6]}-{text[6:]}", tz="UTC")
    except ValueError:
        raise bad("refdate", "the reference date must be a date written yyyymmdd") from None
    shift = pd.Timedelta(hours=float(t.tzone or 0.0))
    if abs(float(t.tzone or 0.0)) > 24:
        raise bad("tzone", "the time zone must lie within ±24 hours")
    unit_name = str(t.tunit or "S").upper()
    if unit_name not in ("D", "H", "M", "S"):
        raise bad("tunit", "the time unit must be D, H, M or S")
    unit = {"D": 86400.0, "H": 3600.0, "M": 60.0, "S": 1.0}[unit_name]
    if t.startdatetime and t.stopdatetime:
        try:
            start = pd.Timestamp(_datetime_text(str(t.startdatetime)), tz="UTC") - shift
        except ValueError:
            raise bad("startdatetime", "not a date and time written yyyymmddHHMMSS") from None
        try:
            end = pd.Timestamp(_datetime_text(str(t.stopdatetime)), tz="UTC") - shift
        except ValueError:
            raise bad("stopdatetime", "not a date and time written yyyymmddHHMMSS") from None
        names = ("startdatetime", "stopdatetime")
    else:
        if t.tstop is None:
            raise bad("tstop", "the model gives no stop time (TStop, or StartDateTime and StopDateTime)")
        tstart, tstop = float(t.tstart or 0.0), float(t.tstop)
        if not (math.isfinite(tstart) and math.isfinite(tstop)) or max(abs(tstart), abs(tstop)) * unit > 3.2e9:
            raise bad("tstop", "the start and stop times must be finite and within a century of the reference date")
        start = refdate + pd.to_timedelta(tstart * unit, unit="s") - shift
        end = refdate + pd.to_timedelta(tstop * unit, unit="s") - shift
        names = ("tstart", "tstop")
    if end <= start:
        raise bad(names[1], f"the period ends ({end.isoformat()}) before it starts ({start.isoformat()})")
    return refdate - shift, start, end


def _datetime_text(text: str) -> str:
    """``yyyymmddHHMMSS`` (D-Flow FM's StartDateTime) as ISO text; a ValueError when it is not that."""
    text = text.strip()
    if not (text.isdigit() and len(text) in (8, 14)):
        raise ValueError(text)
    text = text.ljust(14, "0")
    iso = f"{text[:4]}-{text[4:6]}-{text[6:8]}T{text[8:10]}:{text[10:12]}:{text[12:14]}"
    pd.Timestamp(iso)  # raises ValueError for a day or hour that does not exist
    return iso


def _his_interval(fm) -> int:
    """The model's output interval, s: the his interval (else the user time step, else an hour), whole seconds."""
    his = fm.output.hisinterval
    interval = float(his[0]) if his and float(his[0]) > 0 else float(fm.time.dtuser or 3600.0)
    return max(1, round(interval))


def _whole_intervals(model, ledger: Ledger, start: pd.Timestamp, end: pd.Timestamp) -> pd.Timestamp:
    """The end of the period at the last whole output interval from the start (``end`` when it is one already).

    A case's period holds a whole number of output intervals. When the model's stop time falls between two of its
    his times (TStop = 7199 s with a 60 s his interval), keeping the his interval and the model's time step and
    ending at the last his time before TStop is what a hydrologist expects; the common divisor of the two (1 s
    here) would force a 1 s step and 1 s output. The seconds left out are recorded in the ledger. A period
    shorter than one interval is left alone (the output interval then divides it).
    """
    span = round((end - start).total_seconds())
    interval = _his_interval(model.fm)
    if span <= interval or span % interval == 0:
        return end
    whole = start + pd.Timedelta(seconds=span // interval * interval)
    ledger.approximated("setting", "TStop", f"the model stops {span % interval} s after its last whole his interval "
                        f"({interval} s from the start): the case ends there, at {whole:%Y-%m-%d %H:%M:%S} UTC, "
                        f"{span % interval} s before D-Flow FM would, and keeps the his interval and the time step")
    return whole


def _engine(ctx: Context) -> None:
    fm = ctx.model.fm
    span = round((ctx.end - ctx.start).total_seconds())
    interval = _his_interval(fm)
    if span % interval:
        interval = math.gcd(int(span), int(interval)) or max(span, 1)
    dt_max = max(1, int(min(float(fm.time.dtmax or MAX_DT), MAX_DT)))
    dt = ctx.options.dt or max(d for d in range(1, dt_max + 1) if interval % d == 0)
    ratio = interval / dt
    if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
        raise CaseError(f"{dt:g} s does not divide the model's output interval {interval:g} s (the his interval)",
                        field="--dt")
    engine = {"dt": float(dt), "output_interval": float(interval), "structure_length": STRUCTURE_LENGTH,
              "cross_sections": "interpolated"}
    teta0 = getattr(fm.numerics, "teta0", None)  # D-Flow FM's default, 0.55, where the MDU gives none
    if isinstance(teta0, int | float) and math.isfinite(teta0):
        engine["theta"] = min(max(float(teta0), 0.5), 1.0)
        ctx.ledger.exact("setting", "Teta0", f"implicitness of the continuity flux {engine['theta']:g}")
    ctx.case["engine"] = engine
    from rivercal.io.dhydro._export import SETTINGS_FILE, read_engine_settings

    exported, errors, warnings = read_engine_settings(ctx.model.mdu.parent)
    for line, text in errors:
        ctx.ledger.error(f"{SETTINGS_FILE}, line {line}", text)
    for text in warnings:
        ctx.ledger.warn(text)
    if exported and not errors:
        if ctx.options.dt is not None:
            exported.pop("dt", None)  # --dt given: it wins over the exported time step
        engine.update(exported)
        if engine["output_interval"] % engine["dt"]:
            ctx.ledger.error(SETTINGS_FILE, f"the time step {engine['dt']:g} s does not divide the output interval "
                             f"{engine['output_interval']:g} s")
        ctx.ledger.exact("setting", SETTINGS_FILE, "engine settings written by rivercal's export (cross-section "
                         "placement, numerics) taken over")
    dt_text = f" (at most DtMax = {fm.time.dtmax:g} s)" if isinstance(fm.time.dtmax, int | float) else ""
    ctx.ledger.approximated("setting", "DtMax/DtUser", f"D-Flow FM adapts its time step to a Courant limit{dt_text}; "
                            f"the case steps {engine['dt']:g} s (implicit, no Courant limit), output every "
                            f"{engine['output_interval']:g} s (the his interval)")


def _validate_items(ctx: Context) -> None:
    """Each object of the case checked with the case's own rules; a failure is an error naming its source.

    The values were screened when they were read (finite, sensible signs and magnitudes); what the case's
    rules still reject (a gate below its crest, a table that does not rise) is a value of the model files
    that a case cannot use, and is reported at the block it came from.
    """
    from pydantic import TypeAdapter, ValidationError

    from rivercal.case.schema import EngineSettings, InitialConditions
    from rivercal.network import Boundary, Branch, Friction, FrictionGroup, Lateral, Node, Profile, Station

    models = {"profiles": TypeAdapter(Profile), "nodes": Node, "branches": Branch, "friction_groups": FrictionGroup,
              "boundaries": Boundary, "laterals": Lateral, "stations": Station, **_KINDS}
    for table, model in models.items():
        kept = []
        for item in ctx.case.get(table, []):
            try:
                model.validate_python(item) if isinstance(model, TypeAdapter) else model.model_validate(item)
            except (ValidationError, ValueError) as exc:
                what = f"{table.rstrip('s').replace('_', ' ')} {item.get('id', '?')!r}"
                at_key = _at_source_key(ctx, table, item.get("id", "?"), exc)
                if at_key is not None:
                    ctx.ledger.error(at_key[0], f"{what}, {at_key[1]}")
                else:
                    ctx.ledger.error(ctx.where(table, item.get("id", "?")), f"{what}: {_problem(exc)}")
                continue
            kept.append(item)
        if table in ctx.case:
            ctx.case[table] = kept
    for name, model in (("friction", Friction), ("initial", InitialConditions), ("engine", EngineSettings)):
        if ctx.case.get(name) is None:
            continue
        try:
            model.model_validate(ctx.case[name])
        except (ValidationError, ValueError) as exc:
            ctx.ledger.error(ctx.where(name, name), f"{name}: {_problem(exc)}")


def _at_source_key(ctx: Context, table: str, case_id: str, exc: Exception) -> tuple[str, str] | None:
    """Where the value a case rule refuses was written, as the user wrote it: (``file, line N``, ``key = value: why``).

    The case's rules speak of the case's fields (``crest_width``); the user wrote a D-Flow FM key (``crestWidth``)
    on a line of a block. A field is traced back to the key of the same name (underscores aside) when the block
    it came from has that key; None when it cannot be (the caller then names the block).
    """
    from pydantic import ValidationError

    if not isinstance(exc, ValidationError):
        return None
    err = exc.errors(include_url=False)[0]
    loc = err.get("loc", ())
    obj = ctx.blocks.get((table, case_id))
    if not loc or obj is None or isinstance(obj, str):
        return None
    sources = ctx.model.sources
    found = sources.section_of(obj)
    wanted = str(loc[0]).replace("_", "").lower()
    name = next((n for n in getattr(type(obj), "model_fields", {}) if n.replace("_", "").lower() == wanted), None)
    if found is None or name is None:
        return None
    key = sources.key_of(obj, name)
    raw = found[1].first(key)
    if raw is None:
        return None
    return sources.where(obj, key), f"{key} = {raw.value}: {' '.join(str(err.get('msg', '')).split())}"


def _problem(exc: Exception) -> str:
    from pydantic import ValidationError

    if isinstance(exc, ValidationError):
        err = exc.errors(include_url=False)[0]
        loc = ".".join(str(x) for x in err.get("loc", ()))
        return f"{loc}: {' '.join(str(err.get('msg', '')).split())}" if loc else " ".join(str(err["msg"]).split())
    return " ".join(str(exc).split())


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
                    gate = item.get("gate_lower_edge_level")
                    if gate is not None and gate <= bed and item.get("gate_series") is not None:
                        # the series' values at or below the raised crest close the gate at their times
                        item["gate_lower_edge_level"] = bed + 0.001
                    elif gate is not None and gate <= bed and item.get("allowed_flow") != "none":
                        item["gate_lower_edge_level"] = bed + 0.001
                        item["allowed_flow"] = "none"
                        ctx.ledger.approximated(*ctx.origin(item["id"], table),
                                                f"its gate ({gate:g} m AD) is down below the bed: taken as closed")
            if table == "culverts" and "invert_level_end" not in item and item["invert_level"] < bed:
                item["invert_level_end"] = item["invert_level"]
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


def _end_node_storage(ctx: Context) -> None:
    """D-Flow FM's ``dxDoubleAt1DEndNodes``: a dead end stores the water of a full link instead of half of it.

    With the option on (its default), D-Flow FM gives the flow node at the end of a network, where only one
    link meets and no boundary is attached, the volume of the whole link ``dx`` instead of ``dx/2`` (Deltares
    delft3d, ``addlink1D``: ``dx1 = 2 dx1`` when ``nd(k1)%lnx == 1``). The extra half link becomes storage of
    the node: ``storage_table`` with the area ``dx/2 · B(h)``, B the storage (total) width of the end link's
    cross-section at the depth over its bed there; a storage node's own table is added to it.
    """
    if not getattr(ctx.model.fm.geometry, "dxdoubleat1dendnodes", False):
        return
    profiles = {p["id"]: p for p in ctx.case.get("profiles", [])}
    degree: dict[str, list[tuple[dict, bool]]] = defaultdict(list)
    for b in ctx.case["branches"]:
        degree[b["from_node"]].append((b, True))
        degree[b["to_node"]].append((b, False))
    bounded = {bnd["node"] for bnd in ctx.case.get("boundaries", [])}
    added = 0
    for node in ctx.case["nodes"]:
        ends = degree.get(node["id"], [])
        if len(ends) != 1 or node["id"] in bounded:
            continue
        branch, at_start = ends[0]
        points = branch.get("points") or [0.0, branch["length"]]
        dx = (points[1] - points[0]) if at_start else (points[-1] - points[-2])
        chainage = 0.0 if at_start else branch["length"]
        sections = branch["cross_sections"]
        nearest = min(sections, key=lambda c: abs(c["chainage"] - chainage))
        bed = float(np.interp(chainage, [c["chainage"] for c in sections], [c["bed_level"] for c in sections]))
        heights, widths = _storage_widths(profiles[nearest["profile"]])
        areas = np.maximum.accumulate(0.5 * dx * widths)
        if areas[-1] <= 0:
            continue
        table = {"levels": [bed + float(h) for h in heights], "areas": [float(a) for a in areas]}
        if node.get("storage_table"):
            table = _sum_tables(node["storage_table"], table)
        node["storage_table"] = table
        node.pop("storage_area", None)
        added += 1
    if added:
        ctx.ledger.exact("setting", "dxDoubleAt1DEndNodes", f"{added} dead-end node(s) store the water of their whole "
                         "end link, as D-Flow FM does with this option: the extra half link is storage of the node")


def _storage_widths(prof: dict) -> tuple[np.ndarray, np.ndarray]:
    """Heights above the bed (m) and storage (total) widths there (m) of a case profile, at its break points."""
    kind = prof["type"]
    if kind == "zw":
        heights = np.asarray(prof["heights"], dtype=float)
        widths = np.asarray(prof.get("total_widths") or prof["flow_widths"], dtype=float)
    elif kind == "yz":
        y, z = np.asarray(prof["y"], dtype=float), np.asarray(prof["z"], dtype=float)
        heights = np.unique(z)
        widths = np.array([sum(_wet(y[k], y[k + 1], z[k], z[k + 1], h) for k in range(y.size - 1)) for h in heights])
    elif kind == "rectangular":
        top = prof.get("height") or 10.0
        heights = np.array([0.0, top])
        widths = np.full(2, float(prof["width"]))
    elif kind == "trapezoidal":
        top = prof.get("height") or 10.0
        heights = np.array([0.0, top])
        widths = prof["bottom_width"] + 2 * prof["side_slope"] * heights
    else:  # circular
        r = 0.5 * prof["diameter"]
        heights = np.linspace(0.0, 2 * r, 21)
        widths = 2 * np.sqrt(np.maximum(r * r - (r - heights) ** 2, 0.0))
    if heights.size < 2:
        heights, widths = np.array([0.0, 1.0]), np.array([widths[0], widths[0]])
    return heights, widths


def _wet(y1: float, y2: float, z1: float, z2: float, h: float) -> float:
    """Horizontal wet width (m) of one segment of a yz profile at height h."""
    lo, hi = min(z1, z2), max(z1, z2)
    if h <= lo:
        return 0.0
    return abs(y2 - y1) * (1.0 if h >= hi or hi == lo else (h - lo) / (hi - lo))


def _sum_tables(a: dict, b: dict) -> dict:
    """The sum of two storage tables (linear between levels, constant above, zero below)."""
    levels = sorted(set(a["levels"]) | set(b["levels"]))

    def at(t: dict, z: float) -> float:
        if z < t["levels"][0]:
            return 0.0
        return float(np.interp(z, t["levels"], t["areas"]))

    return {"levels": levels, "areas": [at(a, z) + at(b, z) for z in levels]}


def _other_settings(ctx: Context) -> None:
    two_d = getattr(ctx.model.network, "_mesh2d", None)
    if two_d is not None and getattr(two_d, "mesh2d_node_x", np.empty(0)).size:
        ctx.ledger.refused("2D mesh", "mesh2d", "the 2D part of a 1D2D model is left out (a case is 1D)",
                           hydraulic=False)
    ctx.ledger.approximated("setting", "numerics", "rivercal's engine discretises the same equations (the staggered "
                            "Delft scheme) on D-Flow FM's calculation points, with its own upwinding and structure "
                            "linearisation; D-Flow FM's other numerical settings (advection type, limiters) are not "
                            "carried over")
    used = ctx.used_definitions
    for d in ctx.model.crossdefs.objects:
        if unquote(d.id) not in used:
            ctx.ledger.refused("profile", unquote(d.id), "not used by any cross-section or structure", hydraulic=False)
    for _, did, reason in ctx.model.crossdefs.failed:
        if did not in used:
            ctx.ledger.refused("profile", did, reason, hydraulic=False)


def _parameters(ctx: Context) -> None:
    """``[[parameters]]`` so that the case can be calibrated as imported (:func:`rivercal.io._calibration.write`)."""
    write_parameters(ctx.case, ctx.ledger, parallel=ctx.parallel, pieces=ctx.pieces)


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
             "universal_weirs", "orifices", "culverts", "bridges", "pumps", "boundaries", "laterals", "stations",
             "parameters"]
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
        "parameters": [p.name for p in case.spec.parameters],
    }
