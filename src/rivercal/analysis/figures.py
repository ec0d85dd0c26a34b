"""Figures of the analyses (PNG files; matplotlib figures made without pyplot, imported when drawn).

- :func:`plot_sensitivity`: total cost per scenario (thesis Fig. 4-5);
- :func:`plot_sensitivity_stations`: the same per station (thesis Figs. C-1 … C-5);
- :func:`plot_svd`: singular values, right singular vectors and the identifiability index (Fig. 4-6);
- :func:`plot_correlation`: the correlation matrix (Fig. 4-7);
- :func:`plot_bias`: the moving-window bias of Eq. 2-14 over time with its significance threshold (Fig. 4-11).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal._figure import new_figure, save_figure, subplots
from rivercal.analysis.identifiability import COMBINATION, IDENTIFIABLE, NOT_IDENTIFIABLE, Identifiability
from rivercal.analysis.sensitivity import SensitivityResult

__all__ = ["plot_bias", "plot_correlation", "plot_sensitivity", "plot_sensitivity_stations", "plot_svd"]

VERDICT_COLOURS = {IDENTIFIABLE: "#2f855a", COMBINATION: "#dd6b20", NOT_IDENTIFIABLE: "#c53030"}



def _step_colours(n: int) -> list:
    from matplotlib import colormaps

    cmap = colormaps["coolwarm"]
    return [cmap(0.5 if n == 1 else i / (n - 1)) for i in range(n)]


def _grouped_bars(ax: Any, costs: pd.DataFrame, column: str, table: pd.DataFrame, *, legend: bool) -> None:
    """Bars per parameter (groups) and scenario step (colours); log scale when the costs span decades."""
    rows = costs[costs["parameter"] != ""]
    names = list(dict.fromkeys(rows["parameter"]))
    n_steps = int(table.loc[rows.index, "step"].max()) if len(rows) else 1
    colours = _step_colours(n_steps)
    width = 0.8 / n_steps
    for g, name in enumerate(names):
        part = rows[rows["parameter"] == name]
        for scenario, row in part.iterrows():
            step = int(table.loc[scenario, "step"])
            ax.bar(g - 0.4 + (step - 0.5) * width, row[column], width=width, color=colours[step - 1],
                   edgecolor="none", label=f"scenario {step}" if g == 0 else None)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names)
    positive = rows[column][rows[column] > 0]
    if len(positive) and positive.max() > 100 * positive.min():
        ax.set_yscale("log")
        ax.set_ylim(positive.min() / 3, positive.max() * 3)
    ax.grid(axis="y", alpha=0.3, which="both")
    if legend:
        ax.legend(fontsize=7, ncol=n_steps, loc="upper right")


def plot_sensitivity(result: SensitivityResult, path: str | Path, *, title: str = "") -> Path:
    """Total cost (thesis Eq. 2-3) of every one-at-a-time scenario, grouped by parameter (thesis Fig. 4-5)."""
    costs = result.costs("station")
    fig, ax = subplots(figsize=(10, 4.2))
    _grouped_bars(ax, costs, "total", result.table, legend=True)
    ax.set_ylabel("total cost S (-)")
    ax.set_xlabel("perturbed parameter (scenarios 1 … 5 as in thesis Table 4-4: crest −0.30 … +0.30 m, "
                  "k_s +4 … −4, i.e. water levels low → high)")
    ax.set_title(title or "one-at-a-time sensitivity: total cost per scenario")
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def plot_sensitivity_stations(result: SensitivityResult, path: str | Path, *, title: str = "",
                              max_panels: int = 12) -> Path:
    """Cost per station of every scenario, one panel per station (thesis Figs. C-1 … C-5).

    A model with more than ``max_panels`` stations (an imported model has one at every observation point and
    structure) gets the ``max_panels`` stations whose cost the scenarios move most (largest minus smallest
    cost), in the model's order; the title says how many of how many. The costs of all stations are in the
    table the figure is drawn from (``sensitivity_costs.csv`` of ``rivercal analyse``).
    """
    costs = result.costs("station")
    stations = [c for c in costs.columns if c not in ("parameter", "value", "total")]
    if len(stations) > max_panels:
        title = (f"{title or 'one-at-a-time sensitivity per station'}\nthe {max_panels} stations the "
                 f"scenarios move most, of {len(stations)}")
        stations = most_moved_stations(costs, stations, max_panels)
    height = 2.3 * len(stations) + 0.8
    fig, axes = subplots(len(stations), 1, figsize=(10, height), squeeze=False)
    for row, st in enumerate(stations):
        ax = axes[row, 0]
        _grouped_bars(ax, costs, st, result.table, legend=False)
        ax.set_ylabel(f"cost at {st} (-)")
        ax.set_title(f"station {st}", fontsize=9, loc="left")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    # above the first panel, right of its station's name: inside the panel it covered the tallest bars
    axes[0, 0].legend(handles, labels, fontsize=7, ncol=len(labels), loc="lower right", bbox_to_anchor=(1.0, 1.0),
                      frameon=False, borderaxespad=0.2)
    title = title or "one-at-a-time sensitivity per station"
    fig.suptitle(title)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - (0.22 * (title.count("\n") + 1) + 0.05) / height))  # the title
    return save_figure(fig, path, dpi=120)


def most_moved_stations(costs: pd.DataFrame, stations: list[str], k: int) -> list[str]:
    """The ``k`` of ``stations`` whose cost (dimensionless) the scenarios move most, in their given order."""
    spread = (costs[stations].max() - costs[stations].min()).fillna(0.0)
    chosen = set(spread.sort_values(ascending=False, kind="stable").index[:k])
    return [st for st in stations if st in chosen]


def plot_svd(result: Identifiability, path: str | Path, *, title: str = "") -> Path:
    """Singular values, right singular vectors and identifiability index (thesis Fig. 4-6).

    Top: singular values of the scaled Jacobian (log scale; significant ones in colour, the threshold
    dashed). Bottom left: the singular vectors as columns (a parameter's share V_ij, −1 … 1).
    Bottom right: the identifiability index per parameter, coloured by the verdict.
    """
    s = result.singular_values
    names = list(result.names)
    p = len(names)
    fig = new_figure(figsize=(max(8.0, 0.75 * p + 4.5), max(6.5, 0.42 * p + 4.2)))
    grid = fig.add_gridspec(2, 2, height_ratios=[1, 1.6], width_ratios=[max(p, 4), 3.2])
    ax_s = fig.add_subplot(grid[0, 0])
    ax_t = fig.add_subplot(grid[0, 1])
    ax_t.axis("off")
    lines = []
    for verdict, colour in VERDICT_COLOURS.items():
        members = [n for n, v in zip(names, result.verdict["verdict"], strict=True) if v == verdict]
        lines.append((f"{verdict}:", colour))
        lines.append(("  " + (", ".join(members) if members else "—"), "black"))
    for row, (text, colour) in enumerate(lines):
        ax_t.text(0.02, 0.95 - row * 0.14, text, transform=ax_t.transAxes, fontsize=9, color=colour, va="top",
                  weight="bold" if colour != "black" else "normal", wrap=True)
    ax_v = fig.add_subplot(grid[1, 0])
    ax_i = fig.add_subplot(grid[1, 1], sharey=ax_v)
    idx = np.arange(1, p + 1)
    floor = s[s > 0].min() / 3 if np.any(s > 0) else 1e-16
    colours = ["#2b6cb0" if j < result.k else "#a0aec0" for j in range(p)]
    ax_s.bar(idx, np.maximum(s, floor), color=colours)
    ax_s.set_yscale("log")
    if s[0] > 0:
        ax_s.axhline(result.options.sv_threshold * s[0], ls="--", color="#c53030", lw=1,
                     label=f"threshold {result.options.sv_threshold:g} × s₁")
        ax_s.legend(fontsize=8)
    ax_s.set_xticks(idx)
    ax_s.set_xlim(0.5, p + 0.5)
    ax_s.set_ylabel("singular value (-)")
    ax_s.set_title(f"singular values of the scaled Jacobian ({result.k} significant)", fontsize=10)
    ax_s.grid(axis="y", alpha=0.3, which="both")
    image = ax_v.imshow(result.vectors, cmap="RdBu_r", vmin=-1, vmax=1, aspect="auto",
                        extent=(0.5, p + 0.5, p - 0.5, -0.5))
    for i in range(p):
        for j in range(p):
            value = result.vectors[i, j]
            if abs(value) >= 0.1:
                ax_v.text(j + 1, i, f"{value:.2f}", ha="center", va="center", fontsize=7,
                          color="white" if abs(value) > 0.6 else "black")
    ax_v.set_xticks(idx)
    ax_v.set_xticklabels([f"v{j}" for j in idx])
    ax_v.set_yticks(range(p))
    ax_v.set_yticklabels(names)
    ax_v.set_xlabel("right singular vector (strongest → weakest)")
    fig.colorbar(image, ax=ax_v, fraction=0.04, pad=0.02, label="component V_ij")
    verdicts = result.verdict["verdict"].to_numpy()
    ax_i.barh(range(p), result.index, color=[VERDICT_COLOURS[v] for v in verdicts])
    ax_i.set_xlim(0, 1)
    ax_i.axvline(result.options.identifiable, ls="--", color="grey", lw=0.8)
    ax_i.axvline(result.options.unidentifiable, ls=":", color="grey", lw=0.8)
    ax_i.set_xlabel(f"identifiability index (k = {result.k})")
    ax_i.tick_params(labelleft=False)
    from matplotlib.patches import Rectangle

    handles = [Rectangle((0, 0), 1, 1, color=c) for c in VERDICT_COLOURS.values()]
    ax_i.legend(handles, list(VERDICT_COLOURS), fontsize=7, loc="lower right")
    ax_i.grid(axis="x", alpha=0.3)
    fig.suptitle(title or "singular value decomposition of the Jacobian")
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def plot_correlation(result: Identifiability, path: str | Path, *, title: str = "") -> Path:
    """The correlation matrix of the parameters (thesis Eq. 2-13, Fig. 4-7); grey where undefined."""
    corr = np.asarray(result.correlation, dtype=float)
    names = list(result.names)
    p = len(names)
    fig, ax = subplots(figsize=(0.62 * p + 2.8, 0.55 * p + 1.8))
    from matplotlib import colormaps

    cmap = colormaps["RdBu_r"].with_extremes(bad="#d9d9d9")
    image = ax.imshow(np.ma.masked_invalid(corr), cmap=cmap, vmin=-1, vmax=1)
    for i in range(p):
        for j in range(p):
            value = corr[i, j]
            text = "–" if not np.isfinite(value) else f"{value:.2f}"
            ax.text(j, i, text, ha="center", va="center", fontsize=7,
                    color="white" if np.isfinite(value) and abs(value) > 0.6 else "black")
    ax.set_xticks(range(p))
    ax.set_xticklabels(names, rotation=45, ha="right")
    ax.set_yticks(range(p))
    ax.set_yticklabels(names)
    fig.colorbar(image, ax=ax, fraction=0.046, pad=0.03, label="correlation (-)")
    ax.set_title(title or "parameter correlation (JᵀJ)⁻¹", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def plot_bias(moving: pd.DataFrame, path: str | Path, *, title: str = "", unit: str = "-") -> Path:
    """The moving-window bias b(t) of thesis Eq. 2-14 per series, with its threshold 0.1 σ²_w (Fig. 4-11).

    Parameters
    ----------
    moving
        :func:`~rivercal.analysis.residuals.moving_bias` of one series or stacked for several.
    path
        PNG file to write.
    title
        Figure title.
    unit
        Unit of the squared errors for the axis label (``-`` for weighted errors, ``m²`` for levels).
    """
    if "series" not in moving.columns:
        moving = moving.rename_axis("time").reset_index().assign(series="series")
    series = list(dict.fromkeys(moving["series"]))
    stations = list(dict.fromkeys(s.rpartition(".")[0] or s for s in series))
    fig, axes = subplots(len(stations), 1, figsize=(12, 2.0 * len(stations) + 0.9), sharex=True, squeeze=False)
    for row, st in enumerate(stations):
        ax = axes[row, 0]
        for k, sid in enumerate(s for s in series if (s.rpartition(".")[0] or s) == st):
            part = moving[moving["series"] == sid]
            colour = f"C{k}"
            ax.plot(part["time"], part["bias"], color=colour, lw=1.2, label=f"{sid} bias")
            ax.plot(part["time"], part["threshold"], color=colour, lw=0.8, ls=":", label=f"{sid} 0.1 σ²")
            sig = part[part["significant"].astype(bool)]
            if len(sig):
                ax.plot(sig["time"], sig["bias"], "o", color=colour, ms=2.5)
        here = moving["series"].map(lambda sid, st=st: (sid.rpartition(".")[0] or sid) == st)
        values = moving.loc[here, ["bias", "threshold"]].to_numpy(dtype=float)
        positive = values[np.isfinite(values) & (values > 0)]
        if positive.size and positive.max() > 100 * positive.min():  # bias and threshold differ by decades
            ax.set_yscale("log")
            ax.set_ylim(max(positive.min(), positive.max() * 1e-8) / 2, positive.max() * 2)
        ax.set_ylabel(f"bias ({unit})")
        ax.set_title(f"station {st}", fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0))
    axes[-1, 0].set_xlabel("time (UTC)")
    fig.suptitle(title or "moving-window bias (Eq. 2-14); dots: significant (bias > 0.1 σ²)")
    fig.autofmt_xdate()
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)
