"""A weir a few metres upstream of a junction: steady inflow must give a steady, smooth outflow.

Reference
---------
Mass conservation in a steady state: with a constant inflow Q_in and a constant downstream level,
the discharge over the weir and through every link below it tends to Q_in, and stays there from
step to step. The reference note (delft-scheme-and-engines.md, "Wetting/drying") states the
condition for the scheme to keep a cell's depth positive without throttling: the volume that
leaves a cell in one step must not exceed what it holds, i.e. a velocity Courant number
|u|Δt/Δx ≲ 1.

The set-up reproduces the layout of weir ZL1-3014 in the dommel case, 16 m above the node where its
branch ends, with the bed of the next branch (and the water in the node) below the end of the weir's
branch: with a 10 m structure segment, a cell of 11 m would be left between the weir and the node,
and at Δt = 60 s the water running down from it into the node empties it within one step. The engine
used to throttle that cell every step and flip its level by up to 1.3 m and the weir discharge by a
quarter of the inflow from step to step (solving each step four times); the grid now lets the weir
discharge into the node itself (see ``branch_layout``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.network.grid import branch_layout
from tests.verification._support import START, case_dict, simulator

Q_IN = 0.6  # m³/s
LENGTH, WEIR_AT = 3030.0, 3014.0  # m


def _case() -> dict:
    profile = {"id": "trap", "type": "trapezoidal", "bottom_width": 2.0, "side_slope": 1.5}
    return case_dict(
        hours=12.0,
        nodes=[{"id": "up", "x": 0.0, "y": 0.0}, {"id": "J", "x": LENGTH, "y": 0.0},
               {"id": "down", "x": LENGTH + 1000.0, "y": 0.0}],
        branches=[
            {"id": "A", "from_node": "up", "to_node": "J", "length": LENGTH, "dx": 100.0,
             "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": 10.0},
                                {"chainage": LENGTH, "profile": "trap", "bed_level": 9.7}]},
            {"id": "B", "from_node": "J", "to_node": "down", "length": 1000.0, "dx": 100.0,
             "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": 9.0},
                                {"chainage": 1000.0, "profile": "trap", "bed_level": 8.9}]},
        ],
        profiles=[profile],
        initial={"depth": 0.4},
        weirs=[{"id": "W", "branch": "A", "chainage": WEIR_AT, "crest_level": 10.3, "crest_width": 3.0}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge", "value": Q_IN},
                    {"id": "hout", "node": "down", "type": "level", "value": 9.3}],
        stations=[{"id": "W", "structure": "W", "quantities": ["h_up", "h_down", "Q"]},
                  {"id": "B1", "branch": "B", "chainage": 50.0, "quantities": ["Q"]}],
    )


def test_no_short_cell_is_left_between_a_structure_and_a_branch_end(tmp_path: Path, make_case) -> None:
    case = make_case(_case())
    branch = case.spec.network().branch("A")
    weir = case.spec.weirs[0]
    segments = branch_layout(branch, [weir], case.spec.engine.structure_length)
    last = segments[-1]
    assert last.structure is weir and last.b == LENGTH  # the weir reaches the node J
    assert last.a == pytest.approx(WEIR_AT - 0.5 * case.spec.engine.structure_length)
    channel = [s.b - s.a for s in segments if s.structure is None]
    assert min(channel) >= 0.5 * branch.dx


def test_weir_above_a_junction_carries_the_inflow_smoothly(tmp_path: Path) -> None:
    sim = simulator(_case(), tmp_path)
    result, _ = sim.simulate(output_interval=60.0)
    late = result.series.loc[START + pd.Timedelta(hours=8):]
    for column in ("W.Q", "B1.Q"):
        q = late[column].to_numpy()
        assert np.abs(q - Q_IN).max() < 0.01 * Q_IN, column  # steady at the inflow
        assert np.abs(np.diff(q)).max() < 1e-3 * Q_IN, column  # no step-to-step flip
    assert np.abs(np.diff(late["W.h_down"].to_numpy())).max() < 1e-4  # m per step
    assert sim.last_run_stats["drying_resolves"] == 0
