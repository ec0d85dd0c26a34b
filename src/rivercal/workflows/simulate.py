"""One run of a model: the station series as CSV and CF-1.8 NetCDF, optionally a hydrograph figure."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rivercal.io.cf import add_stations, write_netcdf
from rivercal.models.capabilities import FromCase
from rivercal.models.contract import Model
from rivercal.workflows.progress import NO_PROGRESS, Progress

__all__ = ["simulate_case"]


def simulate_case(model: Model, quantities: Mapping[str, float], out: str | Path, *, start: Any = None, end: Any = None,
                  plot: bool = False, progress: Progress = NO_PROGRESS) -> dict[str, Any]:
    """Run ``model`` with ``quantities`` from ``start`` to ``end`` (default: the case period) and write the series.

    Parameters
    ----------
    model
        A loaded model (:func:`rivercal.model.load_model`).
    quantities
        Model quantities (targets → values: crest levels in m AD, friction in its unit).
    out
        Folder for ``series.csv``, ``series.nc`` and, with ``plot``, ``series.png`` (created).
    start, end
        UTC times inside the case period.
    plot
        Also draw the hydrographs.
    progress
        Where to say what happens.

    Returns
    -------
    dict
        ``case``, ``start``, ``end`` (ISO), ``parameters``, ``wall_s`` (s), the relative volume balance
        error (None for a model that keeps no balance for rivercal), ``files`` and the ``final`` value
        of every series (m, m³/s).
    """
    out = Path(out)
    progress.stage(f"simulating {model.name}")
    result, _ = model.simulate(dict(quantities), start=start, end=end)
    out.mkdir(parents=True, exist_ok=True)
    result.to_csv(out / "series.csv")
    dataset = result.to_dataset()
    if isinstance(model, FromCase):  # stations, CRS and datum of the case
        dataset = add_stations(dataset, model.source_case())
    write_netcdf(dataset, out / "series.nc")
    files = {"csv": str(out / "series.csv"), "netcdf": str(out / "series.nc")}
    if plot:
        from rivercal.report.figures import plot_series

        progress.stage("drawing the hydrographs")
        files["figure"] = str(plot_series(result.series, out / "series.png",
                                          title=f"{model.name}: simulated series"))
    return {
        "case": model.name,
        "start": result.series.index[0].isoformat(),
        "end": result.series.index[-1].isoformat(),
        "parameters": dict(quantities),
        "wall_s": round(result.wall_time, 4),
        # an external model reports its own balance (SWMM: its .rpt file), or none
        "volume_balance_relative_error": result.balance.relative_error if result.balance is not None else None,
        # withdrawals that ran short of water: volume asked and delivered, m³ (empty when all were delivered)
        "shortfalls": {key: {"requested_m3": round(s.requested, 3), "delivered_m3": round(s.delivered, 3)}
                       for key, s in getattr(result, "shortfalls", {}).items()},
        "run": dict(getattr(model, "last_run_stats", {}) or {}),
        "files": files,
        "final": {k: round(float(v), 4) for k, v in result.series.iloc[-1].items()},
    }
