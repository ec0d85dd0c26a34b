"""The SWMM twin of the closing note: roughness factor and crest shift through the adapter and the black box.

Usage: ``python benchmarks/swmm_twin.py`` prints one JSON line per path (estimates, model runs, wall time);
the same experiment as ``tests/verification/test_swmm_twin.py`` (truth FR = 1, Wd = -5 cm; start FR = 1.3,
Wd = +15 cm; window 2010-09-28 .. 2010-10-01 with 24 h warm-up; DuD with the case's stopping rules).
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pandas as pd

from rivercal.models import load_model
from rivercal.models.swmm.template import blackbox_files
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth

TRUTH = {"FR": 1.0, "Wd": -0.05}
START = {"FR": 1.3, "Wd": 0.15}
WINDOW = (pd.Timestamp("2010-09-28", tz="UTC"), pd.Timestamp("2010-10-01", tz="UTC"))


def main() -> None:
    swmm = load_model("dommel-swmm")
    pset = ParameterSet([swmm.calibration.parameter("FR"), swmm.calibration.parameter("Wd")])
    truth = twin_truth(swmm, pset.quantities(TRUTH), WINDOW, warmup=pd.Timedelta("24h"))
    problem = CalibrationProblem(swmm, pset.with_initial(START), truth.observations, WINDOW, state=truth.state,
                                 warmup="24h")
    runs = {"adapter": calibrate(problem, "dud", swmm.calibration.options, workers=1)}
    with tempfile.TemporaryDirectory() as tmp:
        weirs = [c.target[len("weir:"):-len(".crest_level")] for c in pset["Wd"].cluster]
        box = load_model(blackbox_files(Path(tmp), swmm.inp_path, swmm.stations, name="dommel-swmm-blackbox",
                                        start=swmm.start.isoformat(), end=swmm.end.isoformat(), spinup=swmm.spinup,
                                        weirs=weirs))
        params = ParameterSet([pset["FR"].model_copy(update={"targets": ["FR"]}),
                               Parameter(name="Wd", targets=["Wd"], min=-0.3, max=0.3, initial=0.0,
                                         perturbation=0.05, unit="m")])
        _, state = box.simulate(TRUTH, end=WINDOW[0] - pd.Timedelta("24h"))
        problem = CalibrationProblem(box, params.with_initial(START), truth.observations, WINDOW, state=state,
                                     warmup="24h")
        runs["blackbox"] = calibrate(problem, "dud", swmm.calibration.options, workers=1)
    for name, cal in runs.items():
        print(json.dumps({"path": name, "FR": cal.estimates["FR"], "Wd_m": cal.estimates["Wd"],
                          "model_runs": cal.result.nfev, "iterations": cal.result.nit,
                          "wall_s": round(cal.wall_time, 2), "message": cal.result.message}))


if __name__ == "__main__":
    main()
