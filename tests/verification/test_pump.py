"""A pump drains a storage basin between its switch levels, with the cycle times of a volume balance.

Reference
---------
A basin of plan area A (m²) with a constant inflow Q_in (m³/s) and a pump of capacity Q_p > Q_in
that starts at level h_on and stops at h_off (m AD): the level rises at Q_in / A while the pump is off
and falls at (Q_p - Q_in) / A while it runs, so each pause lasts A (h_on - h_off) / Q_in and each run
A (h_on - h_off) / (Q_p - Q_in). The engine decides the switch from the level at the start of a step,
so the level may pass a switch level by up to one step's change (a rise of Q_in Δt / A, a fall of
(Q_p - Q_in) Δt / A): a cycle's amplitude lies between h_on - h_off and that plus one rise and one fall,
and each measured duration within a step of the times of that amplitude.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.verification._support import case_dict, simulator

AREA = 10_000.0  # m², the basin's storage area
CHANNEL_WIDTH = 1.0  # m, the rectangular outlet channel
Q_IN = 0.2  # m³/s
CAPACITY = 0.5  # m³/s
H_ON, H_OFF = 2.0, 1.5  # m AD


def test_pump_cycles_between_its_switch_levels_with_the_volume_balance_times(tmp_path: Path) -> None:
    data = case_dict(
        hours=72.0,
        engine={"dt": 60.0, "output_interval": 60.0},
        initial={"depth": 1.0},
        profiles=[{"id": "ditch", "type": "rectangular", "width": CHANNEL_WIDTH}],
        nodes=[{"id": "basin", "storage_area": AREA}, {"id": "out"}],
        branches=[{"id": "outlet", "from_node": "basin", "to_node": "out", "length": 200.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "ditch", "bed_level": 0.0},
                                      {"chainage": 200.0, "profile": "ditch", "bed_level": -0.5}]}],
        boundaries=[{"id": "in", "node": "basin", "type": "discharge", "value": Q_IN},
                    {"id": "sea", "node": "out", "type": "level", "value": 0.0}],
    )
    data["pumps"] = [{"id": "P", "branch": "outlet", "chainage": 5.0, "capacity": CAPACITY,
                      "start_level": H_ON, "stop_level": H_OFF}]
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    q = result.discharges.iloc[:, sim.compiled.structure_link["P"]].to_numpy()
    basin = result.levels.iloc[:, sim.compiled.hp_label.index("node:basin")].to_numpy()

    # the suction point holds the basin plus half of the pump's 10 m channel segment and the minimum area
    area = AREA + 0.5 * sim.settings.structure_length * CHANNEL_WIDTH + sim.settings.min_storage_area
    rise, fall = Q_IN * sim.dt / area, (CAPACITY - Q_IN) * sim.dt / area  # m per step
    assert set(np.unique(q)) == {0.0, CAPACITY}  # off or at capacity, nothing between
    first_stop = np.flatnonzero(q > 0.0)[0]
    assert basin.max() <= H_ON + rise and basin[first_stop:].min() >= H_OFF - fall

    switches = np.flatnonzero(np.diff(q) != 0.0) + 1
    durations = np.diff(switches) * sim.dt  # s, whole pauses and runs after the first start
    on = durations[q[switches[:-1]] > 0.0]
    off = durations[q[switches[:-1]] == 0.0]
    assert on.size >= 3 and off.size >= 3
    expected_on = area * (H_ON - H_OFF) / (CAPACITY - Q_IN)
    expected_off = area * (H_ON - H_OFF) / Q_IN
    slack_on = (rise + fall) / fall * sim.dt + sim.dt  # s: the extra amplitude, and one step
    slack_off = (rise + fall) / rise * sim.dt + sim.dt
    assert np.all((on >= expected_on - sim.dt) & (on <= expected_on + slack_on)), (on, expected_on)
    assert np.all((off >= expected_off - sim.dt) & (off <= expected_off + slack_off)), (off, expected_off)
    assert abs(result.balance.residual) <= 1e-6 * result.balance.throughput
