"""State updating in the on-line service: a twin on the default case whose laterals are wrong by ~30 %.

The truth runs the dommel case with its inflows and laterals multiplied by AR(1) factors; the service's
model keeps the case's forcing. With ``states`` the ensemble filter alone corrects the state: its
analysed levels at the issue time must be closer to the truth than the model that is not updated, the
members must be kept in the store and the next cycle must continue from them (hot start).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.model import load_model
from rivercal.observations import measurable
from rivercal.online.assimilation import AssimilationConfig
from rivercal.online.metrics import mae_by_lead
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.store import Store
from rivercal.twin.forcing_error import rain_error_model
from rivercal.twin.practical import practical_truth


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    model = load_model("dommel")
    first = pd.Timestamp("2010-10-18", tz="UTC")
    config = OnlineConfig(window="2D", warmup="12h", horizon="12h")
    db = tmp_path_factory.mktemp("enkf") / "run.sqlite"
    store = Store(db)
    assim = AssimilationConfig(mode="states", members=16, localisation_m=20_000.0, seed=3)
    service = OnlineService(model, store, "twin", config, first, assimilation=assim)
    period = service.data_period(first + pd.Timedelta("1D"))
    truth = practical_truth(rain_error_model(model, 0.3, seed=5), "PI-0", *period, noise="gaussian", seed=5,
                            series=service.series)
    store.ingest(truth.observations, source="twin")
    stages: list[str] = []  # what a cycle says it does now (the command line's progress display)
    service.on_stage = stages.append
    outcomes = service.replay(first + pd.Timedelta("1D"))
    service.stages = stages  # for the test of what the cycles said
    yield store, service, truth, outcomes
    store.close()


def test_a_cycle_says_what_it_does_interval_by_interval(twin):
    # states only: no parameter estimate; cycle 0 starts its members at the warm-up's start (2.5 days before its
    # issue time: 60 hourly intervals), cycle 1 continues from cycle 0's members at its issue time (24)
    stages = twin[1].stages
    for cycle, day, count in ((0, "10-18", 60), (1, "10-19", 24)):
        head = f"cycle {cycle} 2010-{day} 00:00: "
        mine = [s.removeprefix(head) for s in stages if s.startswith(head)]
        assert mine == ["forecasting", *(f"16 members, interval {k}/{count}" for k in range(1, count + 1)),
                        "16 members' forecasts"]


@pytest.mark.slow  # the module's twin: about 12 s, 16 members over two cycles
def test_the_analysed_ensemble_is_closer_to_the_truth_than_the_model_without_updating(twin):
    store, service, truth, outcomes = twin
    assert [o.status for o in outcomes] == ["done", "done"]
    mae = mae_by_lead(store, service.run, service.series, truth.series)
    assert mae["against"] == "truth"
    # the DSS runs the same parameters without state updating: the analysis must beat it clearly early on
    assert mae["updated"]["0-6h"] < 0.85 * mae["dss"]["0-6h"], mae
    fc = store.forecasts(service.run, kind="updated")
    lead0 = fc[fc["lead_h"] == 0]
    dss0 = store.forecasts(service.run, kind="dss")
    dss0 = dss0[dss0["lead_h"] == 0]
    t = truth.series.rename_axis("time").reset_index().melt(id_vars="time", var_name="series", value_name="truth")
    err = lambda f: (f.merge(t, on=["series", "time"]).eval("value - truth").abs().mean())  # noqa: E731
    assert err(lead0) < 0.6 * err(dss0)   # measured: 0.38 cm against 0.74 cm


@pytest.mark.slow  # the module's twin: about 12 s, 16 members over two cycles
def test_members_are_stored_and_the_next_cycle_continues_from_them(twin):
    store, service, _, outcomes = twin
    assert "2 days 12 hours" not in outcomes[1].message
    assert outcomes[0].message.count("state analyses") == 1
    first_analyses = int(outcomes[0].message.split(" state analyses")[0].rsplit("; ", 1)[1])
    second_analyses = int(outcomes[1].message.split(" state analyses")[0].rsplit("; ", 1)[1])
    assert first_analyses == 60          # cold: from the window's warm-up start (t0 - 2.5 d), hourly
    assert second_analyses == 24         # hot: from the previous issue time
    when, cycle, n, _, data = store.ensemble(service.run)   # one ensemble per run: the last cycle's
    assert (when, cycle, n) == (outcomes[1].issue_time, 1, 16) and len(data) > 0
    assert store.model_state(service.run, "ensemble:0") is None   # no longer one model state per member
    members, errors = service.filter.from_store(store, service.run, outcomes[1].issue_time)
    assert len(members) == 16 and errors.shape == (16, service.filter.n_forcing)
    spread = np.std([m.z for m in members], axis=0)
    assert spread.max() > 0.0            # the members differ
    # the bands stored with each cycle are the ensemble forecast's
    stored = store.forecast_bands(service.run, cycle=1).pivot(index="time", columns="series", values="low")
    b = outcomes[1].bands
    assert np.allclose(stored.to_numpy(), b.low.loc[stored.index, stored.columns].to_numpy())


@pytest.mark.slow  # the module's twin: about 12 s, 16 members over two cycles
def test_the_90_percent_band_brackets_the_mean(twin):
    _, _, _, outcomes = twin
    b = outcomes[-1].bands
    assert (b.low.to_numpy() <= b.mean.to_numpy()).all() and (b.mean.to_numpy() <= b.high.to_numpy()).all()
    levels = [c for c in b.mean.columns if c.rpartition(".")[2] in ("h", "h_up", "h_down")]
    # at least the observation error's 90 % interval, 2 × 1.645 × 2.5 cm (sampled: 2048 draws, 5 % slack)
    assert (b.high[levels] - b.low[levels]).to_numpy().min() > 0.95 * 2 * 1.645 * 0.025


def test_state_updating_refuses_a_bad_configuration():
    with pytest.raises(ValueError, match="assimilate mode must be one of"):
        AssimilationConfig(mode="everything")
    with pytest.raises(ValueError, match="members must be between"):
        AssimilationConfig(mode="both", members=1)


def _states_twin(model, truth_model, tmp_path, *, members: int, first: str, series=None, name="run") -> tuple:
    """One cycle of state updating alone on ``model``, observing ``truth_model`` (a truth with wrong rain)."""
    first_issue = pd.Timestamp(first, tz="UTC")
    config = OnlineConfig(parameters=tuple(model.calibration.names[:1]), window="1D", warmup="12h", horizon="6h",
                          workers=1, series=series)
    store = Store(tmp_path / f"{name}.sqlite")
    service = OnlineService(model, store, "twin", config, first_issue,
                            assimilation=AssimilationConfig(mode="states", members=members, seed=3))
    truth = practical_truth(truth_model, "PI-0", *service.data_period(first_issue), noise="gaussian", seed=5,
                            series=service.series)
    store.ingest(truth.observations, source="twin")
    outcome = service.replay(first_issue)
    service.close()
    return store, service, truth, outcome


@pytest.mark.slow  # about 20 s: 8 members × 42 one-hour SWMM runs, one after another
def test_state_updating_corrects_a_swmm_model_through_its_hotstart_file(tmp_path):
    """SWMM: the members' states are hotstart files, their analysed heads written back into them."""
    model = load_model("dommel-swmm")
    store, service, truth, (outcome,) = _states_twin(model, rain_error_model(model, 0.3, seed=5), tmp_path,
                                                     members=8, first="2010-09-22")
    assert outcome.status == "done" and "36 state analyses of 8 members" in outcome.message
    mae = mae_by_lead(store, service.run, service.series, truth.series)
    assert mae["updated"]["0-6h"] < 0.8 * mae["dss"]["0-6h"], mae
    store.close()


@pytest.mark.slow  # about 20 s: two services, 6 members each (the BMI one through 250 BMI runs)
def test_state_updating_through_bmi_is_the_engine_s_own(tmp_path):
    """BMI: the engine as a BMI component, updated through get_value/set_value, filters as the engine itself does."""
    from rivercal.case import case_from_dict
    from rivercal.models import build_model
    from tests.unit.test_bmi import _bmi_model

    synthetic = load_model("synthetic")
    model = _bmi_model(tmp_path, synthetic, assimilate=True)
    data = synthetic.case.spec.model_dump(mode="json", exclude_unset=True, by_alias=True)
    data["parameters"] = [{"name": "W2", "targets": ["weir:W2.crest_level"], "min": 12.5, "max": 13.5,
                           "initial": 12.85, "perturbation": 0.05, "unit": "m"}]  # as the BMI model's W2
    engine = build_model(case_from_dict(data, synthetic.case.root))
    truth_model = rain_error_model(synthetic, 0.4, seed=5)
    runs = {name: _states_twin(m, truth_model, tmp_path, members=6, first="2020-01-04", series=model.observables,
                               name=name) for name, m in (("bmi", model), ("engine", engine))}
    forecasts = {name: store.forecasts(service.run, kind="updated").set_index(["series", "time"])["value"]
                 for name, (store, service, _, _) in runs.items()}
    bmi, engine = forecasts["bmi"], forecasts["engine"].loc[forecasts["bmi"].index]
    # the same filter on the same runs: the engine hot-starts its members through the run, BMI hour by hour, and
    # spins the first state up through its component (measured: 0.4 mm of level, 3 l/s of discharge apart)
    assert len(bmi) == 3 * 7 and np.allclose(bmi.to_numpy(), engine.to_numpy(), atol=5e-3)
    store, service, truth, _ = runs["bmi"]
    mae = mae_by_lead(store, service.run, service.series, truth.series)
    assert mae["updated"]["0-6h"] < mae["dss"]["0-6h"], mae
    for store, *_ in runs.values():
        store.close()


def test_a_model_without_the_capabilities_is_refused_with_what_it_lacks(tmp_path):
    from rivercal.models.capabilities import MissingCapability
    from tests.unit.test_bmi import _bmi_model

    model = _bmi_model(tmp_path, load_model("synthetic"))
    with Store(tmp_path / "run.sqlite") as store, pytest.raises(MissingCapability) as refused:
        OnlineService(model, store, "x", OnlineConfig(parameters=("W2",), window="1D", warmup="12h", workers=1),
                      "2020-01-04", assimilation=AssimilationConfig(mode="both"))
    assert "state updating (--assimilate states or both) needs a model with 'state arrays' and 'perturbable " \
           "forcing'; model 'synthetic-bmi' (BmiModel) lacks 'state arrays' and 'perturbable forcing'" \
           == str(refused.value)


def test_a_failed_member_is_replaced_by_a_copy_of_a_survivor_and_all_failed_stops_the_filter(twin):
    from rivercal.errors import ModelRunError
    from rivercal.models.capabilities import MemberRuns

    _, service, _, _ = twin
    filt = service.filter
    times = pd.date_range("2010-10-18", periods=2, freq="h", tz="UTC")
    states = ("a", None, "c")
    values = np.arange(3 * 2 * len(service.model.observables), dtype=float).reshape(3, 2, -1)
    values[1] = np.nan
    errors = np.arange(3.0)[:, None] * np.ones((3, filt.n_forcing))
    runs = MemberRuns(times, tuple(service.model.observables), values, states, failures={1: "diverged"})
    members, new_errors, new_values = filt._survivors(runs, errors, np.random.default_rng(0))
    assert members[1] in ("a", "c") and members[0] == "a" and members[2] == "c"
    donor = 0 if members[1] == "a" else 2
    assert np.array_equal(new_values[1], values[donor]) and np.array_equal(new_errors[1], errors[donor])
    assert np.isnan(values[1]).all() and errors[1, 0] == 1.0   # the inputs are not changed
    dead = MemberRuns(times, tuple(service.model.observables), values, (None,) * 3,
                      failures={0: "diverged", 1: "diverged", 2: "diverged"})
    with pytest.raises(ModelRunError, match="every member of the ensemble failed; the first: diverged"):
        filt._survivors(dead, errors, np.random.default_rng(0))


def test_the_central_forecast_takes_the_forcing_the_members_are_expected_to_have():
    """:meth:`EnsembleFilter.expected_factors` against the mean of many draws of the filter's own AR(1) factors,
    and the central run: in a perfect twin (members with the true state and stationary forcing errors, the truth the
    model on its own forcing) the issued forecast with ``central`` lies closer to the truth than the members' mean."""
    from rivercal.online.assimilation import EnsembleFilter

    model = load_model("dommel")
    series = [s for s in measurable(model.observables) if ".h" in s]   # the stations' levels
    config = AssimilationConfig(mode="states", members=8, seed=0, forcing_tau="12h")
    filt = EnsembleFilter(model, config, series, None, workers=1)
    rng = np.random.default_rng(1)
    errors = 0.3 * rng.standard_normal((8, filt.n_forcing))
    draws = np.mean([filt._factors(6, errors, np.random.default_rng(seed))[0] for seed in range(4000)], axis=0)
    expected = filt.expected_factors(errors, 6)                     # (intervals, forcing): averaged over members
    assert expected.shape == (6, filt.n_forcing)
    assert np.allclose(draws.mean(axis=0), expected, rtol=0.02), np.abs(draws.mean(axis=0) / expected - 1).max()
    far = filt.expected_factors(errors, 2000)[-1]
    assert np.allclose(far, 1.0, atol=1e-6)   # far ahead: the forcing the model was given

    t0 = pd.Timestamp("2010-11-12", tz="UTC")  # a flood: levels respond least in proportion to the inflow
    _, state = model.simulate(None, model.start, t0)
    truth, _ = model.simulate(None, t0, t0 + pd.Timedelta("24h"), state)
    members = [state] * 8
    issued = {}
    for kind in ("mean", "central"):
        f = EnsembleFilter(model, AssimilationConfig(mode="states", members=8, issued=kind), series, None, workers=1)
        fc = f.forecast(members, errors, {}, pd.Timedelta("24h"), 3600.0, np.random.default_rng(2))
        issued[kind] = (fc.mean - truth.series[series].reindex(fc.mean.index)).abs().mean().mean()
    assert issued["central"] < 0.5 * issued["mean"], issued   # measured: 0.51 cm against 2.23 cm
