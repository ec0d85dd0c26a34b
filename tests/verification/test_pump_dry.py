"""A pump whose stop level lies below the bed stops when its suction point runs dry, and never diverges.

Reference: the water balance. A closed basin (no inflow but a small lateral) drained by a pump into a lower
level boundary: the pump can take out at most what the basin holds, so the basin ends at the depth where a
pump must stop (1 cm of water at its suction point) and every cubic metre pumped is a cubic metre the
basin lost. With the lateral, the pump restarts at 2 cm and cycles between the two.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.verification._support import assert_balance_closes, case_dict, simulator


def basin(root: Path, inflow: float, dt: float = 60.0):
    data = case_dict(
        hours=24.0, engine={"dt": dt, "output_interval": 600.0}, initial={"depth": 1.5},
        profiles=[{"id": "r", "type": "rectangular", "width": 10.0}],
        nodes=[{"id": "a"}, {"id": "b"}, {"id": "c"}],
        branches=[{"id": "basin", "from_node": "a", "to_node": "b", "length": 500.0, "dx": 50.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 0.0},
                                      {"chainage": 500.0, "profile": "r", "bed_level": 0.0}]},
                  {"id": "out", "from_node": "b", "to_node": "c", "length": 200.0, "dx": 50.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": -3.0},
                                      {"chainage": 200.0, "profile": "r", "bed_level": -3.0}]}],
        boundaries=[{"id": "sea", "node": "c", "type": "level", "value": -2.0}],
        laterals=[{"id": "seepage", "branch": "basin", "chainage": 250.0, "value": inflow}],
        stations=[{"id": "pool", "branch": "basin", "chainage": 250.0, "quantities": ["h"]}],
    )
    data["pumps"] = [{"id": "P", "branch": "out", "chainage": 100.0, "capacity": 2.0, "start_level": -0.5,
                      "stop_level": -1.0}]  # both below the basin's bed at 0 m AD
    data["initial"] = {"depth": 1.0, "level": 1.5}
    root.mkdir(parents=True, exist_ok=True)
    return simulator(data, root)


@pytest.mark.parametrize("dt", [60.0, 600.0])
def test_a_pump_stopping_below_the_bed_drains_its_basin_to_the_dry_depth_and_stops(tmp_path: Path, dt: float) -> None:
    sim = basin(tmp_path, 0.0, dt)
    result, state = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    pool = result.series["pool.h"]
    assert pool.iloc[0] > 1.4 and pool.iloc[-1] < 0.05  # drained ...
    assert pool.min() > -0.05  # ... never below the bed
    assert state.pump_on[0] == 0.0  # and stopped


def test_with_an_inflow_the_pump_cycles_between_the_dry_depth_and_its_restart(tmp_path: Path) -> None:
    sim = basin(tmp_path, 0.01)
    result, _ = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    late = result.series["pool.h"].iloc[len(result.series) // 2:]
    assert late.min() > -0.01 and late.max() < 0.06
    assert np.isfinite(late).all()
