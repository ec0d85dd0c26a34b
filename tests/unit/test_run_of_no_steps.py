"""A run from the case start to the case start is the cold-start state (after the spin-up), not an error.

Calibration windows, twin truths and on-line cycles whose runs begin exactly at the case start ask the
model for the state there; continuing from it must equal one run from the start.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.model import load_model


def test_state_at_the_case_start_continues_like_one_run() -> None:
    model = load_model("synthetic")
    result, state = model.simulate({}, end=model.start)
    assert state.time == model.start and len(result.series) == 1
    hour = model.start + pd.Timedelta("1h")
    direct, s_direct = model.simulate({}, end=hour)
    _, s_continued = model.simulate({}, start=model.start, end=hour, state=state)
    np.testing.assert_array_equal(s_direct.z, s_continued.z)
    np.testing.assert_array_equal(result.series.iloc[0], direct.series.iloc[0])
    with pytest.raises(ValueError, match="before start"):
        model.simulate({}, start=hour, end=model.start)
