"""Withdrawals larger than the inflow: limited to the water present, reported, never below the bed.

Reference
---------
Conservation of volume. A branch fed with 0.2 m³/s from which a discharge boundary (or an extraction
lateral) asks 0.5 m³/s (1.0 m³/s) cannot deliver more than what flows in plus what it holds: once its
water is drawn down the withdrawal can take the inflow and no more, the levels stay at or above the bed,
the volumes are not negative, and what was asked beyond that is a shortfall (volume asked minus volume
delivered, which closes the balance). Before this, the boundary drew its point 8,918 m below the bed and
diverged later with a velocity message; the lateral was limited silently.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from tests.verification._support import assert_balance_closes, case_dict, simulator

INFLOW = 0.2


def _branch(tmp_path: Path, *, boundary: float | None = None, lateral: float | None = None, hours: float = 48.0):
    boundaries = [{"id": "in", "node": "up", "type": "discharge", "value": INFLOW}]
    laterals = []
    if boundary is not None:
        boundaries.append({"id": "out", "node": "down", "type": "discharge", "value": boundary})
    if lateral is not None:
        laterals.append({"id": "pump", "node": "down", "value": lateral})
    data = case_dict(
        hours=hours,
        engine={"dt": 60.0, "output_interval": 3600.0},
        initial={"depth": 1.0},
        profiles=[{"id": "t", "type": "trapezoidal", "bottom_width": 3.0, "side_slope": 1.5}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "A", "from_node": "up", "to_node": "down", "length": 2000.0, "dx": 100.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "t", "bed_level": 1.0},
                                      {"chainage": 2000.0, "profile": "t", "bed_level": 0.0}]}],
        boundaries=boundaries,
        laterals=laterals,
    )
    sim = simulator(data, tmp_path)
    result, state = sim.simulate(snapshots=True)
    return sim, result, state


@pytest.mark.parametrize(("kind", "key", "asked"),
                         [("boundary", "boundary:out", 0.5), ("lateral", "lateral:pump", 1.0)])
def test_a_withdrawal_takes_only_the_water_there_is_and_reports_the_rest(tmp_path: Path, caplog, kind: str, key: str,
                                                                        asked: float) -> None:
    with caplog.at_level(logging.WARNING, logger="rivercal.engine.simulator"):
        sim, result, state = _branch(tmp_path, **{kind: -asked})
    assert_balance_closes(result, sim)
    bed = sim.compiled.arrays.hp_bed
    assert (result.levels.to_numpy() >= bed - 1e-6).all(), "a level fell below its bed"
    assert (state.vol >= 0.0).all()
    # drawn down, the withdrawal takes what flows in: the levels come to rest
    assert result.levels.iloc[-1].to_numpy() == pytest.approx(result.levels.iloc[-2].to_numpy(), abs=2e-3)
    short = result.shortfalls[key]
    hours = 48.0
    assert short.requested == pytest.approx(asked * hours * 3600.0)
    took = -(result.balance.boundaries["out"] if kind == "boundary" else result.balance.laterals)
    assert short.delivered == pytest.approx(took, rel=1e-9)
    # what it took: the inflow of the two days plus most of what the branch held
    held = result.balance.initial - result.balance.final
    assert short.delivered == pytest.approx(INFLOW * hours * 3600.0 + held, rel=1e-6)
    assert short.missing > 0.5 * short.requested
    assert any(key in r.getMessage() and "asked" in r.getMessage() for r in caplog.records)


def test_a_withdrawal_the_branch_can_feed_has_no_shortfall(tmp_path: Path) -> None:
    _, result, _ = _branch(tmp_path, boundary=-0.1)
    assert result.shortfalls == {}
    assert result.balance.boundaries["out"] == pytest.approx(-0.1 * 48.0 * 3600.0)
