"""The Oriège torrent (Mascaret validation case 19): calibration on 13 measured levels, judged by held-out gauges.

The data (``../shared/data/oriege-mascaret-test19``, GNU GPL v3, read from outside the repository, never copied
into it) are Mascaret's model of 5 km of the Oriège below the Orlu power station (84 surveyed profiles, a steady
12.36 m³/s with a lateral inflow of 0.85 m³/s at x = 2938 m, a level imposed downstream, one Strickler
coefficient of 20 m^(1/3)/s throughout) and the levels read at 13 staff gauges during that steady flow, beside
the levels Mascaret computed there (the table of the case's validation note, ``Test19.tex``; Mascaret's RMSE
against the measurements is 0.17 m).

:func:`calibrate_oriege`

1. imports the model with :func:`rivercal.io.mascaret.import_mascaret`, with a station at each gauge (``G01``
   at x = 0 m … ``G13`` at x = 5007 m);
2. splits Mascaret's single friction zone into three calibration zones of the minor bed (see :data:`ZONES`),
   each starting at Mascaret's 20 m^(1/3)/s;
3. writes the measured levels as an ordinary observation file (``observations.csv``: the steady levels at the
   end of the period) and calibrates the three Strickler coefficients with DuD through the model contract
   (:class:`rivercal.problem.CalibrationProblem`) on the 7 gauges of :data:`CALIBRATION_GAUGES`, then scores the 6
   held-out gauges; then calibrates on all 13, starting from the 7 gauges' estimates;
4. checks that the computed levels are steady (the change over the last 10 minutes of the period).

By default the model is run as imported except for the placement of cross-sections: ``nearest`` (each
calculation point takes the nearest profile). As imported (``cross_sections="points"``: each calculation
point takes the profile interpolated at it, as Mascaret's planimetry does) the torrent is as steady and its levels
at Strickler 20 are as close to the measurements as Mascaret's (RMSE 0.167 m against 0.168 m), but the three zones
calibrated on 7 gauges miss the 6 others by more (0.18 m, against 0.14 m with ``nearest``; 0.14 m and 0.13 m
uncalibrated): the pools' levels follow each profile's own shape, which three coefficients fit less well.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["CALIBRATION_GAUGES", "ZONES", "OriegeCalibration", "build_oriege_case", "calibrate_oriege",
           "oriege_folder", "read_gauges"]

#: How long before the calibration window its runs start, from the flow at the initial coefficients: the levels of
#: a new friction settle along the torrent within it (from Strickler 20 to the estimates, the levels at the end
#: are those of a run from the case's start within 0.06 mm; 45 minutes leave 0.4 mm, enough to make the
#: calibration take more runs).
HOT_START = pd.Timedelta(hours=1)

ENV_VAR = "RIVERCAL_ORIEGE_DIR"
#: Calibration zones of the minor bed: (name, first abscissa, last abscissa, m). The upper reach with its pools
#: (0-1600 m), the steep middle reach down to the lateral inflow (1600-2940 m), and the milder lower reach
#: (2940-5043 m); regression bed slopes about 2.4 %, 2.7 % and 0.7 %. Each profile takes the zone of its abscissa.
ZONES: tuple[tuple[str, float, float], ...] = (("KZ1", 0.0, 1600.0), ("KZ2", 1600.0, 2940.0),
                                              ("KZ3", 2940.0, 5043.0))
#: The gauges the first calibration sees: every other gauge from upstream (G01, G03, ..., G13), two or three per
#: zone; the other six (G02, G04, ..., G12) are held out.
CALIBRATION_GAUGES = ("G01", "G03", "G05", "G07", "G09", "G11", "G13")
#: Bounds of the Strickler coefficients, m^(1/3)/s.
BOUNDS = (5.0, 60.0)


def oriege_folder() -> Path:
    """The Oriège folder: ``$RIVERCAL_ORIEGE_DIR`` or ``<repository>/../shared/data/oriege-mascaret-test19``.

    Raises
    ------
    FileNotFoundError
        When the folder or its case file is missing (the message names the path and the variable).
    """
    env = os.environ.get(ENV_VAR)
    if env:
        path = Path(env).expanduser()
    else:
        path = (Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "oriege-mascaret-test19").resolve()
    if not (path / "mascaret0.xcas").is_file():
        raise FileNotFoundError(f"the Oriège Mascaret model was not found at {path}; set {ENV_VAR} to the folder "
                                "(GPL data from TELEMAC-Mascaret's test 19, not shipped with rivercal)")
    return path


def read_gauges(folder: Path) -> pd.DataFrame:
    """The 13 staff gauges of the validation note ``Test19.tex``: ``id``, ``x`` (m), ``measured`` and ``mascaret`` (m).

    Read from the table of the note at run time (the data are GPL and stay in their folder).
    """
    path = Path(folder) / "Test19.tex"
    rows = []
    number = r"(-?\d+(?:\.\d+)?)"
    pattern = re.compile(rf"^\s*{number}\s*&\s*{number}\s*&\s*{number}\s*&\s*{number}\s*\\\\")
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        m = pattern.match(line)
        if m:
            x, measured, computed, _ = (float(v) for v in m.groups())
            rows.append({"x": x, "measured": measured, "mascaret": computed})
    if len(rows) != 13:
        raise ValueError(f"{path}: expected the table of 13 gauges, found {len(rows)} rows")
    table = pd.DataFrame(rows)
    table.insert(0, "id", [f"G{k + 1:02d}" for k in range(len(table))])
    return table


def build_oriege_case(folder: Path, out: Path, *, cross_sections: str = "nearest") -> Path:
    """Import the Oriège with a station per gauge and three calibration zones; write ``observations.csv`` too.

    Returns the case folder (``out/case``). Also written: ``out/gauges.csv`` (the station list given to the
    import), ``out/observations.csv`` (the measured levels at the end of the period, one column ``<gauge>.h``
    each) and ``out/observations_7.csv`` (the same for the 7 calibration gauges only).
    """
    import tomli_w

    from rivercal.io.mascaret import ImportOptions, StationSpec, import_mascaret

    gauges = read_gauges(folder)
    out.mkdir(parents=True, exist_ok=True)
    gauges[["id"]].assign(reach="Bief_1", abscissa=gauges["x"]).to_csv(out / "gauges.csv", index=False)
    specs = tuple(StationSpec(g.id, "Bief_1", float(g.x)) for g in gauges.itertuples())
    case_dir = out / "case"
    import_mascaret(folder / "mascaret0.xcas", case_dir, ImportOptions(stations=specs, cross_sections=cross_sections))
    data = tomllib.loads((case_dir / "case.toml").read_text(encoding="utf-8"))
    start_value = next(g["value"] for g in data["friction_groups"])
    data["friction_groups"] = [{"id": name, "type": "strickler", "value": start_value} for name, _, _ in ZONES]
    chainage = {cs["profile"]: cs["chainage"] for b in data["branches"] for cs in b["cross_sections"]}
    for p in data["profiles"]:
        zone = next(name for name, a, b in ZONES if chainage[p["id"]] < b or b == ZONES[-1][2])
        p["friction"] = [zone] * len(p["friction"])
    data["parameters"] = [{"name": name, "targets": [f"friction:group:{name}"], "min": BOUNDS[0], "max": BOUNDS[1],
                           "initial": start_value, "transform": "offset", "perturbation": 2.0, "unit": "m^(1/3)/s"}
                          for name, _, _ in ZONES]
    (case_dir / "case.toml").write_text(tomli_w.dumps(data), encoding="utf-8")
    end = pd.Timestamp(data["case"]["end"])
    frame = pd.DataFrame({f"{g.id}.h": [g.measured] for g in gauges.itertuples()},
                         index=[end.strftime("%Y-%m-%dT%H:%M:%SZ")])
    frame.index.name = "time"
    frame.to_csv(out / "observations.csv")
    frame[[f"{g}.h" for g in CALIBRATION_GAUGES]].to_csv(out / "observations_7.csv")
    return case_dir


@dataclass
class OriegeCalibration:
    """Result of :func:`calibrate_oriege` (levels in m, Strickler coefficients in m^(1/3)/s).

    Attributes
    ----------
    gauges
        Per gauge: ``id``, ``x``, ``measured``, ``mascaret``, ``role`` (calibration or held-out), and the levels
        rivercal computed at Mascaret's coefficient (``initial``), calibrated on 7 gauges (``calibrated_7``) and on
        all 13 (``calibrated_13``).
    estimates_7, estimates_13
        Coefficients per zone of the two calibrations.
    runs_7, runs_13
        Model runs of the two calibrations.
    steady_change_m
        Largest change of a gauge's level over the last 10 minutes of the period, calibrated on 13.
    wall_s
        Wall time of the whole benchmark, s.
    case_folder
        The imported case.
    """

    gauges: pd.DataFrame
    estimates_7: dict[str, float]
    estimates_13: dict[str, float]
    runs_7: int
    runs_13: int
    steady_change_m: float
    wall_s: float
    case_folder: Path
    extra: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """``{"gauges", "rmse_m", "max_abs_m", "mascaret_rmse_m", "held_out_rmse_m", ...}`` (m)."""
        g = self.gauges
        held = g["role"] == "held-out"
        err13 = g["calibrated_13"] - g["measured"]
        err7 = g["calibrated_7"] - g["measured"]
        masc = g["mascaret"] - g["measured"]
        init = g["initial"] - g["measured"]
        rounded = g.round({"x": 1, "measured": 3, "mascaret": 3, "initial": 3, "calibrated_7": 3, "calibrated_13": 3})
        return {
            "gauges": rounded.to_dict(orient="records"),
            "rmse_m": _r(_rmse(err13)),
            "max_abs_m": _r(float(np.abs(err13).max())),
            "mascaret_rmse_m": _r(_rmse(masc)),
            "held_out_rmse_m": _r(_rmse(err7[held])),
            "mascaret_held_out_rmse_m": _r(_rmse(masc[held])),
            "calibration_rmse_7_m": _r(_rmse(err7[~held])),
            "mascaret_max_abs_m": _r(float(np.abs(masc).max())),
            "initial_rmse_m": _r(_rmse(init)),
            "initial_held_out_rmse_m": _r(_rmse(init[held])),
            "zones": [{"name": n, "from_m": a, "to_m": b} for n, a, b in ZONES],
            "estimates_7": {k: round(v, 3) for k, v in self.estimates_7.items()},
            "estimates_13": {k: round(v, 3) for k, v in self.estimates_13.items()},
            "model_runs_7": self.runs_7,
            "model_runs_13": self.runs_13,
            "steady_change_m": _r(self.steady_change_m, 6),
            "wall_s": round(self.wall_s, 1),
            **self.extra,
        }


def _rmse(e) -> float:
    return float(np.sqrt(np.mean(np.square(np.asarray(e, dtype=float)))))


def _r(v: float, digits: int = 4) -> float:
    return round(float(v), digits)


def calibrate_oriege(folder: Path | None = None, out: Path | None = None, *, algorithm: str = "dud",
                     workers: int | None = None, cross_sections: str = "nearest") -> OriegeCalibration:
    """Calibrate the Oriège's three zones on 7 gauges, validate on 6, then calibrate on all 13 (module docstring).

    Parameters
    ----------
    folder
        The Oriège folder (default :func:`oriege_folder`).
    out
        Where to write the case and the observation file (default: a temporary folder, kept for the result).
    algorithm
        Optimiser (a name of :data:`rivercal.optimise.OPTIMISERS`).
    workers
        Threads for the batched model runs (None: all cores).
    cross_sections
        The import's placement of the profiles: ``nearest`` or ``points`` (as imported, Mascaret's).
    """
    from rivercal.io.observations import read_observations_csv
    from rivercal.models import load_model
    from rivercal.parameters import ParameterSet
    from rivercal.problem import CalibrationProblem, calibrate

    t0 = time.perf_counter()
    folder = Path(folder) if folder is not None else oriege_folder()
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="oriege-"))
    case_dir = build_oriege_case(folder, out, cross_sections=cross_sections)
    gauges = read_gauges(folder)
    model = load_model(case_dir)
    observations = read_observations_csv(out / "observations.csv")
    params = ParameterSet([p for p in model.calibration.parameters if p.name in {n for n, _, _ in ZONES}])
    end = pd.Timestamp(model.end)
    window = (end - pd.Timedelta(minutes=10), end)
    warmup = window[0] - pd.Timestamp(model.start)

    def levels(values: dict[str, float]) -> pd.Series:
        result, _ = model.simulate(params.quantities(values), start=model.start, end=model.end)
        return result.series[[f"{g}.h" for g in gauges["id"]]].iloc[-1].set_axis(list(gauges["id"]))

    # The calibration's runs start from the flow at the initial coefficients HOT_START before the window: a new
    # friction settles along the 5 km within it, and each run is 70 of the case's 133 minutes. The levels
    # reported (initial, after 7 and after 13 gauges) are of whole runs from the case's start.
    hot = window[0] - HOT_START
    state = None
    if hot > pd.Timestamp(model.start):
        _, state = model.simulate(params.quantities({p.name: p.initial for p in params}), start=model.start,
                                  end=hot)
        warmup = HOT_START

    def fit(ids: list[str], start: ParameterSet):
        problem = CalibrationProblem(model, start, observations.select([f"{g}.h" for g in ids]), window,
                                     warmup=warmup, state=state)
        cal = calibrate(problem, algorithm, workers=workers)
        return cal

    initial = levels({p.name: p.initial for p in params})
    cal7 = fit(list(CALIBRATION_GAUGES), params)
    at7 = levels(cal7.estimates)
    cal13 = fit(list(gauges["id"]), params.with_initial(cal7.estimates))  # all 13 refine the 7 gauges' estimates
    result, _ = model.simulate(params.quantities(cal13.estimates), start=model.start, end=model.end)
    series = result.series[[f"{g}.h" for g in gauges["id"]]]
    at13 = series.iloc[-1].set_axis(list(gauges["id"]))
    before = series.loc[:end - pd.Timedelta(minutes=10)].iloc[-1].to_numpy()
    steady = float(np.max(np.abs(series.iloc[-1].to_numpy() - before)))
    table = gauges.assign(role=["calibration" if g in CALIBRATION_GAUGES else "held-out" for g in gauges["id"]],
                          initial=initial.to_numpy(), calibrated_7=at7.to_numpy(), calibrated_13=at13.to_numpy())
    if not all(math.isfinite(v) for v in table[["initial", "calibrated_7", "calibrated_13"]].to_numpy().ravel()):
        raise RuntimeError("a computed level is not finite")
    return OriegeCalibration(gauges=table, estimates_7=dict(cal7.estimates), estimates_13=dict(cal13.estimates),
                             runs_7=int(cal7.result.nfev), runs_13=int(cal13.result.nfev), steady_change_m=steady,
                             wall_s=time.perf_counter() - t0, case_folder=case_dir,
                             extra={"algorithm": algorithm, "cross_sections": cross_sections,
                                    "messages": [cal7.result.message, cal13.result.message]})
