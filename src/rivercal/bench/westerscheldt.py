"""The Western Scheldt in the storm surge of 5–7 December 2013: state updating judged at a held-out gauge.

The data (packaged with the case ``westerscheldt``: Rijkswaterstaat's measurements, CC0 1.0) are the water
levels measured every 10 minutes at Vlissingen, Terneuzen, Hansweert and Bath, and the astronomical tide
predicted there and at Cadzand, the mouth. A model driven by the predicted tide knows nothing of the surge
(up to 3 m at Bath); state updating from the measured levels is the classic correction.

The model
---------
:func:`write_case` writes the schematic estuary (the packaged case is its output): one channel from Cadzand
along the data's own course — Vlissingen, Terneuzen, Hansweert, Bath, on to Antwerp and Gent, where the
tide ends — with the gauges at the distances between the positions in the files' headers (great circles;
the fairway bends a little more). What was assumed:

- **Widths** (between the dikes, the intertidal flats included) decrease exponentially between published
  figures: 5,000 m at Vlissingen and 1,350 m at Doel (Scheldemonitor, "Morphodynamics",
  https://scheldemonitor.org/en/morphodynamics: "In Vlissingen, the river is as wide as 5000 m"; "from
  Ghent to Doel … the width of the river increases from 50 to 1350 m"), about 800 m at Antwerp (van Rijn
  2011, *Tidal phenomena in the Scheldt estuary, part 2*, Deltares 1204410-000, §1) and 50 m at Gent,
  160 km above the mouth (Scheldemonitor, *Indicators for the Scheldt estuary: safety against flooding*:
  the tide reaches the sluices of Merelbeke 160 km upstream of the mouth); 7,500 m at Cadzand by the same
  exponential. Doel and Antwerp lie at the distances of their map positions (OpenStreetMap).
- **Cross-sections**: the channels and their flats ("two to three deeper channels with shoals in between
  and tidal flats close to the banks", van Rijn 2011, §1) as one tabulated profile: 28 % of the width at
  the bed, 74 % at NAP − 2 m and the whole width at NAP + 2.5 m (mean high water), of which 80 % conveys
  and the rest (the flats) only stores.
- **Bed levels** (m NAP): 16.4 below at Cadzand, 17.6 at Vlissingen, 16.4 at Terneuzen, 15.2 at Hansweert,
  12.9 at Bath, 11.7 at Antwerp and 3.5 at Gent — not published figures: they and the shares above were
  fitted so that the model, driven by the predicted tide at Cadzand, reproduces the predicted tide of
  5 December 03:00–15:00 at the four gauges (RMSE 0.08–0.16 m; Strickler 50 m^(1/3)/s).
- **Upstream** the channel ends closed at Gent; the river discharge (about 100 m³/s) is left out.
- **Spin-up**: the case starts a day before the data, on the predicted tide at Cadzand extended backwards by
  a harmonic fit (M2, M4, M6, K1; RMSE 0.12 m over the 48 hours it is fitted to), joined to the data without a
  jump; nothing before 5 December 02:00 is scored.

The engine runs it at its own step (60 s, 500 m grid); halving both changes the levels at the gauges by
0.4–1.4 cm RMSE (4 cm at most) over the calm cycle.

What :func:`bench_westerscheldt` does
--------------------------------------
1. calibrates the global Strickler coefficient ``KS`` (DuD) on the calm tide before the storm, 5 December
   02:00–15:00, on the measured levels of Vlissingen, Terneuzen and Hansweert (Bath is held out from
   everything);
2. runs the on-line service (:class:`rivercal.online.service.OnlineService`) over the storm with state
   updating (``states``, the ensemble transform filter, 64 members), issuing forecasts of 6 h every hour
   from 5 December 12:00 to 6 December 18:00, assimilating every 10-minute reading of the three gauges and
   none of Bath. The service's filter gives the level boundary at Cadzand an additive AR(1) error
   (σ = :data:`LEVEL_ERROR_M`, the filter's correlation time), kept in the augmented state: the analyses
   estimate what the predicted tide misses (the surge) and the forecasts carry it on;
3. scores the forecasts at Bath by lead time against its measured levels at the whole hours: the service's
   forecast without assimilation (the model on the predicted tide, ``dss``) and with it (``updated``, the
   ensemble mean); and the peak of the storm at Bath, per lead: the highest level the forecasts of that
   lead reach against the highest measured (4.68 m NAP at 04:00 on 6 December), and the highest surge
   (level − tide) against the measured one (3.00 m at 23:00 on 5 December, measured − predicted tide): the
   forecast's surge is its level less the model's own tide (the same cycle's forecast without assimilation);
   ``surge_vs_model_tide_error_m`` takes the measured surge against the model's tide too, so that the
   model's tidal error at Bath cancels.
"""

from __future__ import annotations

import math
import re
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["ASSIMILATED", "CALM_WINDOW", "HELD_OUT", "LEVEL_ERROR_M", "bench_westerscheldt", "calibrate_calm",
           "case_folder", "storm_forecasts", "write_case"]

#: The gauges whose levels are assimilated (and calibrate the friction), and the one held out.
ASSIMILATED = ("vlissingen", "terneuzen", "hansweert")
HELD_OUT = "bath"
GAUGES = (*ASSIMILATED, HELD_OUT)
#: The calm tidal cycle before the storm on which the friction is calibrated (UTC).
CALM_WINDOW = ("2013-12-05T02:00:00Z", "2013-12-05T15:00:00Z")
#: Issue times of the first and the last forecast, UTC, and the forecast horizon.
FIRST_ISSUE, LAST_ISSUE, HORIZON_H = "2013-12-05T12:00:00Z", "2013-12-06T18:00:00Z", 6
#: σ of the additive error of the level boundary at Cadzand in the service's ensemble, m (a storm surge of up to
#: 3 m at Bath: the default of the service, 0.3 m, is for ordinary departures from a boundary's series).
LEVEL_ERROR_M = 0.5

# -- the schematic estuary (module docstring) -------------------------------------------------------------

#: Map positions (longitude, latitude, WGS 84) of places along the channel that are not gauges.
_DOEL, _ANTWERP = (4.2617, 51.3117), (4.3975, 51.2228)
#: Distance of the tidal limit (Gent, Merelbeke sluices) above the mouth, m.
_TIDAL_LIMIT_M = 160_000.0
#: Widths between the dikes, m, at named places (module docstring).
_WIDTHS = {"vlissingen": 5000.0, "doel": 1350.0, "antwerp": 800.0, "gent": 50.0}
#: Bed levels, m NAP, at named places (fitted; module docstring).
_BEDS = {"cadzand": -16.4, "vlissingen": -17.6, "terneuzen": -16.4, "hansweert": -15.2, "bath": -12.9,
         "antwerp": -11.7, "gent": -3.5}
#: Shares of the width: at the bed, at NAP - 2 m, and conveying at and above mean high water.
_BED_SHARE, _LOW_SHARE, _FLOW_SHARE = 0.28, 0.74, 0.80
_LOW_LEVEL, _HIGH_WATER = -2.0, 2.5
#: Constituents of the harmonic fit that extends the tide backwards for the spin-up, degrees per hour.
_SPEEDS = {"M2": 28.9841042, "M4": 57.9682084, "M6": 86.9523127, "K1": 15.0410686}
#: Strickler coefficient at which the shape was fitted, m^(1/3)/s.
_KS0 = 50.0


def case_folder() -> Path:
    """The packaged case ``westerscheldt`` (case, data and sidecar)."""
    from importlib import resources

    return Path(str(resources.files("rivercal.cases") / "westerscheldt"))


def _position(path: Path) -> tuple[float, float]:
    """(longitude, latitude) of a MATROOS file's ``Position`` header line."""
    for line in path.read_text(encoding="utf-8").splitlines():
        m = re.match(r"^#\s*Position\s*:\s*\(\s*([-\d.]+)\s*,\s*([-\d.]+)\s*\)", line)
        if m:
            return float(m.group(1)), float(m.group(2))
    raise ValueError(f"{path}: no Position line in the header")


def _great_circle_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    lon1, lat1, lon2, lat2 = (math.radians(v) for v in (*a, *b))
    h = math.sin((lat2 - lat1) / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin((lon2 - lon1) / 2) ** 2
    return 2 * 6_371_000.0 * math.asin(math.sqrt(h))


def chainages(data: Path | None = None) -> dict[str, float]:
    """Distance of each place from Cadzand along the channel, m (the chain of great circles; module docstring)."""
    data = Path(data) if data is not None else case_folder()
    pos = {"cadzand": _position(data / "tide_cadzand.txt")}
    pos.update({g: _position(data / f"waterlevel_{g}.txt") for g in GAUGES})
    pos.update({"doel": _DOEL, "antwerp": _ANTWERP})
    out, x, prev = {}, 0.0, None
    for place in ("cadzand", *GAUGES, "doel", "antwerp"):
        if prev is not None:
            x += _great_circle_m(pos[prev], pos[place])
        out[place] = round(x, 1)
        prev = place
    out["gent"] = round(out["vlissingen"] + _TIDAL_LIMIT_M, 1)
    return out


def _tide(path: Path) -> pd.Series:
    """A MATROOS file of the predicted tide, through a one-series sidecar (m NAP, UTC)."""
    from rivercal.io.sensors import SensorSpec, read_sensor_series

    spec = SensorSpec(id="tide.h", file=path.name, format="noos")
    return read_sensor_series(spec, path.parent).to_series()


def _extended_tide(tide: pd.Series, hours: float) -> tuple[pd.Series, float]:
    """The tide extended ``hours`` backwards by a harmonic fit (:data:`_SPEEDS`); and the fit's RMSE, m."""
    t = (tide.index - tide.index[0]).total_seconds().to_numpy() / 3600.0

    def basis(th: np.ndarray) -> np.ndarray:
        cols = [np.ones_like(th)]
        for speed in _SPEEDS.values():
            w = math.radians(speed)
            cols += [np.cos(w * th), np.sin(w * th)]
        return np.array(cols).T

    coef, *_ = np.linalg.lstsq(basis(t), tide.to_numpy(), rcond=None)
    rmse = float(np.sqrt(np.mean((basis(t) @ coef - tide.to_numpy()) ** 2)))
    step_s = int(np.median(np.diff(tide.index.asi8)) // 10**9)
    n = round(hours * 3600 / step_s)
    before = np.arange(-n, 0) * step_s / 3600.0
    index = tide.index[0] + pd.to_timedelta(np.arange(-n, 0) * step_s, unit="s")
    # joined without a jump: the fit's miss at the first value fades out backwards over two hours
    miss = float(tide.iloc[0] - (basis(np.zeros(1)) @ coef)[0])
    extension = basis(before) @ coef + miss * np.exp(before / 2.0)
    return pd.concat([pd.Series(extension, index=index), tide]), rmse


def write_case(out: str | Path, data: str | Path | None = None, *, dx: float = 500.0, dt: float = 60.0,
               ks: float = _KS0) -> Path:
    """Write the schematic estuary (module docstring): ``case.toml`` and ``forcing.csv`` in ``out``.

    Parameters
    ----------
    out
        The case folder (created).
    data
        The folder of the MATROOS files (default: the packaged case).
    dx, dt
        Grid spacing (m) and time step (s).
    ks
        The global Strickler coefficient, m^(1/3)/s (the case's friction and the initial value of ``KS``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = Path(data) if data is not None else case_folder()
    x = chainages(data)
    tide, _ = _extended_tide(_tide(data / "tide_cadzand.txt"), 24.0)
    frame = pd.DataFrame({"tide_cadzand": tide.round(4).to_numpy()},
                         index=pd.Index(tide.index.strftime("%Y-%m-%dT%H:%M:%SZ"), name="time"))
    frame.to_csv(out / "forcing.csv")
    anchors = [(x[p], math.log(w)) for p, w in _WIDTHS.items()]

    def width(at: float) -> float:
        (x0, l0), (x1, l1) = anchors[0], anchors[1]
        if at < x0:  # seaward of Vlissingen: the exponential of Vlissingen–Doel continued
            return math.exp(l0 + (l1 - l0) * (at - x0) / (x1 - x0))
        return math.exp(float(np.interp(at, [a for a, _ in anchors], [b for _, b in anchors])))

    def bed(at: float) -> float:
        return float(np.interp(at, [x[p] for p in _BEDS], list(_BEDS.values())))

    places = sorted({0.0, 5000.0, *(x[p] for p in (*GAUGES, "doel", "antwerp")), x["antwerp"] + 22_000.0,
                     x["antwerp"] + 52_000.0, x["gent"]})
    lines = ["# The Western Scheldt, schematic (written by rivercal.bench.westerscheldt.write_case; see README.md)",
             "[case]", 'name = "westerscheldt"',
             'description = "Schematic 1D Western Scheldt and Sea Scheldt, Cadzand to Gent, driven by the predicted '
             'tide at Cadzand; the storm surge of 5-7 December 2013 is in the measured levels only."',
             'start = "2013-12-04T00:00:00Z"', 'end = "2013-12-07T00:00:00Z"', 'vertical_datum = "NAP"', "",
             "[engine]", f"dt = {dt}", "output_interval = 600.0", "",
             "[initial]", "level = 0.0", "depth = 0.0", "",
             "[friction]", 'type = "strickler"', f"value = {ks}", ""]
    sections = []
    for i, at in enumerate(places):
        b, zb = width(at), bed(at)
        high = _HIGH_WATER - zb
        heights = [0.0, _LOW_LEVEL - zb, high, high + 6.0]
        total = [_BED_SHARE * b, _LOW_SHARE * b, b, 1.1 * b]
        flow = [_BED_SHARE * b, _LOW_SHARE * b, _FLOW_SHARE * b, _FLOW_SHARE * 1.05 * b]
        pid = f"P{i:02d}"
        lines += ["[[profiles]]", f'id = "{pid}"', 'type = "zw"', f"heights = {_list(heights, 3)}",
                  f"flow_widths = {_list(flow, 1)}", f"total_widths = {_list(total, 1)}", ""]
        sections.append(f'  {{ chainage = {at:.1f}, profile = "{pid}", bed_level = {zb:.3f} }},')
    lines += ["[[nodes]]", 'id = "mouth"', "", "[[nodes]]", 'id = "gent"', "",
              "[[branches]]", 'id = "scheldt"', 'from_node = "mouth"', 'to_node = "gent"',
              f"length = {x['gent']:.1f}", f"dx = {dx}", "cross_sections = [", *sections, "]", "",
              "[[boundaries]]", 'id = "cadzand"', 'node = "mouth"', 'type = "level"',
              'series = { file = "forcing.csv", column = "tide_cadzand" }', ""]
    for place in GAUGES:  # none at Cadzand: its level is the boundary's (and a station there is never observed)
        lines += ["[[stations]]", f'id = "{place}"', 'branch = "scheldt"', f"chainage = {x[place]:.1f}", ""]
    lines += ["[[parameters]]", 'name = "KS"', 'targets = ["friction:global"]', "min = 15.0", "max = 100.0",
              f"initial = {ks}", 'transform = "offset"', "perturbation = 5.0", 'unit = "m^(1/3)/s"', "",
              "[[windows]]", 'name = "calm"', f'start = "{CALM_WINDOW[0]}"', f'end = "{CALM_WINDOW[1]}"',
              'description = "The calm tide before the storm (the friction is calibrated on it)."', ""]
    (out / "case.toml").write_text("\n".join(lines), encoding="utf-8")
    return out


def _list(values: list[float], digits: int) -> str:
    return "[" + ", ".join(f"{float(v):.{digits}f}" for v in values) + "]"


# -- the calm cycle ---------------------------------------------------------------------------------------


def _observations(ids: tuple[str, ...]) -> Any:
    from rivercal.io import read_sidecar

    return read_sidecar(case_folder() / "gauges.toml").select([f"{g}.h" for g in ids])


def calibrate_calm(model: Any, *, algorithm: str = "dud") -> dict[str, Any]:
    """Calibrate ``KS`` on the calm tide (:data:`CALM_WINDOW`) at the assimilated gauges; RMSE per gauge (m).

    Returns ``{"ks", "ks_std", "model_runs", "message", "rmse_m": {gauge: before/after}, "bias_m"}``; Bath is
    scored, never fitted.
    """
    from rivercal.parameters import ParameterSet
    from rivercal.problem import CalibrationProblem, calibrate

    params = ParameterSet([p for p in model.calibration.parameters if p.name == "KS"])
    window = (pd.Timestamp(CALM_WINDOW[0]), pd.Timestamp(CALM_WINDOW[1]))
    problem = CalibrationProblem(model, params, _observations(ASSIMILATED), window,
                                 warmup=window[0] - pd.Timestamp(model.start))
    cal = calibrate(problem, algorithm)
    all_obs = _observations(GAUGES)
    scores: dict[str, dict[str, float]] = {"rmse_m": {}, "bias_m": {}}
    for label, ks in (("initial", _KS0), ("calibrated", cal.estimates["KS"])):
        result, _ = model.simulate(params.quantities({"KS": ks}), start=model.start, end=model.end)
        for g in GAUGES:
            o = all_obs[f"{g}.h"].within(*window).to_series()
            err = result.series[f"{g}.h"].reindex(o.index) - o
            scores["rmse_m"].setdefault(g, {})[label] = round(float(np.sqrt(np.mean(err**2))), 4)
            scores["bias_m"].setdefault(g, {})[label] = round(float(err.mean()), 4)
    std = getattr(cal.result, "std", None)
    return {"ks": round(float(cal.estimates["KS"]), 3),
            "ks_std": None if std is None else round(float(np.ravel(std)[0]), 3),
            "model_runs": int(cal.result.nfev), "message": cal.result.message, **scores}


# -- the storm --------------------------------------------------------------------------------------------


@dataclass
class StormRun:
    """The forecasts of one run of the service over the storm (:func:`storm_forecasts`).

    Attributes
    ----------
    forecasts
        Long table of the stored forecasts (cycle, kind, series, lead_h, time, value; m NAP).
    analyses
        State analyses per cycle.
    wall_s
        Wall time, s.
    forcing_tau
        Correlation time of the ensemble's boundary errors.
    """

    forecasts: pd.DataFrame
    analyses: list[int]
    wall_s: float
    forcing_tau: str = ""


def storm_forecasts(model: Any, *, members: int = 64, seed: int = 0, folder: Path | None = None,
                    level_error: float = LEVEL_ERROR_M, options: dict[str, Any] | None = None) -> StormRun:
    """Run the on-line service with ``states`` over the storm, assimilating :data:`ASSIMILATED` (module docstring).

    Parameters
    ----------
    model
        The case's model with its calibrated friction (the DSS: the model as it is).
    members, seed
        Ensemble size and seed.
    folder
        Where the store goes (default: a temporary folder, removed).
    level_error
        σ of the level boundary's additive error in the ensemble, m.
    options
        Further settings of :class:`~rivercal.online.assimilation.AssimilationConfig` (e.g. ``interval``).
    """
    from rivercal.online.assimilation import AssimilationConfig
    from rivercal.online.service import OnlineConfig, OnlineService
    from rivercal.store import Store

    series = tuple(f"{g}.h" for g in GAUGES)
    config = OnlineConfig(parameters=("KS",), window="6h", period="1h", horizon=f"{HORIZON_H}h", warmup="6h",
                          skill_cycles=0, series=series, deadline_s=None)
    assimilation = AssimilationConfig(mode="states", members=members, seed=seed, level_error=level_error,
                                      **(options or {}))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="westerscheldt-") as tmp:
        where = Path(folder) if folder is not None else Path(tmp)
        where.mkdir(parents=True, exist_ok=True)
        db = where / "storm.sqlite"
        for suffix in ("", "-wal", "-shm"):
            Path(f"{db}{suffix}").unlink(missing_ok=True)
        with Store(db) as store:
            service = OnlineService(model, store, "storm", config, pd.Timestamp(FIRST_ISSUE), assimilation=assimilation)
            store.ingest(_observations(ASSIMILATED), source="gauges")  # Bath is never stored: held out
            outcomes = service.replay(pd.Timestamp(LAST_ISSUE))
            forecasts = store.forecasts(service.run)
    analyses = [int(m.group(1)) for o in outcomes for m in [re.search(r"(\d+) state analyses", o.message)] if m]
    return StormRun(forecasts=forecasts, analyses=analyses, wall_s=time.perf_counter() - t0,
                    forcing_tau=assimilation.forcing_tau)


def _bath_scores(run: StormRun, measured: pd.Series, astro: pd.Series) -> dict[str, Any]:
    """RMSE and bias at Bath by lead (m) of both kinds, and the peaks (module docstring)."""
    fc = run.forecasts[run.forecasts["series"] == f"{HELD_OUT}.h"].copy()
    times = pd.DatetimeIndex(fc["time"])
    fc["measured"] = measured.reindex(times).to_numpy()
    fc["astro"] = astro.reindex(times).to_numpy()
    fc = fc.dropna(subset=["measured"])
    out: dict[str, Any] = {}
    for kind in ("dss", "updated"):
        part = fc[fc["kind"] == kind]
        err = part["value"] - part["measured"]
        by = err.groupby(part["lead_h"])
        out[kind] = {"rmse_m": [round(float(np.sqrt(np.mean(by.get_group(h) ** 2))), 4) for h in _LEADS],
                     "bias_m": [round(float(by.get_group(h).mean()), 4) for h in _LEADS],
                     "n": [int(by.get_group(h).size) for h in _LEADS]}
    # peaks: the highest level, and the highest surge (level − tide), over the valid times of each lead
    hourly = fc.drop_duplicates("time").set_index("time")
    peak_level = float(hourly["measured"].max())
    peak_surge = float((hourly["measured"] - hourly["astro"]).max())
    wide = fc.pivot_table(index=["cycle", "time", "lead_h"], columns="kind", values="value").reset_index()
    peaks = {"measured_level_m": round(peak_level, 3), "measured_level_time": str(hourly["measured"].idxmax()),
             "measured_surge_m": round(peak_surge, 3),
             "measured_surge_time": str((hourly["measured"] - hourly["astro"]).idxmax()),
             "level_error_m": {}, "surge_error_m": {}, "surge_vs_model_tide_error_m": {}, "level_error_without_m": {}}
    for h in _LEADS:
        w = wide[wide["lead_h"] == h]
        if "updated" in w:
            peaks["level_error_m"][f"{h}h"] = round(float(w["updated"].max()) - peak_level, 3)
            # the forecast's surge: its level less the model's own tide (the same cycle's forecast without updating)
            peaks["surge_error_m"][f"{h}h"] = round(float((w["updated"] - w["dss"]).max()) - peak_surge, 3)
            # both surges against the model's own tide (its error at Bath then cancels)
            measured_h = measured.reindex(pd.DatetimeIndex(w["time"])).to_numpy()
            peaks["surge_vs_model_tide_error_m"][f"{h}h"] = round(
                float((w["updated"] - w["dss"]).max()) - float(np.nanmax(measured_h - w["dss"].to_numpy())), 3)
        peaks["level_error_without_m"][f"{h}h"] = round(float(w["dss"].max()) - peak_level, 3)
    out["peak"] = peaks
    return out


_LEADS = tuple(range(1, HORIZON_H + 1))


def bench_westerscheldt(*, members: int = 64, seed: int = 0, out: str | Path | None = None) -> dict[str, Any]:
    """The whole benchmark (module docstring): JSON-ready errors at Bath by lead, with and without assimilation.

    Parameters
    ----------
    members, seed
        Ensemble size and seed of the state updating.
    out
        Keep the stores (and ``bath_forecasts.csv``) here (default: nothing kept).
    """
    from rivercal.models import load_model

    t0 = time.perf_counter()
    calm = calibrate_calm(load_model(case_folder()))
    folder = Path(out) if out is not None else None
    with tempfile.TemporaryDirectory(prefix="westerscheldt-case-") as tmp:
        # the DSS: the model with the friction of the calm tide (its own friction and KS's initial value)
        model = load_model(write_case(Path(tmp), ks=calm["ks"]))
        fixed = storm_forecasts(model, members=members, seed=seed, folder=folder)
    measured = _observations((HELD_OUT,))[f"{HELD_OUT}.h"].to_series()
    astro = _tide(case_folder() / f"tide_{HELD_OUT}.txt")
    scores = _bath_scores(fixed, measured, astro)
    without, with_ = scores["dss"]["rmse_m"], scores["updated"]["rmse_m"]
    ratio = [round(w / wo, 4) for w, wo in zip(with_, without, strict=True)]
    first3 = float(np.mean(with_[:3])) / float(np.mean(without[:3]))
    if folder is not None:
        fixed.forecasts.to_csv(folder / "forecasts.csv", index=False)
    return {
        "case": "westerscheldt",
        "held_out": HELD_OUT,
        "assimilated": list(ASSIMILATED),
        "issues": f"{FIRST_ISSUE} .. {LAST_ISSUE}, every hour",
        "lead_h": list(_LEADS),
        "bath_rmse_without_m": without,
        "bath_rmse_with_m": with_,
        "ratio_with_to_without": ratio,
        "ratio_leads_1_3": round(first3, 4),
        "bath_bias_without_m": scores["dss"]["bias_m"],
        "bath_bias_with_m": scores["updated"]["bias_m"],
        "forecasts_per_lead": scores["updated"]["n"],
        "surge_peak": scores["peak"],
        "calibration": {"window": list(CALM_WINDOW), "parameter": "KS (global Strickler, m^(1/3)/s)", **calm},
        "assimilation": {"mode": "states", "filter": "etkf", "members": members, "analysis_interval": "1h",
                         "level_boundary_error_m": LEVEL_ERROR_M, "forcing_tau": fixed.forcing_tau,
                         "analyses_per_cycle": sorted(set(fixed.analyses)), "wall_s": round(fixed.wall_s, 1)},
        "workarounds": [],
        "wall_s": round(time.perf_counter() - t0, 1),
    }
