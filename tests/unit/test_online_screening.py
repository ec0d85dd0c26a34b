"""What the on-line service refuses before it runs: implausible observations, unknown series, impossible times.

The model is the toy river of ``test_online_service`` (two gauges whose levels the model computes), so the
plausible ranges follow from its own run and the store is the real one. The refusals are checked against
the model's numbers: a level in cm is 100 times the model's, a window of 30 minutes is not a whole number
of hourly output intervals, a forecast past the model's end has no forcing.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import CaseError
from rivercal.evaluate import Tasks, default_workers
from rivercal.observations import ObservationSeries, ObservationSet, ScreenRule
from rivercal.online.config import OnlineConfig, check_schedule
from rivercal.online.screening import LEVEL_MARGIN_M, check_delivery, check_series, plausible_ranges
from rivercal.store import Store
from tests.unit.test_online_service import END, START, ToyRiver, _observations

FIRST = pd.Timestamp("2010-10-25", tz="UTC")


def _ranges(model: ToyRiver) -> dict:
    return plausible_ranges(model, model.observables, FIRST - pd.Timedelta("8D"), FIRST + pd.Timedelta("2D"), {},
                            3600.0)


def test_the_plausible_range_is_the_models_own_levels_widened() -> None:
    model = ToyRiver()
    ranges = _ranges(model)
    result, _ = model.simulate(None, START, FIRST + pd.Timedelta("2D"))
    for sid in ("A.h", "B.h"):
        own = result.series[sid].loc[FIRST - pd.Timedelta("8D"):]
        margin = max(LEVEL_MARGIN_M, own.max() - own.min())
        assert ranges[sid].low == pytest.approx(own.min() - margin, abs=1e-9)
        assert ranges[sid].high == pytest.approx(own.max() + margin, abs=1e-9)


def test_levels_in_cm_are_refused_naming_file_series_and_unit() -> None:
    model = ToyRiver()
    obs = _observations(model, [], start="2010-10-17", end="2010-10-27")
    assert check_delivery(obs, "levels.csv", _ranges(model)) == []  # the truth in m: plausible
    in_cm = ObservationSet(tuple(ObservationSeries(s.id, s.times, s.values * 100.0, s.sigma) for s in obs))
    with pytest.raises(CaseError) as err:
        check_delivery(in_cm, "levels.csv", _ranges(model))
    text = str(err.value)
    assert err.value.file == "levels.csv" and err.value.field == "column 'A.h'"
    assert "241 of 241 values lie outside the plausible range" in text and "they look like cm" in text


def test_a_few_implausible_values_are_stored_as_outliers_and_left_out(tmp_path) -> None:
    model = ToyRiver()
    obs = _observations(model, [], start="2010-10-17", end="2010-10-27")
    a = obs["A.h"]
    values = a.values.copy()
    values[[10, 100]] = -999.0  # a logger's code for a missing value, twice
    delivery = ObservationSet((ObservationSeries("A.h", a.times, values, a.sigma), obs["B.h"]))
    ranges = _ranges(model)
    (note,) = check_delivery(delivery, "levels.csv", ranges)
    assert "column 'A.h': 2 of 241 values outside the plausible range" in note and "-999" in note
    with Store(tmp_path / "s.sqlite") as store:
        store.ingest(delivery, "levels.csv", screen=ScreenRule(),
                     plausible={sid: r.bounds() for sid, r in ranges.items()})
        used = store.observation_table(["A.h"], a.times[0], a.times[-1])
        assert len(used) == len(a) - 2 and used["value"].min() > ranges["A.h"].low
        flagged = store.observation_table(["A.h"], a.times[0], a.times[-1], flagged=True)
        assert sorted(flagged.loc[flagged["flag"] == "outlier", "value"]) == [-999.0, -999.0]


def test_values_before_the_period_the_model_ran_are_stored_unjudged(tmp_path) -> None:
    """A file with months of history: its values before the data period (a flood, levels metres apart from the
    period's) are neither refused nor flagged; a spike inside the period still is."""
    model = ToyRiver()
    obs = _observations(model, [], start="2010-10-03", end="2010-10-27")
    a = obs["A.h"]
    ranges = _ranges(model)
    before = np.asarray(a.times < ranges["A.h"].start)
    assert before.sum() > (~before).sum()  # most of the file lies before the period
    values = np.where(before, a.values - 10.0, a.values)  # far outside the period's range
    inside = int(np.flatnonzero(~before)[5])
    values[inside] = -999.0
    delivery = ObservationSet((ObservationSeries("A.h", a.times, values, a.sigma),))
    (note,) = check_delivery(delivery, "history.csv", ranges)
    assert f"1 of {(~before).sum()} values outside the plausible range" in note and "-999" in note
    assert "the period the model ran" in note
    with Store(tmp_path / "s.sqlite") as store:
        store.ingest(delivery, "history.csv", plausible={sid: r.bounds() for sid, r in ranges.items()})
        flagged = store.observation_table(["A.h"], a.times[0], a.times[-1], flagged=True)
        assert flagged.loc[flagged["flag"] == "outlier", "value"].tolist() == [-999.0]
        assert len(store.observation_table(["A.h"], a.times[0], a.times[-1])) == len(a) - 1


def test_a_series_the_model_does_not_simulate_is_refused_with_the_known_ids() -> None:
    model = ToyRiver()
    obs = _observations(model, [], start="2010-10-17", end="2010-10-20")
    renamed = ObservationSet((ObservationSeries("Z.h", obs["A.h"].times, obs["A.h"].values),))
    with pytest.raises(CaseError, match=r"gauges.csv: column 'Z.h': station 'Z' is not in model 'toy'; its stations "
                                        r"are A, B"):
        check_series(renamed, model.observables, "gauges.csv", model.name)
    other = ObservationSet((ObservationSeries("A.Q", obs["A.h"].times, obs["A.h"].values),))
    with pytest.raises(CaseError, match=r"series locationId=A parameterId=Q: model 'toy' does not simulate 'A.Q'; at "
                                        r"station A it has A.h"):
        check_series(other, model.observables, "gauges.xml", model.name)


@pytest.mark.parametrize(("settings", "first", "last", "message"), [
    ({"horizon": "1000D"}, "2010-10-25", "2010-10-26", "horizon 1000D: the last cycle, issued at 2010-10-26 00:00, "
     "would forecast to 2013-07-22 00:00, after the end of the model's period (2010-11-30 00:00), where its forcing "
     "ends; the horizon can be 1h to 35D, or issue every cycle (first issue and last issue) at 2008-03-05 00:00 or "
     "earlier"),
    ({"period": "7s"}, "2010-10-25", "2010-10-26", "period 7s: must be a whole number of the service's time step "
     "(1h, "),
    ({"window": "30min"}, "2010-10-25", "2010-10-26", "window 30min: must be a whole number of the service's time "
     "step"),
    ({"warmup": "90min"}, "2010-10-25", "2010-10-26", "warmup 90min: must be a whole number of the service's time "
     "step (1h, the step of its forecasts and windows), 0 or more; e.g. 1h or 2h"),
    ({}, "2010-10-25T00:30", "2010-10-26", "first issue 2010-10-25 00:30: cycles are issued on the service's "
     "time step, every 1h from 2010-10-01 00:00"),
    ({"window": "90D"}, "2010-10-25", "2010-10-26", "window 90D: with the warm-up (1D) longer than the model's "
     "period (60D) allows; give 1h to 58D23h"),
    ({}, "2010-10-25", "2010-12-02", "last issue 2010-12-02 00:00: after the end of the model's period"),
    ({"window": "12h", "warmup": "6h"}, "2010-10-25", "2010-10-26", "window 12h: with the warm-up (6h) shorter "
     "than the cycle (period 1D); each cycle starts from the state the cycle before saved one cycle after the start "
     "of its warm-up, so the window and its warm-up must span at least one cycle: lengthen warmup to 12h or more"),
])
def test_impossible_times_are_refused_with_the_allowed_range(settings, first, last, message) -> None:
    config = OnlineConfig(parameters=("FA",), workers=1, **settings)
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        check_schedule(ToyRiver(), config, pd.Timestamp(first, tz="UTC"), pd.Timestamp(last, tz="UTC"))


def test_the_longest_horizon_it_allows_ends_with_the_model() -> None:
    last = pd.Timestamp("2010-10-26", tz="UTC")
    assert last + pd.Timedelta("35D") == END
    check_schedule(ToyRiver(), OnlineConfig(parameters=("FA",), workers=1, horizon="35D"), FIRST, last)
    with pytest.raises(ValueError, match="the horizon can be 1h to 35D"):
        check_schedule(ToyRiver(), OnlineConfig(parameters=("FA",), workers=1, horizon="35D1h"), FIRST, last)


def test_more_workers_than_cores_are_refused_with_the_limit() -> None:
    limit = default_workers()
    with pytest.raises(ValueError, match=f"workers {limit + 1}: give 1 to {limit} worker processes"):
        Tasks(None, limit + 1)
    with pytest.raises(ValueError, match=f"online workers {limit + 1}: give 1 to {limit}"):
        OnlineConfig(workers=limit + 1)
    assert Tasks(None, limit).workers == limit and Tasks(None).workers == limit
    with pytest.raises(ValueError, match="online workers 0: give 1 to"):
        OnlineConfig(workers=0)
    assert np.isfinite(limit)


class _Notes:
    """A progress display that keeps the notes (the lines a terminal would show)."""

    def __init__(self) -> None:
        self.notes: list[str] = []

    def stage(self, text: str) -> None:
        pass

    def step(self, done: int, total: int | None, text: str) -> None:
        pass

    def note(self, text: str) -> None:
        self.notes.append(text)


def test_following_a_folder_skips_refused_files_and_stores_the_rest(tmp_path) -> None:
    """--follow: a file of another network and one in cm are reported and skipped; the good one runs the cycle."""
    from rivercal.io import write_observations_csv
    from rivercal.workflows.online import run_online

    model = ToyRiver()
    obs = _observations(model, [], start="2010-10-20", end="2010-10-28")
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    write_observations_csv(obs, inbox / "good.csv")
    write_observations_csv(ObservationSet(tuple(ObservationSeries("Z" + s.id, s.times, s.values) for s in obs)),
                           inbox / "other.csv")
    write_observations_csv(ObservationSet(tuple(ObservationSeries(s.id, s.times, s.values * 100) for s in obs)),
                           inbox / "cm.csv")
    notes = _Notes()
    config = OnlineConfig(parameters=("FA",), workers=1, window="2D", deadline_s=None)
    summary = run_online(model, tmp_path / "run.sqlite", "r", config, FIRST, FIRST, follow=inbox, poll=0.01,
                         progress=notes)
    assert summary["cycles"] == 1 and summary["status"] == {"done": 1}
    text = "\n".join(notes.notes)
    assert "skipped other.csv: other.csv: column 'ZA.h': station 'ZA' is not in model 'toy'" in text
    assert "skipped cm.csv: cm.csv: column 'A.h':" in text and "they look like cm" in text
    with Store(tmp_path / "run.sqlite") as store:
        sources = {r[0] for r in store._conn.execute("SELECT DISTINCT source FROM observations")}
    assert sources == {"good.csv"}
