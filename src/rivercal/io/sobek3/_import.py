"""``import_sobek3``: a SOBEK 3 model (``Flow1D.md1d`` and the files it names) → a case folder with ``import.md``."""

from __future__ import annotations

import logging
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case import Case
from rivercal.errors import CaseError, StructureOverlap
from rivercal.io._calibration import write_parameters
from rivercal.io.ledger import conclude
from rivercal.io.sobek3._compound import place_compounds
from rivercal.io.sobek3._context import MIN_DT, Context, ImportOptions, Sobek3Ledger, load_model
from rivercal.io.sobek3._forcing import convert_forcing
from rivercal.io.sobek3._friction import DEFAULT_CHEZY
from rivercal.io.sobek3._network import convert_network
from rivercal.io.sobek3._profiles import SECTION_NAMES, unused_definitions
from rivercal.io.sobek3._structures import convert_structures
from rivercal.network import Branch, Bridge, Culvert, Orifice, Pump, UniversalWeir, Weir
from rivercal.network.grid import branch_layout, chainages

__all__ = ["ImportResult", "import_sobek3"]

log = logging.getLogger(__name__)

#: Longest time step a case takes, s.
MAX_DT = 3600.0
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
        boundaries, laterals, stations, exact, approximated, refused; and the time step (s).
    ledger
        The full account (also in ``import.md``).
    case
        The case as written, loaded and validated (what :func:`rivercal.case.load_case` of ``folder`` returns).
    """

    folder: Path
    summary: dict
    ledger: Sobek3Ledger
    case: Case | None = None


def import_sobek3(md1d: Path | str, out: Path | str, options: ImportOptions | None = None) -> ImportResult:
    """Convert a SOBEK 3 model into a case folder.

    Parameters
    ----------
    md1d
        The model's ``Flow1D.md1d`` file.
    out
        The case folder to write (created; files of an earlier import are replaced).
    options
        :class:`ImportOptions` (partial imports, time step).

    Returns
    -------
    ImportResult
        The folder, the summary and the ledger.

    Raises
    ------
    CaseError
        When a file cannot be read or holds a bad value (the message names the file, the line and the key), or
        when objects that change the hydraulics were refused and partial imports are not allowed (the message
        lists them; ``import.md`` is written all the same).
    """
    options = options or ImportOptions()
    md1d, out = Path(md1d), Path(out)
    ledger = Sobek3Ledger()
    model = load_model(md1d, ledger)
    start, end = _period(model)
    ctx = Context(model=model, options=options, ledger=ledger, start=start, end=end)
    ctx.case["case"] = {"name": _model_name(md1d),
                        "description": f"imported from SOBEK 3 model {md1d}",
                        "start": start.isoformat().replace("+00:00", "Z"),
                        "end": end.isoformat().replace("+00:00", "Z")}
    convert_network(ctx)
    _finish_friction(ctx)
    convert_structures(ctx)
    unused_definitions(ctx)
    convert_forcing(ctx)
    place_compounds(ctx)
    _engine(ctx)
    _fit_the_grid(ctx)
    _settings(ctx)
    _stations_if_none(ctx)
    write_parameters(ctx.case, ledger, parallel=ctx.parallel, pieces=ctx.pieces)
    case = conclude(ledger, out, md1d, allow_partial=options.allow_partial, write=lambda: _write(ctx, out))
    return ImportResult(folder=out, summary=_summary(ctx, case), ledger=ledger, case=case)


def _model_name(md1d: Path) -> str:
    """The name of the SOBEK 3 project (``<name>.dsproj_data/...``), else of the md1d file."""
    for parent in md1d.resolve().parents:
        if parent.name.endswith(".dsproj_data"):
            return parent.name[: -len(".dsproj_data")] or md1d.stem
    return md1d.stem


def _period(model) -> tuple[pd.Timestamp, pd.Timestamp]:
    times = {}
    for key in ("StartTime", "StopTime"):
        section = model.setting_section("Time", key)
        if section is None:
            raise CaseError(f"the model has no [Time] {key}", file=str(model.md1d), field=key)
        try:
            stamp = pd.Timestamp(section.text(key))
        except ValueError:
            raise section.error(key, f"{section.text(key)!r} is not a date and time (yyyy-MM-dd HH:mm:ss)") from None
        times[key] = stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    if times["StopTime"] <= times["StartTime"]:
        section = model.setting_section("Time", "StopTime")
        raise section.error("StopTime", f"the stop time {times['StopTime']} is not after the start time "
                                        f"{times['StartTime']}")
    return times["StartTime"], times["StopTime"]


def _finish_friction(ctx: Context) -> None:
    """Profiles refer to the case ids of their roughness sections; a section without a roughness file gets one."""
    groups = {g["id"] for g in ctx.case["friction_groups"]}
    for prof in ctx.case.get("profiles", []):
        names = prof.get("friction")
        if not names:
            continue
        ids = []
        for name in names:
            gid = ctx.id("friction group", name)
            if gid not in groups:
                ctx.case["friction_groups"].append({"id": gid, "type": "chezy", "value": DEFAULT_CHEZY})
                groups.add(gid)
                ctx.ledger.approximated("friction group", name, "no roughness file for this section: Chézy "
                                        f"{DEFAULT_CHEZY:g} m^(1/2)/s, SOBEK 3's default roughness")
            ids.append(gid)
        prof["friction"] = ids
    order = {name.lower(): k for k, name in enumerate(SECTION_NAMES)}
    ctx.case["friction_groups"].sort(key=lambda g: order.get(g["id"].lower(), len(order)))


def _engine(ctx: Context) -> None:
    model = ctx.model
    span = (ctx.end - ctx.start).total_seconds()
    step = model.number("Time", "TimeStep", default=None)
    if step is None or not step > 0:
        raise CaseError("the model has no positive [Time] TimeStep", file=str(model.md1d), field="TimeStep")
    interval = model.number("Time", "OutTimeStepGridPoints", default=step) or step
    notes = []
    if interval < MIN_DT or _tenths(span) % _tenths(interval):
        new = math.gcd(_tenths(span), max(_tenths(interval), 1)) / 10.0
        notes.append(f"output every {new:g} s instead of {interval:g} s (a divisor of the simulated period in whole "
                     "tenths of a second)")
        interval = new
    dt = float(step if ctx.options.dt is None else ctx.options.dt)
    if dt > MAX_DT:
        notes.append(f"time step {dt:g} s cut to {MAX_DT:g} s, the case's longest")
        dt = MAX_DT
    if dt < MIN_DT:  # only the model's own step: ImportOptions refuses a shorter one
        notes.append(f"time step {dt:g} s raised to {MIN_DT:g} s, the case's shortest (the engine divides a step "
                     "further where the Courant number asks for it)")
        dt = MIN_DT
    new = _divisor(interval, dt)
    if new != dt:
        notes.append(f"time step {new:g} s instead of {dt:g} s (a divisor of the output interval)")
        dt = new
    engine: dict = {"dt": dt, "output_interval": float(interval), "cross_sections": "interpolated"}
    theta = model.number("NumericalParameters", "Theta", default=None)
    if theta is not None:
        engine["theta"] = min(max(theta, 0.5), 1.0)
    iterations = model.number("NumericalParameters", "MaxIterations", default=None)
    if iterations is not None:
        engine["max_iterations"] = int(min(max(iterations, 1), 50))
    area = model.number("NumericalParameters", "MinimumSurfaceinNode", default=None)
    if area is not None and area > 0:
        engine["min_storage_area"] = area
    courant = model.number("NumericalParameters", "CourantNumber", default=COURANT)
    if courant is not None and courant > 0:
        engine["courant"] = courant
    ctx.case["engine"] = engine
    what = "the model's own time step" if ctx.options.dt is None else "the time step given"
    (ctx.ledger.approximated if notes else ctx.ledger.exact)(
        "setting", "TimeStep", "; ".join(notes) or f"{what}, {dt:g} s; output every {interval:g} s")


def _tenths(seconds: float) -> int:
    return round(seconds * 10.0)


def _divisor(interval: float, dt: float) -> float:
    """The longest step of at most ``dt`` that divides ``interval`` into whole steps, s.

    A whole number of seconds when one of at least 1 s does, else a whole number of tenths of a second (the
    case's shortest step is 0.1 s; ``interval`` is a whole number of tenths).
    """
    ratio = interval / dt
    if ratio >= 1 - 1e-9 and abs(ratio - round(ratio)) < 1e-9:
        return dt
    total, most = _tenths(interval), math.floor(dt * 10.0 + 1e-6)
    whole = [k for k in range(min(most, total) // 10, 0, -1) if total % (10 * k) == 0]
    if whole:
        return float(whole[0])
    return next(k for k in range(min(most, total), 0, -1) if total % k == 0) / 10.0


def _fit_the_grid(ctx: Context) -> None:
    """Make the case's grid rules hold: crests above the bed, one structure per stretch, stations beside them."""
    beds = {b["id"]: (np.array([c["chainage"] for c in b["cross_sections"]]),
                      np.array([c["bed_level"] for c in b["cross_sections"]])) for b in ctx.case["branches"]}
    on_branch: dict[str, list[tuple[str, dict]]] = defaultdict(list)
    for table in _KINDS:
        kept = []
        for item in ctx.case.get(table, []):
            if item["branch"] not in beds:
                ctx.ledger.refused(*ctx.origin(item["id"], table), "its branch has no cross-section")
                continue
            kept.append(item)
            on_branch[item["branch"]].append((table, item))
        if table in ctx.case:
            ctx.case[table] = kept
    for bid, items in on_branch.items():
        ch, zb = beds[bid]
        for table, item in items:
            bed = float(np.interp(item["chainage"], ch, zb))
            if "crest_level" in item and item["crest_level"] < bed:
                ctx.ledger.approximated(*ctx.origin(item["id"], table), f"the crest {item['crest_level']:g} m AD "
                                        f"lies below the bed ({bed:.3f} m AD): raised to the bed")
                item["crest_level"] = bed
                if "gate_lower_edge_level" in item:
                    item["gate_lower_edge_level"] = max(item["gate_lower_edge_level"], bed + 1e-3)
    branches = {b["id"]: b for b in ctx.case["branches"]}
    layouts = {}
    for bid, b in branches.items():
        branch = Branch.model_validate(b)
        structures = [_KINDS[t].model_validate(i) for t, i in on_branch.get(bid, [])]
        while True:
            try:
                layouts[bid] = branch_layout(branch, structures, 10.0)
                break
            except StructureOverlap as exc:
                table, item = next((t, i) for t, i in on_branch[bid] if i["id"] == exc.structure.id)
                ctx.case[table].remove(item)
                structures = [s for s in structures if s.id != exc.structure.id]
                where = ctx.places.get(item["id"])
                ctx.ledger.refused(*ctx.origin(item["id"], table), (f"{where}: " if where else "") + "it lies between "
                                   f"the same two grid points as {ctx.origin(exc.previous.id, table)[1]!r}; each "
                                   "structure needs a stretch of its own")
    present = {i["id"] for t in _KINDS for i in ctx.case.get(t, [])}
    ctx.case["stations"] = [st for st in ctx.case["stations"] if "structure" not in st or st["structure"] in present]
    for st in ctx.case["stations"]:
        if "structure" in st or "h" not in st["quantities"] or st["branch"] not in layouts:
            continue
        for seg in layouts[st["branch"]]:
            if seg.structure is not None and seg.a + 1e-9 < st["chainage"] < seg.b - 1e-9:
                end = seg.a if st["chainage"] - seg.a <= seg.b - st["chainage"] else seg.b
                ctx.ledger.approximated(*ctx.origin(st["id"], "observation point"),
                                        f"at {st['chainage']:g} m it lies between the grid points around structure "
                                        f"{seg.structure.id!r}; moved to the nearer grid point ({end:g} m)")
                st["chainage"] = end
    ctx.case["stations"] = [st for st in ctx.case["stations"] if "structure" in st or st["branch"] in branches]
    nodes = {n for b in branches.values() for n in (b["from_node"], b["to_node"])}
    ctx.case["laterals"] = [lat for lat in ctx.case["laterals"]
                            if lat.get("branch") in branches or lat.get("node") in nodes]


def _stations_if_none(ctx: Context) -> None:
    """A level station at the middle of each branch when the model has no observation point and no structure.

    A case without stations can be simulated but not calibrated or run on-line (those compare series at
    stations); the model's files said nothing of where its water levels are known, so the import says which
    stations it placed, to be replaced by the water board's gauges.
    """
    if ctx.case.get("stations"):
        return
    placed = []
    for b in ctx.case["branches"]:
        points = b.get("points") or [0.0, b["length"]]
        chainage = float(points[len(points) // 2])
        sid = f"{b['id']}_middle"
        ctx.case.setdefault("stations", []).append({"id": sid, "branch": b["id"], "chainage": chainage,
                                                    "quantities": ["h", "Q"]})
        placed.append(f"`{sid}` ({b['id']} at {chainage:g} m)")
    ctx.ledger.warn("the model has no observation point: a station (level and discharge) is placed at the middle of "
                    "each branch so that the case can be calibrated and run on-line; replace them by your gauges: "
                    + ", ".join(placed[:10]) + (f" and {len(placed) - 10} more" if len(placed) > 10 else ""))


#: SOBEK 3's Courant number when the model does not give one (flow1d's readModelParameters.f90 default).
COURANT = 1.0


def _settings(ctx: Context) -> None:
    model = ctx.model
    ctx.ledger.approximated("setting", "numerics", "rivercal's engine discretises the same equations (the staggered "
                            "Delft scheme) on SOBEK 3's grid points, with its own upwinding and structure "
                            "linearisation; SOBEK 3's other numerical settings (Iadvec1D, Limtyphu1D, Momdilution1D, "
                            "AccurateVersusSpeed, relaxation) are not carried over")
    courant = model.number("NumericalParameters", "CourantNumber", default=COURANT)
    if courant is not None and courant > 0:
        ctx.ledger.exact("setting", "CourantNumber", f"engine.courant = {courant:g}: a step whose flow crosses a grid "
                         "segment faster is divided, as SOBEK 3 reduces its time step")
    theta = model.number("NumericalParameters", "Theta", default=None)
    if theta is not None:
        ctx.ledger.exact("setting", "Theta", f"implicitness {min(max(theta, 0.5), 1.0):g}")
    if model.number("Salinity", "SaltComputation", default=0) or model.number("TransportComputation", "Temperature",
                                                                              default=0):
        ctx.ledger.refused("setting", "transport", "salt and temperature are not computed by a case",
                           hydraulic=False)
    if model.number("Morphology", "CalculateMorphology", default=0):
        ctx.ledger.refused("setting", "morphology", "a case keeps its bed fixed")


def _write(ctx: Context, out: Path) -> None:
    import tomli_w

    for old in out.glob("*.csv"):
        old.unlink()
    for file, columns in ctx.series.items():
        index = pd.DatetimeIndex(sorted(set().union(*(s.index for s in columns.values()))))
        frame = pd.DataFrame({name: np.interp((index - ctx.start).total_seconds(),
                                              (s.index - ctx.start).total_seconds(), s.to_numpy(dtype=float))
                              for name, s in columns.items()}, index=index)
        frame.index = frame.index.strftime("%Y-%m-%dT%H:%M:%S.%fZ").str.replace(".000000Z", "Z", regex=False)
        frame.index.name = "time"
        frame.to_csv(out / file)
    order = ["case", "engine", "initial", "friction", "friction_groups", "profiles", "nodes", "branches", "weirs",
             "universal_weirs", "orifices", "culverts", "bridges", "pumps", "boundaries", "laterals", "stations",
             "parameters"]
    data = {k: ctx.case[k] for k in order if ctx.case.get(k) not in (None, [], {})}
    (out / "case.toml").write_text(tomli_w.dumps(_clean(data)), encoding="utf-8")


def _clean(value):
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _summary(ctx: Context, case) -> dict:
    net = case.network
    by_branch: dict[str, list] = defaultdict(list)
    for s in net.structures:
        by_branch[s.branch].append(s)
    n_points = len(net.nodes)
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
        "objects": len(ctx.ledger.entries),
        "exact": ctx.ledger.counts("exact"),
        "approximated": ctx.ledger.counts("approximated"),
        "refused": ctx.ledger.counts("refused"),
        "dt_s": case.spec.engine.dt,
        "parameters": [p.name for p in case.spec.parameters],
    }
