"""The report of an on-line run, rendered from its store (thesis chapter 5: Tables 5-1 … 5-5, Figs 5-2 … 5-15).

Everything comes from the store, and the report runs no model: cycles, estimates, alerts, forecasts, their
scores and the run metrics the service stored with its cycles (:mod:`rivercal.online.metrics`). For a run on
twin observations of a practical scenario (the run's stored ``meta.scenario``), the levels at every point of
the truth, the DSS and rivercal that the run stored (:mod:`rivercal.twin.fields`) show what the stations
cannot: the levels at the weir of Fig. 5-4 and the average level error at every calculation point
(Figs 5-2/5-3).

Errors are model − truth (m); Δŷ_avg of a point is the mean error over a period, as in the thesis
(positive: the model is too high).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal._figure import subplots
from rivercal._time import utc
from rivercal.io.cf import add_stations, write_netcdf
from rivercal.models.capabilities import FromCase
from rivercal.models.contract import Model
from rivercal.online.service import OPTIMISER_NOTE
from rivercal.report.figures import mark_change
from rivercal.report.html import Page, bullets, figure, paragraph, table
from rivercal.report.online_bands import band_blocks
from rivercal.report.online_figures import figure_blocks, forecast_words, stored_metrics
from rivercal.store import Run, Store
from rivercal.store.export import export_estimates_csv, export_forecasts_csv, to_xarray

__all__ = ["write_online_report"]

log = logging.getLogger(__name__)

_LEVELS = ("h", "h_up", "h_down")
_RED, _BLUE, _GREY = "#c53030", "#2b6cb0", "#718096"




def _meta(run: Run) -> dict[str, Any]:
    return dict(run.config.get("meta") or {})


def _perturbed(meta: dict[str, Any]) -> list[str]:
    """What made the truth behind a twin's observations differ from the model (empty: nothing did)."""
    from rivercal.twin.realism import Realism

    realism = Realism.model_validate(meta["realism"]) if meta.get("realism") else None
    out = [f"realism {realism.name}"] if realism is not None and realism.changes_truth else []
    return out + ([f"a rain error of about {float(meta['rain_error']):.0%}"] if meta.get("rain_error") else [])


def _observation_words(meta: dict[str, Any]) -> str:
    """What the twin's observations carry, as the run's ``meta`` says (one sentence, no unused setting named)."""
    realism = (meta.get("realism") or {}).get("name", "ideal")
    parts = []
    if realism != "ideal":
        parts.append(f"realism {realism}: the truth differs from the model and the observations carry sensor "
                     "errors (docs/realism.md)")
    if meta.get("noise") not in (None, "none"):
        parts.append(f"{meta['noise']} noise on the observations")
    if meta.get("rain_error"):
        parts.append(f"a rain error of about {float(meta['rain_error']):.0%} on the truth's inflows and laterals")
    return ("; ".join(parts) if parts else "an identical twin: the truth is the model and the observations are "
            "exact") + "."


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


def _change_time(run: Run) -> pd.Timestamp | None:
    scenario = _meta(run).get("scenario")
    if not scenario:
        return None
    from rivercal.twin.practical import SCENARIOS

    return utc(SCENARIOS[scenario].change_time)


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


def _parameter_table(model: Model, run: Run, est: pd.DataFrame, change: pd.Timestamp | None) -> pd.DataFrame:
    """Thesis Tables 5-1 … 5-5: crest per adjustable weir and friction — true, DSS and rivercal.

    Rows: every single-target parameter of the case that the DSS or the truth sets, every single-target
    parameter the run estimates (a factor the DSS keeps at the model's own value shows no DSS number), plus
    the quantities the scenario changes (e.g. the friction of one section). A branch friction that rivercal
    does not estimate takes its global friction.
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
    for p in params:  # every estimated parameter has its row, also a factor the DSS has no number for
        if len(p.targets) == 1 and p.name not in rows_for.values():
            rows_for.setdefault(p.targets[0], p.name)
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
    columns = ["parameter", "target", "unit", "DSS", *(["true before"] if scenario is not None else []),
               "rivercal before", *(["true after"] if scenario is not None else []), "rivercal after"]
    return pd.DataFrame(rows, columns=columns).set_index("parameter")


def _station_scores(scores: pd.DataFrame) -> pd.DataFrame:
    s = scores.copy()
    s["station"] = s["series"].str.rpartition(".")[0]
    s["lead"] = s["lead_from_h"].map("{:g}".format) + "–" + s["lead_to_h"].map("{:g}".format) + " h"
    order = s.drop_duplicates("lead").sort_values("lead_from_h")["lead"].tolist()
    s["lead"] = pd.Categorical(s["lead"], categories=order, ordered=True)
    out = s.groupby(["station", "lead", "kind"], observed=True)["rmse"].mean().unstack("kind") * 100
    out = out.rename(columns={"dss": "DSS RMSE [cm or 0.01 m³/s]", "updated": "rivercal RMSE [cm or 0.01 m³/s]"})
    return out


def _parameter_words(change: pd.Timestamp | None, estimated: list[str], ptable: pd.DataFrame) -> str:
    """What the table of crest levels and friction shows, for this run: its columns, units and what was estimated."""
    if change is not None:
        sides = ("'before': the last cycle whose window ends before the transition; 'after': the last cycle, whose "
                 "window lies after it." + _missing_columns(ptable))
    else:
        sides = ("No transition was found, so 'rivercal after' is each parameter's value accepted by the last cycle "
                 "('rivercal before' is empty).")
    return (f"{sides} Each row in its own unit (the unit column). rivercal estimates {', '.join(estimated)}; the "
            "other rows keep the DSS's value (a branch's friction the global one), so a local change can only show "
            "as a compromise in what is estimated. The rivercal columns are accepted values; whether the forecast a "
            "cycle issued used them or the DSS's says the table of the headline (do no harm).")


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


# -- the report --------------------------------------------------------------------------------------------


def write_online_report(store: Store, run_name: str, out: str | Path, *, model: Model) -> dict[str, str]:
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
        The run's model: its calibration setup names the parameters and the DSS's values; a model built from a
        case (:class:`~rivercal.models.capabilities.FromCase`) places the stations and draws the maps. It is not run.

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
    case = model.source_case() if isinstance(model, FromCase) else None  # the stations' places, the maps
    if case is not None:
        dataset = add_stations(dataset, case)
    files["netcdf"] = str(write_netcdf(dataset, out / "run.nc"))
    cycles.to_csv(out / "cycles.csv", index=False)
    files["cycles_csv"] = str(out / "cycles.csv")
    coverage = _data_coverage(store, run, cycles, alerts, model)
    if len(coverage):
        coverage.to_csv(out / "data_coverage.csv", index=False)
        files["data_coverage_csv"] = str(out / "data_coverage.csv")

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
                     f"the change happens at {change:%Y-%m-%d %H:%M} UTC; {_observation_words(meta)}")
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
                     figure(fig_est, "Estimates per cycle with ±σ (thesis Eq. 2-12); dotted: the truth, the scenario's "
                                     "values before and after the change"
                                     + (f" — the truth behind the observations, with {' and '.join(perturbed)}, is "
                                        "not the model, so a global estimate settles near these values, not on "
                                        "them, and what counts is its change" if perturbed else "")
                                     + "; red: the DSS; dashed: the transition (named under the time axis when it lies "
                                       "outside the period shown)."),
                     table(wide.reset_index().set_index("cycle"), "Estimates per cycle", float_format=".4g"))
        ptable = _parameter_table(model, run, est, change)
        ptable.to_csv(out / "parameters.csv")
        files["parameters_csv"] = str(out / "parameters.csv")
        from rivercal.twin.practical import SCENARIOS

        twin = (_meta(run).get("scenario") or "") in SCENARIOS
        page.section("Crest levels and friction: true, DSS and rivercal (thesis Tables 5-1 … 5-5)" if twin else
                     "The model's parameters: DSS and rivercal",
                     paragraph(_parameter_words(change, list(config["parameters"]), ptable)),
                     table(ptable, "Parameters", float_format=".4g"))
        shown = cycles[["cycle", "issue_time", "status", "algorithm", "model_runs", "wall_time_s", "cost_before",
                        "cost_after", "message"]].set_index("cycle")
        # the optimiser's own stopping rule stays in cycles.csv and the store, not in the page's table
        shown = shown.assign(message=shown["message"].fillna("").str.replace(OPTIMISER_NOTE, "", regex=True))
        page.section("Cycles", table(shown, "Cycles: status, model runs, wall time (s), cost before and after "
                                            "(thesis Eq. 2-3)", float_format=".4g"))
        page.section("Alerts", table(alerts.set_index("cycle"), "Alerts (magnitude: |Δθ| / σ)"
                                     + ("; data_coverage.csv lists, for each cycle with a data alert, the share of "
                                        "the window each series covers" if "data_coverage_csv" in files else ""))
                     if len(alerts) else paragraph("No alerts."))
        held = est[~est["accepted"]]
        if len(held):
            page.section("Held estimates", table(held[["cycle", "parameter", "value", "reason"]].set_index("cycle"),
                                                 "Estimates not accepted, and why"))
    if len(scores):
        fig_scores = _scores_figure(scores, out / "forecast_scores.png")
        files["scores_figure"] = str(fig_scores)
        stations = _station_scores(scores)
        stations.to_csv(out / "forecast_scores.csv")
        files["scores_csv"] = str(out / "forecast_scores.csv")
        words = (forecast_words(stored_metrics(store, run)) + " (The headline's figure.) The figure and the table "
                 "below score instead the updated forecasts of every cycle, by lead time, as RMSE.")
        page.section("Forecasts against the observations",
                     paragraph(words),
                     figure(fig_scores, "RMSE of the level forecasts by lead time, all stations and cycles: "
                                        "rivercal's updated forecasts (issued or not) and the DSS's."),
                     table(stations, "RMSE per station and lead time (levels in cm, discharges in 0.01 m³/s)",
                           float_format=".3g"))
    bands = band_blocks(store, run, out, files)
    if bands:
        page.section("Ensemble forecast and its 90 % band", *bands)
    if scenario is not None and len(cycles):
        _twin_sections(page, case, store, run, change, out, files, perturbed)
    page.write(out / "index.html")
    files["report"] = str(out / "index.html")
    return files


def _twin_sections(page: Page, case: Any, store: Store, run: Run, change: pd.Timestamp, out: Path,
                   files: dict[str, str], perturbed: list[str]) -> None:
    """Figs 5-2 … 5-15 from the stored twin fields: the levels at weir ZL1-5930, the error maps, the error over time."""
    from rivercal.report.figures import plot_network_pair, plot_transition_levels
    from rivercal.twin.fields import load_twin_fields
    from rivercal.twin.practical import LOCAL_WEIR

    fields = load_twin_fields(store, run)
    if fields is None or fields.levels["truth"].empty:
        page.section("Errors over the network (thesis Figs 5-2, 5-3, 5-5 … 5-15)", paragraph(
            "Not shown: the run stored no levels at every point of the truth, the DSS and rivercal (the service "
            "stores them after a twin run on a model that gives them, e.g. the embedded engine; not when the replayed "
            "cycles end at the end of the model's period, where no model time follows them)."))
        return
    runs = {**fields.levels, **{f"{k}_series": v for k, v in fields.series.items()}}
    start, end = runs["truth"].index[0], runs["truth"].index[-1] + pd.Timedelta("1h")
    errors = {k: runs[k] - runs["truth"] for k in ("dss", "rivercal")}
    fig_time = _error_time_figure(errors, change, out / "error_over_time.png")
    files["error_time_figure"] = str(fig_time)
    if fields.weir_points is not None:
        up, down = fields.weir_points
        names = {up: f"{LOCAL_WEIR} upstream", down: f"{LOCAL_WEIR} downstream"}
        observed = runs["truth"][[up, down]].rename(columns=names)
        fig_weir = plot_transition_levels(observed, runs["dss"][[up, down]].rename(columns=names),
                                          runs["rivercal"][[up, down]].rename(columns=names),
                                          series=list(names.values()), change_time=change, observed_label="truth",
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
        worst = sel["dss"][sel["dss"].abs() >= 0.0005].abs().sort_values(ascending=False).head(5)
        if case is not None:
            path = out / f"error_map_{'before' if 'before' in label else 'after'}.png"
            fig = plot_network_pair(case, sel["dss"], sel["rivercal"], titles=("fixed DSS", "rivercal"),
                                    label="Δŷ_avg [m]", suptitle=f"Average level error per calculation point, {label}")
            fig.savefig(path, dpi=110)
            files[f"error_map_{'before' if 'before' in label else 'after'}"] = str(path)
            blocks.append(figure(path, f"Average level error Δŷ_avg (model − truth, m) per calculation point, "
                                       f"{label} ({a0:%Y-%m-%d %H:%M} – {a1:%Y-%m-%d %H:%M}); thesis Figs 5-2/5-3."))
        blocks.append(paragraph(_map_words(label, sel, worst, before="before" in label, perturbed=perturbed)))
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
    if "weir_figure" in files:
        page.section("Levels at weir ZL1-5930 (thesis Fig. 5-4)",
                     figure(out / "weir_levels.png", f"Levels just up- and downstream of weir {LOCAL_WEIR}: the "
                                                     "truth (grey; no station there), the DSS (red) and rivercal "
                                                     "(blue); dashed: the transition (named under the time axis when "
                                                     "it lies outside the period shown)."))
    page.section("Errors over the network (thesis Figs 5-2, 5-3, 5-5 … 5-15)",
                 figure(fig_time, "Mean absolute level error over all calculation points, hourly."), *blocks,
                 bullets([f"DSS: the case's fixed parameters throughout (run {run.name}).",
                          "rivercal: each cycle's accepted parameters from its issue time until the next cycle.",
                          *_truth_words(perturbed)]))


def _map_words(label: str, sel: dict[str, pd.Series], worst: pd.Series, *, before: bool, perturbed: list[str]) -> str:
    """The error maps of one period in words: both means, the DSS's largest errors, and why the DSS's is zero.

    Before the change the DSS's parameters are the scenario's, which is what the maps' truth runs: its error
    is zero by construction, and rivercal's is the distance of its estimates from the scenario's values.
    """
    dss, riv = sel["dss"].abs().mean() * 100, sel["rivercal"].abs().mean() * 100
    text = f"{label.capitalize()}: mean |Δŷ_avg| over all points: DSS {dss:.2f} cm, rivercal {riv:.2f} cm."
    if len(worst):
        text += " Largest DSS errors at " + ", ".join(f"{k} ({v * 100:.1f} cm)" for k, v in worst.items()) + "."
    if before and dss < 0.05:
        text += (" The DSS's error is zero by construction: before the change its parameters are the scenario's, "
                 "which the maps' truth runs. rivercal's is the distance of its estimates from those values"
                 + (f" — estimates fitted to observations of a truth with {' and '.join(perturbed)}, which is not "
                    "the model, so they settle on effective values; how well rivercal forecasts shows in the "
                    "forecast scores above, against the observations" if perturbed else "") + ".")
    return text


def _data_coverage(store: Store, run: Run, cycles: pd.DataFrame, alerts: pd.DataFrame, model: Model) -> pd.DataFrame:
    """Per cycle with a ``data`` alert and per series: the share of the window's values stored and not flagged.

    The full list behind a data alert, which names only the worst few series when many are thin; the rule
    is the service's (:func:`rivercal.online.guardrails.data_alerts`): values at the output interval over
    the window, both ends included.
    """
    from rivercal.observations import measurable

    columns = ["cycle", "series", "values", "expected", "coverage"]
    if alerts.empty or not (alerts["kind"] == "data").any() or cycles.empty:
        return pd.DataFrame(columns=columns)
    config = run.config
    series = list(config.get("series") or measurable(model.observables))
    interval = float(config.get("output_interval_s") or 3600.0)
    expected = int(pd.Timedelta(config["window"]) / pd.Timedelta(seconds=interval)) + 1
    rows = []
    windows = cycles.set_index("cycle")
    for cycle in sorted(set(alerts.loc[alerts["kind"] == "data", "cycle"])):
        if cycle not in windows.index:
            continue
        w = windows.loc[cycle]
        counts = store.flag_counts(series, w["window_start"], w["window_end"])
        ok = counts[counts["flag"] == "ok"].groupby("series")["n"].sum() if len(counts) else pd.Series(dtype=int)
        for s in series:
            n = int(ok.get(s, 0))
            rows.append((int(cycle), s, n, expected, round(n / expected, 4)))
    return pd.DataFrame(rows, columns=columns).sort_values(["cycle", "coverage", "series"])
