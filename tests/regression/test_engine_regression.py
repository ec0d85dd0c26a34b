"""The engine's station series have not moved: regression against stored references.

The references (``data/*.csv``, written by ``python -m tests.regression.references``) are the engine's
own earlier results, not an independent truth: the verification tests check the physics, these check
that a refactoring or a speed-up leaves the results where they were. The tolerance, 0.02 mm and
0.02 l/s, is well below the engine's Picard tolerance (0.1 mm): round-off differences (a different
but equivalent order of operations) pass, a changed equation does not.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.regression.references import RUNS, path, simulate

TOLERANCE = 2e-5  # m for levels, m³/s for discharges


@pytest.mark.parametrize("name", sorted(RUNS))
def test_station_series_match_the_reference(name: str) -> None:
    ref = pd.read_csv(path(name), index_col="time", parse_dates=["time"])
    new = simulate(name)
    assert list(new.columns) == list(ref.columns), "the case's observables changed: regenerate the references"
    assert new.index.equals(ref.index), "the output times changed"
    diff = np.abs(new.to_numpy() - ref.to_numpy())
    assert not np.isnan(new.to_numpy()).any()
    worst = np.unravel_index(int(np.argmax(diff)), diff.shape)
    assert diff.max() <= TOLERANCE, (
        f"{name}: {new.columns[worst[1]]} at {new.index[worst[0]]} moved by {diff.max():.3g} "
        f"(reference {ref.iat[worst]:.6f}, now {new.iat[worst]:.6f}); if the change is meant, regenerate with "
        "`python -m tests.regression.references` and say why in the commit"
    )
