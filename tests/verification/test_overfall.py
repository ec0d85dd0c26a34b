"""A ditch that falls into a deeper channel: critical flow over the brink, at rest, instead of a flip-flop.

Reference
---------
Where a channel's bed ends above the water of the channel it joins, the water leaves over a free
overfall, and the flow over the brink is critical (Chow 1959, *Open-channel hydraulics*, §3-4 and
§15-1): for a rectangular section of width W, Q = W √g d_c^(3/2) with the upstream depth above the brink
h1 = 3/2 d_c (specific energy, the approach velocity head neglected). A horizontal ditch of 1.5 m
carrying 0.3 m³/s onto a main channel whose water stands 0.5 m below its bed must so stand 1.5 d_c =
0.240 m deep just above the brink (its last calculation point, 10 m upstream), and come to rest. Before
the overfall treatment (:mod:`rivercal.engine.kernels.overfall`) such a point — Dellen's culvert outlet
above a deeper watercourse, imported from D-HYDRO — alternated by 2.4 m from step to step and stood up to
1.5 m below its bed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.verification._support import G, assert_balance_closes, branch_points, case_dict, max_level_change, simulator

DITCH_Q, DITCH_W, BRINK = 0.3, 1.5, 1.2


def test_a_ditch_falls_freely_into_a_deeper_channel_at_critical_flow(tmp_path: Path) -> None:
    data = case_dict(
        hours=24.0,
        engine={"dt": 60.0, "output_interval": 600.0},
        initial={"depth": 0.0, "level": 0.6},
        profiles=[{"id": "main", "type": "trapezoidal", "bottom_width": 10.0, "side_slope": 1.5},
                  {"id": "ditch", "type": "rectangular", "width": DITCH_W}],
        nodes=[{"id": "a"}, {"id": "J"}, {"id": "b"}, {"id": "s"}],
        branches=[
            {"id": "M1", "from_node": "a", "to_node": "J", "length": 1000.0,
             "cross_sections": [{"chainage": 0.0, "profile": "main", "bed_level": 0.2},
                                {"chainage": 1000.0, "profile": "main", "bed_level": 0.0}]},
            {"id": "M2", "from_node": "J", "to_node": "b", "length": 1000.0,
             "cross_sections": [{"chainage": 0.0, "profile": "main", "bed_level": 0.0},
                                {"chainage": 1000.0, "profile": "main", "bed_level": -0.2}]},
            {"id": "D", "from_node": "s", "to_node": "J", "length": 200.0, "dx": 10.0,
             "cross_sections": [{"chainage": 0.0, "profile": "ditch", "bed_level": BRINK},
                                {"chainage": 200.0, "profile": "ditch", "bed_level": BRINK}]},
        ],
        boundaries=[{"id": "Qa", "node": "a", "type": "discharge", "value": 2.0},
                    {"id": "Qs", "node": "s", "type": "discharge", "value": DITCH_Q},
                    {"id": "hb", "node": "b", "type": "level", "value": 0.5}],
    )
    sim = simulator(data, tmp_path)
    assert sim.compiled.arrays.dl_link.size == 1  # the ditch's last link ends above the junction's bed
    result, _ = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    assert max_level_change(result.levels) < 1e-5  # at rest, no step-to-step alternation
    last_hours = result.levels.iloc[-7:].to_numpy()
    assert np.ptp(last_hours, axis=0).max() < 1e-4
    junction = result.levels.iloc[-1].to_numpy()[sim.compiled.hp_label.index("node:J")]
    assert junction < BRINK - 0.3  # the fall is free: the main channel stands far below the brink
    _, idx = branch_points(sim, "D")
    above_brink = result.levels.iloc[-1].to_numpy()[idx[-2]] - BRINK  # the ditch's last point, 10 m upstream
    d_c = (DITCH_Q / (DITCH_W * np.sqrt(G))) ** (2.0 / 3.0)
    assert above_brink == pytest.approx(1.5 * d_c, rel=0.03)
    bed = sim.compiled.arrays.hp_bed
    assert (result.levels.to_numpy() >= bed - 1e-6).all()
