"""Guardrails in the parameters' own units: a Manning n on a log scale, resolutions per friction law, data alerts.

The identifiability gate scales the optimiser's Jacobian — with respect to ln n for a ``transform = "ln"``
parameter — by each parameter's resolution; the resolution is physical (0.0005 s/m^(1/3)), so it must be
converted to a step in ln n first. The reference is the calibration's own σ of n (from the same Jacobian, in
physical units): a parameter whose σ is well below its resolution is one the window sees, and the gate must
accept it, whatever its transform.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from rivercal.analysis.identifiability import fd_jacobian
from rivercal.models import load_model
from rivercal.observations import ObservationSeries, ObservationSet
from rivercal.online.config import DEFAULT_RESOLUTION, default_resolution
from rivercal.online.guardrails import data_alerts, gate, optimiser_resolution
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem
from rivercal.store import Store

START = pd.Timestamp("2020-01-04T00:00Z")
WINDOW = (START, START + pd.Timedelta("2D"))


def _manning(transform: str) -> Parameter:
    return Parameter(name="nB", targets=["friction:branch:B"], min=0.02, max=0.08, initial=0.04,
                     perturbation=0.1 if transform == "ln" else 0.004, transform=transform, unit="s/m^(1/3)")


@pytest.fixture(scope="module")
def problems():
    model = load_model("synthetic")
    truth, _ = model.simulate({"friction:branch:B": 0.04}, start=WINDOW[0] - pd.Timedelta("1D"), end=WINDOW[1])
    levels = [c for c in truth.series.columns if c.rpartition(".")[2] in ("h", "h_up", "h_down")]
    obs = ObservationSet(tuple(ObservationSeries.from_series(truth.series[c], id=c, sigma=0.01, source="truth")
                               for c in levels))
    return {t: CalibrationProblem(model, ParameterSet([_manning(t)]), obs, WINDOW, warmup="12h")
            for t in ("ln", "offset")}


def test_a_log_manning_n_whose_sigma_is_below_its_resolution_is_accepted(problems) -> None:
    problem = problems["ln"]
    p = problem.parameters["nB"]
    resolution = default_resolution(p)
    assert resolution == pytest.approx(0.0005)
    x = np.array([np.log(0.04)])
    jac = fd_jacobian(problem, x, workers=1).matrix                       # d r / d ln n
    sigma_n = 0.04 * float(np.sqrt(np.linalg.inv(jac.T @ jac))[0, 0])     # σ of n, s/m^(1/3)
    assert sigma_n < 0.5 * resolution                                      # the window sees n to its resolution
    held, _ = gate(problem, SimpleNamespace(x=x, jac=jac), {"nB": resolution}, {"nB": p.unit}, gate_sv=1.0,
                   gate_index=0.5, algorithm="dud", workers=1)
    assert held == {}
    # what the gate measures is the cost of a move by the resolution, whatever the transform: the scaled
    # Jacobian of ln n equals that of n itself (offset), to the finite differences' accuracy
    plain = problems["offset"]
    jac_n = fd_jacobian(plain, np.array([0.04]), workers=1).matrix
    scaled_ln = np.linalg.norm(jac * optimiser_resolution(problem.parameters, x, {"nB": resolution}))
    scaled_n = np.linalg.norm(jac_n * optimiser_resolution(plain.parameters, np.array([0.04]), {"nB": resolution}))
    assert scaled_ln == pytest.approx(scaled_n, rel=0.05)
    assert scaled_ln > 1.0


def test_the_resolution_of_each_friction_law() -> None:
    def friction(unit: str, initial: float, targets=("friction:global",)) -> Parameter:
        return Parameter(name="f", targets=list(targets), min=initial / 10, max=initial * 10, initial=initial,
                         perturbation=initial / 10, unit=unit)

    assert default_resolution(friction("m^(1/3)/s", 30.0)) == 0.5              # Strickler
    assert default_resolution(friction("s/m^(1/3)", 0.033)) == 0.0005          # Manning: 1.5 % of n = 1/30
    assert default_resolution(friction("m^(1/2)/s", 40.0)) == 0.5              # Chézy
    wc = default_resolution(friction("m", 0.2))                                # White-Colebrook k_n, relative
    assert wc == pytest.approx(0.016)
    # the same share of the conveyance as Strickler's 0.5 of 30: C = 18 log10(12 R / k_n) at R = 2 m
    c = lambda k: 18 * np.log10(12 * 2.0 / k)  # noqa: E731
    assert abs(c(0.2 + wc) - c(0.2)) / c(0.2) == pytest.approx(0.5 / 30, rel=0.25)
    crest = Parameter(name="W", targets=["weir:W1.crest_level"], min=9, max=11, initial=10, perturbation=0.05,
                      unit="m")
    assert default_resolution(crest) == DEFAULT_RESOLUTION["m"] == 0.01      # a crest in m stays 1 cm


def test_a_declared_series_that_is_never_observed_is_named_once(tmp_path) -> None:
    times = pd.date_range("2021-01-01", periods=49, freq="h", tz="UTC")
    h = ObservationSeries.from_series(pd.Series(1.0, index=times), id="G.h", sigma=0.01, source="gauge")
    with Store(tmp_path / "s.sqlite") as store:
        store.ingest(ObservationSet((h,)), source="gauge")
        window = store.observations(["G.h", "G.Q"], times[0], times[-1])
        first = data_alerts(window, "48h", 3600.0, 0.5, store=store, first=True)
        later = data_alerts(window, "48h", 3600.0, 0.5, store=store, first=False)
        assert len(first) == 1 and "G.Q" in first[0].message and "G.h" not in first[0].message
        assert later == []
        # a gauge that is observed elsewhere in time but silent in this window is still thin, every cycle
        silent = store.observations(["G.h"], times[-1] + pd.Timedelta("1D"), times[-1] + pd.Timedelta("3D"))
        alerts = data_alerts(silent, "48h", 3600.0, 0.5, store=store, first=False)
        assert len(alerts) == 1 and "G.h (0%)" in alerts[0].message
        # an imported model follows every structure's series, of which a few are gauged: the alert says so first
        many = store.observations(["G.h", *(f"S{k}.h_up" for k in range(9))], times[0], times[-1])
        (alert,) = data_alerts(many, "48h", 3600.0, 0.5, store=store, first=True)
        assert alert.message.startswith("readings of 1 of the 10 series the run follows are stored; none of the "
                                        "other 9 (S0.h_up, S1.h_up, ")
        assert "and 1 more series): they are left out of the calibration" in alert.message


def test_alerts_put_a_unit_after_a_value_and_none_after_a_dimensionless_one() -> None:
    # an imported SOBEK 3 model's friction factor F_scale has unit "-": "from 1 to 1.2 (+0.2 ...", not "1.2 - (+0.2"
    from rivercal.online.guardrails import jump_alert, limit_alerts
    from rivercal.store import CycleSpec

    spec = CycleSpec(3, START, START + pd.Timedelta("2D"), START + pd.Timedelta("2D"))
    jump = jump_alert("F_scale", "-", 1.0, 1.2, 5.0, spec, "found")
    assert jump.message.startswith("F_scale changed from 1 to 1.2 (+0.2, 5 σ) found in the window")
    assert jump_alert("FA", "m^(1/3)/s", 16, 25, 5.0, spec, "found").message.startswith(
        "FA changed from 16 to 25 m^(1/3)/s (+9, 5 σ)")
    scale = Parameter(name="F_scale", targets=["friction:scale"], min=0.5, max=2.0, initial=1.0, perturbation=0.1,
                      unit="-")
    (limit,) = limit_alerts([scale], {"F_scale": 1.0}, {"F_scale": 1.1}, {"F_scale": 0.1})
    assert limit.message.startswith("F_scale stopped at the per-cycle change bound ±0.1; the true change")
