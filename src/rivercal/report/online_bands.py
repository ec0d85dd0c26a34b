"""The forecast of an on-line run with its uncertainty band (state updating: the ensemble's 90 % band).

For a run that stored forecast bands (:meth:`Store.forecast_bands <rivercal.store.Store.forecast_bands>`),
:func:`band_blocks` draws the last cycle's level forecasts at the stations: the updated forecast (the
analysed ensemble's mean) inside its band, the fixed DSS's forecast and the observations before and after
the issue time; and it says which share of all the level observations that fell on a band (lead > 0, not
flagged as outliers) lay inside it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from rivercal._figure import subplots
from rivercal.store import Run, Store

__all__ = ["band_blocks", "band_figure"]

_LEVELS = ("h", "h_up", "h_down")
_RED, _BLUE = "#c53030", "#2b6cb0"
#: Level series drawn at most (the first in name order that have observations).
MAX_PANELS = 4


def _levels(bands: pd.DataFrame) -> pd.DataFrame:
    return bands[bands["series"].str.rpartition(".")[2].isin(_LEVELS)] if len(bands) else bands


def band_figure(store: Store, run: Run, path: Path, *, cycle: int | None = None) -> Path | None:
    """The level forecasts of one cycle (default the last with a band) with their band; None without bands."""
    bands = _levels(store.forecast_bands(run))
    if bands.empty:
        return None
    cycle = int(bands["cycle"].max()) if cycle is None else int(cycle)
    bands = bands[bands["cycle"] == cycle]
    fc = store.forecasts(run, cycle=cycle)
    t0 = bands["issue_time"].iloc[0]
    t1 = bands["time"].max()
    before = t0 - (t1 - t0) / 2
    obs = store.observation_table(sorted(bands["series"].unique()), before, t1, sources=run.config.get("sources"))
    observed = [s for s in sorted(bands["series"].unique()) if (obs["series"] == s).any()]
    series = (observed or sorted(bands["series"].unique()))[:MAX_PANELS]
    central = (run.config.get("assimilation") or {}).get("issued") == "central"
    issued = "central run" if central else "ensemble mean"
    fig, axes = subplots(len(series), 1, figsize=(8.5, 2.3 * len(series) + 0.6), sharex=True, squeeze=False)
    for ax, name in zip(axes[:, 0], series, strict=True):
        b = bands[bands["series"] == name].set_index("time").sort_index()
        probability = float(b["probability"].iloc[0])
        ax.fill_between(b.index, b["low"], b["high"], color=_BLUE, alpha=0.22, linewidth=0,
                        label=f"{probability:.0%} band (ensemble)")
        for kind, colour, style, label in (("updated", _BLUE, "-", f"rivercal ({issued})"),
                                           ("dss", _RED, "--", "fixed DSS")):
            f = fc[(fc["kind"] == kind) & (fc["series"] == name)].set_index("time").sort_index()
            if len(f):
                ax.plot(f.index, f["value"], style, color=colour, linewidth=1.4, label=label)
        o = obs[obs["series"] == name].set_index("time").sort_index()
        if len(o):
            ax.plot(o.index, o["value"], ".", color="black", markersize=3, label="observations")
        ax.axvline(t0, color="grey", linestyle=":", linewidth=1)
        ax.set_ylabel(f"{name} [m AD]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8, ncol=2)
    axes[0, 0].set_title(f"Level forecasts of cycle {cycle}, issued {t0:%Y-%m-%d %H:%M} UTC (dotted)")
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def band_blocks(store: Store, run: Run, out: Path, files: dict[str, str]) -> list[Any]:
    """Report blocks of the band figure and the band's coverage (empty when the run stored no bands)."""
    from rivercal.report.html import figure, paragraph
    from rivercal.report.online_figures import stored_metrics

    path = band_figure(store, run, out / "forecast_band.png")
    if path is None:
        return []
    files["band_figure"] = str(path)
    cover = stored_metrics(store, run).get("band_coverage_90") or {"n": 0}  # as the service measured it
    words = ("The updated forecast is the mean of an ensemble of model states analysed with the observations up "
             "to the issue time; the band holds the observation with the stated probability (the members' spread "
             "plus the observation error).")
    if cover["n"]:
        words += (f" Over all cycles, {cover['fraction']:.0%} of {cover['n']} level observations fell inside the "
                  f"{cover['probability']:.0%} band (a well-calibrated band holds about {cover['probability']:.0%}).")
    return [paragraph(words), figure(path, "The last cycle's level forecasts at the stations with their band, the "
                                           "fixed DSS's forecast and the observations.")]
