"""The twin suites enumerate exactly the thesis' scenarios (Tables 4-5 … 4-12), in the thesis' order."""

import pytest

from rivercal.twin.reference import THESIS, thesis_row
from rivercal.twin.suites import SUITES, suite_scenarios


@pytest.mark.parametrize("suite", list(SUITES))
def test_scenarios_are_those_of_the_thesis_table(suite):
    ours = [s.id for s in suite_scenarios(suite)]
    assert len(ours) == len(set(ours))
    # every scenario of the thesis' table is generated and nothing else
    assert sorted(ours) == sorted(THESIS[suite])


def test_order_follows_the_thesis_table():
    ours = [s.id for s in suite_scenarios("FaWc")]
    assert ours[:4] == ["H1H1", "H1H2", "H2H1", "H2H2"]
    assert ours[-1] == "L2L2"
    assert [s.id for s in suite_scenarios("F1W0")] == ["H1", "H2", "M1", "M2", "L1", "L2"]


def test_scenario_values_decode_the_id():
    s = next(s for s in suite_scenarios("FaWc") if s.id == "M2L1")
    assert s.truth == {"FA": 16.0, "Wc": 0.4}
    assert s.start == {"FA": 18.0, "Wc": 0.1}
    assert s.window == "moderate" and s.series is None and s.noise == "none"
    w = next(s for s in suite_scenarios("F0W1") if s.id == "L2")
    assert w.truth == {"W2": 10.15} and w.start == {"W2": 10.90}


def test_scenarios_with_one_truth_share_one_truth_run_and_noise_realisation():
    scen = suite_scenarios("FaWcN")
    keys = {s.truth_key for s in scen}
    assert len(keys) == 4  # 2 friction truths × 2 crest truths; 4 start points each
    h1h1 = next(s for s in scen if s.id == "H1H1")
    h2h2 = next(s for s in scen if s.id == "H2H2")
    assert h1h1.truth_key == h2h2.truth_key and h1h1.seed == h2h2.seed
    l1l1 = next(s for s in scen if s.id == "L1L1")
    assert l1l1.seed != h1h1.seed


def test_ids_and_window_filters():
    scen = suite_scenarios("FaWcP", ids=["L2L2", "H1H1"], window="2010-11-01/2010-11-08")
    assert [s.id for s in scen] == ["H1H1", "L2L2"]
    assert all(s.window == "2010-11-01/2010-11-08" for s in scen)
    with pytest.raises(KeyError, match="FaWcP has no scenario 'M1M1'"):
        suite_scenarios("FaWcP", ids=["M1M1"])
    with pytest.raises(KeyError, match="unknown suite 'FaW'"):
        suite_scenarios("FaW")


def test_thesis_rows_are_the_printed_values():
    # spot checks against the thesis text (Tables 4-6 and 4-8)
    assert thesis_row("F1W0", "H1") == {"F1_estimate": 19.9997, "iterations": 4, "cost": 1.34e-09,
                                        "rmse": 2.93e-06, "bias": 2.78e-06, "std_error": 9.21e-07}
    assert thesis_row("FaWcN", "L1H1")["FA_estimate"] == 11.9851
    assert thesis_row("FaWc", "X9") is None
    # the thesis reports 100 % robustness in every suite: its estimates, decoded with our scenario ids,
    # all lie within our tolerances — which checks both the typed-in table and the id decoding
    for suite, rows in THESIS.items():
        d = SUITES[suite]
        for sid, (estimates, *_rest) in rows.items():
            scen = suite_scenarios(suite, ids=[sid])[0]
            assert set(estimates) == set(scen.truth)
            assert all(abs(estimates[p] - scen.truth[p]) <= d.tolerance[p] + 1e-12 for p in estimates), (suite, sid)
