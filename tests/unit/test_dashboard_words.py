"""What the dashboard says of a model's parameters and of the DSS, from the packaged case dommel itself."""

from __future__ import annotations

import pytest

from rivercal.case import load_case
from rivercal.dashboard.facts import ModelFacts, dss_values, model_facts
from rivercal.dashboard.words import describe_parameter, describe_series


@pytest.fixture(scope="module")
def dommel() -> ModelFacts:
    return model_facts("dommel")


def test_parameters_are_said_in_words(dommel: ModelFacts) -> None:
    assert dommel.describe("FA") == "bed friction of the whole network"
    assert dommel.describe("F1") == "bed friction of branch ZL1_3030_3990"
    assert dommel.describe("W2") == "crest level of weir ZL1-3014"
    assert dommel.describe("Wd") == "common shift of the crests of 9 weirs"
    assert dommel.describe("Wc") == "crest levels of 9 weirs, as a share of their ranges"
    assert dommel.describe("nothing") == ""
    assert describe_series("0028.h_up") == "0028, level upstream" and describe_series("0029.Q") == "0029, discharge"


def test_the_dss_values_are_the_cases_own(dommel: ModelFacts) -> None:
    spec = load_case("dommel").spec
    crest = {w.id: w.crest_level for w in spec.weirs}
    values = dss_values(dommel, {}, ["FA", "Wd", "W2", "Wc"])
    assert values["FA"] == pytest.approx(spec.friction.value)  # 16 m^(1/3)/s
    assert values["Wd"] == pytest.approx(0.0, abs=1e-12)  # no shift of the crests
    assert values["W2"] == pytest.approx(crest["ZL1-3014"])
    wc = dommel.parameters["Wc"]  # the share of each crest's range, averaged over the cluster
    shares = [(crest[c.target.removeprefix("weir:").removesuffix(".crest_level")] - c.min) / (c.max - c.min)
              for c in wc.cluster]
    assert values["Wc"] == pytest.approx(sum(shares) / len(shares))
    # a run whose DSS was given its own friction: that value
    assert dss_values(dommel, {"friction:global": 18.5}, ["FA"])["FA"] == pytest.approx(18.5)


def test_a_model_that_cannot_be_loaded_leaves_the_facts_empty_and_says_why() -> None:
    facts = model_facts("no-such-model-anywhere")
    assert facts.parameters == {} and facts.network is None and "cannot be loaded" in facts.problem
    assert describe_parameter(object()) == ""


def test_a_model_in_a_folder_of_its_own_is_found_through_its_registered_folder(tmp_path, monkeypatch) -> None:
    # an imported model: folder 'comp/', model name 'test_compound' (what the store keeps); rivercal dashboard --case
    import shutil
    from importlib import resources
    from pathlib import Path

    from rivercal.dashboard import facts as module

    monkeypatch.setattr(module, "_SOURCES", {})
    monkeypatch.chdir(tmp_path)
    shutil.copytree(Path(str(resources.files("rivercal.cases") / "dommel")), tmp_path / "comp")
    toml = tmp_path / "comp" / "case.toml"
    toml.write_text(toml.read_text(encoding="utf-8").replace('name = "dommel"', 'name = "test_compound"', 1),
                    encoding="utf-8")
    unknown = model_facts("test_compound")
    assert unknown.network is None and "rivercal dashboard --case" in unknown.problem
    assert module.register_model("comp") == "test_compound"
    found = model_facts("test_compound")
    assert found.problem == "" and found.network is not None
    assert found.describe("W2") == "crest level of weir ZL1-3014"
    model_facts.cache_clear()


def test_the_network_map_of_a_run_without_scores_draws_the_network_without_errors(tmp_path) -> None:
    # a run of one cycle has no scored forecast yet: the map page failed with HTTP 500 (KeyError in the split of
    # no series names) once the model could be loaded
    import pandas as pd

    from rivercal.dashboard.views import map_view
    from rivercal.store import CycleRecord, Schedule, Store

    with Store(tmp_path / "s.sqlite") as store:
        run = store.ensure_run("online", "dommel", {})
        view = map_view(store, run)
        assert "problem" not in view or not view["problem"]
        assert len(view["figures"]) == 2   # DSS and rivercal
        assert view["rows"] == [] and view["unscored"] == 5   # nothing scored yet: no row of dashes
        # scores at two of the five stations: the table lists those two (an imported model has hundreds of
        # stations, most without a gauge) and counts the rest
        schedule = Schedule("2010-11-01T00:00:00Z", period=pd.Timedelta(days=1), window=pd.Timedelta(days=2))
        spec = store.begin_cycle(run.id, store.next_cycle(run.id, schedule))
        store.commit_cycle(run.id, CycleRecord(0, spec.window_start, spec.window_end, spec.issue_time))
        store.put_scores(run, pd.DataFrame({"cycle": 0, "kind": ["updated", "dss", "updated", "dss"],
                                            "series": ["0029.h", "0029.h", "0031.h", "0031.h"], "lead_from_h": 0.0,
                                            "lead_to_h": 24.0, "rmse": 0.05, "bias": [0.01, -0.02, 0.03, 0.04],
                                            "n": 24}))
        view = map_view(store, run)
    assert [(r["station"], r["updated"]["text"], r["dss"]["text"]) for r in view["rows"]] == [
        ("0029", "+1.0", "-2.0"), ("0031", "+3.0", "+4.0")]
    assert view["unscored"] == 3


def test_the_forecast_page_draws_the_observed_series_and_counts_the_others(tmp_path) -> None:
    # an imported model forecasts every series of every structure (Dellen: 546) while FEWS hands over a few
    # gauges (21): the page drew all 546 (2.5 MB, 9 s); now the observed ones, and says how many are left out
    import numpy as np
    import pandas as pd

    from rivercal.dashboard.views import forecast_view
    from rivercal.observations import ObservationSet
    from rivercal.store import CycleRecord, Schedule, Store

    series = ["G1.h", "S1.h_up", "S1.Q"]
    schedule = Schedule("2010-11-01T00:00:00Z", period=pd.Timedelta(days=1), window=pd.Timedelta(days=2))
    with Store(tmp_path / "s.sqlite") as store:
        run = store.ensure_run("r", "dommel", {})
        spec = store.begin_cycle(run.id, store.next_cycle(run.id, schedule))
        times = pd.date_range(spec.issue_time, periods=25, freq="h")
        mean = pd.DataFrame({c: np.full(25, 7.0) for c in series}, index=times)
        store.commit_cycle(run.id, CycleRecord(0, spec.window_start, spec.window_end, spec.issue_time,
                                               forecasts={"updated": mean, "dss": mean + 0.005}))
        before = pd.date_range(spec.issue_time - pd.Timedelta("12h"), spec.issue_time, freq="h")
        store.ingest(ObservationSet.from_frame(pd.DataFrame({"G1.h": 7.01}, index=before)), "telemetry")
        view = forecast_view(store, run)
        assert [f["series"] for f in view["figures"]] == ["G1.h"] and view["latest"]["unobserved"] == 2
        store.ingest(ObservationSet.from_frame(pd.DataFrame({"S1.Q": 1.0, "S1.h_up": 7.0}, index=before)), "more")
        view = forecast_view(store, run)
    assert [f["series"] for f in view["figures"]] == ["G1.h", "S1.h_up", "S1.Q"]
    assert view["latest"]["unobserved"] == 0
    # a level that does not move (Dellen's basin at -0.66414 m AD, its forecast 4e-7 m off) gets an axis of 2 cm,
    # not one of 4e-7 m; one that moves keeps plotly's own range
    axes = {f["series"]: f["figure"]["layout"]["yaxis"] for f in view["figures"]}
    assert axes["S1.h_up"]["range"] == pytest.approx([7.0025 - 0.01, 7.0025 + 0.01])   # 7.0 and 7.005
    assert axes["G1.h"]["range"] == pytest.approx([7.005 - 0.01, 7.005 + 0.01])   # 7.0 and 7.005, 7.01 observed
    assert "range" not in axes["S1.Q"]   # from 1 m³/s observed to 7 forecast
