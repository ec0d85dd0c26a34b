"""Tables and figures of twin-experiment suites, beside the reference study's numbers.

Per suite: ``<suite>.csv`` (every indicator of every scenario), ``<suite>.md`` (the thesis' columns —
truth, start, calibrated values, iterations, cost, RMSE, bias, STD — ours beside the thesis'), and the
thesis' figures: parameter convergence per iteration (Fig. 4-8), cost per iteration (Fig. 4-9),
observed / initial / calibrated series of the first scenario (Fig. 4-10).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.twin.reference import thesis_row
from rivercal.twin.suites import SUITES, ScenarioResult

__all__ = ["suite_summary", "write_suite"]

_COLOURS = {"H": "#c53030", "M": "#2f855a", "L": "#2b6cb0"}
_MARKERS = {"1": "o", "2": "x", "11": "o", "12": "x", "21": "s", "22": "*"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


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


def _markdown(suite: str, results: list[ScenarioResult]) -> str:
    names = list(results[0].truth)
    head = ["scenario", *[f"{n} true" for n in names], *[f"{n} start" for n in names],
            *[f"{n} ours" for n in names], *[f"{n} thesis" for n in names],
            "iter. ours", "iter. thesis", "cost ours", "cost thesis", "RMSE ours", "RMSE thesis",
            "bias ours", "bias thesis", "STD ours", "STD thesis", "within tol."]
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
            + "\n".join(lines) + "\n")


def _style(r: ScenarioResult) -> tuple[str, str]:
    letters = r.id[0::2]
    digits = r.id[1::2]
    colour_letter = letters[-1] if len(letters) > 1 else letters[0]
    return _COLOURS[colour_letter], _MARKERS.get(digits, "o")


def _convergence(suite: str, results: list[ScenarioResult], path: Path) -> Path:
    plt = _pyplot()
    names = list(results[0].truth)
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.6 * len(names) + 0.8), sharex=True, squeeze=False)
    for ax, name in zip(axes[:, 0], names, strict=True):
        for r in results:
            colour, marker = _style(r)
            ax.plot([h["iteration"] for h in r.history], [h[name] for h in r.history], marker=marker, color=colour,
                    lw=0.9, ms=4, alpha=0.8)
        for value in sorted({r.truth[name] for r in results}):
            ax.axhline(value, ls="--", color="0.4", lw=0.8)
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("iteration")
    fig.suptitle(f"{suite}: parameter convergence (true values dashed; cf. thesis Fig. 4-8)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _cost(suite: str, results: list[ScenarioResult], path: Path) -> Path:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    for r in results:
        colour, marker = _style(r)
        ax.semilogy([h["iteration"] for h in r.history], [max(h["cost"], 1e-25) for h in r.history], marker=marker,
                    color=colour, lw=0.9, ms=4, alpha=0.8, label=r.id)
    ax.set_xlabel("iteration")
    ax.set_ylabel("cost (-)")
    ax.grid(alpha=0.3, which="both")
    if len(results) <= 16:
        ax.legend(fontsize=7, ncol=4)
    ax.set_title(f"{suite}: cost per iteration (cf. thesis Fig. 4-9)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _states(suite: str, result: ScenarioResult, path: Path) -> Path:
    plt = _pyplot()
    ids = [c for c in result.series["calibrated"].columns if not c.endswith(".Q")][:4]
    fig, axes = plt.subplots(len(ids), 1, figsize=(10, 2.4 * len(ids) + 0.6), sharex=True, squeeze=False)
    obs = result.series["observed"]
    for ax, sid in zip(axes[:, 0], ids, strict=True):
        ax.plot(obs.index, obs[sid], ".", color="#2b6cb0", ms=3, label="observed")
        ax.plot(result.series["initial"].index, result.series["initial"][sid], color="#c53030", lw=1, label="initial")
        ax.plot(result.series["calibrated"].index, result.series["calibrated"][sid], color="#2f855a", lw=1.2,
                label="calibrated")
        ax.set_ylabel(f"{sid} (m AD)")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    fig.suptitle(f"{suite} {result.id}: observed, initial and calibrated levels (cf. thesis Fig. 4-10)")
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_suite(suite: str, results: list[ScenarioResult], out: str | Path) -> dict[str, str]:
    """Write the tables and figures of one suite into ``out``; return the files by kind."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    pd.DataFrame([r.row() for r in results]).to_csv(out / f"{suite}.csv", index=False)
    files["csv"] = str(out / f"{suite}.csv")
    (out / f"{suite}.md").write_text(_markdown(suite, results), encoding="utf-8")
    files["markdown"] = str(out / f"{suite}.md")
    files["convergence"] = str(_convergence(suite, results, out / f"{suite}_convergence.png"))
    files["cost"] = str(_cost(suite, results, out / f"{suite}_cost.png"))
    files["states"] = str(_states(suite, results[0], out / f"{suite}_{results[0].id}_levels.png"))
    return files
