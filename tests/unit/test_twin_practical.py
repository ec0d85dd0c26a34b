"""Practical-implication truths of thesis chapter 5 (rivercal.twin.practical) on the dommel case.

To keep the runs short the scenarios are moved to a change on 2010-09-08 00:00 (a week after the case
start, on a rising limb with a few tenths of m³/s), with the period 2010-09-07 … 2010-09-10; one test
keeps the thesis' change time and looks at a period before it.
"""

import pickle
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from rivercal.model import load_model
from rivercal.parameters import ParameterSet
from rivercal.twin import (
    ADJUSTABLE_WEIRS,
    CHANGE_TIME,
    PRACTICAL_SCENARIOS,
    QuantityChange,
    practical_truth,
)
from rivercal.twin.noise import LEVEL_AMPLITUDE, Q_AMPLITUDE

CHANGE = pd.Timestamp("2010-09-08T00:00:00Z")
START, END = pd.Timestamp("2010-09-07T00:00:00Z"), pd.Timestamp("2010-09-10T00:00:00Z")
H_DOWN = ["0028.h_down", "0040.h_down", "0029.h_down", "0030.h_down", "0031.h_down"]


def moved(name: str):
    return replace(PRACTICAL_SCENARIOS[name], change_time=CHANGE)


@pytest.fixture(scope="module")
def model():
    return load_model("dommel")


@pytest.fixture(scope="module")
def plain(model):
    """The DSS (model defaults) from the case start to END, with the levels at every calculation point."""
    result, _ = model.simulate({}, end=END, snapshots=True)
    return result


@pytest.fixture(scope="module")
def truths(model):
    return {name: practical_truth(model, moved(name), START, END, levels=True) for name in ("PI-Fg", "PI-Wg", "PI-Wl")}


# -- the scenarios ---------------------------------------------------------------------------------


def test_registry_holds_the_five_thesis_scenarios_changing_on_1_november():
    assert list(PRACTICAL_SCENARIOS) == ["PI-0", "PI-Fg", "PI-Wg", "PI-Fl", "PI-Wl"]
    assert all(s.change_time == pd.Timestamp("2010-11-01T00:00:00Z") == CHANGE_TIME
               for s in PRACTICAL_SCENARIOS.values())
    assert all(s.before == () for s in PRACTICAL_SCENARIOS.values())  # before the change: the DSS


def test_after_quantities_are_relative_to_the_model_defaults(model):
    d = model.default_parameters()
    q = {name: s.quantities(d, after=True) for name, s in PRACTICAL_SCENARIOS.items()}
    assert q["PI-0"] == {}
    assert q["PI-Fg"] == {"friction:global": 25.0}
    assert q["PI-Fl"] == {"friction:branch:Nriv_ZL_1_9820": 25.0}
    assert q["PI-Wl"] == {"weir:ZL1-5930.crest_level": pytest.approx(7.145 - 0.15)}
    assert q["PI-Wg"] == {f"weir:{w}.crest_level": pytest.approx(d[f"weir:{w}.crest_level"] - 0.15)
                          for w in ADJUSTABLE_WEIRS}
    # the same scenario on a model with other defaults shifts from those
    shifted = PRACTICAL_SCENARIOS["PI-Wl"].quantities({"weir:ZL1-5930.crest_level": 7.0}, after=True)
    assert shifted == {"weir:ZL1-5930.crest_level": pytest.approx(6.85)}
    with pytest.raises(KeyError, match=r"no such quantity to shift by -0\.15"):
        PRACTICAL_SCENARIOS["PI-Wl"].quantities({}, after=True)
    with pytest.raises(ValueError, match="exactly one of value and shift"):
        QuantityChange("friction:global")


def test_true_fa_and_wd_reproduce_the_truth_with_the_case_parameters(model):
    params = {p.name: p for p in model.case.spec.parameters}
    assert sorted(t.rpartition(":")[2].removesuffix(".crest_level") for t in params["Wd"].quantities(0.0)) == \
        sorted(ADJUSTABLE_WEIRS)
    d = model.default_parameters()
    for s in PRACTICAL_SCENARIOS.values():
        assert dict(s.true_before) == ({"FA": 16.0, "Wd": 0.0, "FL": 16.0} if s.name == "PI-Fl" else
                                       {"FA": 16.0, "Wd": 0.0})
        truth = {**d, **s.quantities(d, after=True)}
        fa, wd = s.true_after["FA"], s.true_after["Wd"]
        assert fa == truth["friction:global"]  # FA's target is the global friction, which always has a truth
        if wd is None:
            assert s.name == "PI-Wl"  # one crest moved: no common shift of the nine exists
            continue
        by_fa_wd = {**d, **ParameterSet([params["FA"], params["Wd"]]).quantities({"FA": fa, "Wd": wd})}
        differs = {k for k in truth if by_fa_wd.get(k) != pytest.approx(truth[k])}
        # FA and Wd describe the truth exactly, except the branch of PI-Fl, which only FL targets
        assert differs == ({"friction:branch:Nriv_ZL_1_9820"} if s.name == "PI-Fl" else set())
        if s.name == "PI-Fl":
            with_fl = ParameterSet([params["FA"], params["Wd"], params["FL"]])
            by_fl = {**d, **with_fl.quantities({"FA": fa, "Wd": wd, "FL": s.true_after["FL"]})}
            assert all(by_fl.get(k) == pytest.approx(v) for k, v in truth.items())


def test_represented_by_names_case_parameters_that_reproduce_the_change(model):
    params = {p.name: p for p in model.case.spec.parameters}
    d = model.default_parameters()
    values = {"PI-Fg": {"FA": 25.0}, "PI-Wg": {"Wd": -0.15}, "PI-Fl": {"FL": 25.0}, "PI-Wl": {"W4": 7.145 - 0.15}}
    for s in PRACTICAL_SCENARIOS.values():
        after = s.quantities(d, after=True)
        if not s.represented_by:
            # PI-0 has nothing to represent
            targets = {t for p in params.values() for t in p.quantities(p.initial)}
            assert not set(after) & targets
            continue
        chosen = ParameterSet(params[n] for n in s.represented_by)
        assert chosen.quantities(values[s.name]) == pytest.approx(after)


# -- the truth -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["PI-Fg", "PI-Wg", "PI-Wl"])
def test_truth_is_a_plain_run_up_to_the_change_and_differs_after_it(truths, plain, name):
    t = truths[name]
    assert t.series.index[0] == START and t.series.index[-1] == END
    assert (t.series.index.to_series().diff().dropna() == pd.Timedelta("1h")).all()
    pd.testing.assert_frame_equal(t.series.loc[:CHANGE], plain.series.loc[START:CHANGE], check_exact=True)
    pd.testing.assert_frame_equal(t.levels.loc[:CHANGE], plain.levels.loc[START:CHANGE], check_exact=True)
    after = (t.series - plain.series.loc[START:END]).loc[CHANGE + pd.Timedelta("1h"):]
    assert after.abs().to_numpy().max() > 0.01
    assert t.change_time == CHANGE and t.start == START and t.end == END


def test_smoother_bed_lowers_every_level_downstream_of_a_weir(truths, plain):
    d = (truths["PI-Fg"].series - plain.series.loc[START:END]).loc[CHANGE:, H_DOWN]
    assert (d <= 1e-9).all().all()  # never higher
    assert (d.mean() < -0.01).all()  # at least 1 cm lower on average at every station (0040: -1.4 cm)
    assert truths["PI-Fg"].after == {"friction:global": 25.0}
    assert truths["PI-Fg"].true_after == {"FA": 25.0, "Wd": 0.0}


def test_lowered_crests_lower_the_level_upstream_of_0028_by_their_15_cm(truths, plain):
    d = (truths["PI-Wg"].series - plain.series.loc[START:END])["0028.h_up"]
    assert (d.loc[:CHANGE] == 0.0).all()
    # a weir pool follows its crest: after a few hours h_up is 15 ± 1 cm lower
    assert d.loc[CHANGE + pd.Timedelta("6h"):].to_numpy() == pytest.approx(-0.15, abs=0.01)


def test_one_lowered_crest_changes_only_its_own_pool(model, truths, plain):
    t = truths["PI-Wl"]
    d = (t.series - plain.series.loc[START:END]).loc[CHANGE:]
    # upstream of ZL1-5930 (behind the free-flowing weir ZL1-5126) the stations see nothing at all
    upstream = [c for c in d.columns if c.startswith(("0028.", "0040."))]
    assert d[upstream].abs().to_numpy().max() < 1e-4
    # downstream the pool drains once: a few cm at 0029 in the first hours, then less than 1.5 mm anywhere
    assert d["0029.h_down"].abs().max() > 0.01
    settled = d.loc[CHANGE + pd.Timedelta("12h"):].drop(columns="0029.Q")
    assert settled.abs().to_numpy().max() < 0.0015
    # the calculation points that change are those between ZL1-5126 (chainage 1136) and ZL1-5930 (1940)
    dl = (t.levels - plain.levels.loc[START:END]).loc[CHANGE + pd.Timedelta("12h"):].abs().mean()
    changed = dl[dl > 0.01].index
    assert len(changed) >= 5
    c = model.compiled
    where = {lab: (b, ch) for lab, b, ch in zip(c.hp_label, c.hp_branch, c.hp_chainage, strict=True)}
    assert all(where[p][0] == "Nriv_ZL_1_9820" and 1136 < where[p][1] < 1940 for p in changed)
    assert dl.max() > 0.12


def test_periods_before_or_after_the_change(model, truths):
    # entirely before the thesis' change: the observations are PI-0's
    fg = practical_truth(model, "PI-Fg", "2010-09-02", "2010-09-03")
    p0 = practical_truth(model, "PI-0", "2010-09-02", "2010-09-03")
    pd.testing.assert_frame_equal(fg.observations.to_frame(), p0.observations.to_frame(), check_exact=True)
    assert fg.observations["0028.h_up"].source.startswith("practical scenario PI-Fg")
    assert fg.state is not None and fg.true_after == {"FA": 25.0, "Wd": 0.0}
    again = pickle.loads(pickle.dumps(fg))  # process pools hand truths around
    pd.testing.assert_frame_equal(again.series, fg.series)
    # entirely after the change: the same values as the longer truth over that part
    late = practical_truth(model, moved("PI-Wg"), "2010-09-09", END)
    pd.testing.assert_frame_equal(late.series, truths["PI-Wg"].series.loc["2010-09-09":], check_exact=True)
    assert late.levels is None and late.state is not None and late.state.time == pd.Timestamp("2010-09-09", tz="UTC")


def test_noise_is_seeded_and_bounded(model):
    kw = {"noise": "white", "series": ["0029.h_up", "0029.Q"], "output_interval": 1800}
    a = practical_truth(model, "PI-Fg", "2010-09-02", "2010-09-03", seed=3, **kw)
    b = practical_truth(model, "PI-Fg", "2010-09-02", "2010-09-03", seed=3, **kw)
    c = practical_truth(model, "PI-Fg", "2010-09-02", "2010-09-03", seed=4, **kw)
    assert a.observations.ids == ["0029.h_up", "0029.Q"]
    assert len(a.observations["0029.Q"]) == 49  # half-hourly, both ends included
    np.testing.assert_array_equal(a.observations.to_frame(), b.observations.to_frame())
    assert not np.array_equal(a.observations.to_frame(), c.observations.to_frame())
    err = a.observations.to_frame() - a.series[["0029.h_up", "0029.Q"]]
    assert err["0029.h_up"].abs().max() <= LEVEL_AMPLITUDE and err["0029.Q"].abs().max() <= Q_AMPLITUDE
    assert err["0029.h_up"].abs().max() > 0.5 * LEVEL_AMPLITUDE  # there is noise
    assert a.observations["0029.h_up"].sigma == 0.025 and a.observations["0029.Q"].sigma == 0.1
    assert "noise white (seed 3)" in a.observations["0029.Q"].source


def test_bad_requests_name_the_value(model):
    with pytest.raises(KeyError, match="unknown practical scenario 'PI-X'"):
        practical_truth(model, "PI-X", START, END)
    with pytest.raises(ValueError, match="outside the model's period"):
        practical_truth(model, "PI-0", "2010-08-30", END)
    with pytest.raises(ValueError, match="start 2010-09-07T00:30:00\\+00:00 is not on the 3600 s output grid"):
        practical_truth(model, "PI-0", "2010-09-07T00:30", END)
    with pytest.raises(ValueError, match="must be after start"):
        practical_truth(model, "PI-0", END, START)
    with pytest.raises(KeyError, match=r"series .0099\.h. is not simulated"):
        practical_truth(model, "PI-0", START, END, series=["0099.h"])
    with pytest.raises(ValueError, match="unknown noise model 'red'"):
        practical_truth(model, "PI-0", START, END, noise="red")
