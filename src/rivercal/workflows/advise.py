"""Where to put the next gauge: the advice of :mod:`rivercal.analysis.advise` as files, a map and a summary.

Candidates are every calculation point (``points``), either side of every structure (``structures``) or a
CSV file of practical places (columns ``branch``, ``chainage`` in m, ``name``, optionally ``cost`` and
``id``), asked of the model through its optional capability
:class:`~rivercal.models.capabilities.VirtualStations`.

Files under ``out``: ``candidates.csv`` (every candidate added to the present stations: its worth,
identifiable parameters, smallest singular value, verdict and posterior σ per parameter, posterior
variance per target), ``steps.csv`` (the chosen gauges in order, with the gain of each step),
``before.csv`` and ``after.csv`` (the verdict per parameter with the present stations and with the
chosen gauges), ``worth_map.png`` (the network with every candidate's place coloured by its worth and
the chosen gauges numbered; for models with a network that has map coordinates) and ``advice.json``
(the summary).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from rivercal.errors import OptionError
from rivercal.workflows.progress import NO_PROGRESS, Progress, jsonable

if TYPE_CHECKING:
    from rivercal.models.contract import Model
    from rivercal.parameters import ParameterSet

__all__ = ["CANDIDATE_KINDS", "MEASURES", "advise_gauges", "candidates_of", "gauges_only", "read_candidates"]

#: The candidate places a model offers itself.
CANDIDATE_KINDS = ("points", "structures")
#: What a new gauge measures.
MEASURES = ("level", "discharge", "both")


def _capable(model: Model, option: str) -> None:
    from rivercal.models.capabilities import VirtualStations

    if not isinstance(model, VirtualStations):
        raise OptionError(f"{option}: model {getattr(model, 'name', '?')!r} cannot simulate series at places where it "
                          "has no station (it lacks the optional capability VirtualStations), so it cannot be "
                          "asked where a new gauge would help", option=option)


def gauges_only(model: Model, stations: Sequence[str]) -> Any:
    """The model measuring at ``stations`` only (``--gauges``): the places of its other stations become candidates.

    Raises
    ------
    OptionError
        When no station is named, a name is not a station of the model, or the model cannot drop stations.
    """
    _capable(model, "--gauges")
    if not stations:
        raise OptionError("--gauges: name at least one station that is a gauge today", option="--gauges")
    try:
        return model.only_stations(stations)
    except ValueError as exc:
        raise OptionError(f"--gauges: {exc}", option="--gauges") from None


def candidates_of(model: Model, where: str, measure: str) -> list[Any]:
    """The model's own candidate places (``points`` or ``structures``) for a gauge measuring ``measure``."""
    from rivercal.analysis.advise import model_candidates

    _capable(model, "--candidates")
    return model_candidates(model, where, measure)


def read_candidates(path: str | Path, model: Model, measure: str) -> list[Any]:
    """Candidates from a CSV file of practical places: ``branch``, ``chainage`` (m), ``name``, ``cost``, ``id``.

    ``cost`` (any unit, the same for all rows) and ``id`` (a station id; default from the name) are optional.

    Raises
    ------
    OptionError
        Naming the file, the line and the column of a bad value (``--candidates``).
    """
    from rivercal.analysis.advise import Candidate

    _capable(model, "--candidates")
    path = Path(path)
    label = f"--candidates {path}"
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise OptionError(f"{label}: cannot be read ({exc})", option="--candidates") from None
    reader = csv.DictReader(text.splitlines())
    columns = [c.strip() for c in reader.fieldnames or []]
    missing = [c for c in ("branch", "chainage", "name") if c not in columns]
    if missing:
        raise OptionError(f"{label}: line 1: the header must name the columns branch, chainage and name (optional: "
                          f"cost, id); column {missing[0]!r} is missing (found: {', '.join(columns) or 'none'})",
                          option="--candidates")
    out, ids = [], {s.rpartition('.')[0] for s in model.observables}
    for line, raw in enumerate(reader, start=2):
        row = {str(k).strip(): (v or "").strip() for k, v in raw.items() if k is not None}
        where = f"{label}: line {line}"
        name = row["name"]
        if not name:
            raise OptionError(f"{where}: column 'name' is empty", option="--candidates")
        try:
            chainage = float(row["chainage"])
        except ValueError:
            raise OptionError(f"{where}: column 'chainage': {row['chainage']!r} is not a number (m from the branch's "
                              "start)", option="--candidates") from None
        cost = None
        if row.get("cost"):
            try:
                cost = float(row["cost"])
            except ValueError:
                raise OptionError(f"{where}: column 'cost': {row['cost']!r} is not a number", option="--candidates") \
                    from None
            if not (math.isfinite(cost) and cost > 0):
                raise OptionError(f"{where}: column 'cost': {cost:g} must be a positive number", option="--candidates")
        ident = row.get("id") or "".join(ch if ch.isalnum() or ch in "_-" else "_" for ch in name)[:64]
        if ident in ids:
            raise OptionError(f"{where}: id {ident!r} is used twice (or by a station of the model); give an 'id' "
                              "column with unique ids", option="--candidates")
        ids.add(ident)
        try:
            loc = model.location_at(row["branch"], chainage, id=ident, measure=measure, name=name)
        except ValueError as exc:
            column = "branch" if "branch" in str(exc) and "outside" not in str(exc) else "chainage"
            raise OptionError(f"{where}: column {column!r}: {exc}", option="--candidates") from None
        out.append(Candidate(loc.id, loc.series, name, cost, loc))
    if not out:
        raise OptionError(f"{label}: the file lists no place", option="--candidates")
    if any(c.cost is not None for c in out) and not all(c.cost is not None for c in out):
        first = next(i for i, c in enumerate(out) if c.cost is None)
        raise OptionError(f"{label}: line {first + 2}: column 'cost' is empty; give a cost on every line or on none",
                          option="--candidates")
    try:
        model.with_stations([c.location for c in out])
    except ValueError as exc:
        for line, c in enumerate(out, start=2):  # the first line that cannot be a station on its own
            try:
                model.with_stations([c.location])
            except ValueError as one:
                raise OptionError(f"{label}: line {line}: {one}", option="--candidates") from None
        raise OptionError(f"{label}: {exc}", option="--candidates") from None
    return out


def advise_gauges(model: Model, parameters: ParameterSet, window: tuple[pd.Timestamp, pd.Timestamp], out: str | Path, *,
                  candidates: Sequence[Any], add: int | None = None, forecasts: Sequence[str] = (),
                  sigma: Mapping[str, float] | None = None, horizon: str = "48h", warmup: str = "24h",
                  rel_step: float = 0.01, scheme: str = "forward", options: Any = None, exchange: bool = True,
                  workers: Any = None, source: str = "", progress: Progress = NO_PROGRESS) -> dict[str, Any]:
    """Advise where to add gauges and write the files of the module docstring.

    Parameters
    ----------
    model, parameters, window, candidates, add, forecasts, sigma, horizon, warmup, rel_step, scheme, options,
    exchange, workers
        As for :func:`rivercal.analysis.advise.advise`.
    out
        Output folder (created).
    source
        What the candidates are (``points``, ``structures`` or the file), for the summary.
    progress
        Where to say what happens.

    Returns
    -------
    dict
        The summary (also ``advice.json``).
    """
    from rivercal.analysis.advise import advise

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result = advise(model, parameters, window, candidates, add=add, sigma=sigma, forecasts=forecasts,
                    horizon=horizon, warmup=warmup, rel_step=rel_step, scheme=scheme, options=options,
                    exchange=exchange, workers=workers, progress=progress.stage)
    lw = result.analysis
    names = list(parameters.names)
    by_id = {c.id: c for c in lw.candidates}
    files: dict[str, str] = {}
    table = result.table.copy()
    table.insert(0, "place", [_where(by_id[i]) for i in table.index])
    table.to_csv(out / "candidates.csv", float_format="%.6g")
    files["candidates"] = str(out / "candidates.csv")
    steps = [_step_row(s, by_id, names, lw) for s in result.steps]
    pd.DataFrame(steps).drop(columns=["verdict"], errors="ignore").to_csv(out / "steps.csv", index=False,
                                                                          float_format="%.6g")
    files["steps"] = str(out / "steps.csv")
    for key, a in (("before", result.before), ("after", result.after)):
        frame = a.identifiability.verdict[["verdict", "index"]].copy()
        frame["posterior_std"] = a.posterior_std
        frame["prior_std"] = np.sqrt(lw.prior_var)
        frame["unit"] = [p.unit for p in parameters]
        frame.to_csv(out / f"{key}.csv", float_format="%.6g")
        files[key] = str(out / f"{key}.csv")
    units = {p.name: p.unit for p in parameters}
    summary: dict[str, Any] = {
        "case": model.name, "window": [window[0].isoformat(), window[1].isoformat()], "parameters": names,
        "units": units, "analysis_point": {p.name: p.initial for p in parameters},
        "candidates": {"source": source, "count": len(lw.candidates)},
        "stations": sorted({s.rpartition(".")[0] for s in (lw.base_rows or ())}),
        "sigma": _sigma_summary(result.extra["sigma"]),
        "prior_std": {n: float(v) for n, v in zip(names, np.sqrt(lw.prior_var), strict=True)},
        "targets": list(lw.targets), "forecasts": list(forecasts), "horizon": horizon if forecasts else None,
        "before": result.before.summary(), "after": result.after.summary(),
        "steps": steps, "chosen": result.chosen, "enough": result.enough,
        "top": [_table_row(table, i, by_id) for i in table.index[:10]],
        "jacobian_runs": result.jacobian_runs, "wall_s": round(result.wall_s, 2),
    }
    figure = _worth_map(model, result, out / "worth_map.png")
    if figure is not None:
        files["worth_map"] = str(figure)
    else:
        summary["worth_map"] = "not drawn: the model has no network with map coordinates"
    files["summary"] = str(out / "advice.json")
    summary["files"] = files
    summary = jsonable(summary)
    (out / "advice.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary


def _where(c: Any) -> str:
    loc = c.location
    if loc is None:
        return c.name
    if loc.structure is not None:
        return f"structure {loc.structure}" + (f" ({loc.side}stream)" if loc.side else "")
    return f"branch {loc.branch} at {loc.chainage:.1f} m"


def _sigma_summary(sigma: Mapping[str, float]) -> dict[str, float]:
    """σ by quantity where all series of a quantity share it (else by series)."""
    by_q: dict[str, set[float]] = {}
    for sid, s in sigma.items():
        by_q.setdefault(sid.rpartition(".")[2], set()).add(float(s))
    if all(len(v) == 1 for v in by_q.values()):
        return {q: next(iter(v)) for q, v in by_q.items()}
    return dict(sigma)


def _step_row(step: Any, by_id: Mapping[str, Any], names: list[str], lw: Any) -> dict[str, Any]:
    a = step.assessment
    c = by_id[step.candidate]
    row = {"step": step.number, "candidate": step.candidate, "name": c.name, "place": _where(c),
           "series": list(c.series), "cost": c.cost, "worth": step.worth, "identifiable": a.identifiable,
           "smallest_singular_value": a.smallest_singular_value, "relative_variance": a.relative_variance,
           "verdict": a.verdicts}
    row.update({f"std:{n}": float(v) for n, v in zip(names, a.posterior_std, strict=True)})
    row.update({f"forecast_std:{k}": v for k, v in a.forecast_std.items()})
    return row


def _table_row(table: pd.DataFrame, i: str, by_id: Mapping[str, Any]) -> dict[str, Any]:
    r = table.loc[i]
    return {"candidate": i, "name": r["name"], "place": r["place"], "series": list(by_id[i].series),
            "worth": float(r["worth"]), "identifiable": int(r["identifiable"]),
            "smallest_singular_value": float(r["smallest_singular_value"]), "cost": by_id[i].cost}


def _worth_map(model: Model, result: Any, path: Path) -> Path | None:
    """The network with each candidate's point coloured by its worth, the chosen gauges numbered; None without a map."""
    case = getattr(model, "case", None)
    compiled = getattr(model, "compiled", None)
    if case is None or compiled is None:
        return None
    network = case.network
    if any(n.x is None or n.y is None for n in network.nodes):
        return None
    from rivercal.report.figures import plot_network_values

    worth = pd.Series(np.nan, index=pd.Index(compiled.hp_label))
    by_id = {c.id: c for c in result.analysis.candidates}
    for cid, value in result.table["worth"].items():
        point = getattr(by_id[cid].location, "point", None)
        if point in worth.index and not (worth[point] >= value):
            worth[point] = value
    fig = plot_network_values(case, worth, title=f"{model.name}: worth of one gauge added to the present stations "
                              "(numbers: the advised gauges in order)", label="data worth (mean fractional "
                              "variance reduction)", cmap="RdBu_r")
    ax = fig.axes[0]
    # worth is never negative: a sequential scale from zero instead of the map's symmetric one
    from matplotlib.colors import Normalize

    coloured = next((c for c in ax.collections if c.get_array() is not None and getattr(c, "colorbar", None)), None)
    if coloured is not None:
        top = float(np.nanmax(worth.to_numpy())) if np.isfinite(worth.to_numpy()).any() else 1.0
        coloured.set_cmap("YlOrRd")
        coloured.set_norm(Normalize(0.0, top if top > 0 else 1.0))
        coloured.colorbar.update_normal(coloured)
    for step in result.steps:
        loc = by_id[step.candidate].location
        if loc is not None and loc.x is not None and loc.y is not None:
            ax.plot(loc.x, loc.y, marker="*", ms=15, color="#d69e2e", mec="black", zorder=7)
            ax.annotate(str(step.number), (loc.x, loc.y), xytext=(-4, -14), textcoords="offset points", fontsize=9,
                        weight="bold", color="#744210")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    return path
