"""What the dashboard's pages show, read from the store (no model runs; nothing is written).

Each function takes an open (read-only) :class:`~rivercal.store.Store` and a run and returns plain data
for a template: rows of tables (values in the store's units, with the full-precision number beside the
shown text) and plotly figures as dictionaries (``{"data": [...], "layout": {...}}``) that the page's
script draws with the plotly.js shipped by the ``plotly`` package.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
import pandas as pd

from rivercal.store import FINAL_STATUSES

__all__ = ["cycles_view", "estimates_view", "forecasts_view", "map_view", "now_view", "run_version"]

_LEVELS = ("h", "h_up", "h_down")
_BLUE, _RED, _GREY = "#2b6cb0", "#c53030", "#718096"


def _t(value: Any) -> str | None:
    """A UTC time as plotly and people read it: 'YYYY-MM-DD HH:MM' (None for NaT)."""
    return None if pd.isna(value) else pd.Timestamp(value).strftime("%Y-%m-%d %H:%M")


def _num(value: Any) -> float | None:
    """A number for JSON (None for NaN or None)."""
    if value is None:
        return None
    x = float(value)
    return x if math.isfinite(x) else None


def _cell(value: Any, digits: int = 4) -> dict[str, Any]:
    """A number as shown (``digits`` significant) and as stored (``raw``, for machines and tests)."""
    x = _num(value)
    return {"text": "–" if x is None else f"{x:.{digits}g}", "raw": "" if x is None else repr(x)}


def _words(td: Any) -> str:
    seconds = pd.Timedelta(td).total_seconds()
    for unit, size in (("day", 86400), ("hour", 3600), ("minute", 60)):
        if seconds >= size and seconds % size == 0:
            n = int(seconds // size)
            return f"{n} {unit}" + ("" if n == 1 else "s")
    return f"{seconds:g} s"


def run_version(store: Any, run: Any) -> str:
    """A token that changes whenever a cycle of the run is stored or finished (the page polls it)."""
    cycles = store.cycles(run)
    if cycles.empty:
        return "0"
    return f"{len(cycles)}:{(cycles['status'] == 'done').sum()}:{cycles['finished'].max()}"


def now_view(store: Any, run: Any) -> dict[str, Any]:
    """The latest estimates with σ and whether they are in use (and why not), the issued forecast, the open alerts.

    The issued forecast is the latest cycle's: the updated parameters' or, as a fallback, the DSS's, and why.

    An estimate is *accepted* (the forecast uses it), *held* (the service kept the previous value: the
    window cannot see the parameter, or the change is too large) or a *fallback* (the cycle's
    calibration failed or was aborted; the last accepted value is kept). Alerts are open while their
    cycle's issue time lies within one calibration window of the latest cycle.
    """
    cycles = store.cycles(run)
    final = cycles[cycles["status"].isin(FINAL_STATUSES)]
    out: dict[str, Any] = {"n_cycles": len(cycles), "latest": None, "estimates": [], "alerts": [],
                           "window": _words(run.config.get("window", "7D")), "running": None}
    running = cycles[~cycles["status"].isin(FINAL_STATUSES)]
    if len(running):
        out["running"] = {"cycle": int(running["cycle"].iloc[0]), "issue_time": _t(running["issue_time"].iloc[0])}
    if final.empty:
        return out
    last = final.iloc[-1]
    issued = last.get("issued_forecast")
    out["latest"] = {"cycle": int(last["cycle"]), "issue_time": _t(last["issue_time"]), "status": str(last["status"]),
                     "message": str(last["message"] or ""), "model_runs": _cell(last["model_runs"], 6),
                     "wall_time_s": _cell(last["wall_time_s"], 3),
                     "issued": str(issued) if isinstance(issued, str) else "",
                     "issued_reason": str(last.get("issued_reason") or "")}
    est = store.estimates(run)
    in_use = store.last_accepted(run)
    for r in est[est["cycle"] == last["cycle"]].itertuples():
        if last["status"] != "done":
            state, why = "fallback", f"the calibration {last['status']}: {last['message'] or 'no message'}"
        elif r.accepted:
            state, why = "accepted", ""
        else:
            state, why = "held", r.reason or ""
        out["estimates"].append({"parameter": r.parameter, "value": _cell(r.value), "std": _cell(r.std, 3),
                                 "unit": r.unit, "state": state, "why": why,
                                 "in_use": _cell(in_use.get(r.parameter))})
    alerts = store.alerts(run)
    since = last["issue_time"] - pd.Timedelta(run.config.get("window", "7D"))
    for a in alerts[alerts["issue_time"] >= since].iloc[::-1].itertuples():
        out["alerts"].append({"cycle": int(a.cycle), "issue_time": _t(a.issue_time), "kind": a.kind,
                              "parameter": a.parameter or "", "message": a.message,
                              "magnitude": _cell(a.magnitude, 3)})
    return out


def estimates_view(store: Any, run: Any) -> dict[str, Any]:
    """One figure per parameter: the estimate per cycle with ±σ, held ones open, over the issue time."""
    est = store.estimates(run)
    figures = []
    for name, g in est.groupby("parameter", sort=True):
        ok, held = g[g["accepted"]], g[~g["accepted"]]
        unit = str(g["unit"].iloc[0])
        data = [{"type": "scatter", "mode": "lines+markers", "name": "estimate (accepted, ±σ)",
                 "x": [_t(t) for t in ok["issue_time"]], "y": [_num(v) for v in ok["value"]],
                 "error_y": {"type": "data", "array": [_num(s) or 0.0 for s in ok["std"]], "visible": True},
                 "marker": {"color": _BLUE, "size": 6}, "line": {"color": _BLUE, "width": 1}}]
        if len(held):
            data.append({"type": "scatter", "mode": "markers", "name": "held (not accepted)",
                         "x": [_t(t) for t in held["issue_time"]], "y": [_num(v) for v in held["value"]],
                         "text": list(held["reason"].fillna("")),
                         "marker": {"color": _RED, "size": 9, "symbol": "circle-open"}})
        figures.append({"id": f"est-{len(figures)}", "parameter": str(name), "n": len(g),
                        "last": _cell(g["value"].iloc[-1]),
                        "figure": {"data": data, "layout": _layout(f"{name} [{unit}]", "issue time (UTC)")}})
    return {"figures": figures}


def _layout(ytitle: str, xtitle: str, **extra: Any) -> dict[str, Any]:
    return {"height": 300, "margin": {"l": 60, "r": 20, "t": 10, "b": 45}, "yaxis": {"title": {"text": ytitle}},
            "xaxis": {"title": {"text": xtitle}}, "legend": {"orientation": "h", "y": 1.12}, **extra}


def forecast_choices(store: Any, run: Any) -> tuple[list[str], list[float]]:
    """The forecast series of the run and the lead times stored (h), from its latest cycle with forecasts."""
    cycles = store.cycles(run)
    done = cycles[cycles["status"].isin(FINAL_STATUSES)]
    for cycle in done["cycle"].iloc[::-1][:3]:
        fc = store.forecasts(run, cycle=int(cycle))
        if len(fc):
            return sorted(fc["series"].unique()), sorted(float(v) for v in fc["lead_h"].unique())
    return [], []


def forecasts_view(store: Any, run: Any, series: str, lead_h: float) -> dict[str, Any]:
    """Forecasts at one lead time against the observations and the DSS, and the scores by lead time."""
    fc = store.forecasts(run, series=[series])
    at = fc[np.isclose(fc["lead_h"], lead_h)]
    data = []
    if len(fc):
        obs = store.observations([series], fc["time"].min(), fc["time"].max())[series]
        data.append({"type": "scatter", "mode": "lines", "name": "observed", "x": [_t(t) for t in obs.times],
                     "y": [_num(v) for v in obs.values], "line": {"color": "#1a202c", "width": 1}})
    for kind, colour, label in (("dss", _RED, "fixed DSS"), ("updated", _BLUE, "rivercal")):
        part = at[at["kind"] == kind]
        data.append({"type": "scatter", "mode": "markers", "name": f"{label}, {lead_h:g} h ahead",
                     "x": [_t(t) for t in part["time"]], "y": [_num(v) for v in part["value"]],
                     "marker": {"color": colour, "size": 5}})
    unit = "m³/s" if series.endswith(".Q") else "m"
    scores = store.scores(run)
    scores = scores[scores["series"] == series]
    table = []
    if len(scores):
        mean = scores.groupby(["lead_from_h", "lead_to_h", "kind"])[["rmse", "bias"]].mean().unstack("kind")
        n = scores.groupby(["lead_from_h", "lead_to_h"])["cycle"].nunique()
        for (a, b), row in mean.iterrows():
            table.append({"lead": f"{a:g}–{b:g} h", "cycles": int(n.loc[(a, b)]),
                          **{f"{m}_{k}": _cell(row.get((m, k)), 3) for m in ("rmse", "bias")
                             for k in ("updated", "dss")}})
    return {"series": series, "lead_h": lead_h, "unit": unit, "n_points": int((at["kind"] == "updated").sum()),
            "figure": {"data": data, "layout": _layout(f"{series} [{unit}]", "time (UTC)", height=380)},
            "scores": table}


@functools.lru_cache(maxsize=8)
def _network(case: str) -> Any:
    from rivercal.case import load_case

    return load_case(case).network


def map_view(store: Any, run: Any) -> dict[str, Any]:
    """The network with each station's mean level-forecast error (bias, forecast − observed), DSS and rivercal."""
    from rivercal.network.coordinates import branch_polylines, station_coordinates

    try:
        network = _network(run.case)
        where = station_coordinates(network)
    except (ValueError, OSError) as exc:  # a case that cannot be loaded here, or without map coordinates
        return {"problem": f"the network of case {run.case!r} cannot be drawn here: {exc}", "figures": [], "rows": []}
    scores = store.scores(run)
    scores = scores[scores["series"].str.rpartition(".")[2].isin(_LEVELS)]
    scores = scores.assign(station=scores["series"].str.rpartition(".")[0])
    bias = scores.groupby(["station", "kind"])["bias"].mean().unstack("kind") if len(scores) else pd.DataFrame()
    lines_x: list[float | None] = []
    lines_y: list[float | None] = []
    for xy in branch_polylines(network).values():
        lines_x += [*xy[:, 0].tolist(), None]
        lines_y += [*xy[:, 1].tolist(), None]
    top = max([abs(float(v)) for v in bias.to_numpy().ravel() if math.isfinite(v)] or [0.01]) * 100
    figures, rows = [], []
    for kind, label in (("dss", "fixed DSS"), ("updated", "rivercal")):
        ids = [s for s in where if not bias.empty and s in bias.index and kind in bias]
        values = [_num(bias.loc[s, kind] * 100) for s in ids]
        data = [{"type": "scatter", "mode": "lines", "x": lines_x, "y": lines_y, "hoverinfo": "skip",
                 "line": {"color": "#a0aec0", "width": 2}, "showlegend": False},
                {"type": "scatter", "mode": "markers+text", "x": [where[s][0] for s in ids],
                 "y": [where[s][1] for s in ids], "text": ids, "textposition": "top center", "showlegend": False,
                 "marker": {"size": 16, "color": values, "colorscale": "RdBu", "reversescale": True, "cmin": -top,
                            "cmax": top, "line": {"color": "#1a202c", "width": 1},
                            "colorbar": {"title": {"text": "cm"}}}}]
        layout = {"height": 420, "margin": {"l": 10, "r": 10, "t": 30, "b": 10}, "title": {"text": label},
                  "xaxis": {"visible": False}, "yaxis": {"visible": False, "scaleanchor": "x"}}
        figures.append({"id": f"map-{kind}", "figure": {"data": data, "layout": layout}})
    for s in where:
        row = bias.loc[s] if not bias.empty and s in bias.index else {}
        rows.append({"station": s, "dss": _cell(_scaled(row, "dss"), 3), "updated": _cell(_scaled(row, "updated"), 3)})
    return {"problem": None, "figures": figures, "rows": rows}


def _scaled(row: Any, kind: str) -> float | None:
    value = row.get(kind) if hasattr(row, "get") else None
    return None if value is None or not math.isfinite(value) else float(value) * 100


def cycles_view(store: Any, run: Any) -> dict[str, Any]:
    """The cycle log, newest first: status, model runs, wall time, costs and the message."""
    cycles = store.cycles(run)
    rows = [{"cycle": int(c.cycle), "issue_time": _t(c.issue_time), "status": c.status, "algorithm": c.algorithm or "",
             "model_runs": _cell(c.model_runs, 6), "wall_time_s": _cell(c.wall_time_s, 3),
             "cost_before": _cell(c.cost_before), "cost_after": _cell(c.cost_after), "message": c.message or "",
             "finished": _t(c.finished)} for c in cycles.iloc[::-1].itertuples()]
    wall = cycles["wall_time_s"].dropna()
    return {"rows": rows, "median_wall_s": _cell(wall.median() if len(wall) else None, 3),
            "total_runs": int(cycles["model_runs"].fillna(0).sum())}
