"""What the Python objects a user meets first print as: a model, its windows, a missing window's name."""

from __future__ import annotations

import pickle

import numpy as np
import pandas as pd
import pytest

import rivercal
from rivercal._time import Window, Windows


def test_windows_print_as_periods_and_unpack_as_start_and_end() -> None:
    windows = rivercal.load_model("dommel").calibration.windows
    assert repr(windows) == ("Windows({'moderate': Window(2010-09-27 00:00 … 2010-10-04 00:00 UTC), "
                             "'extreme': Window(2010-11-08 00:00 … 2010-11-15 00:00 UTC)})")
    start, end = windows["moderate"]
    assert (start, end) == (windows["moderate"].start, windows["moderate"].end)
    assert start == pd.Timestamp("2010-09-27T00:00Z") and windows["moderate"].duration == pd.Timedelta("7D")
    assert list(windows) == ["moderate", "extreme"] and len(windows) == 2
    assert pickle.loads(pickle.dumps(windows)) == windows


def test_a_missing_window_names_the_windows_there_are() -> None:
    windows = rivercal.load_model("dommel").calibration.windows
    with pytest.raises(KeyError, match=r"no window 'Moderate': case dommel has 'moderate', 'extreme'; did you mean "
                                       r"'moderate'\?"):
        windows["Moderate"]
    with pytest.raises(KeyError, match="no window 'wet': the windows are none"):
        Windows()["wet"]
    assert Windows({"a": ("2010-01-01", "2010-01-02")})["a"] == Window(pd.Timestamp("2010-01-01T00:00Z"),
                                                                          pd.Timestamp("2010-01-02T00:00Z"))


def test_external_models_print_what_they_are() -> None:
    text = repr(rivercal.load_model("dommel-swmm"))
    assert text == ("SwmmModel('dommel-swmm', 2010-09-20 00:00 … 2010-11-20 00:00 UTC, Δt 30 s, 100 quantities, "
                    "11 series)")
    assert " object at 0x" not in text


def test_the_quantity_table_shows_what_the_model_runs_with() -> None:
    model = rivercal.load_model("dommel")
    table = model.quantities_frame()
    assert not table["value"].isna().any()  # no NaN: an inheriting branch shows the global friction it takes
    inherit = table.loc["friction:branch:ZL12"]
    assert inherit["value"] == table.loc["friction:global", "value"] == 16.0
    assert inherit["description"].endswith("(inherits friction:global)")
    crest = table.loc["weir:ZL1-3014.crest_level"]
    assert (crest["min"], crest["max"]) == (-np.inf, np.inf)  # no bound of its own, not ±10 km
    assert table.loc["friction:global", "min"] == 1.0 and table.loc["friction:scale", "value"] == 1.0
