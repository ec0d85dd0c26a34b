"""Every shared real model, imported and run as a user would, against its own engine's results.

One row per model (:func:`model_row`): how its import went (objects read, converted exactly, approximated,
refused), whether it runs as imported (its own time step and period), and the root-mean-square difference of
its levels from a reference at every compared point, over the whole run and after the spin-up:

============================  ========  ==============================================================
model                         format    reference
============================  ========  ==============================================================
``dhydro-dellen``             dhydro    D-HYDRO's coupled-run levels at 144 locations (29 points), 7 days
``dhydro-1d-steady-state``    dhydro    the gradually-varied-flow ODE (scipy) at every point, steady
``dhydro-korte-woerden-1d``   dhydro    none published: runs as imported (72 realtime laterals at 1 l/s)
``sobek3-waal``               sobek3    SOBEK 3's levels at 927 grid points every hour, its discharges at
                                        185 observation points
``sobek3-compound``           sobek3    SOBEK 3's levels at 62 grid points every hour
``oriege-mascaret-test19``    mascaret  Mascaret's steady levels at its 13 gauges
============================  ========  ==============================================================

:func:`sweep` runs each model at several longest time steps and gives, per step, the largest difference at a
compared point from the run at the shortest step (after the spin-up), or the engine's message: a model either
runs right at every step or stops with a clear error.

The data stay in ``../shared/data`` (their licences keep them out of the repository; ``$RIVERCAL_SHARED_DATA``
points elsewhere).
"""

from __future__ import annotations

import copy
import os
import tempfile
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from rivercal.case import case_from_dict
from rivercal.engine import Simulator
from rivercal.errors import ModelRunError

__all__ = ["MODELS", "ModelRun", "model_row", "shared_data", "steady_gvf_levels", "sweep"]

ENV_VAR = "RIVERCAL_SHARED_DATA"
G = 9.81


def shared_data() -> Path:
    """The shared data folder: ``$RIVERCAL_SHARED_DATA`` or ``<repository>/../shared/data``."""
    env = os.environ.get(ENV_VAR)
    return Path(env).expanduser() if env else (Path(__file__).resolve().parents[3] / ".." / "shared" /
                                                "data").resolve()


@dataclass
class ModelRun:
    """One run of a model at one time step, with its reference.

    Attributes
    ----------
    model, format
        The model's shared folder name and its file format.
    imported
        ``{"objects", "exact", "approximated", "refused"}`` of its import.
    dt_s, imported_dt_s
        The longest time step of the run and the model's own, s.
    error
        The engine's message when the run failed, else None.
    levels
        Simulated levels at the compared points (columns: one per point), m AD; empty without a reference.
    reference
        The reference's levels at the same points and times, m AD (same shape), or None.
    spinup
        The first time of the ``after_spinup`` figures.
    wall_s
        Wall time of the simulation, s.
    run_stats
        The engine's counts of the run (steps, solves …): ``solves_per_step`` in the row.
    extra
        Further figures of the row (discharge scores, the reference's name).
    """

    model: str
    format: str
    imported: dict
    dt_s: float
    imported_dt_s: float
    error: str | None
    levels: pd.DataFrame
    reference: pd.DataFrame | None
    spinup: pd.Timestamp | None
    wall_s: float
    run_stats: dict
    extra: dict

    def row(self) -> dict:
        """The JSON line of ``rivercal bench models``."""
        from rivercal.bench.sobek3 import solves_per_step

        out = {"model": self.model, "format": self.format, **self.imported,
               "runs_as_imported": self.error is None and self.dt_s == self.imported_dt_s, "dt_s": self.dt_s,
               "points_compared": 0, "level_rmse_m": None, "after_spinup": None, "wall_s": round(self.wall_s, 3),
               "solves_per_step": solves_per_step(self.run_stats), **self.extra}
        if self.error is not None:
            out["error"] = self.error
        if self.reference is not None and self.error is None:
            diff = self.levels - self.reference
            out["points_compared"] = int(diff.shape[1])
            out["level_rmse_m"] = _stats(np.sqrt((diff**2).mean()))
            later = diff[diff.index >= self.spinup] if self.spinup is not None else diff
            out["after_spinup"] = {"from": str(later.index[0]), "level_rmse_m": _stats(np.sqrt((later**2).mean())),
                                   **out.pop("after_spinup_extra", {})}
        out.pop("after_spinup_extra", None)
        return out


def _stats(values: pd.Series) -> dict:
    return {"median": round(float(values.median()), 4), "p90": round(float(values.quantile(0.9)), 4),
            "max": round(float(values.max()), 4)}


# -- the models ------------------------------------------------------------------------------------------------


def _dellen(root: Path, out: Path, dt: float | None) -> ModelRun:
    from rivercal.bench.dhydro import compare_dellen

    c = compare_dellen(root / "dhydro-dellen", out, dt=dt)
    levels = c.series[[col for col in c.series.columns if col.endswith(".h")]]
    reference = c.series[[col for col in c.series.columns if col.endswith(".dhydro")]]
    reference.columns = levels.columns
    # several D-HYDRO locations share a calculation point: score each point once
    points = c.table.drop_duplicates("station_point").set_index("station")["station_point"]
    keep = [f"{st}.h" for st in points.index]
    return ModelRun("dhydro-dellen", "dhydro", c.imported, c.dt_s, c.imported_dt_s, None, levels[keep],
                    reference[keep], levels.index[0] + pd.Timedelta(days=1), c.wall_s, c.run_stats,
                    {"reference": "D-HYDRO's coupled-run levels (flow_to_rr.nc, flow_to_rtc.nc)",
                     "locations": int(c.table.shape[0])})


def _dhydro_import(mdu: Path, out: Path, dt: float | None, **options) -> tuple[dict, dict, Path]:
    from rivercal.bench.dhydro import ledger_counts
    from rivercal.io.dhydro import ImportOptions, import_dhydro

    result = import_dhydro(mdu, out, ImportOptions(**options))
    data = tomllib.loads((out / "case.toml").read_text(encoding="utf-8"))
    return data, ledger_counts(result.ledger), result.folder


def _run(data: dict, folder: Path, dt: float | None) -> tuple[Simulator | None, object, str | None, float, float]:
    """Run a case dict at the longest step ``dt`` (default its own): (simulator, result, error, wall, own dt)."""
    own = float(data["engine"]["dt"])
    data = copy.deepcopy(data)
    if dt is not None:
        data["engine"]["dt"] = float(dt)
        interval = float(data["engine"].get("output_interval", 3600.0))
        if interval % float(dt):  # the output on the longest step's grid, and the period a whole number of it
            interval = float(np.lcm(int(interval), int(dt)))
            data["engine"]["output_interval"] = interval
            start, end = pd.Timestamp(data["case"]["start"]), pd.Timestamp(data["case"]["end"])
            outputs = int((end - start).total_seconds() // interval)
            data["case"]["end"] = (start + pd.Timedelta(seconds=outputs * interval)).isoformat()
    sim = Simulator(case_from_dict(data, folder))
    t0 = time.perf_counter()
    try:
        result, _ = sim.simulate(snapshots=True)
    except ModelRunError as exc:
        return sim, None, str(exc), time.perf_counter() - t0, own
    return sim, result, None, time.perf_counter() - t0, own


def _steady(root: Path, out: Path, dt: float | None) -> ModelRun:
    data, counts, folder = _dhydro_import(root / "dhydro-1d-steady-state-flow" / "Boundary.mdu", out, None)
    sim, result, error, wall, own = _run(data, folder, dt)
    levels = reference = None
    if result is not None:
        c = sim.compiled
        last = result.levels.iloc[[-1]]
        keep = [i for i, b in enumerate(c.hp_branch) if b in ("T1", "T2", "T3", "T4")]
        levels = last.iloc[:, keep]
        gvf = steady_gvf_levels(100.0, 45.0, 0.5, 0.0, 2000.0, 2.5)
        reference = pd.DataFrame([gvf(c.hp_chainage[keep])], index=last.index, columns=levels.columns)
    return ModelRun("dhydro-1d-steady-state-flow", "dhydro", counts, dt or own, own, error,
                    levels if levels is not None else pd.DataFrame(), reference, None, wall, dict(sim.last_run_stats),
                    {"reference": "the gradually-varied-flow ODE (scipy) at the steady state after 3 days"})


def _korte_woerden(root: Path, out: Path, dt: float | None) -> ModelRun:
    mdu = root / "dhydro-korte-woerden-1d" / "dflowfm" / "FlowFM.mdu"
    data, counts, folder = _dhydro_import(mdu, out, None, realtime_lateral=0.001)
    sim, result, error, wall, own = _run(data, folder, dt)
    levels = pd.DataFrame() if result is None else result.levels
    spinup = None if result is None else levels.index[0] + (levels.index[-1] - levels.index[0]) / 10
    return ModelRun("dhydro-korte-woerden-1d", "dhydro", counts, dt or own, own, error, levels, None, spinup, wall,
                    dict(sim.last_run_stats),
                    {"reference": "none published (72 realtime laterals at a constant 1 l/s each)"})


def _sobek3(name: str) -> Callable[[Path, Path, float | None], ModelRun]:
    def run(root: Path, out: Path, dt: float | None) -> ModelRun:
        from rivercal.bench.sobek3 import MODELS as SOBEK3
        from rivercal.bench.sobek3 import compare_sobek3

        c = compare_sobek3(root / name / SOBEK3[name], out, dt=dt)
        s = c.summary
        levels = c.levels[[col for col in c.levels.columns if not col.endswith(".sobek3")]] if c.error is None \
            else pd.DataFrame()
        reference = c.levels[[col for col in c.levels.columns if col.endswith(".sobek3")]] if c.error is None \
            else None
        if reference is not None:
            reference.columns = levels.columns
        extra = {"reference": "SOBEK 3's own levels (output/gridpoints.nc)"}
        if c.discharge_relative_rmse.size:
            extra["after_spinup_extra"] = {"discharge_stations": int(c.discharge_relative_rmse.size),
                                           "discharge_relative_rmse": _stats(c.discharge_relative_rmse)}
        return ModelRun(name, "sobek3", {k: s[k] for k in ("objects", "exact", "approximated", "refused")}, c.dt_s,
                        c.imported_dt_s, c.error, levels, reference,
                        None if c.error else levels.index[0] + pd.Timedelta(hours=c.spinup_h), c.wall_s, c.run_stats,
                        extra)

    return run


def _oriege(root: Path, out: Path, dt: float | None) -> ModelRun:
    from rivercal.bench.oriege import read_gauges
    from rivercal.io.mascaret import ImportOptions, StationSpec, import_mascaret

    folder = root / "oriege-mascaret-test19"
    gauges = read_gauges(folder)
    specs = tuple(StationSpec(g.id, "Bief_1", float(g.x)) for g in gauges.itertuples())
    result = import_mascaret(folder / "mascaret0.xcas", out, ImportOptions(stations=specs))
    data = tomllib.loads((out / "case.toml").read_text(encoding="utf-8"))
    sim, run, error, wall, own = _run(data, out, dt)
    levels = reference = None
    if run is not None:
        levels = run.series[[f"{g}.h" for g in gauges["id"]]].iloc[[-1]]
        reference = pd.DataFrame([gauges["mascaret"].to_numpy()], index=levels.index, columns=levels.columns)
    ledger = result.ledger
    counts = {"objects": len(ledger.entries), "exact": ledger.counts("exact"),
              "approximated": ledger.counts("approximated"), "refused": ledger.counts("refused")}
    return ModelRun("oriege-mascaret-test19", "mascaret", counts, dt or own, own, error,
                    levels if levels is not None else pd.DataFrame(), reference, None, wall, dict(sim.last_run_stats),
                    {"reference": "Mascaret's steady levels at the 13 gauges (Test19.tex)"})


#: The shared models with their runner: (shared folder, runner(shared data root, case folder, dt) -> ModelRun).
MODELS: dict[str, Callable[[Path, Path, float | None], ModelRun]] = {
    "dhydro-dellen": _dellen,
    "dhydro-1d-steady-state-flow": _steady,
    "dhydro-korte-woerden-1d": _korte_woerden,
    "sobek3-waal": _sobek3("sobek3-waal"),
    "sobek3-compound": _sobek3("sobek3-compound"),
    "oriege-mascaret-test19": _oriege,
}


def _check(name: str) -> Path:
    if name not in MODELS:
        raise KeyError(f"unknown shared model {name!r}; known: {', '.join(MODELS)}")
    root = shared_data()
    if not (root / name).is_dir():
        raise FileNotFoundError(f"the shared model {name} was not found in {root}; set {ENV_VAR} to the shared data "
                                "folder (its licence keeps it out of rivercal)")
    return root


def model_row(name: str, out: Path | None = None, *, dt: float | None = None) -> ModelRun:
    """Import the shared model ``name``, run it (at its own step, or ``dt`` as the longest) and compare it.

    Raises
    ------
    KeyError, FileNotFoundError
        For an unknown model, or a model missing from the shared data.
    CaseError
        When the model does not import strictly.
    """
    root = _check(name)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix=f"{name}-"))
    return MODELS[name](root, out, dt)


def sweep(name: str, steps: tuple[float, ...] = (10.0, 60.0, 300.0, 600.0), out: Path | None = None) -> dict:
    """Run a shared model at each longest time step of ``steps``; compare every run with the shortest one's.

    Each run is compared with the run at the shortest step that ran, at every compared point (every point where the
    model has no reference), at the output times after the spin-up (the first day; the first tenth of a run of hours):

    - ``level_rmse_m``: the root mean square of the level difference (m) over those times, at the point where it
      is largest (``rmse_where``) — the measure of the model's fidelity figures, per point;
    - ``max_diff_m``: the largest absolute level difference (m) at any point and time (``where``, ``when``) — in a
      transient that the shortest step does not resolve either (a swing of minutes, a sewer filling), this is
      where runs at two short steps differ too, so it is reported beside the root mean square, not instead of it.

    Returns ``{"model", "steps": [{"dt_s", "ok", "error", "level_rmse_m", "rmse_where", "max_diff_m", "where",
    "when", "points_over_1cm", "wall_s", "solves_per_step"}], "rmse_within_1cm", "max_within_1cm"}``;
    ``points_over_1cm`` counts the points whose root mean square difference exceeds 1 cm.
    """
    from rivercal.bench.sobek3 import solves_per_step

    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix=f"sweep-{name}-"))
    runs = [model_row(name, out / f"dt{dt:g}", dt=dt) for dt in sorted(steps)]
    finest = next((r for r in runs if r.error is None), None)
    rows = []
    for r in runs:
        item = {"dt_s": r.dt_s, "ok": r.error is None, "error": r.error, "wall_s": round(r.wall_s, 3),
                "solves_per_step": solves_per_step(r.run_stats)}
        if r.error is None and finest is not None:
            if len(finest.levels) == 1:  # a steady state: the last levels, whatever the last time
                diff = (r.levels.iloc[[-1]] - finest.levels.iloc[[-1]].to_numpy()).abs()
            else:
                common = r.levels.index.intersection(finest.levels.index)
                if finest.spinup is not None:
                    common = common[common >= finest.spinup]
                diff = (r.levels.loc[common] - finest.levels.loc[common]).abs()
            rmse = np.sqrt((diff**2).mean())
            largest = diff.max()
            item.update(level_rmse_m=round(float(rmse.max()), 4), rmse_where=str(rmse.idxmax()),
                        max_diff_m=round(float(largest.max()), 4), where=str(largest.idxmax()),
                        when=str(diff[largest.idxmax()].idxmax()), points_over_1cm=int((rmse > 0.01).sum()))
        rows.append(item)
    ran = [row for row in rows if row["ok"]]
    return {"model": name, "steps": rows, "rmse_within_1cm": all(row["level_rmse_m"] <= 0.01 for row in ran),
            "max_within_1cm": all(row["max_diff_m"] <= 0.01 for row in ran)}


# -- the steady reference ------------------------------------------------------------------------------------------

#: The c01 model's yz profile (``CrossSectionDefinitions.ini``): across (m) and bed (m above its lowest point).
C01_Y = np.array([0.0, 0.001, 5.0, 10.0, 20.0, 30.0, 40.0, 45.0, 49.999, 50.0])
C01_Z = np.array([3.0, 2.5, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 2.5, 3.0])


def _yz_geometry(depth: float) -> tuple[float, float, float]:
    """Flow area (m²), wetted perimeter (m) and top width (m) of the c01 profile at a depth above its lowest point.

    The bed between the survey points is linear; above the end points the walls are vertical. Computed by dense
    sampling, independently of the engine's tables.
    """
    y = np.linspace(C01_Y[0], C01_Y[-1], 200_001)
    z = np.interp(y, C01_Y, C01_Z)
    wet = np.clip(depth - z, 0.0, None)
    area = float(np.sum(0.5 * (wet[1:] + wet[:-1]) * np.diff(y)))
    width = float(np.sum(np.diff(y)[(wet[1:] > 0) | (wet[:-1] > 0)]))
    per = 0.0
    for k in range(C01_Y.size - 1):
        lo, hi = sorted((C01_Z[k], C01_Z[k + 1]))
        if depth <= lo:
            continue
        frac = 1.0 if depth >= hi or hi == lo else (depth - lo) / (hi - lo)
        per += frac * np.hypot(C01_Y[k + 1] - C01_Y[k], C01_Z[k + 1] - C01_Z[k])
    per += max(depth - C01_Z[0], 0.0) + max(depth - C01_Z[-1], 0.0)
    return area, per, width


def steady_gvf_levels(q: float, chezy: float, bed_up: float, bed_down: float, length: float,
                      level_down: float) -> Callable[[np.ndarray], np.ndarray]:
    """Steady levels (m AD) along a c01 channel by chainage (m), from the gradually-varied-flow ODE.

    dh/dx = (S0 - Q²/K²) / (1 - Q² B / (g A³)),  K = C A √(A/P),

    integrated upstream from ``level_down`` (m AD) with scipy; ``q`` in m³/s, ``chezy`` in m^(1/2)/s, beds in m AD,
    ``length`` in m.
    """
    slope = (bed_up - bed_down) / length

    def rhs(x, h):
        a, p, b = _yz_geometry(h[0])
        k = chezy * a * np.sqrt(a / p)
        return [(slope - q * q / (k * k)) / (1.0 - q * q * b / (G * a**3))]

    sol = solve_ivp(rhs, (length, 0.0), [level_down - bed_down], rtol=1e-9, atol=1e-10, dense_output=True)
    return lambda x: sol.sol(x)[0] + bed_up + (bed_down - bed_up) * np.asarray(x) / length
