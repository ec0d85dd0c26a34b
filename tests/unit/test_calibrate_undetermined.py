"""A calibration says which parameters the window could not determine, whatever the optimiser's stopping rule."""

from __future__ import annotations

import math

from rivercal.parameters import Parameter, ParameterSet
from rivercal.workflows.calibrate import undetermined


def test_a_parameter_whose_sigma_is_wider_than_its_range_is_named_with_why() -> None:
    # the D-HYDRO steady-state model c01 observes discharges only, which its discharge boundaries set: a twin of
    # a branch's Chézy value 'converged' at its start value with σ 1.7e11 m^(1/2)/s
    pset = ParameterSet([
        Parameter(name="F_T1", targets=["friction:branch:T1"], min=22.5, max=112.5, initial=45, perturbation=4.5),
        Parameter(name="F_T2", targets=["friction:branch:T2"], min=22.5, max=112.5, initial=45, perturbation=4.5),
        Parameter(name="F_T3", targets=["friction:branch:T3"], min=22.5, max=112.5, initial=45, perturbation=4.5),
        Parameter(name="F_T4", targets=["friction:branch:T4"], min=22.5, max=112.5, initial=45, perturbation=4.5)])
    found = undetermined(pset, {"F_T1": 1.7e11, "F_T2": 0.054, "F_T3": math.inf})  # F_T4: no σ from this method
    assert set(found) == {"F_T1", "F_T3"}
    assert found["F_T1"] == ("σ 1.7e+11 is wider than its whole range 22.5 .. 112.5: the observations in this window "
                             "hardly depend on it, so its estimate says little")
    assert found["F_T3"].startswith("σ infinite is wider")
    assert undetermined(pset, {"F_T1": 89.9}) == {}   # just inside its range of 90
