"""The report of an on-line run, rendered from its store (thesis chapter 5: Tables 5-1 … 5-5, Figs 5-2 … 5-15).

Everything comes from the store: cycles, estimates, alerts, forecasts and their scores. For a run on
twin observations of a practical scenario (the run's stored ``meta.scenario``), the report also
re-runs the truth and two continuous model runs over the replayed period to draw what the stations
cannot show: the levels at the weir of Fig. 5-4 and the average level error at every calculation
point (Figs 5-2/5-3). The continuous runs are

- the **DSS**: the case's fixed parameters throughout, from a cold start;
- **rivercal**: the model as the on-line service keeps it, with each cycle's accepted parameters
  from its issue time until the next cycle's (a piecewise-constant parameter history, one run).

Errors are model − truth (m); Δŷ_avg of a point is the mean error over a period, as in the thesis
(positive: the model is too high).
"""

from __future__ import annotations

import itertools
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal._figure import subplots
from rivercal._time import utc
from rivercal.io.cf import add_stations, write_netcdf
from rivercal.models.contract import spun_up
from rivercal.report.figures import mark_change
from rivercal.report.html import Page, bullets, figure, paragraph, table
from rivercal.report.online_bands import band_blocks
from rivercal.report.online_figures import figure_blocks
from rivercal.store.export import export_estimates_csv, export_forecasts_csv, to_xarray

__all__ = ["continuous_runs", "forecast_errors", "write_online_report"]

log = logging.getLogger(__name__)

_LEVELS = ("h", "h_up", "h_down")
_RED, _BLUE, _GREY = "#c53030", "#2b6cb0", "#718096"




def _meta(run: Any) -> dict[str, Any]:
    return dict(run.config.get("meta") or {})


def _perturbed(meta: dict[str, Any]) -> list[str]:
    """What made the truth behind a twin's observations differ from the model (empty: nothing did)."""
    from rivercal.twin.realism import Realism

    realism = Realism.model_validate(meta["realism"]) if meta.get("realism") else None
    out = [f"realism {realism.name}"] if realism is not None and realism.changes_truth else []
    return out + ([f"a rain error of about {float(meta['rain_error']):.0%}"] if meta.get("rain_error") else [])


def _truth_words(perturbed: list[str]) -> list[str]:
    """What "truth" means on the error maps, and whether the observations came from another truth.

    The maps re-run the scenario's parameters on the model itself: the truth of an identical twin (also
    under sensor errors alone), not that of a realism level with rain, runoff or structural errors or of
    a rain error (``perturbed``: :func:`_perturbed`).
    """
    if not perturbed:
        return ["truth: the scenario's parameters on the model itself (the identical twin of the observations)."]
    return [f"truth: the scenario's parameters on the model itself. The observations came from a truth with "
            f"{' and '.join(perturbed)}, which these maps do not use (its grid, forcing or friction differ from "
            "the model's): they show what the parameter estimates leave of the change, not the model's error "
            "against that truth; the forecast scores above are against the observations."]


def _change_time(run: Any) -> pd.Timestamp | None:
    scenario = _meta(run).get("scenario")
    if not scenario:
        return None
    from rivercal.twin.practical import SCENARIOS

    return utc(SCENARIOS[scenario].change_time)


# -- forecast errors -------------------------------------------------------------------------------------


def forecast_errors(store: Any, run: Any, *, after: Any | None = None, lead_h: float = 24.0) -> dict[str, Any]:
    """Mean absolute error of the level forecasts at the stations: rivercal (updated) against the fixed DSS.

    Parameters
    ----------
    store, run
        The store and the run (or its name).
    after
        Only cycles whose calibration window starts at or after this time (UTC); default: for a twin
        scenario its change time (the transition has left the window), else every cycle.
    lead_h
        Lead times (0, lead_h] h are scored.

    Returns
    -------
    dict
        ``n`` (compared values per kind), ``lead_h``, ``from`` (ISO time or None), ``updated_mae_m`` and
        ``dss_mae_m`` (m), ``ratio`` (DSS / rivercal; None when rivercal's error is zero or nothing was
        compared), and ``reason``: why nothing could be compared (None when ``n`` > 0).
    """
    run = store.get_run(run) if isinstance(run, str) else run
    if after is None:
        after = _change_time(run)
    out: dict[str, Any] = {"n": 0, "lead_h": lead_h, "from": None if after is None else utc(after).isoformat(),
                           "updated_mae_m": None, "dss_mae_m": None, "ratio": None, "reason": None}
    cycles = store.cycles(run)
    if cycles.empty:
        out["reason"] = "the run has no finished cycle yet"
        return out
    keep = cycles if after is None else cycles[cycles["window_start"] >= utc(after)]
    if keep.empty:
        out["reason"] = _no_cycle_after(run, cycles, utc(after))
        return out
    fc = store.forecasts(run)
    fc = fc[fc["cycle"].isin(keep["cycle"]) & (fc["lead_h"] > 0) & (fc["lead_h"] <= lead_h)]
    if not fc.empty:
        fc = fc[fc["series"].str.rpartition(".")[2].isin(_LEVELS)]
    if fc.empty:
        out["reason"] = f"the scored cycles stored no level forecast with a lead time of at most {lead_h:g} h"
        return out
    series = sorted(fc["series"].unique())
    obs = [s for s in store.observations(series, fc["time"].min(), fc["time"].max()) if len(s)]
    joined = fc.iloc[:0]
    if obs:
        observed = pd.concat({s.id: pd.Series(s.values, index=s.times) for s in obs}, names=["series", "time"])
        joined = fc.join(observed.rename("observed"), on=["series", "time"], how="inner")
    if joined.empty:
        out["reason"] = _no_observations(store, series, fc)
        return out
    joined["abs_error"] = (joined["value"] - joined["observed"]).abs()
    mae = joined.groupby("kind")["abs_error"].mean()
    n = joined.groupby("kind").size()
    if "updated" not in mae or "dss" not in mae:
        missing = "rivercal's" if "updated" not in mae else "the DSS's"
        out["reason"] = f"no observation falls on {missing} forecasts, so the two cannot be compared"
        return out
    out.update(n=int(n.min()), updated_mae_m=float(mae["updated"]), dss_mae_m=float(mae["dss"]),
               ratio=float(mae["dss"] / mae["updated"]) if mae["updated"] > 0 else None)
    return out


def _no_cycle_after(run: Any, cycles: pd.DataFrame, after: pd.Timestamp) -> str:
    """Why no cycle counts: none has a calibration window that starts at or after ``after``."""
    window = pd.Timedelta(run.config["window"])
    period = pd.Timedelta(run.config["period"])
    first = utc(run.config.get("first_issue") or cycles["issue_time"].min())
    k = max(0, -(-(after + window - first) // period))  # the first cycle whose window starts at or after
    return (f"the comparison counts only cycles whose calibration window ({_span(run.config['window'])}) starts at or "
            f"after the change at {after:%Y-%m-%d %H:%M}; the first such cycle is issued at "
            f"{first + k * period:%Y-%m-%d %H:%M}, the last cycle of this run at "
            f"{cycles['issue_time'].max():%Y-%m-%d %H:%M}")


def _no_observations(store: Any, series: list[str], fc: pd.DataFrame) -> str:
    """Why no forecast meets an observation: the observations end (or start) outside the forecasts' times."""
    table = store.availability(series)
    first_fc = fc["time"].min()
    if table.empty:
        return "the store holds no observation of the forecast series"
    last_obs = pd.Timestamp(table["last"].max())
    if last_obs < first_fc:
        return (f"the observations end at {last_obs:%Y-%m-%d %H:%M}, before the forecasts' first lead time "
                f"({first_fc:%Y-%m-%d %H:%M})")
    return (f"no observation falls on a forecast time between {first_fc:%Y-%m-%d %H:%M} and "
            f"{fc['time'].max():%Y-%m-%d %H:%M}")


# -- continuous runs (twin scenarios) --------------------------------------------------------------------


def continuous_runs(model: Any, store: Any, run: Any, start: Any, end: Any) -> dict[str, pd.DataFrame]:
    """Levels at every calculation point, hourly, of the truth, the DSS and rivercal (module docstring).

    Returns
    -------
    dict
        ``truth``, ``dss``, ``rivercal``: DataFrames indexed by time (UTC), one column per calculation
        point, m AD; ``truth_series``, ``dss_series``, ``rivercal_series``: the observable series.
    """
    from rivercal.parameters import ParameterSet
    from rivercal.twin.practical import practical_truth

    run = store.get_run(run) if isinstance(run, str) else run
    meta, config = _meta(run), run.config
    start, end = utc(start), utc(end)
    truth = practical_truth(model, meta["scenario"], start, end, levels=True)
    dss_q = dict(config.get("dss") or {})
    state = spun_up(model, dss_q, start)
    dss, _ = model.simulate(dss_q, start=start, end=end, state=state, output_interval=3600, snapshots=True)
    known = {p.name: p for p in model.calibration.parameters}
    params = ParameterSet(known[n] for n in config["parameters"])
    est = store.estimates(run)
    cycles = store.cycles(run)
    accepted: dict[str, float] = {p.name: p.initial for p in params}
    segments: list[tuple[pd.Timestamp, dict[str, float]]] = []
    for c in cycles.itertuples():
        rows = est[(est["cycle"] == c.cycle) & est["accepted"]]
        accepted = {**accepted, **dict(zip(rows["parameter"], rows["value"], strict=True))}
        segments.append((c.issue_time, dict(accepted)))
    first = [q for t, q in segments if t <= start]
    values = first[-1] if first else {p.name: p.initial for p in params}
    state = spun_up(model, {**dss_q, **params.quantities(values)}, start)
    bounds = [t for t, _ in segments if start < t < end]
    edges = [start, *bounds, end]
    level_parts, series_parts = [], []
    for a, b in itertools.pairwise(edges):
        later = [q for t, q in segments if t <= a]
        values = later[-1] if later else values
        res, state = model.simulate({**dss_q, **params.quantities(values)}, start=a, end=b, state=state,
                                    output_interval=3600, snapshots=True)
        level_parts.append(res.levels.iloc[:-1])
        series_parts.append(res.series.iloc[:-1])
    rivercal_levels = pd.concat(level_parts)
    rivercal_series = pd.concat(series_parts)
    idx = rivercal_levels.index
    return {"truth": truth.levels.loc[idx], "dss": dss.levels.loc[idx], "rivercal": rivercal_levels,
            "truth_series": truth.series.loc[idx], "dss_series": dss.series.loc[idx],
            "rivercal_series": rivercal_series}


# -- figures -----------------------------------------------------------------------------------------------


def _estimates_figure(est: pd.DataFrame, units: dict[str, str], truth: dict[str, tuple], dss: dict[str, float],
                      change: pd.Timestamp | None, path: Path) -> Path:
    _estimates_plot(est, units, truth, dss, change).savefig(path, dpi=110)
    return path


def _estimates_plot(est: pd.DataFrame, units: dict[str, str], truth: dict[str, tuple], dss: dict[str, float],
                    change: pd.Timestamp | None) -> Any:
    """One panel per parameter: the estimates per cycle (parameter units), the DSS's value and the truth."""
    names = list(dict.fromkeys(est["parameter"]))
    # the period the estimates speak for: from the first window's start to the last issue time
    lo, t0, t1 = est["window_start"].min(), est["issue_time"].min(), est["issue_time"].max()
    fig, axes = subplots(len(names), 1, figsize=(9.5, 2.6 * len(names)), sharex=True, squeeze=False)
    for ax, name in zip(axes[:, 0], names, strict=True):
        e = est[est["parameter"] == name]
        ok, held = e[e["accepted"]], e[~e["accepted"]]
        ax.errorbar(ok["issue_time"], ok["value"], yerr=ok["std"].fillna(0.0), fmt="o", color=_BLUE, ms=4,
                    capsize=2, label="rivercal (accepted, ±σ)")
        if len(held):
            ax.plot(held["issue_time"], held["value"], "o", mfc="none", color=_RED, ms=6,
                    label="estimate held (not accepted)")
        if name in dss:
            ax.axhline(dss[name], color=_RED, lw=1.2, ls="-", label="DSS (fixed)")
        if name in truth:
            before, after = truth[name]
            if change is not None and before is not None and after is not None:
                if change <= t0:  # changed before the first cycle: the truth is its value after
                    ax.plot([t0, t1], [after, after], color="k", lw=1, ls=":", label="truth")
                elif change >= t1:
                    ax.plot([t0, t1], [before, before], color="k", lw=1, ls=":", label="truth")
                else:
                    ax.step([t0, change, t1], [before, after, after], where="post", color="k", lw=1, ls=":",
                            label="truth")
            elif before is not None:
                ax.axhline(before, color="k", lw=1, ls=":", label="truth")
        ax.set_ylabel(f"{name} [{units.get(name, '')}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=2, loc="best")
    mark_change(axes[:, 0], change, lo, t1, axis_label="issue time (UTC)")
    fig.suptitle("Estimates per cycle (window ending at the issue time)")
    fig.autofmt_xdate()
    fig.tight_layout()
    return fig


def _scores_figure(scores: pd.DataFrame, path: Path) -> Path:
    levels = scores[scores["series"].str.rpartition(".")[2].isin(_LEVELS)]
    table_ = levels.groupby(["kind", "lead_to_h"])["rmse"].mean().unstack("kind")
    fig, ax = subplots(figsize=(7.5, 3.8))
    width = 0.38
    x = np.arange(len(table_))
    for k, (kind, colour, label) in enumerate((("dss", _RED, "fixed DSS"), ("updated", _BLUE, "rivercal"))):
        if kind in table_:
            ax.bar(x + (k - 0.5) * width, table_[kind] * 100, width, color=colour, label=label)
    ax.set_xticks(x, [f"≤ {v:g} h" for v in table_.index])
    ax.set_xlabel("lead time")
    ax.set_ylabel("RMSE of level forecasts [cm]")
    ax.set_title("Forecast error at the stations by lead time (all cycles)")
    ax.legend()
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _error_time_figure(errors: dict[str, pd.DataFrame], change: pd.Timestamp | None, path: Path) -> Path:
    fig, ax = subplots(figsize=(9.5, 3.6))
    for key, colour, label in (("dss", _RED, "fixed DSS"), ("rivercal", _BLUE, "rivercal")):
        ax.plot(errors[key].index, errors[key].abs().mean(axis=1) * 100, color=colour, lw=1.3, label=label)
    mark_change(ax, change, errors["rivercal"].index[0], errors["rivercal"].index[-1], axis_label="time (UTC)",
                label="transition")
    ax.set_ylabel("mean |level error| over all points [cm]")
    ax.set_title("Level error over time, every calculation point")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


# -- tables ------------------------------------------------------------------------------------------------


def _parameter_table(model: Any, run: Any, est: pd.DataFrame, change: pd.Timestamp | None) -> pd.DataFrame:
    """Thesis Tables 5-1 … 5-5: crest per adjustable weir and friction — true, DSS and rivercal.

    Rows: every single-target parameter of the case that the DSS or the truth sets, plus the quantities
    the scenario changes (e.g. the friction of one section). A branch friction that rivercal does not
    estimate takes its global friction.
    """
    from rivercal.parameters import ParameterSet
    from rivercal.twin.practical import SCENARIOS

    known = {p.name: p for p in model.calibration.parameters}
    defaults = model.default_parameters()
    scenario = SCENARIOS.get(_meta(run).get("scenario") or "")
    changed_before = scenario.quantities(defaults, after=False) if scenario else {}
    changed_after = scenario.quantities(defaults, after=True) if scenario else {}
    rows_for: dict[str, str] = {}
    for p in model.calibration.parameters:
        if len(p.targets) == 1 and not p.cluster and (p.targets[0] in defaults or p.targets[0] in changed_after):
            rows_for[p.targets[0]] = p.name
    for target in changed_after:
        rows_for.setdefault(target, target.split(":", 1)[1])
    params = ParameterSet(known[n] for n in run.config["parameters"])
    windows = est.drop_duplicates("cycle").set_index("cycle")

    def rivercal_at(pick: int | None) -> dict[str, float]:
        if pick is None:
            return {}
        values = {p.name: p.initial for p in params}
        for _, g in est[est["cycle"] <= pick].groupby("cycle"):
            ok = g[g["accepted"]]
            values.update(dict(zip(ok["parameter"], ok["value"], strict=True)))
        return {**defaults, **params.quantities(values)}

    def value(q: dict[str, float], target: str) -> float:
        if target in q:
            return q[target]
        return q.get("friction:global", np.nan) if target.startswith("friction:branch:") else np.nan

    if change is not None:
        before = windows.index[windows["window_end"] <= change]
        after = windows.index[windows["window_start"] >= change]
    else:
        before, after = windows.index[:0], windows.index
    q_before = rivercal_at(int(before.max()) if len(before) else None)
    q_after = rivercal_at(int(after.max()) if len(after) else None)
    dss = dict(defaults)
    rows = []
    for target, name in rows_for.items():
        unit = known[name].unit if name in known else ("m^(1/3)/s" if target.startswith("friction") else "m AD")
        row = {"parameter": name, "target": target.split(":", 1)[1].removesuffix(".crest_level"), "unit": unit,
               "DSS": value(dss, target)}
        if scenario is not None:
            row["true before"] = value({**dss, **changed_before}, target)
        row["rivercal before"] = value(q_before, target) if q_before else np.nan
        if scenario is not None:
            row["true after"] = value({**dss, **changed_after}, target)
        row["rivercal after"] = value(q_after, target) if q_after else np.nan
        rows.append(row)
    return pd.DataFrame(rows).set_index("parameter")


def _station_scores(scores: pd.DataFrame) -> pd.DataFrame:
    s = scores.copy()
    s["station"] = s["series"].str.rpartition(".")[0]
    s["lead"] = s["lead_from_h"].map("{:g}".format) + "–" + s["lead_to_h"].map("{:g}".format) + " h"
    order = s.drop_duplicates("lead").sort_values("lead_from_h")["lead"].tolist()
    s["lead"] = pd.Categorical(s["lead"], categories=order, ordered=True)
    out = s.groupby(["station", "lead", "kind"], observed=True)["rmse"].mean().unstack("kind") * 100
    out = out.rename(columns={"dss": "DSS RMSE [cm or 0.01 m³/s]", "updated": "rivercal RMSE [cm or 0.01 m³/s]"})
    return out


def _missing_columns(ptable: pd.DataFrame) -> str:
    """Say why a 'rivercal before/after' column is empty (the run has no cycle on that side of the change)."""
    empty = [c for c in ("rivercal before", "rivercal after") if c in ptable and ptable[c].isna().all()]
    words = {"rivercal before": "no cycle's window ends before the transition",
             "rivercal after": "no cycle's window lies after the transition yet"}
    return "".join(f" '{c}' is empty: {words[c]}." for c in empty)


def _span(text: str) -> str:
    """'7D' → '7 days', '48h' → '48 hours', '90min' → '90 minutes' (a duration as a reader says it)."""
    seconds = pd.Timedelta(text).total_seconds()
    for unit, size in (("day", 86400), ("hour", 3600), ("minute", 60)):
        if seconds >= size and seconds % size == 0:
            return _count(int(seconds // size), unit)
    return _count(int(seconds), "second") if seconds == int(seconds) else f"{seconds:g} s"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _ratio_words(ratio: float | None) -> str:
    if ratio is None:
        return "."
    return " — more than 1000× smaller." if ratio > 1000 else f" — {ratio:.1f}× smaller."


# -- the report --------------------------------------------------------------------------------------------


def write_online_report(store: Any, run_name: str, out: str | Path, *, model: Any) -> dict[str, str]:
    """Write ``index.html`` with the tables and figures of an on-line run, plus CSV/NetCDF exports.

    Parameters
    ----------
    store
        The store (read access is enough).
    run_name
        The run.
    out
        Folder for the report (created).
    model
        The run's model (for the parameter table and, for twin scenarios, the continuous runs).

    Returns
    -------
    dict
        Written files by kind (``report`` is the HTML page).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    run = store.get_run(run_name)
    if run is None:
        raise ValueError(f"no run {run_name!r} in {store.path}")
    files: dict[str, str] = {}
    meta = _meta(run)
    change = _change_time(run)
    cycles = store.cycles(run)
    est = store.estimates(run)
    alerts = store.alerts(run)
    scores = store.scores(run)
    units = {p.name: p.unit for p in model.calibration.parameters}
    files["estimates_csv"] = str(export_estimates_csv(store, run, out / "estimates.csv"))
    files["forecasts_csv"] = str(export_forecasts_csv(store, run, out / "forecasts.csv"))
    dataset = to_xarray(store, run)
    case = getattr(model, "case", None)  # an embedded model knows its stations' places; other models do not
    if case is not None:
        dataset = add_stations(dataset, case)
    files["netcdf"] = str(write_netcdf(dataset, out / "run.nc"))
    cycles.to_csv(out / "cycles.csv", index=False)
    files["cycles_csv"] = str(out / "cycles.csv")

    page = Page(f"rivercal on-line run {run.name} ({run.case})")
    scenario = None
    if meta.get("scenario"):
        from rivercal.twin.practical import SCENARIOS

        scenario = SCENARIOS[meta["scenario"]]
    config = run.config
    intro = [f"{_count(len(cycles), 'cycle')} from {cycles['issue_time'].min():%Y-%m-%d %H:%M} to "
             f"{cycles['issue_time'].max():%Y-%m-%d %H:%M} UTC; every {_span(config['period'])} the parameters "
             f"{', '.join(config['parameters'])} are re-estimated by {config['algorithm']} over the last "
             f"{_span(config['window'])} of observations and the model forecasts {_span(config['horizon'])} ahead, "
             "beside the DSS with its fixed parameters."] if len(cycles) else ["The run has no cycles yet."]
    if scenario is not None:
        intro.append(f"Observations: twin truth of scenario {scenario.name} (thesis §5-2): {scenario.description}; "
                     f"the change happens at {change:%Y-%m-%d %H:%M} UTC; noise {meta.get('noise', 'none')}, realism "
                     f"{(meta.get('realism') or {}).get('name', 'ideal')}.")
    page.intro(*intro)
    page.section("Headline figures", *figure_blocks(store, run))

    if len(cycles):
        truth: dict[str, tuple] = {}
        if scenario is not None:
            truth = {n: (scenario.true_before.get(n), scenario.true_after.get(n)) for n in config["parameters"]}
        dss_values = {p.name: p.initial for p in model.calibration.parameters if p.name in config["parameters"]}
        fig_est = _estimates_figure(est, units, truth, dss_values, change, out / "estimates.png")
        files["estimates_figure"] = str(fig_est)
        wide = est.pivot_table(index=["cycle", "issue_time"], columns="parameter", values="value")
        perturbed = _perturbed(meta)
        page.section("Estimates per cycle",
                     figure(fig_est, "Estimates per cycle with ±σ (thesis Eq. 2-12); dotted: the truth"
                                     + (f" (the scenario's values; the truth behind the observations, with "
                                        f"{' and '.join(perturbed)}, has no single value to draw)"
                                        if perturbed else "")
                                     + ", red: the DSS; dashed: the transition (named under the time axis when it lies "
                                       "outside the period shown)."),
                     table(wide.reset_index().set_index("cycle"), "Estimates per cycle", float_format=".4g"))
        ptable = _parameter_table(model, run, est, change)
        ptable.to_csv(out / "parameters.csv")
        files["parameters_csv"] = str(out / "parameters.csv")
        page.section("Crest levels and friction: true, DSS and rivercal (thesis Tables 5-1 … 5-5)",
                     paragraph("'before': the last cycle whose window ends before the transition; 'after': the "
                               "last cycle, whose window lies after it. Crest levels in m AD, friction in "
                               "m^(1/3)/s. rivercal moves all adjustable crests alike (Wd) and one global friction "
                               "(FA), so a local change can only show as a compromise in those two."
                               + _missing_columns(ptable)),
                     table(ptable, "Parameters", float_format=".4g"))
        shown = cycles[["cycle", "issue_time", "status", "algorithm", "model_runs", "wall_time_s", "cost_before",
                        "cost_after", "message"]].set_index("cycle")
        page.section("Cycles", table(shown, "Cycles: status, model runs, wall time (s), cost before and after "
                                            "(thesis Eq. 2-3)", float_format=".4g"))
        page.section("Alerts", table(alerts.set_index("cycle"), "Alerts (magnitude: |Δθ| / σ)")
                     if len(alerts) else paragraph("No alerts."))
        held = est[~est["accepted"]]
        if len(held):
            page.section("Held estimates", table(held[["cycle", "parameter", "value", "reason"]].set_index("cycle"),
                                                 "Estimates not accepted, and why"))
    errors = forecast_errors(store, run)
    if len(scores):
        fig_scores = _scores_figure(scores, out / "forecast_scores.png")
        files["scores_figure"] = str(fig_scores)
        stations = _station_scores(scores)
        stations.to_csv(out / "forecast_scores.csv")
        files["scores_csv"] = str(out / "forecast_scores.csv")
        words = (f"rivercal against the fixed DSS{' after the change' if errors['from'] else ''}: nothing to "
                 f"compare yet — {errors['reason']}. The figure and table below score every cycle's forecasts.")
        if errors["n"]:
            words = (f"Mean absolute level error of the forecasts at the stations, lead 0–{errors['lead_h']:g} h"
                     + (f", cycles whose window starts after {errors['from'][:16]}" if errors["from"] else "")
                     + f": rivercal {errors['updated_mae_m'] * 100:.2f} cm, "
                     + f"fixed DSS {errors['dss_mae_m'] * 100:.2f} cm"
                     + _ratio_words(errors["ratio"]))
        page.section("Forecasts against the observations",
                     paragraph(words),
                     figure(fig_scores, "RMSE of the level forecasts by lead time, all stations and cycles."),
                     table(stations, "RMSE per station and lead time (levels in cm, discharges in 0.01 m³/s)",
                           float_format=".3g"))
    bands = band_blocks(store, run, out, files)
    if bands:
        page.section("Ensemble forecast and its 90 % band", *bands)
    if scenario is not None and len(cycles) and hasattr(model, "compiled"):  # the maps need every point's level
        _twin_sections(page, model, store, run, cycles, change, out, files, perturbed)
    page.write(out / "index.html")
    files["report"] = str(out / "index.html")
    return files


def _twin_sections(page: Page, model: Any, store: Any, run: Any, cycles: pd.DataFrame, change: pd.Timestamp,
                   out: Path, files: dict[str, str], perturbed: list[str]) -> None:
    """Figs 5-2 … 5-15: the levels at weir ZL1-5930, the error maps, the error over time."""
    from rivercal.report.figures import plot_network_pair, plot_transition_levels
    from rivercal.twin.practical import LOCAL_WEIR

    period = pd.Timedelta(run.config["period"])
    start, end = cycles["issue_time"].min(), min(cycles["issue_time"].max() + period, utc(model.end))
    if not end > start:  # the only cycle is issued at the case's end: no model time follows it
        page.section("Errors over the network (thesis Figs 5-2, 5-3, 5-5 … 5-15)", paragraph(
            f"Not shown: the replayed cycles are issued at the end of the case ({end:%Y-%m-%d %H:%M}), so no model "
            "time follows them in which to compare the levels of the truth, the DSS and rivercal."))
        return
    runs = continuous_runs(model, store, run, start, end)
    errors = {k: runs[k] - runs["truth"] for k in ("dss", "rivercal")}
    fig_time = _error_time_figure(errors, change, out / "error_over_time.png")
    files["error_time_figure"] = str(fig_time)
    compiled = model.compiled
    link = compiled.structure_link[LOCAL_WEIR]
    a = compiled.arrays
    up, down = compiled.hp_label[int(a.lk_k1[link])], compiled.hp_label[int(a.lk_k2[link])]
    names = {up: f"{LOCAL_WEIR} upstream", down: f"{LOCAL_WEIR} downstream"}
    observed = runs["truth"][[up, down]].rename(columns=names)
    fig_weir = plot_transition_levels(observed, runs["dss"][[up, down]].rename(columns=names),
                                      runs["rivercal"][[up, down]].rename(columns=names),
                                      series=list(names.values()), change_time=change,
                                      title=f"Levels at weir {LOCAL_WEIR} (thesis Fig. 5-4)")
    fig_weir.savefig(out / "weir_levels.png", dpi=110)
    files["weir_figure"] = str(out / "weir_levels.png")
    window = pd.Timedelta(run.config["window"])
    periods = {"before the transition": (start, change), "after the transition has left the window":
               (change + window, end)}
    blocks: list[Any] = []
    for label, (a0, a1) in periods.items():
        if not a1 > a0:
            continue
        sel = {k: e.loc[a0:a1 - pd.Timedelta(seconds=1)].mean() for k, e in errors.items()}
        path = out / f"error_map_{'before' if 'before' in label else 'after'}.png"
        fig = plot_network_pair(model.case, sel["dss"], sel["rivercal"], titles=("fixed DSS", "rivercal"),
                                label="Δŷ_avg [m]", suptitle=f"Average level error per calculation point, {label}")
        fig.savefig(path, dpi=110)
        files[f"error_map_{'before' if 'before' in label else 'after'}"] = str(path)
        worst = sel["dss"].abs().sort_values(ascending=False).head(5)
        blocks.append(figure(path, f"Average level error Δŷ_avg (model − truth, m) per calculation point, {label} "
                                   f"({a0:%Y-%m-%d %H:%M} – {a1:%Y-%m-%d %H:%M}); thesis Figs 5-2/5-3."))
        blocks.append(paragraph(
            f"{label.capitalize()}: mean |Δŷ_avg| over all points: DSS {sel['dss'].abs().mean() * 100:.2f} cm, "
            f"rivercal {sel['rivercal'].abs().mean() * 100:.2f} cm. Largest DSS errors at "
            + ", ".join(f"{k} ({v * 100:.1f} cm)" for k, v in worst.items()) + "."))
    station_cols = [c for c in runs["truth_series"].columns if c.rpartition(".")[2] in _LEVELS]
    after = (runs["dss_series"][station_cols] - runs["truth_series"][station_cols]).loc[change + window:]
    if after.empty:
        blocks.append(paragraph(
            f"What the stations see of the change: not yet measurable here. The transition leaves a "
            f"{window / pd.Timedelta('1D'):g}-day calibration window at {change + window:%Y-%m-%d %H:%M}, after "
            f"the replayed period (up to {end:%Y-%m-%d %H:%M})."))
    else:
        seen = after.abs().mean()
        visible = seen[seen > 0.01]
        blocks.append(paragraph(
            "What the stations see of the change (mean |DSS − truth| after the transition left the window): "
            + ", ".join(f"{k} {v * 100:.2f} cm" for k, v in seen.items()) + ". "
            + (f"{len(visible)} of {len(seen)} station series differ by more than 1 cm."
               if len(visible) else "No station series differs by more than 1 cm: the stations cannot see this "
               "change, so no estimator fed by them can follow it; a station at the points with the largest DSS "
               "errors above would.")))
    page.section("Levels at weir ZL1-5930 (thesis Fig. 5-4)",
                 figure(out / "weir_levels.png", f"Levels just up- and downstream of weir {LOCAL_WEIR}: the truth "
                                                 "(grey; no station there), the DSS (red) and rivercal (blue); "
                                                 "dashed: the transition (named under the time axis when it lies "
                                                 "outside the period shown)."))
    page.section("Errors over the network (thesis Figs 5-2, 5-3, 5-5 … 5-15)",
                 figure(fig_time, "Mean absolute level error over all calculation points, hourly."), *blocks,
                 bullets([f"DSS: the case's fixed parameters throughout (run {run.name}).",
                          "rivercal: each cycle's accepted parameters from its issue time until the next cycle.",
                          *_truth_words(perturbed)]))
