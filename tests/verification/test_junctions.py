"""Junctions: a dead-end branch rests at the junction's level, symmetric junctions stay symmetric, mass closes.

Reference
---------
- A branch that ends blind (no boundary, no lateral) carries no flow in a steady state: the exact
  solution there is u = 0 and a horizontal surface at the junction's level, and the main channel runs
  as if the branch were not there. A link that leaves a junction takes momentum from the flows arriving
  there only in proportion to its own share of the outflow; were it given the junction's whole inflow,
  a side branch would stand about a velocity head above the junction and swing for ever.
- Mirror symmetry: in a network that is its own mirror image (two identical branches leaving, or two
  identical branches with identical inflows joining) the two branches carry the same discharges and
  levels at every time, whatever the numbering of their points and links.
- Conservation of volume (``VolumeBalance.residual`` at round-off), as in ``test_mass_balance.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tests.verification._support import START, assert_balance_closes, branch_points, case_dict, simulator, write_series

PROFILES = [
    {"id": "main", "type": "trapezoidal", "bottom_width": 10.0, "side_slope": 1.5},
    {"id": "side", "type": "trapezoidal", "bottom_width": 4.0, "side_slope": 1.5},
]


def _branch(ident: str, a: str, b: str, length: float, bed_a: float, bed_b: float, profile: str = "main") -> dict:
    return {"id": ident, "from_node": a, "to_node": b, "length": length,
            "cross_sections": [{"chainage": 0.0, "profile": profile, "bed_level": bed_a},
                               {"chainage": length, "profile": profile, "bed_level": bed_b}]}


def _straight_channel(tmp_path: Path, *, dead_end: bool):
    """15 m³/s through 4 km of channel (0.55 m/s at the junction), with or without a 1 km blind side branch."""
    branches = [_branch("A", "up", "J", 2000.0, 0.4, 0.2), _branch("B", "J", "down", 2000.0, 0.2, 0.0)]
    nodes = [{"id": "up"}, {"id": "J"}, {"id": "down"}]
    if dead_end:
        branches.append(_branch("S", "J", "dead", 1000.0, 0.2, 0.2, "side"))
        nodes.append({"id": "dead"})
    data = case_dict(
        hours=48.0,
        engine={"dt": 60.0, "output_interval": 600.0},
        initial={"depth": 0.0, "level": 1.8},
        profiles=PROFILES,
        nodes=nodes,
        branches=branches,
        boundaries=[{"id": "Q", "node": "up", "type": "discharge", "value": 15.0},
                    {"id": "h", "node": "down", "type": "level", "value": 1.8}],
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    return sim, result


def test_a_dead_end_branch_comes_to_rest_at_the_junction_level(tmp_path: Path) -> None:
    sim, result = _straight_channel(tmp_path, dead_end=True)
    assert_balance_closes(result, sim)
    last_hours = result.discharges.index >= result.discharges.index[-1] - pd.Timedelta(hours=6)
    side_links = [c for c in result.discharges.columns if c.startswith("S@")]
    side_q = result.discharges.loc[last_hours, side_links].to_numpy()
    assert np.abs(side_q).max() < 1e-6, f"side branch still flows: {np.abs(side_q).max():.3g} m³/s"
    _, idx = branch_points(sim, "S")
    levels = result.levels.iloc[-1].to_numpy()
    junction = levels[sim.compiled.hp_label.index("node:J")]
    assert np.abs(levels[idx] - junction).max() < 1e-3
    # the main channel flows past the branch as if it were not there
    main = result.discharges.iloc[-1][[c for c in result.discharges.columns if c[0] in "AB"]].to_numpy()
    assert np.allclose(main, 15.0, atol=1e-6)
    plain_sim, plain = _straight_channel(tmp_path, dead_end=False)
    for branch in ("A", "B"):
        _, with_idx = branch_points(sim, branch)
        _, plain_idx = branch_points(plain_sim, branch)
        diff = levels[with_idx] - plain.levels.iloc[-1].to_numpy()[plain_idx]
        assert np.abs(diff).max() < 1e-6, f"branch {branch}: {np.abs(diff).max():.3g} m from the channel without it"


def _hydrograph(root: Path, hours: float) -> str:
    times = pd.date_range(START, START + pd.Timedelta(hours=hours), freq="1h")
    t = (times - START).total_seconds().to_numpy() / 3600.0
    flood = 6.0 + 18.0 * np.exp(-(((t - 12.0) / 5.0) ** 2))
    return write_series(root, "flood.csv", times, flood=flood)


def _mirrored(sim, result, left: str, right: str) -> None:
    """The two branches ``left`` and ``right`` hold the same discharges and levels at every output time."""
    dl = result.discharges[[c for c in result.discharges.columns if c.startswith(f"{left}@")]].to_numpy()
    dr = result.discharges[[c for c in result.discharges.columns if c.startswith(f"{right}@")]].to_numpy()
    assert dl.shape == dr.shape and np.abs(dl).max() > 1.0
    assert np.abs(dl - dr).max() <= 1e-9 * np.abs(dl).max()
    _, il = branch_points(sim, left)
    _, ir = branch_points(sim, right)
    levels = result.levels.to_numpy()
    assert np.abs(levels[:, il[1:-1]] - levels[:, ir[1:-1]]).max() <= 1e-9


def test_a_symmetric_bifurcation_splits_evenly(tmp_path: Path) -> None:
    hours = 36.0
    csv = _hydrograph(tmp_path, hours)
    data = case_dict(
        hours=hours,
        engine={"dt": 60.0},
        initial={"depth": 1.5},
        profiles=PROFILES,
        nodes=[{"id": "up"}, {"id": "J"}, {"id": "b"}, {"id": "c"}],
        branches=[_branch("A", "up", "J", 3000.0, 0.6, 0.3), _branch("B", "J", "b", 2000.0, 0.3, 0.1, "side"),
                  _branch("C", "J", "c", 2000.0, 0.3, 0.1, "side")],
        boundaries=[{"id": "Q", "node": "up", "type": "discharge", "series": {"file": csv, "column": "flood"}},
                    {"id": "hb", "node": "b", "type": "level", "value": 1.6},
                    {"id": "hc", "node": "c", "type": "level", "value": 1.6}],
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    _mirrored(sim, result, "B", "C")
    inflow = result.discharges.iloc[-1][[c for c in result.discharges.columns if c.startswith("A@")][-1]]
    outflow = result.discharges.iloc[-1][next(c for c in result.discharges.columns if c.startswith("B@"))]
    assert abs(2.0 * outflow - inflow) < 1e-3 * inflow


def test_two_equal_streams_join_symmetrically(tmp_path: Path) -> None:
    hours = 36.0
    csv = _hydrograph(tmp_path, hours)
    data = case_dict(
        hours=hours,
        engine={"dt": 60.0},
        initial={"depth": 1.5},
        profiles=PROFILES,
        nodes=[{"id": "a"}, {"id": "c"}, {"id": "J"}, {"id": "down"}],
        branches=[_branch("A", "a", "J", 2500.0, 0.5, 0.3, "side"), _branch("C", "c", "J", 2500.0, 0.5, 0.3, "side"),
                  _branch("B", "J", "down", 3000.0, 0.3, 0.0)],
        boundaries=[{"id": "Qa", "node": "a", "type": "discharge", "series": {"file": csv, "column": "flood"}},
                    {"id": "Qc", "node": "c", "type": "discharge", "series": {"file": csv, "column": "flood"}},
                    {"id": "h", "node": "down", "type": "level", "value": 1.8}],
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    _mirrored(sim, result, "A", "C")
