"""The on-line report says which truth its error maps compare with.

The maps re-run the scenario's parameters on the model itself. That is the truth of an identical twin
(also under sensor errors alone), but not of a run whose observations came from a perturbed truth
(realism with rain, runoff or structural errors, or a rain error): the report must say so.
"""

from __future__ import annotations

import pytest

from rivercal.report.online import _perturbed, _truth_words
from rivercal.twin.realism import REALISM_LEVELS


@pytest.mark.parametrize("level", ["noisy", "realistic"])
def test_the_words_follow_whether_the_realism_changes_the_truth(level: str) -> None:
    realism = REALISM_LEVELS[level]
    words = " ".join(_truth_words(_perturbed({"scenario": "PI-Wg", "realism": realism.summary()})))
    if realism.changes_truth:
        assert f"a truth with realism {level}, which these maps do not use" in words
        assert "not the model's error against that truth" in words
    else:
        assert "identical twin" in words and "do not use" not in words


def test_a_rain_error_is_named() -> None:
    words = " ".join(_truth_words(_perturbed({"scenario": "PI-Fg", "rain_error": 0.3})))
    assert "a rain error of about 30%, which these maps do not use" in words


def test_the_identical_twin() -> None:
    assert _truth_words(_perturbed({"scenario": "PI-Fg"})) == [
        "truth: the scenario's parameters on the model itself (the identical twin of the observations)."]


def test_what_perturbed_the_truth_is_named_for_the_estimates_caption() -> None:
    both = {"realism": REALISM_LEVELS["realistic"].summary(), "rain_error": 0.25}
    assert _perturbed(both) == ["realism realistic", "a rain error of about 25%"]
    assert _perturbed({"realism": REALISM_LEVELS["noisy"].summary()}) == []  # sensor errors leave the truth alone
