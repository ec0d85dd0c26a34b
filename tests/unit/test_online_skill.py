"""Do no harm and the headline figures of a run: which forecast a cycle issues, and what the run achieved.

The rule (:func:`rivercal.online.skill.choose_forecast`) is checked on score tables made by hand, and
end to end on the toy river of ``test_online_service``: a gauge whose sensor read 5 cm high for a
while pulls the friction estimate away, the updated forecasts lose to the DSS's (which is the truth
there) and the service falls back; the mowed river of thesis §5-2-1 (PI-Fg's change on the toy) gives
the headline figures of :func:`rivercal.online.metrics.run_figures`.
"""

from __future__ import annotations

import pandas as pd
import pytest

from rivercal.observations import ObservationSeries, ObservationSet
from rivercal.online.metrics import run_figures
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.online.skill import choose_forecast
from rivercal.store import Store
from tests.unit.test_online_service import CHANGE, IDS, MOWED, ToyRiver, _observations


def _scores(rows: list[tuple[int, str, str, float, float]]) -> pd.DataFrame:
    """(cycle, kind, series, lead_from_h, rmse) rows, 10 values each, lead buckets of 6 h."""
    return pd.DataFrame([(c, k, s, f, f + 6.0, r, 10) for c, k, s, f, r in rows],
                        columns=["cycle", "kind", "series", "lead_from_h", "lead_to_h", "rmse", "n"])


def test_the_updated_forecast_is_issued_while_it_scores_no_worse_than_the_dss() -> None:
    rows = [(c, k, "A.h", 0.0, r) for c in (1, 2, 3, 4) for k, r in (("updated", 0.02), ("dss", 0.03))]
    choice = choose_forecast(_scores(rows), 5, cycles=3)
    assert choice.issued == "updated" and choice.cycles == (2, 3, 4)
    assert choice.rmse_updated == pytest.approx(0.02) and choice.rmse_dss == pytest.approx(0.03)
    # pooled over cycles by the number of values: √((10·0.01² + 20·0.04²) / 30) against 0.02
    worse = _scores([(1, "updated", "A.h", 0.0, 0.01), (2, "updated", "A.h", 0.0, 0.04),
                     (2, "updated", "B.h", 6.0, 0.04), (1, "dss", "A.h", 0.0, 0.02), (2, "dss", "A.h", 0.0, 0.02),
                     (2, "dss", "B.h", 6.0, 0.02)])
    choice = choose_forecast(worse, 3)
    assert choice.issued == "dss" and "fallback" in choice.reason
    assert choice.rmse_updated == pytest.approx(((10 * 0.01**2 + 20 * 0.04**2) / 30) ** 0.5)
    # discharges and lead times past 24 h do not count; equal forecasts tie (the 1 mm slack)
    mixed = _scores([(1, "updated", "A.Q", 0.0, 9.0), (1, "dss", "A.Q", 0.0, 0.1),
                     (1, "updated", "A.h", 24.0, 9.0), (1, "dss", "A.h", 24.0, 0.1),
                     (1, "updated", "A.h", 0.0, 0.0305), (1, "dss", "A.h", 0.0, 0.03)])
    assert choose_forecast(mixed, 2).issued == "updated"


def test_nothing_scored_issues_the_dss_unless_an_intervention_was_found() -> None:
    empty = _scores([])
    assert choose_forecast(empty, 0).issued == "dss"
    rows = [(c, k, "A.h", 0.0, r) for c in (5, 6) for k, r in (("updated", 0.09), ("dss", 0.03))]
    # the forecasts before the change used the old values: from cycle 7 on, nothing is scored yet
    choice = choose_forecast(_scores(rows), 7, since=(7, "cycle 7 found that FA changed"))
    assert choice.issued == "updated" and "cycle 7 found" in choice.reason
    assert choose_forecast(_scores(rows), 7).issued == "dss"


def _faulty_gauge() -> ObservationSet:
    """The truth (no change) with gauge B reading 5 cm high until 2010-10-26."""
    obs = _observations(ToyRiver(), [])
    b = obs["B.h"].to_series()
    b[b.index < pd.Timestamp("2010-10-26", tz="UTC")] += 0.05
    return ObservationSet((obs["A.h"], ObservationSeries.from_series(b, id="B.h", sigma=0.01, source="truth")))


def test_a_faulty_gauge_makes_the_service_fall_back_to_the_dss_and_say_so(tmp_path) -> None:
    config = OnlineConfig(parameters=("FA",), workers=1, deadline_s=None, loss="l2")
    with Store(tmp_path / "run.sqlite") as store:
        store.ingest(_faulty_gauge(), "truth")
        svc = OnlineService(ToyRiver(), store, "toy", config, first_issue="2010-10-25")
        out = svc.replay("2010-11-06")
        # the windows that hold the faulty readings pull FA away from the truth (16) ...
        assert abs(out[1].accepted["FA"] - 16.0) > 0.5
        # ... its forecasts lose to the DSS's against the sound readings after the fault, and the service falls back
        back = [o for o in out if o.issued == "dss" and "fallback" in o.issued_reason]
        assert back, [(o.cycle, o.issued, o.issued_reason) for o in out]
        cycles = store.cycles(svc.run).set_index("cycle")
        for o in back:
            assert cycles.loc[o.cycle, "issued_forecast"] == "dss"
            assert cycles.loc[o.cycle, "skill_updated"] > cycles.loc[o.cycle, "skill_dss"]
        # once the fault has left the windows, FA is right again and its forecasts are issued again
        assert abs(out[-1].accepted["FA"] - 16.0) < 0.05 and out[-1].issued == "updated"
        assert out[0].issued == "dss" and "no forecast" in out[0].issued_reason


def test_headline_figures_of_the_mowed_river(tmp_path) -> None:
    config = OnlineConfig(parameters=("FA", "Wd"), workers=1, deadline_s=None)
    with Store(tmp_path / "run.sqlite") as store:
        store.ingest(_observations(ToyRiver(), MOWED), "truth")
        # the toy's mowing is PI-Fg's (16 → 25 on 2010-11-01), so the scenario's truth applies
        from rivercal.twin.practical import SCENARIOS

        meta = {"scenario": "PI-Fg", "truth": SCENARIOS["PI-Fg"].facts()}
        svc = OnlineService(ToyRiver(), store, "toy", config, first_issue="2010-10-27", meta=meta)
        out = svc.replay("2010-11-08")
        f = run_figures(store, svc.run)
        # the service stored these figures with its last cycle: readers read that value, not their own
        stored = store.metrics(svc.run)
        assert {k: stored[k] for k in f} == f and store.metrics(svc.run, cycle=out[-1].cycle) == stored
        assert stored["forecast_errors"]["n"] > 0 and store.metrics(svc.run, cycle=0)["jump_alerts"] == 0
        second = [o for o in out if o.issue_time > CHANGE][1]
        assert f["jump_alerts"] == 1 and f["time_to_correct_cycles"] == 2 and f["time_to_settle_cycles"] == 2
        assert abs(second.accepted["FA"] - 25.0) <= 0.45  # 5 % of the change
        # the ratio: the DSS's error over rivercal's as issued, level forecasts up to 24 h of the cycles after the
        # change, against the observations (here exact) — recomputed from the stored forecasts
        fc = store.forecasts(svc.run)
        fc = fc[(fc["issue_time"] > CHANGE) & (fc["lead_h"] > 0) & (fc["lead_h"] <= 24)]
        truth = _observations(ToyRiver(), MOWED).to_frame()
        err = fc.assign(obs=[truth.at[t, s] for t, s in zip(fc["time"], fc["series"], strict=True)])
        err = err.assign(e=(err["value"] - err["obs"]).abs())
        issued = {o.cycle: o.issued for o in out}
        mine = err[[issued[c] == k for c, k in zip(err["cycle"], err["kind"], strict=True)]]["e"].mean()
        assert f["dss_mae_m"] == pytest.approx(err.loc[err["kind"] == "dss", "e"].mean(), rel=1e-9)
        assert f["rivercal_mae_m"] == pytest.approx(mine, rel=1e-9)
        assert f["forecast_mae_ratio"] == pytest.approx(f["dss_mae_m"] / mine, rel=1e-9) and f["forecast_mae_ratio"] > 5
        assert set(IDS) <= set(fc["series"])


def test_the_report_says_what_errors_an_ideal_twin_carried() -> None:
    from rivercal.report.online_figures import _twin_words

    exact = _twin_words({"realism": "ideal", "noise": "none", "rain_error": 0.0})
    assert "observations are exact" in exact
    words = _twin_words({"realism": "ideal", "noise": "gaussian", "rain_error": 0.3})
    assert "exact" not in words and "rain error of about 30%" in words and "gaussian noise" in words
    assert "sensor errors" in _twin_words({"realism": "realistic", "noise": "none", "rain_error": 0.0})
