"""Imported SOBEK 3 models against the SOBEK 3 kernel's own results.

The shared SOBEK 3 models (``../shared/data/sobek3-waal`` and ``sobek3-compound``, LGPL-3.0, read from outside the
repository) come with what the SOBEK 3 kernel (cf_dll) computed: the water level at every grid point every hour
(``output/gridpoints.nc``) and, for the Waal, the level and discharge at its observation points
(``output/observations.nc``).

:func:`compare_sobek3` imports a model strictly (no refusal that changes the hydraulics may remain), runs it as
imported — its own time step and period, cold-started from its own initial levels — or at another time step, and
scores the root-mean-square difference of the level series at every grid point (the case's calculation points are
SOBEK 3's grid points), over the whole run and after a spin-up, and the relative root-mean-square difference of
the discharge at every observation point: RMSE(Q - Q_SOBEK) / mean |Q_SOBEK| over the same hours.
"""

from __future__ import annotations

import os
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case import case_from_dict
from rivercal.engine import Simulator
from rivercal.errors import ModelRunError
from rivercal.io.sobek3 import import_sobek3, read_results

__all__ = ["MODELS", "Sobek3Comparison", "compare_sobek3", "sobek3_model"]

ENV_VAR = "RIVERCAL_SHARED_DATA"
#: The shared SOBEK 3 models: folder under the shared data → the md1d inside it.
MODELS = {
    "sobek3-waal": "waal.dsproj_data/Flow1D_output/dflow1d/Flow1D.md1d",
    "sobek3-compound": "test_compound.dsproj_data/Flow1D_output/dflow1d/Flow1D.md1d",
}


def sobek3_model(name: str) -> Path:
    """The md1d of a shared SOBEK 3 model: under ``$RIVERCAL_SHARED_DATA`` or ``<repository>/../shared/data``.

    Raises
    ------
    FileNotFoundError
        When the model is missing (the message names the path and the variable).
    """
    if name not in MODELS:
        raise KeyError(f"unknown SOBEK 3 model {name!r}; known: {', '.join(MODELS)}")
    env = os.environ.get(ENV_VAR)
    root = Path(env).expanduser() if env else (Path(__file__).resolve().parents[3] / ".." / "shared" /
                                                "data").resolve()
    path = root / name / MODELS[name]
    if not path.is_file():
        raise FileNotFoundError(f"the SOBEK 3 model {name} was not found at {path}; set {ENV_VAR} to the shared "
                                "data folder (LGPL-3.0 data, not shipped with rivercal)")
    return path


def solves_per_step(stats: dict) -> float | None:
    """Level solves per time step of a run (its engine counts): 1 where no step was divided; None without a step.

    How far the engine's step control divided the model's own step: 256 means sub-steps of 1/256 of it.
    """
    steps = int(stats.get("steps", 0) or 0)
    return round(float(stats.get("solves", 0)) / steps, 2) if steps else None


def _stats(values: pd.Series) -> dict:
    return {"median": round(float(values.median()), 4), "p90": round(float(values.quantile(0.9)), 4),
            "max": round(float(values.max()), 4)}


@dataclass
class Sobek3Comparison:
    """Result of :func:`compare_sobek3`.

    Attributes
    ----------
    model
        The model's name (its shared folder, or the md1d path).
    summary
        The import's summary (:attr:`rivercal.io.sobek3.ImportResult.summary`).
    dt_s, imported_dt_s
        The time step run and the model's own, s.
    error
        The engine's message when the run failed, else None.
    level_rmse, level_rmse_after
        Per grid point: RMSE of the level (m) over the whole run and after the spin-up.
    discharge_relative_rmse
        Per observation point with discharges: RMSE(Q - Q_SOBEK) / mean |Q_SOBEK| after the spin-up (-).
    spinup_h
        The spin-up left out of the ``after`` figures, h.
    wall_s
        Wall time of the simulation, s.
    levels
        rivercal's and SOBEK 3's levels at the grid points (columns ``<grid point>`` and ``<grid point>.sobek3``).
    run_stats
        The engine's counts of the run (steps, solves, divided steps …, :attr:`Simulator.last_run_stats`).
    """

    model: str
    summary: dict
    dt_s: float
    imported_dt_s: float
    error: str | None
    level_rmse: pd.Series
    level_rmse_after: pd.Series
    discharge_relative_rmse: pd.Series
    spinup_h: float
    wall_s: float
    levels: pd.DataFrame = field(repr=False)
    run_stats: dict = field(default_factory=dict)

    @property
    def runs_as_imported(self) -> bool:
        """Whether the run was at the model's own time step and completed."""
        return self.error is None and self.dt_s == self.imported_dt_s

    def row(self) -> dict:
        """One JSON-able line (the ``rivercal bench models`` table's columns)."""
        out = {
            "model": self.model, "format": "sobek3", "objects": self.summary["objects"],
            "exact": self.summary["exact"], "approximated": self.summary["approximated"],
            "refused": self.summary["refused"], "runs_as_imported": self.runs_as_imported, "dt_s": self.dt_s,
            "imported_dt_s": self.imported_dt_s, "points_compared": int(self.level_rmse.size),
            "level_rmse_m": _stats(self.level_rmse) if self.level_rmse.size else None,
            "after_spinup": {
                "spinup_h": self.spinup_h,
                "level_rmse_m": _stats(self.level_rmse_after) if self.level_rmse_after.size else None,
                "discharge_stations": int(self.discharge_relative_rmse.size),
                "discharge_relative_rmse": (_stats(self.discharge_relative_rmse)
                                            if self.discharge_relative_rmse.size else None),
            },
            "wall_s": round(self.wall_s, 3),
            "solves_per_step": solves_per_step(self.run_stats),
        }
        if self.error is not None:
            out["error"] = self.error
        return out


def compare_sobek3(model: str | Path, out: Path | None = None, *, dt: float | None = None,
                   spinup_h: float = 24.0) -> Sobek3Comparison:
    """Import a SOBEK 3 model, run it, and compare with SOBEK 3's own levels and discharges.

    Parameters
    ----------
    model
        A shared model's name (:data:`MODELS`) or the path of an md1d whose ``output`` folder holds SOBEK 3's
        results.
    out
        Folder for the imported case (default: a temporary folder, kept).
    dt
        Time step of the run, s (default: the model's own).
    spinup_h
        Hours after the start left out of the ``after`` figures.

    Raises
    ------
    CaseError
        When the model does not import strictly.
    """
    md1d = sobek3_model(model) if isinstance(model, str) and model in MODELS else Path(model)
    name = model if isinstance(model, str) and model in MODELS else str(md1d)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="sobek3-"))
    result = import_sobek3(md1d, out)
    case = result.case  # loaded once by the import (the Waal's case.toml takes 1.7 s of processor time to parse)
    imported_dt = float(case.spec.engine.dt)
    run_dt = float(dt) if dt is not None else imported_dt
    if run_dt != imported_dt:
        data = tomllib.loads((out / "case.toml").read_text(encoding="utf-8"))
        data["engine"]["dt"] = run_dt
        data["engine"]["output_interval"] = max(float(data["engine"]["output_interval"]), run_dt)
        case = case_from_dict(data, out)
    sim = Simulator(case)
    sobek = read_results(md1d.parent / "output", [b.id for b in case.network.branches])
    error = None
    t0 = time.perf_counter()
    try:
        run, _ = sim.simulate(snapshots=True)
    except ModelRunError as exc:
        error = str(exc)
        run = None
    wall = time.perf_counter() - t0
    empty = pd.Series(dtype=float)
    if run is None:
        return Sobek3Comparison(name, result.summary, run_dt, imported_dt, error, empty, empty, empty, spinup_h, wall,
                                pd.DataFrame(), dict(sim.last_run_stats))
    columns = _grid_columns(sim, case, sobek.points)
    ours = run.levels.iloc[:, columns]
    ours.columns = sobek.levels.columns
    common = ours.index.intersection(sobek.levels.index)
    diff = ours.loc[common] - sobek.levels.loc[common]
    after = diff[diff.index >= diff.index[0] + pd.Timedelta(hours=spinup_h)]
    level_rmse = np.sqrt((diff**2).mean())
    level_after = np.sqrt((after**2).mean())
    discharge = empty
    if sobek.observation_discharges is not None:
        stations = {s.id: s for s in case.network.stations if "Q" in s.quantities and s.structure is None}
        rel = {}
        for name_q in sobek.observation_discharges.columns:
            sid = name_q.replace(".", "_")
            if sid not in stations:
                continue
            q_ours = run.series[f"{sid}.Q"]
            q_sob = sobek.observation_discharges[name_q]
            times = q_ours.index.intersection(q_sob.index)
            times = times[times >= times[0] + pd.Timedelta(hours=spinup_h)]
            d = q_ours.loc[times].to_numpy() - q_sob.loc[times].to_numpy()
            rel[name_q] = float(np.sqrt(np.mean(d**2)) / np.mean(np.abs(q_sob.loc[times].to_numpy())))
        discharge = pd.Series(rel, dtype=float)
    levels = pd.concat([ours.loc[common], sobek.levels.loc[common].add_suffix(".sobek3")], axis=1)
    return Sobek3Comparison(name, result.summary, run_dt, imported_dt, None, level_rmse, level_after, discharge,
                            spinup_h, wall, levels, dict(sim.last_run_stats))


def _grid_columns(sim: Simulator, case, points: pd.DataFrame) -> list[int]:
    """The h-point of every SOBEK 3 grid point: its node at a branch end, else the point at its chainage."""
    c = sim.compiled
    branches = {b.id: b for b in case.network.branches}
    nodes = {label[5:]: i for i, label in enumerate(c.hp_label) if label.startswith("node:")}
    out = []
    for branch, chainage in zip(points["branch"], points["chainage"], strict=True):
        b = branches.get(str(branch).replace(" ", "_"))
        if b is None:
            raise KeyError(f"grid point on branch {branch!r}, which the imported case does not have")
        if chainage < 1e-6:
            out.append(nodes[b.from_node])
        elif abs(chainage - b.length) < 1e-3:
            out.append(nodes[b.to_node])
        else:
            candidates = [i for i, hb in enumerate(c.hp_branch) if hb == b.id]
            k = min(candidates, key=lambda i: abs(c.hp_chainage[i] - chainage))
            if abs(c.hp_chainage[k] - chainage) > 1e-3:
                raise KeyError(f"no calculation point of branch {b.id!r} at chainage {chainage:g} m")
            out.append(k)
    return out
