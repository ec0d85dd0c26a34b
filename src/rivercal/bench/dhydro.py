"""The imported D-HYDRO model "Dellen" against D-HYDRO's own computed water levels.

The Dellen model (../shared/data/dhydro-dellen, LGPL-3.0, read from outside the repository) comes with the
exchange files of a coupled 7-day D-HYDRO run (D-Flow FM + rainfall-runoff + real-time control): the lateral
inflows the rainfall-runoff model delivered (``rr_to_flow.nc``), the structure settings real-time control
imposed (``rtc_to_flow.nc``), and the water levels D-Flow FM computed at 6 observation points
(``flow_to_rtc.nc``) and 138 lateral locations (``flow_to_rr.nc``), every 600 s.

:func:`compare_dellen` imports the model driven by the first two (:func:`rivercal.io.dhydro.import_dhydro`
with ``realtime``), adds a station at every compared location — the calculation point D-Flow FM reports
there: the point nearest to a lateral, the node of a lateral on a node, the observation point as imported —
runs the seven days and scores the root-mean-square difference of the level series per location.
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
from rivercal.io.dhydro import ImportOptions, import_dhydro, read_exchange

__all__ = ["DellenComparison", "compare_dellen", "dellen_folder", "ledger_counts"]

ENV_VAR = "RIVERCAL_DELLEN_DIR"
#: The first day of the run is its spin-up: the model starts from 1 m of water everywhere.
SPINUP_DAYS = 1


def dellen_folder() -> Path:
    """The Dellen folder: ``$RIVERCAL_DELLEN_DIR`` or ``<repository>/../shared/data/dhydro-dellen``.

    Raises
    ------
    FileNotFoundError
        When the folder or its MDU is missing (the message names the path and the variable).
    """
    env = os.environ.get(ENV_VAR)
    if env:
        path = Path(env).expanduser()
    else:
        path = (Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "dhydro-dellen").resolve()
    if not (path / "dflowfm" / "Flow1D.mdu").is_file():
        raise FileNotFoundError(f"the Dellen D-HYDRO model was not found at {path}; set {ENV_VAR} to the folder "
                                "(LGPL-3.0 data, not shipped with rivercal)")
    return path


@dataclass
class DellenComparison:
    """Result of :func:`compare_dellen`.

    Attributes
    ----------
    table
        Per location: ``location`` (the D-HYDRO quantity), ``station``, ``station_point`` (its calculation point),
        ``rmse_m``, ``bias_m`` (rivercal minus D-HYDRO), ``max_abs_m``, ``rmse_after_spinup_m`` (from day 2 on).
    wall_s
        Wall time of the simulation (7 days), s.
    period_s
        The simulated period, s.
    series
        rivercal's level series at the compared locations and D-HYDRO's (columns ``<station>.h`` and
        ``<station>.dhydro``), every 600 s.
    balance_error
        Relative volume-balance error of the run.
    case_folder
        The imported case.
    imported
        The import's summary (:attr:`rivercal.io.dhydro.ImportResult.summary`).
    dt_s, imported_dt_s
        The time step run (the longest, s) and the model's own.
    run_stats
        The engine's counts of the run (steps, solves, divided steps …, :attr:`Simulator.last_run_stats`).
    """

    table: pd.DataFrame
    wall_s: float
    period_s: float
    balance_error: float
    case_folder: Path
    series: pd.DataFrame = field(repr=False)
    imported: dict = field(default_factory=dict)
    dt_s: float = 0.0
    imported_dt_s: float = 0.0
    run_stats: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """The scores over the whole run and after the spin-up day.

        ``{"locations", "points", "rmse_median_m", "rmse_p90_m", "rmse_max_m", "after_spinup": {"median", "p90",
        "max"}, "wall_s", "dhydro_period_s"}``: RMSE over the locations, m; ``points`` counts the distinct
        calculation points behind them (several laterals enter at one point).
        """
        rmse = self.table["rmse_m"]
        after = self.table["rmse_after_spinup_m"]
        return {
            "locations": int(rmse.size),
            "points": int(self.table["station_point"].nunique()),
            "rmse_median_m": round(float(rmse.median()), 4),
            "rmse_p90_m": round(float(rmse.quantile(0.9)), 4),
            "rmse_max_m": round(float(rmse.max()), 4),
            "after_spinup": {"median": round(float(after.median()), 4), "p90": round(float(after.quantile(0.9)), 4),
                             "max": round(float(after.max()), 4)},
            "wall_s": round(self.wall_s, 3),
            "dhydro_period_s": self.period_s,
        }


def compare_dellen(folder: Path | None = None, out: Path | None = None, *,
                   parameters: dict[str, float] | None = None, dt: float | None = None,
                   case: Path | None = None) -> DellenComparison:
    """Import Dellen with its exchange series, run it, and compare with D-HYDRO's levels.

    Parameters
    ----------
    folder
        The Dellen folder (default :func:`dellen_folder`).
    out
        Folder for the imported case (default: a temporary folder that is kept for the result).
    parameters
        Model quantities to set for the run (default: the model as imported).
    dt
        The longest time step of the run, s (default: the model's own).
    case
        A case folder already imported from ``folder`` with its two exchange files, as this function imports it
        (``rivercal import dhydro Flow1D.mdu --realtime rr_to_flow.nc --realtime rtc_to_flow.nc``): run as it
        is, not imported again (``out`` is then unused, and :attr:`DellenComparison.imported` is empty: the
        import's ledger is not at hand).
    """
    folder = Path(folder) if folder is not None else dellen_folder()
    imported: dict[str, int] = {}
    if case is None:
        out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="dellen-"))
        result = import_dhydro(folder / "dflowfm" / "Flow1D.mdu", out,
                               ImportOptions(realtime=(folder / "rr_to_flow.nc", folder / "rtc_to_flow.nc")))
        case, imported = result.folder, ledger_counts(result.ledger)
    case = Path(case)
    data = tomllib.loads((case / "case.toml").read_text(encoding="utf-8"))
    refdate = pd.Timestamp(str(data["case"]["start"])).normalize()
    computed = read_exchange(folder / "flow_to_rtc.nc", refdate)
    computed.update(read_exchange(folder / "flow_to_rr.nc", refdate))
    targets = add_comparison_stations(data, computed)
    imported_dt = float(data["engine"]["dt"])
    data["engine"]["dt"] = float(dt) if dt is not None else imported_dt
    sim = Simulator(case_from_dict(data, case))
    t0 = time.perf_counter()
    run, _ = sim.simulate(parameters)
    wall = time.perf_counter() - t0
    rows, columns = [], {}
    spun_up = sim.start + pd.Timedelta(days=SPINUP_DAYS)
    points = {s["id"]: f"{s['branch']}@{s['chainage']:.3f}" for s in data["stations"] if "branch" in s}
    for key, station in targets.items():
        ours = run.series[f"{station}.h"]
        theirs = computed[key]
        common = ours.index.intersection(theirs.index)
        diff = ours[common].to_numpy() - theirs[common].to_numpy()
        later = diff[common >= spun_up]
        rows.append({"location": key, "station": station, "station_point": points.get(station, station),
                     "rmse_m": float(np.sqrt(np.mean(diff**2))), "bias_m": float(np.mean(diff)),
                     "max_abs_m": float(np.max(np.abs(diff))),
                     "rmse_after_spinup_m": float(np.sqrt(np.mean(later**2))) if later.size else float("nan")})
        columns[f"{station}.h"] = ours[common]
        columns[f"{station}.dhydro"] = theirs[common]
    table = pd.DataFrame(rows).sort_values("rmse_m", ascending=False, ignore_index=True)
    return DellenComparison(table=table, wall_s=wall, period_s=(sim.end - sim.start).total_seconds(),
                            balance_error=run.balance.relative_error, case_folder=case,
                            series=pd.DataFrame(columns), imported=imported,
                            dt_s=float(data["engine"]["dt"]), imported_dt_s=imported_dt,
                            run_stats=dict(sim.last_run_stats))


def ledger_counts(ledger) -> dict[str, int]:
    """``{"objects", "exact", "approximated", "refused"}`` of an import's ledger."""
    return {"objects": len(ledger.entries), "exact": ledger.counts("exact"),
            "approximated": ledger.counts("approximated"), "refused": ledger.counts("refused")}


def add_comparison_stations(data: dict, computed: dict[str, pd.Series]) -> dict[str, str]:
    """Add to a case dict a level station at every location D-HYDRO computed a level for; D-HYDRO key → station.

    A lateral's level is that of the calculation point its inflow enters (D-Flow FM's flow node): the point of
    the branch nearest to its chainage, or its node. An observation point is the station the import made of it.
    """
    laterals = {lat["id"]: lat for lat in data["laterals"]}
    branches = {b["id"]: b for b in data["branches"]}
    stations = {s["id"] for s in data["stations"]}
    targets: dict[str, str] = {}
    for key in sorted(computed):
        kind, name, quantity = key.split("/", 2)
        if quantity != "water_level":
            continue
        if kind == "observations" and name in stations:
            targets[key] = name
            continue
        if kind != "laterals" or name not in laterals:
            continue
        lat = laterals[name]
        if "node" in lat:
            branch = next(b for b in data["branches"] if lat["node"] in (b["from_node"], b["to_node"]))
            chainage = 0.0 if branch["from_node"] == lat["node"] else branch["length"]
        else:
            branch = branches[lat["branch"]]
            points = np.asarray(branch.get("points") or [0.0, branch["length"]], dtype=float)
            chainage = float(points[np.argmin(np.abs(points - lat["chainage"]))])
        station = f"lateral_{name}".replace(".", "_")[:64]
        data["stations"].append({"id": station, "branch": branch["id"], "chainage": chainage, "quantities": ["h"]})
        targets[key] = station
    return targets
