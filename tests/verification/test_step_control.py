"""The engine's step control: a step is divided where the flow needs it, the same way in a run split in two,
and a numerical pulsation of the old fixed step is gone.

References: the same case at a step short enough that the control never acts (5 or 10 s), and the run itself,
split in two at a hot start (exact: a run continued from a state must compute what the whole run computes,
to the last bit, which holds only if the step control's state travels with the engine state).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.verification._support import case_dict, simulator

pytestmark = pytest.mark.slow


def steep(root: Path, dt: float, hours: float = 6.0):
    """A steep reach (slope 0.01, 2.6 m/s) on a 25 m grid: any step above ~20 s is divided."""
    data = case_dict(
        hours=hours, engine={"dt": dt, "output_interval": max(600.0, dt)}, initial={"depth": 0.5},
        friction={"type": "strickler", "value": 30.0},
        profiles=[{"id": "r", "type": "rectangular", "width": 7.0}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "A", "from_node": "up", "to_node": "down", "length": 3000.0, "dx": 25.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 30.0},
                                      {"chainage": 3000.0, "profile": "r", "bed_level": 0.0}]}],
        boundaries=[{"id": "Q", "node": "up", "type": "discharge", "value": 20.0},
                    {"id": "h", "node": "down", "type": "level", "value": 1.0}],
    )
    root.mkdir(parents=True, exist_ok=True)
    return simulator(data, root)


def test_a_run_split_while_its_steps_are_divided_equals_the_whole_run(tmp_path: Path) -> None:
    sim = steep(tmp_path, 600.0)
    whole, end_state = sim.simulate(snapshots=True)
    assert sim.last_run_stats["divided_steps"] > 0
    mid = sim.start + pd.Timedelta(hours=1)  # the cold start's adjustment is still going on
    first, state = sim.simulate(end=mid, snapshots=True)
    assert state.control.any()  # the control is dividing steps at the split
    second, split_state = sim.simulate(start=mid, state=state, snapshots=True)
    joined = pd.concat([first.levels, second.levels.iloc[1:]])
    assert np.array_equal(joined.to_numpy(), whole.levels.to_numpy())
    assert np.array_equal(split_state.z, end_state.z) and np.array_equal(split_state.control, end_state.control)


def _shallow(root: Path, dt: float):
    """A shallow stream (Manning 0.1, 1 m wide, 20 l/s) with two culverts and a weir, falling onto a low
    downstream level: with a fixed 300 s step the last point pulsed by 2 cm every 20-25 minutes for two days."""
    slope, length = 2e-3, 3000.0
    data = case_dict(
        hours=48.0, engine={"dt": dt, "output_interval": 300.0}, initial={"depth": 0.15},
        friction={"type": "manning", "value": 0.1},
        profiles=[{"id": "p", "type": "trapezoidal", "bottom_width": 1.0, "side_slope": 1.5}],
        nodes=[{"id": "a"}, {"id": "b"}],
        branches=[{"id": "B", "from_node": "a", "to_node": "b", "length": length, "dx": 20.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "p", "bed_level": slope * length},
                                      {"chainage": length, "profile": "p", "bed_level": 0.0}]}],
        boundaries=[],
        weirs=[{"id": "W1", "branch": "B", "chainage": 1500.0, "crest_level": 3.1, "crest_width": 1.0}],
    )
    data["culverts"] = [{"id": "C0", "branch": "B", "chainage": 700.0, "shape": "circular", "diameter": 0.3,
                   "invert_level": 4.65, "length": 20.0},
                  {"id": "C2", "branch": "B", "chainage": 2300.0, "shape": "circular", "diameter": 0.6,
                   "invert_level": 1.4, "length": 20.0}]
    data["boundaries"] = [{"id": "Q", "node": "a", "type": "discharge", "value": 0.02},
                          {"id": "H", "node": "b", "type": "level", "value": 0.1}]
    root.mkdir(parents=True, exist_ok=True)
    return simulator(data, root)


def test_a_pulsation_of_the_fixed_step_is_resolved_and_agrees_with_a_short_step(tmp_path: Path) -> None:
    fine_sim = _shallow(tmp_path / "fine", 10.0)
    fine, _ = fine_sim.simulate(snapshots=True)
    sim = _shallow(tmp_path / "coarse", 300.0)
    coarse, _ = sim.simulate(snapshots=True)
    assert sim.last_run_stats["flickers"] > 0 or sim.last_run_stats["divided_steps"] > 0
    after = coarse.levels.index >= coarse.levels.index[0] + pd.Timedelta(hours=12)
    levels = coarse.levels[after].to_numpy()
    change = np.diff(levels, axis=0)
    turns = (change[1:] * change[:-1] < 0) & (np.abs(change[1:]) > 0.01) & (np.abs(change[:-1]) > 0.01)
    assert turns.sum() == 0  # no level turns up and down by more than 1 cm from one output to the next
    assert np.abs(levels - fine.levels[after].to_numpy()).max() < 0.01
