"""The ensemble filter on readings at the sensors' own time stamps: a twin with known truth.

The truth is the synthetic model run with its inflows 40 % higher than the model knows (a wrong rain); the
filter sees its levels at three stations, either on the whole hours or every 31 minutes with second offsets
(as an urban creek's depth sensors deliver them). Both must correct the forecast alike: the skill
1 − MAE(filtered forecast) / MAE(free forecast) against the truth over the next 6 h within 5 % of each other.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.models import load_model
from rivercal.models.contract import spun_up
from rivercal.online.assimilation import AssimilationConfig, EnsembleFilter

SERIES = ["S1.h_up", "S3.h_up", "S6.h"]
T0 = pd.Timestamp("2020-01-05T00:00Z")
SPAN = pd.Timedelta("12h")
HORIZON = pd.Timedelta("6h")


@pytest.fixture(scope="module")
def twin():
    model = load_model("synthetic")
    state = spun_up(model, {}, T0)
    wrong = np.full((int((SPAN + HORIZON) / pd.Timedelta("1h")), len(model.perturbable_forcing())), 1.4)
    truth, _ = model.simulate_perturbed({}, T0, T0 + SPAN + HORIZON, state, wrong, 3600.0, output_interval=60.0)
    free, _ = model.simulate({}, start=T0, end=T0 + SPAN + HORIZON, state=state, output_interval=3600.0)
    return model, state, truth.series[SERIES], free.series[SERIES]


def _readings(truth: pd.DataFrame, stamps: pd.DatetimeIndex) -> pd.DataFrame:
    """The truth at the stamps, interpolated linearly between its minutes (no noise: an identical twin)."""
    seconds = (truth.index - T0).total_seconds().to_numpy()
    at = (stamps - T0).total_seconds().to_numpy()
    return pd.DataFrame({s: np.interp(at, seconds, truth[s].to_numpy()) for s in SERIES}, index=stamps)


def _forecast_mae(twin, stamps: pd.DatetimeIndex) -> tuple[float, int]:
    model, state, truth, _ = twin
    filt = EnsembleFilter(model, AssimilationConfig(mode="states", members=16, seed=4, forcing_error=0.3), SERIES)
    rng = np.random.default_rng(5)
    members, errors = filt.initial(state, rng)
    members, errors, analyses = filt.assimilate(members, errors, {}, T0 + SPAN, _readings(truth, stamps), rng)
    fc = filt.forecast(members, errors, {}, HORIZON, 3600.0, rng)
    mean = fc.mean.loc[fc.mean.index > T0 + SPAN]
    return float((mean - truth.reindex(mean.index)).abs().to_numpy().mean()), analyses


def _free_mae(twin) -> float:
    _, _, truth, free = twin
    part = free.loc[(free.index > T0 + SPAN)]
    return float((part - truth.reindex(part.index)).abs().to_numpy().mean())


def test_readings_every_31_minutes_with_second_offsets_give_the_skill_of_readings_on_the_hour(twin) -> None:
    hours = pd.date_range(T0 + pd.Timedelta("1h"), T0 + SPAN, freq="1h")
    offsets = [pd.Timedelta(minutes=31 * k, seconds=int(s)) for k, s in
               zip(range(1, 24), np.random.default_rng(0).integers(0, 60, 23), strict=True)]
    odd = pd.DatetimeIndex([T0 + o for o in offsets if T0 + o <= T0 + SPAN])
    assert not odd.isin(hours).any()
    free = _free_mae(twin)
    mae_hours, n_hours = _forecast_mae(twin, hours)
    mae_odd, n_odd = _forecast_mae(twin, odd)
    skill_hours, skill_odd = 1 - mae_hours / free, 1 - mae_odd / free
    assert n_hours == 12 and n_odd == 12      # every hour holds a reading of the 31-minute sensor
    assert skill_hours > 0.3                  # the filter does correct a wrong inflow
    assert abs(skill_odd - skill_hours) <= 0.05 * skill_hours, (skill_hours, skill_odd, free)


# -- the service on the sensors' own stamps ----------------------------------------------------------------------


def test_the_service_with_states_corrects_its_forecast_from_readings_at_31_minute_stamps(tmp_path) -> None:
    """``--assimilate states`` on readings nobody resampled: the forecast changes, towards the truth, and scores."""
    import shutil

    from rivercal.observations import ObservationSeries, ObservationSet
    from rivercal.online.metrics import run_metrics
    from rivercal.online.service import OnlineConfig, OnlineService
    from rivercal.store import Store

    folder = tmp_path / "case"
    shutil.copytree(str(_synthetic_folder()), folder)
    with (folder / "case.toml").open("a", encoding="utf-8") as f:   # the service needs a parameter to name
        f.write('\n[[parameters]]\nname = "KS"\ntargets = ["friction:global"]\nmin = 10.0\nmax = 60.0\n'
                'initial = 25.0\nperturbation = 2.0\nunit = "m^(1/3)/s"\n')
    model = load_model(folder)
    first = pd.Timestamp("2020-01-05T12:00Z")
    start = first - pd.Timedelta("18h")
    state = spun_up(model, {}, start)
    span = pd.Timedelta("30h")
    wrong = np.full((30, len(model.perturbable_forcing())), 1.4)
    truth, _ = model.simulate_perturbed({}, start, start + span, state, wrong, 3600.0, output_interval=60.0)
    seconds = np.random.default_rng(2).integers(1, 59, 58)
    stamps = pd.DatetimeIndex([start + pd.Timedelta(minutes=31 * k, seconds=int(s))
                               for k, s in zip(range(1, 59), seconds, strict=True)])
    readings = _readings(truth.series[SERIES], stamps)
    assert not stamps.isin(pd.date_range(start, start + span, freq="h")).any()
    config = OnlineConfig(parameters=("KS",), window="12h", period="6h", horizon="6h", warmup="6h", series=SERIES,
                          deadline_s=None, workers=1)
    with Store(tmp_path / "run.sqlite") as store:
        store.ingest(ObservationSet(tuple(ObservationSeries.from_series(readings[s], id=s, sigma=0.01, source="s")
                                          for s in SERIES)), source="sensor")
        service = OnlineService(model, store, "stamps", config, first,
                                assimilation=AssimilationConfig(mode="states", members=12, seed=1))
        outcomes = service.replay(first + pd.Timedelta("6h"))
        assert all("state analyses" in o.message for o in outcomes)
        fc = store.forecasts(service.run).pivot_table(index=["cycle", "series", "time"], columns="kind",
                                                       values="value")
        fc = fc[fc.index.get_level_values("time") > first]
        assert (fc["updated"] - fc["dss"]).abs().max() > 0.02            # the forecast changed …
        true = truth.series[SERIES].stack().rename_axis(["time", "series"]).rename("truth")
        joined = fc.join(true.reorder_levels(["series", "time"]), on=["series", "time"])
        err = lambda k: float((joined[k] - joined["truth"]).abs().mean())  # noqa: E731
        assert err("updated") < 0.5 * err("dss")                          # … towards the truth
        metrics = run_metrics(store, service.run)
        by_lead = metrics["forecast_mae_by_lead"]
        assert by_lead["updated"]["0-6h"] is not None and by_lead["dss"]["0-6h"] is not None
        assert by_lead["updated"]["0-6h"] < by_lead["dss"]["0-6h"]
        assert metrics["forecast_errors"]["n"] > 0


def _synthetic_folder():
    from importlib import resources

    return resources.files("rivercal.cases") / "synthetic"
