"""The packaged ``dommel`` case over its whole period (Sep-Nov 2010) with the true parameters.

References: conservation of volume (the balance of the run), the case's own geometry (bed and bank
level of every calculation point) and the plausibility requirements of the case issue (dry-weather
flows of tenths of m³/s; the 8-15 November 2010 event several-fold higher).
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.model import load_model


@pytest.fixture(scope="module")
def run():
    sim = load_model("dommel")
    result, state = sim.simulate(snapshots=True)
    return sim, result, state


def _bank_heights(sim) -> np.ndarray:
    """Bank height above the bed (m) of every calculation point: the profile's ``height``."""
    a = sim.compiled.arrays
    profiles = sim.case.network.profiles
    heights = []
    for i in range(sim.compiled.n_hpoints):
        first = a.sc_prof[a.sc_ptr[i]]
        heights.append(profiles[first].height)
    assert all(h is not None for h in heights), "every dommel profile states its bank height"
    return np.asarray(heights, dtype=float)


def test_three_month_volume_balance_closes(run) -> None:
    _, result, _ = run
    assert result.balance.relative_error < 1e-6
    assert result.balance.throughput > 1e7  # m³: Sep-Nov inflow of 130 km²


def test_every_series_is_finite(run) -> None:
    _, result, _ = run
    assert np.isfinite(result.series.to_numpy()).all()
    assert np.isfinite(result.levels.to_numpy()).all() and np.isfinite(result.discharges.to_numpy()).all()


def test_levels_stay_between_bed_and_bank(run) -> None:
    sim, result, _ = run
    z = result.levels.to_numpy()
    bed = sim.compiled.arrays.hp_bed
    bank = bed + _bank_heights(sim)
    assert (z >= bed).all(), f"lowest depth {(z - bed).min():.3f} m"
    assert (z <= bank).all(), f"highest level above bank {(z - bank).max():.3f} m"


def test_discharges_are_plausible_for_the_area(run) -> None:
    _, result, _ = run
    q = result.series["0029.Q"]
    dry = q.loc["2010-09-01":"2010-09-06"]
    assert 0.03 < dry.min() and dry.max() < 1.0  # tenths of m³/s in dry weather
    assert q.loc["2010-11-08":"2010-11-15"].max() > 5 * q.loc["2010-11-01":"2010-11-07"].mean()
