"""Tables and figures of twin-experiment suites and of the initial model analysis, beside the thesis' numbers.

Per suite (:func:`write_suite`): ``<suite>.csv`` (every indicator of every scenario, with the Eq. 2-14
bias test), ``<suite>.md`` (the thesis' columns — truth, start, calibrated values, iterations, cost, RMSE,
bias, STD — ours beside the thesis'), ``<suite>_bias.csv`` (the moving-window bias per scenario) and the
thesis' figures: parameter convergence per iteration (Fig. 4-8), cost per iteration (Fig. 4-9),
observed / initial / calibrated series of the first scenario (Fig. 4-10) and the bias over time of the
calibrated runs (Fig. 4-11; the suite's own figure numbers are in
:data:`~rivercal.twin.reference.THESIS_FIGURES`).

The initial model analysis (:func:`write_initial_analysis`, thesis §4-5-1): sensitivity tables and
figures (Table 4-4, Fig. 4-5, C-1 … C-5) and the identifiability tables and figures (Figs. 4-6, 4-7).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal._figure import iteration_axis, subplots
from rivercal.analysis import bias_significance, errors, moving_bias
from rivercal.report.identifiability import verdict_table
from rivercal.twin.reference import THESIS_FIGURES, thesis_row
from rivercal.twin.suites import SUITES, InitialAnalysis, ScenarioResult

__all__ = ["BIAS_WINDOW", "bias_table", "suite_summary", "write_initial_analysis", "write_suite"]

#: Moving window T of the bias of thesis Eq. 2-14 in the suite reports (the thesis' T = 2 h).
BIAS_WINDOW = "2h"

_COLOURS = {"H": "#c53030", "M": "#2f855a", "L": "#2b6cb0"}
_MARKERS = {"1": "o", "2": "x", "11": "o", "12": "x", "21": "s", "22": "*"}
_LINES = {"H": "-", "M": "--", "L": ":"}  # friction letter of two-parameter scenarios



def suite_summary(results: list[ScenarioResult]) -> dict[str, Any]:
    """Performance indicators of a suite (thesis §2-3-3): robustness, efficiency, effectiveness."""
    n = len(results)
    errors = {name: [abs(r.errors[name]) for r in results] for name in results[0].errors} if results else {}
    return {
        "scenarios": n,
        "robustness": sum(r.within_tolerance for r in results) / n if n else float("nan"),
        "succeeded": sum(r.success for r in results),
        "iterations_median": float(np.median([r.iterations for r in results])) if n else float("nan"),
        "iterations_max": max((r.iterations for r in results), default=0),
        "model_runs_total": sum(r.model_runs for r in results),
        "model_runs_median": float(np.median([r.model_runs for r in results])) if n else float("nan"),
        "wall_s_total": float(sum(r.wall_s for r in results)),
        "max_abs_error": {name: float(max(v)) for name, v in errors.items()},
        "cost_median": float(np.median([r.cost for r in results])) if n else float("nan"),
        "state_rmse_max_m": float(max((r.state_rmse for r in results), default=float("nan"))),
    }


def _markdown(suite: str, results: list[ScenarioResult], bias: pd.DataFrame) -> str:
    names = list(results[0].truth)
    head = ["scenario", *[f"{n} true" for n in names], *[f"{n} start" for n in names],
            *[f"{n} ours" for n in names], *[f"{n} thesis" for n in names],
            "iter. ours", "iter. thesis", "cost ours", "cost thesis", "RMSE ours", "RMSE thesis",
            "bias ours", "bias thesis", "STD ours", "STD thesis", "Eq. 2-14 bias / σ²_w", "within tol."]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        ref = thesis_row(suite, r.id) or {}
        cells = [r.id, *[f"{r.truth[n]:g}" for n in names], *[f"{r.start[n]:g}" for n in names],
                 *[f"{r.estimates[n]:.5g}" for n in names],
                 *[f"{ref[f'{n}_estimate']:g}" if f"{n}_estimate" in ref else "–" for n in names],
                 str(r.iterations), str(ref.get("iterations", "–")),
                 f"{r.cost:.2e}", f"{ref['cost']:.2e}" if "cost" in ref else "–",
                 f"{r.rmse:.2e}", f"{ref['rmse']:.2e}" if "rmse" in ref else "–",
                 f"{r.bias:.2e}", f"{ref['bias']:.2e}" if "bias" in ref else "–",
                 f"{r.std_error:.2e}", f"{ref['std_error']:.2e}" if "std_error" in ref else "–",
                 f"{bias.loc[r.id, 'ratio']:.2g}" + (" (sign.)" if bias.loc[r.id, "significant"] else ""),
                 "yes" if r.within_tolerance else "**no**"]
        lines.append("| " + " | ".join(cells) + " |")
    d = SUITES[suite]
    s = suite_summary(results)
    tol = ", ".join(f"|Δ{n}| ≤ {v:g}" for n, v in d.tolerance.items())
    return (f"# {suite}: {d.description}\n\nWindow: {d.window}; observed: "
            f"{', '.join(d.series) if d.series else 'all stations'}; noise: {d.noise}. Tolerance: {tol}.\n\n"
            f"Robustness {s['robustness']:.0%} ({sum(r.within_tolerance for r in results)}/{s['scenarios']}); "
            f"iterations median {s['iterations_median']:g}, max {s['iterations_max']}; model runs "
            f"{s['model_runs_total']} in all; largest parameter errors "
            + ", ".join(f"{n} {v:.2g}" for n, v in s["max_abs_error"].items()) + ".\n\n"
            "Costs, RMSE, bias and STD are of the weighted, dimensionless residuals (ours: 1/σ weights with "
            "σ = 2.5 cm and 0.1 m³/s; the thesis: Eq. 2-6), so they compare in order of magnitude only.\n\n"
            f"Bias test (thesis Eq. 2-14, T = {BIAS_WINDOW}, at {', '.join(sorted(set(bias['series'])))}): the "
            f"bias is significant when its time mean exceeds 0.1 of the mean window variance of the errors; "
            f"significant in {int(bias['significant'].sum())} of {len(bias)} scenarios.\n\n"
            + "\n".join(lines) + "\n")


def _fig(suite: str, kind: str) -> str:
    """``Fig. 4-8`` and the like: the thesis' figure of this kind for the suite."""
    number = THESIS_FIGURES.get(suite, {}).get(kind)
    if number is None:
        return "the thesis' figures"
    return f"Fig{'s' if ',' in number or '/' in number else ''}. {number}"


def _bias_series(suite: str, result: ScenarioResult) -> str:
    """The series whose bias is shown: the suite's (thesis figure) if observed, else the first level series."""
    wanted = SUITES[suite].bias_series if suite in SUITES else ""
    columns = list(result.series["observed"].columns)
    if wanted in columns:
        return wanted
    levels = [c for c in columns if not str(c).endswith(".Q")]
    return str((levels or columns)[0])


def scenario_bias(suite: str, result: ScenarioResult, window: str = BIAS_WINDOW) -> tuple[str, pd.DataFrame]:
    """The moving-window bias (thesis Eq. 2-14) of the calibrated run of one scenario.

    Returns the series id and :func:`~rivercal.analysis.moving_bias` of its weighted errors
    (observed − calibrated, divided by the series' σ: dimensionless).
    """
    sid = _bias_series(suite, result)
    observed = result.series["observed"][[sid]]
    err = errors(observed, result.series["calibrated"], sigma={sid: result.sigma.get(sid)} if sid in result.sigma
                 else None)
    return sid, moving_bias(err[sid], window)


def bias_table(suite: str, results: list[ScenarioResult], window: str = BIAS_WINDOW
               ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The bias test of thesis Eq. 2-14 per scenario, and the moving bias of every scenario.

    Returns
    -------
    (table, moving)
        ``table``: index scenario; columns ``series``, ``bias`` (time mean of b(t)), ``variance`` (time
        mean of σ²_w), ``ratio``, ``significant`` (bias > 0.1 · variance, thesis §2-3-2) and
        ``fraction_significant``; all dimensionless (weighted errors). ``moving``: the moving bias stacked,
        with ``scenario`` and ``series`` columns.
    """
    rows, frames = [], []
    for r in results:
        sid, moving = scenario_bias(suite, r, window)
        test = bias_significance(moving).iloc[0]
        rows.append({"scenario": r.id, "series": sid, **{k: test[k] for k in test.index}})
        frames.append(moving.rename_axis("time").reset_index().assign(scenario=r.id, series=sid))
    table = pd.DataFrame(rows).set_index("scenario")
    moving = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    return table, moving


def _bias_figure(suite: str, results: list[ScenarioResult], moving: pd.DataFrame, path: Path) -> Path:
    """Thesis Fig. 4-11 (4-15, 4-25, 4-29, 4-33): b(t) of every scenario, and the observed series below."""
    sid = str(moving["series"].iloc[0]) if len(moving) else ""
    fig, (ax, ax_h) = subplots(2, 1, figsize=(10, 6.2), sharex=True, height_ratios=[2.2, 1])
    plotted = 0
    for r in results:
        part = moving[moving["scenario"] == r.id]
        b = part["bias"].where(part["bias"] > 0)
        if b.notna().any():
            colour, marker = _style(r)
            ax.plot(part["time"], b, color=colour, marker=marker, markevery=12, lw=0.8, ms=4, alpha=0.8,
                    label=r.id)
            plotted += 1
    if plotted:
        ax.set_yscale("log")
    ax.set_ylabel("bias b(t) (-)")
    ax.grid(alpha=0.3, which="both")
    if len(results) <= 16:
        ax.legend(fontsize=7, ncol=4)
    ax.set_title(f"{suite}: bias of the calibrated runs at {sid} (Eq. 2-14, T = {BIAS_WINDOW}, weighted errors; "
                 f"cf. thesis {_fig(suite, 'bias')})", fontsize=10)
    seen = set()
    for r in results:
        key = tuple(sorted(r.truth.items()))
        if key in seen or sid not in r.series["observed"]:
            continue
        seen.add(key)
        obs = r.series["observed"][sid]
        ax_h.plot(obs.index, obs, lw=0.9, color=_style(r)[0], ls=_LINES.get(r.id[0], "-") if len(r.id) > 2 else "-",
                  label=", ".join(f"{k}={v:g}" for k, v in key))
    ax_h.set_ylabel(f"{sid} (m AD)" if not sid.endswith(".Q") else f"{sid} (m³/s)")
    ax_h.grid(alpha=0.3)
    if len(seen) <= 9:
        ax_h.legend(fontsize=7, ncol=3, title="observed, per truth", title_fontsize=7)
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _style(r: ScenarioResult) -> tuple[str, str]:
    letters = r.id[0::2]
    digits = r.id[1::2]
    colour_letter = letters[-1] if len(letters) > 1 else letters[0]
    return _COLOURS[colour_letter], _MARKERS.get(digits, "o")


def _convergence(suite: str, results: list[ScenarioResult], path: Path) -> Path:
    names = list(results[0].truth)
    fig, axes = subplots(len(names), 1, figsize=(8, 2.6 * len(names) + 0.8), sharex=True, squeeze=False)
    for ax, name in zip(axes[:, 0], names, strict=True):
        for r in results:
            colour, marker = _style(r)
            ax.plot([h["iteration"] for h in r.history], [h[name] for h in r.history], marker=marker, color=colour,
                    lw=0.9, ms=4, alpha=0.8)
        for value in sorted({r.truth[name] for r in results}):
            ax.axhline(value, ls="--", color="0.4", lw=0.8)
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    iteration_axis(axes[-1, 0])
    fig.suptitle(f"{suite}: parameter convergence (true values dashed; cf. thesis {_fig(suite, 'convergence')})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _cost(suite: str, results: list[ScenarioResult], path: Path) -> Path:
    fig, ax = subplots(figsize=(8, 4))
    for r in results:
        colour, marker = _style(r)
        ax.semilogy([h["iteration"] for h in r.history], [max(h["cost"], 1e-25) for h in r.history], marker=marker,
                    color=colour, lw=0.9, ms=4, alpha=0.8, label=r.id)
    iteration_axis(ax)
    ax.set_ylabel("cost (-)")
    ax.grid(alpha=0.3, which="both")
    if len(results) <= 16:
        ax.legend(fontsize=7, ncol=4)
    ax.set_title(f"{suite}: cost per iteration (cf. thesis {_fig(suite, 'cost')})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _states(suite: str, result: ScenarioResult, path: Path) -> Path:
    ids = [c for c in result.series["calibrated"].columns if not c.endswith(".Q")][:4]
    fig, axes = subplots(len(ids), 1, figsize=(10, 2.4 * len(ids) + 0.6), sharex=True, squeeze=False)
    obs = result.series["observed"]
    for ax, sid in zip(axes[:, 0], ids, strict=True):
        ax.plot(obs.index, obs[sid], ".", color="#2b6cb0", ms=3, label="observed")
        ax.plot(result.series["initial"].index, result.series["initial"][sid], color="#c53030", lw=1, label="initial")
        ax.plot(result.series["calibrated"].index, result.series["calibrated"][sid], color="#2f855a", lw=1.2,
                label="calibrated")
        ax.set_ylabel(f"{sid} (m AD)")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    fig.suptitle(f"{suite} {result.id}: observed, initial and calibrated levels (cf. thesis {_fig(suite, 'levels')})")
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def write_suite(suite: str, results: list[ScenarioResult], out: str | Path) -> dict[str, str]:
    """Write the tables and figures of one suite into ``out``; return the files by kind.

    Kinds: ``csv``, ``markdown``, ``bias_csv``, and the figures ``convergence``, ``cost``, ``states``
    (first scenario) and ``bias``.
    """
    if not results:
        raise ValueError(f"suite {suite}: no scenario results to write")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    bias, moving = bias_table(suite, results)
    rows = pd.DataFrame([r.row() for r in results])
    test = bias.rename(columns=lambda c: f"bias_eq214_{c}").reset_index(drop=True)
    pd.concat([rows, test], axis=1).to_csv(out / f"{suite}.csv", index=False)
    files["csv"] = str(out / f"{suite}.csv")
    (out / f"{suite}.md").write_text(_markdown(suite, results, bias), encoding="utf-8")
    files["markdown"] = str(out / f"{suite}.md")
    moving.to_csv(out / f"{suite}_bias.csv", index=False)
    files["bias_csv"] = str(out / f"{suite}_bias.csv")
    files["convergence"] = str(_convergence(suite, results, out / f"{suite}_convergence.png"))
    files["cost"] = str(_cost(suite, results, out / f"{suite}_cost.png"))
    files["states"] = str(_states(suite, results[0], out / f"{suite}_{results[0].id}_levels.png"))
    files["bias"] = str(_bias_figure(suite, results, moving, out / f"{suite}_bias.png"))
    return files


def write_initial_analysis(analysis: InitialAnalysis, out: str | Path, case_name: str = "") -> dict[str, str]:
    """Write the tables and figures of the initial model analysis (thesis §4-5-1) into ``out``.

    Files: ``sensitivity_scenarios.csv`` (Table 4-4), ``sensitivity_costs.csv`` (total and per station),
    ``sensitivity_costs_series.csv``, ``sensitivity_ranking.csv``, ``sensitivity.png`` (Fig. 4-5),
    ``sensitivity_stations.png`` (C-1 … C-5); with the identifiability analysis also
    ``singular_values.csv``, ``singular_vectors.csv``, ``correlation.csv``, ``covariance.csv``,
    ``identifiability.csv`` (verdict), ``svd.png`` (Fig. 4-6) and ``correlation.png`` (Fig. 4-7).
    Returns the files by kind.
    """
    from rivercal.analysis.figures import plot_correlation, plot_sensitivity, plot_sensitivity_stations, plot_svd

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sens = analysis.sensitivity
    name = f"{case_name}: " if case_name else ""
    tables = {"sensitivity_scenarios": sens.table, "sensitivity_costs": sens.costs("station"),
              "sensitivity_costs_series": sens.costs("series"), "sensitivity_ranking": sens.ranking()}
    ident = analysis.identifiability
    if ident is not None:
        tables.update(singular_values=ident.singular_frame(), singular_vectors=ident.vectors_frame(),
                      correlation=ident.correlation_frame(), covariance=ident.covariance_frame(),
                      identifiability=verdict_table(ident))
    files = {}
    for kind, frame in tables.items():
        frame.to_csv(out / f"{kind}.csv")
        files[kind] = str(out / f"{kind}.csv")
    files["sensitivity_figure"] = str(plot_sensitivity(
        sens, out / "sensitivity.png", title=f"{name}total cost per one-at-a-time scenario (cf. thesis Fig. 4-5)"))
    files["sensitivity_stations_figure"] = str(plot_sensitivity_stations(
        sens, out / "sensitivity_stations.png", title=f"{name}cost per station (cf. thesis Figs. C-1 … C-5)"))
    if ident is not None:
        files["svd_figure"] = str(plot_svd(ident, out / "svd.png",
                                           title=f"{name}singular value decomposition (cf. thesis Fig. 4-6)"))
        files["correlation_figure"] = str(plot_correlation(
            ident, out / "correlation.png", title=f"{name}parameter correlation (cf. thesis Fig. 4-7)"))
    return files
