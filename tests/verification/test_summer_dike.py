"""A summer dike's storage fills by one curve and drains by another (SOBEK 3's hysteresis), through the engine.

Reference
---------
SOBEK 3's summer dike (flow1d ``GetSummerDikeTotal``, Deltares): the total area behind the dike grows along two
parabolas from 0 at the crest to full at crest + transition while the dike is "rising"; once the level has reached
crest + transition it drains along the same two parabolas spread from that level down to the dike's base level,
until the level has fallen to the base, after which it fills by the first curve again. At rest (a channel closed at
one end and held at a level at the other) the volume at a calculation point is therefore known by hand: the channel's
own (a rectangle here), the minimum storage area, and the dike's area on the curve its history selects.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.engine import EngineState
from tests.verification._support import START, case_dict, simulator, write_series

WIDTH, CREST, BASE, TRANSITION, TOTAL, FLOW = 20.0, 2.0, 1.2, 0.5, 500.0, 300.0
DX = 100.0
#: The boundary level (m AD) at hours: up over the full height, held, down between base and crest, held, down
#: below the base, up into the transition again, held.
PATH = {0: 1.0, 6: 3.0, 9: 3.0, 12: 1.8, 18: 1.8, 22: 1.0, 26: 1.0, 32: 2.2, 38: 2.2}


def _dike_area(level: float, falling: bool) -> float:
    """The area behind the dike (m²) at ``level`` on the rising or falling curve, written out from SOBEK 3's rule."""
    low = BASE if falling else CREST
    x = min(max((level - low) / (CREST + TRANSITION - low), 0.0), 1.0)
    return TOTAL * (2.0 * x * x if x <= 0.5 else 1.0 - 2.0 * (1.0 - x) ** 2)


def _sim(root: Path, mode: str = "interpolated"):
    hours = np.arange(0, 39)
    levels = np.interp(hours, list(PATH), list(PATH.values()))
    times = START + pd.to_timedelta(hours, unit="h")
    write_series(root, "level.csv", times, h=levels)
    data = case_dict(
        hours=38.0,
        engine={"dt": 300.0, "output_interval": 3600.0, "cross_sections": mode},
        initial={"level": 1.0, "depth": 0.0},
        profiles=[{"id": "p", "type": "zw", "heights": [0.0, 5.0], "flow_widths": [WIDTH, WIDTH],
                   "summer_dike": {"crest": CREST, "base": BASE, "flow_area": FLOW, "total_area": TOTAL,
                                   "transition": TRANSITION}}],
        nodes=[{"id": "sea"}, {"id": "end"}],
        branches=[{"id": "b", "from_node": "sea", "to_node": "end", "length": 1000.0, "dx": DX,
                   "cross_sections": [{"chainage": 0.0, "profile": "p", "bed_level": 0.0}]}],
        boundaries=[{"id": "h", "node": "sea", "type": "level", "series": {"file": "level.csv", "column": "h"}}],
    )
    return simulator(data, root)


def _expected_volume(sim, point: int, level: float, falling: bool) -> float:
    length = DX  # an inner point stores the water of its two half-links
    amin = sim.case.spec.engine.min_storage_area
    return length * (WIDTH * level + _dike_area(level, falling)) + amin * level


@pytest.mark.parametrize("mode", ["nearest", "interpolated"])
def test_the_storage_behind_a_summer_dike_drains_by_its_falling_curve_and_fills_again_by_its_rising_one(
        tmp_path: Path, mode: str) -> None:
    sim = _sim(tmp_path, mode)
    point = sim.compiled.hp_label.index("b@500.0")
    assert point in sim.compiled.dikes.hp
    checks = [("2020-01-01T09:00Z", 3.0, False), ("2020-01-01T18:00Z", 1.8, True),
              ("2020-01-02T02:00Z", 1.0, False), ("2020-01-02T14:00Z", 2.2, False)]
    state = None
    start = sim.start
    for when, level, falling in checks:
        end = pd.Timestamp(when)
        _, state = sim.simulate(start=start, end=end, state=state)
        start = end
        assert state.z[point] == pytest.approx(level, abs=2e-3)  # at rest: the boundary's level
        expected = _expected_volume(sim, point, float(state.z[point]), falling)
        assert state.vol[point] == pytest.approx(expected, rel=2e-4)
        other = _expected_volume(sim, point, float(state.z[point]), not falling)
        assert abs(state.vol[point] - other) > 100.0 * abs(state.vol[point] - expected) or level >= 3.0 \
            or level <= BASE
    # after the fall to 1.8 m AD the dike holds 0.43 of its area (the falling curve); the rising curve, none
    assert _dike_area(1.8, True) > 0.4 * TOTAL and _dike_area(1.8, False) == 0.0


def test_a_run_split_where_the_dikes_drain_equals_the_whole_run(tmp_path: Path) -> None:
    sim = _sim(tmp_path)
    whole, end_state = sim.simulate()
    middle = pd.Timestamp("2020-01-01T15:00Z")
    first, state = sim.simulate(end=middle)
    assert state.dikes is not None and state.dikes.all()  # every dike was topped by then, and drains
    state = EngineState.from_bytes(state.to_bytes())  # as the on-line store keeps it
    second, last = sim.simulate(start=middle, state=state)
    joined = pd.concat([first.series, second.series.iloc[1:]])
    assert np.array_equal(joined.to_numpy(), whole.series.to_numpy())
    assert np.array_equal(last.z, end_state.z) and np.array_equal(last.vol, end_state.vol)
    assert np.array_equal(last.dikes, end_state.dikes)
