"""Twin on the SWMM case: DuD finds a roughness factor and a common crest shift back through EPA SWMM.

The truth (FR = 1, Wd = -5 cm) makes the observations with SWMM itself (hourly levels and the discharge
at the five stations) over one day, 28 September 2010, after a day's warm-up; DuD starts 30 % and 20 cm away.
(a) runs SWMM in process through the SWMM adapter; (b) runs SWMM's command-line runner as an external program
on a template of the same input file through the black box. Both must find the truth within 1 % and 1 mm and
agree within 0.1 % and 0.1 mm (SWMM's binary output holds single precision). Over three days instead of one,
both took the same 12 and 10 runs to the same estimates (to 1e-5), each run twice as long.
"""

from __future__ import annotations

import logging

import pandas as pd
import pytest

from rivercal.models import load_model
from rivercal.models.swmm.template import blackbox_files
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth

pytestmark = pytest.mark.slow
log = logging.getLogger(__name__)

TRUTH = {"FR": 1.0, "Wd": -0.05}
START = {"FR": 1.3, "Wd": 0.15}
WINDOW = (pd.Timestamp("2010-09-28", tz="UTC"), pd.Timestamp("2010-09-29", tz="UTC"))


def test_dud_finds_roughness_and_crest_shift_through_the_swmm_adapter_and_the_black_box(tmp_path) -> None:
    swmm = load_model("dommel-swmm")
    pset = ParameterSet([swmm.calibration.parameter("FR"), swmm.calibration.parameter("Wd")])
    truth = twin_truth(swmm, pset.quantities(TRUTH), WINDOW, warmup=pd.Timedelta("24h"))
    options = swmm.calibration.options

    # (a) the SWMM adapter
    problem_a = CalibrationProblem(swmm, pset.with_initial(START), truth.observations, WINDOW, state=truth.state,
                                   warmup="24h")
    a = calibrate(problem_a, "dud", options, workers=1)

    # (b) the black box: SWMM's command-line runner on a template of the same .inp
    weirs = [c.target[len("weir:"):-len(".crest_level")] for c in pset["Wd"].cluster]
    toml = blackbox_files(tmp_path / "bb", swmm.inp_path, swmm.stations, name="dommel-swmm-blackbox",
                          start=swmm.start.isoformat(), end=swmm.end.isoformat(), spinup=swmm.spinup, weirs=weirs)
    box = load_model(toml)
    box_params = ParameterSet([pset["FR"].model_copy(update={"targets": ["FR"]}),
                               Parameter(name="Wd", targets=["Wd"], min=-0.3, max=0.3, initial=0.0,
                                         perturbation=0.05, unit="m")])
    _, box_state = box.simulate(TRUTH, end=WINDOW[0] - pd.Timedelta("24h"))
    problem_b = CalibrationProblem(box, box_params.with_initial(START), truth.observations, WINDOW, state=box_state,
                                   warmup="24h")
    b = calibrate(problem_b, "dud", options, workers=1)

    for cal in (a, b):
        assert cal.result.success, cal.result.message
        assert abs(cal.estimates["FR"] / TRUTH["FR"] - 1.0) < 0.01
        assert abs(cal.estimates["Wd"] - TRUTH["Wd"]) < 0.001
    assert abs(a.estimates["FR"] / b.estimates["FR"] - 1.0) < 0.001
    assert abs(a.estimates["Wd"] - b.estimates["Wd"]) < 0.0001
    log.warning("SWMM twin: adapter %d runs %.1f s; black box %d runs %.1f s; FR %.5f / %.5f, Wd %.5f / %.5f m",
                a.result.nfev, a.wall_time, b.result.nfev, b.wall_time, a.estimates["FR"], b.estimates["FR"],
                a.estimates["Wd"], b.estimates["Wd"])
