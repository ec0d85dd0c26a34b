"""What real gauges need of the on-line service, shown on its own parts.

Real telemetry has readings at any time stamp (every 10 minutes, every 31 minutes with second offsets), and a
tidal river is driven by a level at its mouth. Each test states what the service does with them:

- the ensemble filter analyses every reading inside an analysis interval, each against the members
  interpolated to its time, not only the readings that fall on a whole hour;
- the ensemble perturbs level boundaries too (additive AR(1) errors in the augmented state), so a model driven
  by a tide at its mouth has spread and its analyses move it towards a surge the tide does not know;
- forecast scores pair each reading with the forecast interpolated to its time, not at equal time stamps.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.models import load_model
from rivercal.models.contract import spun_up
from rivercal.online.assimilation import AssimilationConfig, EnsembleFilter
from rivercal.online.metrics import score_forecasts


def _point(filt: EnsembleFilter, series: str) -> int:
    """The calculation point of a level series of the filter's model."""
    a = filt.model.compiled.arrays
    return int(a.ob_i1[filt.columns[filt.series.index(series)]])


# -- readings off the whole hour -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synthetic():
    model = load_model("synthetic")
    series = ["S1.h_up"]
    t0 = pd.Timestamp("2020-01-05T00:00Z")
    state = spun_up(model, {}, t0)
    free, _ = model.simulate({}, start=t0, end=t0 + pd.Timedelta("3h"), state=state, output_interval=60.0)
    return model, series, t0, state, free.series[series[0]]


def _assimilate(synthetic, stamps: pd.DatetimeIndex) -> tuple[int, float]:
    """Analyses made and the shift of the members' mean at the gauge, for readings 10 cm above the model's run."""
    model, series, t0, state, free = synthetic
    filt = EnsembleFilter(model, AssimilationConfig(mode="states", members=8, seed=1), series)
    observed = pd.DataFrame({series[0]: free.reindex(stamps, method="nearest").to_numpy() + 0.10}, index=stamps)
    rng = np.random.default_rng(2)
    members, errors = filt.initial(state, rng)
    end = t0 + pd.Timedelta("3h")
    done, _, analyses = filt.assimilate(members, errors, {}, end, observed, rng)
    k = _point(filt, series[0])
    return analyses, float(np.mean([m.z[k] for m in done]) - free.loc[end])


def test_readings_on_the_whole_hours_move_the_ensemble_towards_them(synthetic) -> None:
    t0 = synthetic[2]
    analyses, shift = _assimilate(synthetic, pd.DatetimeIndex([t0 + pd.Timedelta(hours=h) for h in (1, 2, 3)]))
    assert analyses == 3 and shift > 0.02


def test_readings_at_31_minute_stamps_with_second_offsets_are_assimilated_too(synthetic) -> None:
    t0 = synthetic[2]
    _, on_the_hour = _assimilate(synthetic, pd.DatetimeIndex([t0 + pd.Timedelta(hours=h) for h in (1, 2, 3)]))
    stamps = pd.DatetimeIndex([t0 + pd.Timedelta(minutes=31 * k, seconds=s) for k, s in ((1, 7), (2, 13), (3, 2),
                                                                                       (4, 41), (5, 19))])
    analyses, shift = _assimilate(synthetic, stamps)
    assert analyses >= 3 and shift > 0.5 * on_the_hour


# -- a river driven by a level at its mouth ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def estuary():
    from rivercal.bench.westerscheldt import case_folder

    model = load_model(case_folder())
    t0 = pd.Timestamp("2013-12-05T18:00Z")
    return model, t0, spun_up(model, {}, t0)


def _surge_analysis(estuary) -> float:
    """The shift of the members' mean at Vlissingen after analysing a reading 0.5 m above the model's (m)."""
    model, t0, state = estuary
    series = ["vlissingen.h"]
    filt = EnsembleFilter(model, AssimilationConfig(mode="states", members=8, seed=1), series)
    end = t0 + pd.Timedelta("1h")
    free, _ = model.simulate({}, start=t0, end=end, state=state)
    observed = pd.DataFrame({series[0]: [free.series[series[0]].loc[end] + 0.5]}, index=[end])
    rng = np.random.default_rng(3)
    members, errors = filt.initial(state, rng)
    done, _, analyses = filt.assimilate(members, errors, {}, end, observed, rng)
    assert analyses == 1
    k = _point(filt, series[0])
    return float(np.mean([m.z[k] for m in done]) - free.series[series[0]].loc[end])


def test_the_services_filter_corrects_a_river_driven_by_a_level_at_its_mouth(estuary) -> None:
    assert _surge_analysis(estuary) > 0.25


# -- forecast scores ---------------------------------------------------------------------------------------------


def _forecast_table() -> pd.DataFrame:
    issue = pd.Timestamp("2021-06-01T00:00Z")
    leads = np.arange(1, 7)
    return pd.DataFrame({"cycle": 0, "kind": "updated", "series": "S.h", "lead_h": leads.astype(float),
                         "time": issue + pd.to_timedelta(leads, unit="h"), "value": 1.0 + 0.1 * leads})


def _truth(times: pd.DatetimeIndex) -> np.ndarray:
    """A level that the forecast misses by exactly 5 cm everywhere (the forecast is linear in time)."""
    hours = (times - pd.Timestamp("2021-06-01T00:00Z")).total_seconds() / 3600.0
    return 1.0 + 0.1 * hours.to_numpy() - 0.05


def test_scores_pair_readings_on_the_forecasts_hours() -> None:
    times = pd.DatetimeIndex(_forecast_table()["time"])
    observed = pd.DataFrame({"series": "S.h", "time": times, "value": _truth(times)})
    scores = score_forecasts(_forecast_table(), observed)
    assert scores["rmse"].iloc[0] == pytest.approx(0.05) and int(scores["n"].iloc[0]) == 6


def test_scores_pair_readings_a_minute_off_the_hour_with_the_forecast_at_their_time() -> None:
    times = pd.DatetimeIndex(_forecast_table()["time"])[:-1] + pd.Timedelta(minutes=1, seconds=7)
    observed = pd.DataFrame({"series": "S.h", "time": times, "value": _truth(times)})
    scores = score_forecasts(_forecast_table(), observed)
    assert len(scores) == 1 and scores["rmse"].iloc[0] == pytest.approx(0.05) and int(scores["n"].iloc[0]) == 5


def test_a_level_boundary_offset_is_added_to_the_level_it_prescribes(estuary) -> None:
    """The model contract's ``perturbable levels``: the column after the forcing's is an offset in m, not a factor."""
    model, t0, state = estuary
    assert model.perturbable_forcing() == () and model.perturbable_levels() == ("boundary:cadzand",)
    mouth = model.state_layout().forcing_places["boundary:cadzand"]
    end = t0 + pd.Timedelta("1h")
    _, plain = model.simulate({}, start=t0, end=end, state=state)
    _, raised = model.simulate_perturbed({}, t0, end, state, np.full((1, 1), 0.3), 3600.0)
    assert raised.z[mouth] - plain.z[mouth] == pytest.approx(0.3, abs=1e-9)
    _, same = model.simulate_perturbed({}, t0, end, state, np.zeros((1, 0)), 3600.0)   # no level column: as is
    assert same.z[mouth] == pytest.approx(plain.z[mouth], abs=1e-12)


def test_the_level_error_is_checked_and_stored_only_when_set() -> None:
    with pytest.raises(ValueError, match="level boundaries' error"):
        AssimilationConfig(mode="states", level_error=-0.1)
    assert "level_error" not in AssimilationConfig(mode="states").stored()  # runs stored before resume as they were
    assert AssimilationConfig(mode="states", level_error=0.5).stored()["level_error"] == 0.5
