"""The on-line report's sentences say what the run did, without contradicting themselves."""

from __future__ import annotations

import pandas as pd

from rivercal.report.online import _map_words, _observation_words
from rivercal.report.online_figures import forecast_words, headline_lines, ratio_words


def test_the_observations_are_described_by_what_they_carry_not_by_unused_settings() -> None:
    realistic = _observation_words({"realism": {"name": "realistic"}, "noise": "none"})
    assert realistic.startswith("realism realistic: the truth differs from the model") and "noise" not in realistic
    assert _observation_words({"noise": "pink"}) == "pink noise on the observations."
    assert _observation_words({}).startswith("an identical twin")


def test_a_dss_without_error_is_explained_in_the_sentence_and_no_zero_is_listed() -> None:
    points = ["a", "b", "c"]
    sel = {"dss": pd.Series(0.0, index=points), "rivercal": pd.Series([0.02, -0.03, 0.01], index=points)}
    worst = sel["dss"][sel["dss"].abs() >= 0.0005]
    text = _map_words("before the transition", sel, worst, before=True, perturbed=["realism realistic"])
    assert "DSS 0.00 cm, rivercal 2.00 cm" in text
    assert "Largest DSS errors" not in text and "(0.0 cm)" not in text
    assert "zero by construction" in text and "realism realistic" in text
    after = {"dss": pd.Series([0.10, -0.2, 0.0], index=points), "rivercal": sel["rivercal"]}
    text = _map_words("after", after, after["dss"].abs().sort_values(ascending=False).head(2), before=False,
                      perturbed=[])
    assert "Largest DSS errors at b (20.0 cm), a (10.0 cm)." in text and "construction" not in text


def test_the_ratio_says_larger_when_rivercal_is_worse() -> None:
    assert ratio_words(1.2) == " (rivercal's error 1.2× smaller)"
    assert ratio_words(0.8) == " (rivercal's error 1.2× larger)"
    assert ratio_words(None) == ""
    assert ratio_words(1.02) == ratio_words(0.97) == " (about the same)"


def test_the_forecast_sentence_names_the_cycles_leads_and_count_it_covers() -> None:
    f = {"scenario": "PI-Fg", "realism": "realistic", "change_time": "2010-11-01T00:00:00+00:00", "lead_h": 24.0,
         "forecast_values": 3262, "rivercal_mae_m": 0.0249, "dss_mae_m": 0.0555, "updated_mae_m": 0.0251,
         "forecast_mae_ratio": 0.0555 / 0.0249, "time_to_correct_cycles": 6, "time_to_settle_cycles": None,
         "jump_alerts": 1, "fallbacks": 0, "unscored_cycles": 1,
         "forecast_scope": {"first_cycle": 14, "last_cycle": 28, "cycles": 15, "after": "2010-11-01T00:00:00+00:00"}}
    text = forecast_words(f)
    assert "issued by cycles 14–28 (the cycles issued after the change at 2010-11-01 00:00)" in text
    assert "lead times up to 24 h, n = 3262 values" in text
    assert "rivercal as issued 2.49 cm, the fixed DSS 5.55 cm (rivercal's error 2.2× smaller)" in text
    lines = headline_lines(f)
    assert lines[0].startswith("Twin scenario PI-Fg, realism realistic: ") and lines[1] == text
    assert "Time to correct the changed parameters: 6 cycles." in lines
    assert lines[-1] == ("Jump alerts: 1; fallbacks to the DSS's forecast: 0 (besides 1 first cycle that issued the "
                         "DSS's forecast because nothing was scored yet).")
    assert forecast_words({**f, "forecast_values": 0, "forecast_errors": {"reason": "no cycle yet"}}).endswith(
        "nothing to compare yet — no cycle yet.")


def test_the_parameter_table_is_explained_for_what_the_run_estimated_and_found() -> None:
    # an imported D-HYDRO model (Dellen) estimating one friction group on real-like observations: the text said
    # 'rivercal moves all adjustable crests alike (Wd) and one global friction (FA)' and spoke of a transition
    from rivercal.report.online import _parameter_words

    table = pd.DataFrame({"parameter": ["F_Strickler_35_0"], "rivercal before": [float("nan")],
                          "rivercal after": [44.98]})
    text = _parameter_words(None, ["F_Strickler_35_0"], table)
    assert text.startswith("No transition was found, so 'rivercal after' is each parameter's value accepted by the "
                           "last cycle ('rivercal before' is empty).")
    assert "rivercal estimates F_Strickler_35_0;" in text and "(Wd)" not in text and "(FA)" not in text
    with_change = _parameter_words(pd.Timestamp("2010-11-01", tz="UTC"), ["FA", "Wd"], table)
    assert with_change.startswith("'before': the last cycle whose window ends before the transition")
    assert "'rivercal before' is empty: no cycle's window ends before the transition." in with_change
