"""A step divided after a long one starts from the last change scaled to its own length.

Reference
---------
A channel that falls dry towards its mouth, where its last profile is a closed rectangle (a culvert-like
section, 30 m wide and 4 m high, interpolated with the open profile upstream), fills from a level boundary of
2.5 m at the mouth and from 100 m³/s at its head. The first step at 60 s filled the mouth's last point by 2.4 m in
its first half; the step control then divided the second half 2^14 times. Each sub-step's first iterate was the
level plus the *whole* last change, 2.4 m: past the top of the closed rectangle, where its storage width drops to
the slot's, so that the iterations never came back and the smallest sub-step committed a level 3.5 km above the
bed; the run stopped ("velocity 20.3 m/s exceeds engine.max_velocity"). The engine, like the accuracy control that
judges the sub-step, extrapolates the last change over the sub-step's own length
(:func:`rivercal.engine.kernels.picard.first_iterate`).

Checked: the run at the model's own step of 60 s finishes, no level rises above the highest level the model
can reach (the boundary's 2.5 m plus the head that carries 100 m³/s, well under 4 m: the rectangle never fills),
and its levels after the first hour are within 1 cm (root mean square per point) of a run at 10 s, the robustness
sweep's measure (docs/real-models.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.verification._support import case_dict, simulator

#: The open profile upstream (across m, bed m above its lowest point): D-Flow FM's c01 test model's yz profile.
Y = [0.0, 0.001, 5.0, 10.0, 20.0, 30.0, 40.0, 45.0, 49.999, 50.0]
Z = [3.0, 2.5, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 2.5, 3.0]
MOUTH_LEVEL = 2.5  # m AD


def _case(dt: float) -> dict:
    return case_dict(
        hours=2.0,
        engine={"dt": dt, "output_interval": 60.0, "cross_sections": "interpolated", "theta": 0.55},
        initial={"depth": 0.0},
        friction={"type": "chezy", "value": 55.0},
        profiles=[{"id": "open", "type": "yz", "y": Y, "z": Z},
                  {"id": "closed", "type": "rectangular", "width": 30.0, "height": 4.0, "closed": True}],
        nodes=[{"id": "head", "x": 2000.0, "y": 0.0}, {"id": "mouth", "x": 0.0, "y": 0.0}],
        branches=[{"id": "T1", "from_node": "head", "to_node": "mouth", "length": 2000.0, "dx": 50.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "open", "bed_level": 0.5},
                                      {"chainage": 2000.0, "profile": "closed", "bed_level": 0.0}]}],
        boundaries=[{"id": "inflow", "node": "head", "type": "discharge", "value": 100.0},
                    {"id": "sea", "node": "mouth", "type": "level", "value": MOUTH_LEVEL}],
    )


def test_a_channel_filling_into_a_closed_profile_runs_at_its_own_step(tmp_path: Path) -> None:
    runs = {}
    for dt in (60.0, 10.0):
        sim = simulator(_case(dt), tmp_path)
        result, _ = sim.simulate(snapshots=True)
        runs[dt] = result.levels
        assert sim.last_run_stats["divided_steps"] > 0  # the filling divides steps at both
    coarse, fine = runs[60.0], runs[10.0]
    assert coarse.to_numpy().max() < 4.0 and fine.to_numpy().max() < 4.0  # never up to the rectangle's top
    later = coarse.index >= coarse.index[0] + np.timedelta64(1, "h")
    rmse = np.sqrt(((coarse[later] - fine.loc[coarse.index[later]]) ** 2).mean())
    assert rmse.max() < 0.01, rmse.sort_values().tail(3)
