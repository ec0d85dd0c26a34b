"""Calibration on an imported model: Dellen's friction found back by DuD.

The imported D-HYDRO model Dellen (../shared/data) with its roughness scaled by a factor 1.2 (every friction
group's coefficient: k_s × 1.2, n / 1.2) is the truth; its levels at the 21 observation points over one day,
with the reference study's sensor noise (uniform within ±2.5 cm), are the observations. DuD, started from the
model as imported (factor 1), must stop by its own rules with the truth inside the uncertainty it states
(two standard deviations of thesis Eq. 2-12), and that uncertainty must be smaller than the change it finds.
Dellen's levels are held by its weirs: a 20 % change of roughness moves them by about a millimetre on average
against noise of ±2.5 cm, so one day of these gauges knows the factor to about 10 % (σ = 0.12 for this noise
draw, seed 1; the estimate 1.23); what the test proves is that DuD converges on an imported model and says
honestly how well the data pin the parameter, not that they pin it to a percent. Each run starts 12 h before
the window from the truth's state (the model's first two days, its recession from the initial levels, are by
far its slowest to simulate: a day's warm-up cost 3/4 of every run). (Without noise, DuD would chase
differences below a millimetre that the engine's step control makes between neighbouring parameter values,
and end on its iteration limit: no gauge resolves them.)
"""

from __future__ import annotations

import pandas as pd
import pytest

from rivercal.model import load_model
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth
from tests.run_artefacts import dellen

TRUTH = 1.2


@pytest.mark.slow
def test_dud_recovers_a_scaled_roughness_of_dellen(tmp_path) -> None:
    sim = load_model(dellen(tmp_path / "case"))  # imported with its two exchange files, once in the run
    params = ParameterSet([Parameter(name="FS", targets=["friction:scale"], min=0.5, max=2.0, initial=1.0,
                                     transform="factor", perturbation=0.1)])
    window = (sim.start + pd.Timedelta("2D"), sim.start + pd.Timedelta("3D"))
    observed = [s for s in sim.observables if s.startswith("ObservationPoint_") and s.endswith(".h")]
    assert len(observed) == 21
    truth = twin_truth(sim, params.quantities({"FS": TRUTH}), window, warmup="12h", series=observed, noise="white",
                       seed=1)
    problem = CalibrationProblem(sim, params, truth.observations, window, state=truth.state, warmup="12h")
    fit = calibrate(problem, "dud", {"max_outer": 15}, workers=1)
    assert fit.result.success, fit.result.message
    sigma = fit.std["FS"]
    assert abs(fit.estimates["FS"] - TRUTH) <= 2.0 * sigma, (fit.estimates, fit.std)
    assert sigma < TRUTH - 1.0  # the data resolve a change of this size (here by about 1.7 σ)
