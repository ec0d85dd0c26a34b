"""Mass conservation through junctions, loops, structures, laterals and drying branches.

Reference
---------
Conservation of volume over the model domain: final volume - initial volume = Σ volume in through
the boundaries + Σ lateral volume, i.e. ``VolumeBalance.residual`` = 0. The engine updates the
volumes with the same link fluxes that it reports at the boundaries (volume is its prognostic
variable), so the residual must be at round-off level: |residual| ≤ 1e-6 × throughput (the gross
volume exchanged with the outside). The balance is only as good as its test case, so the runs
here are dynamic (hydrographs, a tide, laterals that switch on and off, an extraction) and each
network includes the difficult parts: a junction of three branches, loops (a non-tree level
matrix with fill-in), weirs in free and submerged flow, and a side branch that falls dry.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.verification._support import START, assert_balance_closes, case_dict, simulator, write_series


def _hourly(hours: float) -> pd.DatetimeIndex:
    return pd.date_range(START, START + pd.Timedelta(hours=hours), freq="1h")


def _forcing_csv(root: Path, hours: float) -> str:
    """Hourly forcing: a flood wave, a side inflow that stops after 36 h, a rain pulse and a tide."""
    times = _hourly(hours)
    t = (times - START).total_seconds().to_numpy() / 3600.0
    flood = 8.0 + 22.0 * np.exp(-(((t - 30.0) / 10.0) ** 2)) + 10.0 * np.exp(-(((t - 110.0) / 8.0) ** 2))
    side = np.where(t < 36.0, 3.0, np.maximum(0.0, 3.0 * (1.0 - (t - 36.0) / 6.0)))
    rain = 4.0 * np.exp(-(((t - 60.0) / 4.0) ** 2))
    tide = 1.6 + 0.35 * np.sin(2.0 * np.pi * t / 12.42)
    return write_series(root, "forcing.csv", times, flood=flood, side=side, rain=rain, tide=tide)


def _branch(ident: str, a: str, b: str, length: float, bed_a: float, bed_b: float, profile: str, **extra) -> dict:
    """A prismatic branch from node ``a`` (bed ``bed_a``, m AD) to node ``b`` (bed ``bed_b``)."""
    return {"id": ident, "from_node": a, "to_node": b, "length": length, **extra,
            "cross_sections": [{"chainage": 0.0, "profile": profile, "bed_level": bed_a},
                               {"chainage": length, "profile": profile, "bed_level": bed_b}]}


PROFILES = [
    {"id": "main", "type": "trapezoidal", "bottom_width": 10.0, "side_slope": 1.5},
    {"id": "side", "type": "trapezoidal", "bottom_width": 3.0, "side_slope": 1.0},
    {"id": "ditch", "type": "zw", "heights": [0.0, 0.5, 2.0, 4.0], "flow_widths": [1.0, 4.0, 8.0, 10.0],
     "total_widths": [1.0, 5.0, 12.0, 20.0]},
]


def test_y_junction_conserves_mass(tmp_path: Path) -> None:
    hours = 48.0
    csv = _forcing_csv(tmp_path, hours)
    data = case_dict(
        hours=hours,
        engine={"dt": 60.0},
        initial={"depth": 1.2},
        profiles=PROFILES,
        nodes=[{"id": "a"}, {"id": "c"}, {"id": "j"}, {"id": "o"}],
        branches=[
            _branch("A", "a", "j", 4000.0, 2.6, 1.0, "main"),
            _branch("C", "c", "j", 2500.0, 2.0, 1.0, "side"),
            _branch("O", "j", "o", 3000.0, 1.0, 0.4, "main"),
        ],
        boundaries=[
            {"id": "Qa", "node": "a", "type": "discharge", "series": {"file": csv, "column": "flood"}},
            {"id": "Qc", "node": "c", "type": "discharge", "series": {"file": csv, "column": "side"}},
            {"id": "ho", "node": "o", "type": "level", "series": {"file": csv, "column": "tide"}},
        ],
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    # the boundary accounting against the forcing itself (step means of the linearly interpolated series)
    forcing = pd.read_csv(tmp_path / csv)
    assert result.balance.boundaries["Qa"] == pytest.approx(3600.0 * np.trapezoid(forcing["flood"]), rel=1e-9)
    assert result.balance.boundaries["Qc"] == pytest.approx(3600.0 * np.trapezoid(forcing["side"]), rel=1e-9)


def test_looped_network_conserves_mass(tmp_path: Path) -> None:
    """Two loops (j1-j2 via P and via Q-R; j3-j2 via R and via S-T), one arm with a weir, a rating outflow."""
    hours = 48.0
    csv = _forcing_csv(tmp_path, hours)
    data = case_dict(
        hours=hours,
        engine={"dt": 60.0},
        initial={"depth": 1.2},
        profiles=PROFILES,
        nodes=[{"id": "a"}, {"id": "j1"}, {"id": "j2"}, {"id": "j3"}, {"id": "j4", "storage_area": 500.0},
               {"id": "o"}],
        branches=[
            _branch("A", "a", "j1", 3000.0, 2.5, 1.5, "main"),
            _branch("P", "j1", "j2", 2000.0, 1.5, 1.0, "main"),
            _branch("Q", "j1", "j3", 1200.0, 1.5, 1.3, "side"),
            _branch("R", "j3", "j2", 1500.0, 1.3, 1.0, "side"),
            _branch("S", "j3", "j4", 800.0, 1.3, 1.2, "ditch"),
            _branch("T", "j4", "j2", 900.0, 1.2, 1.0, "ditch"),
            _branch("O", "j2", "o", 2500.0, 1.0, 0.5, "main"),
        ],
        weirs=[{"id": "WP", "branch": "P", "chainage": 1000.0, "crest_level": 2.2, "crest_width": 6.0}],
        laterals=[{"id": "rainQ", "branch": "Q", "chainage": 600.0, "series": {"file": csv, "column": "rain"}}],
        boundaries=[
            {"id": "Qa", "node": "a", "type": "discharge", "series": {"file": csv, "column": "flood"}},
            {"id": "ro", "node": "o", "type": "rating",
             "rating": {"levels": [0.5, 1.5, 2.5, 4.0], "discharges": [0.0, 8.0, 30.0, 90.0]}},
        ],
    )
    sim = simulator(data, tmp_path)
    assert sim.compiled.arrays.sv_nedge > sim.compiled.n_links  # loops: the factorisation has fill-in
    result, _ = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    # the weir arm carries water part of the time and none (head water below the crest) at other times
    weir_q = result.discharges["weir:WP"].to_numpy()
    assert weir_q.max() > 0.5 and (weir_q < 1e-9).any()


def test_week_with_laterals_weirs_and_a_drying_branch(tmp_path: Path) -> None:
    """One week: flood waves, tide, rain pulse, an extraction, two weirs, a side branch that runs dry.

    The side branch S falls steeply towards the junction; its inflow stops after 36-42 h. Its weir
    crest (3.3 m AD) then lies above the receding level, so a pond is trapped behind it while the
    reaches above the pond and between the weir and the backwater of the main river drain dry.
    """
    hours = 7 * 24.0
    csv = _forcing_csv(tmp_path, hours)
    data = case_dict(
        hours=hours,
        engine={"dt": 60.0},
        initial={"depth": 1.0},
        profiles=PROFILES,
        nodes=[{"id": "a"}, {"id": "s"}, {"id": "j"}, {"id": "o"}],
        branches=[
            _branch("A", "a", "j", 5000.0, 3.0, 1.0, "main"),
            _branch("S", "s", "j", 1500.0, 4.0, 1.0, "side", dx=50.0),
            _branch("O", "j", "o", 4000.0, 1.0, 0.2, "main"),
        ],
        weirs=[
            {"id": "WA", "branch": "A", "chainage": 2500.0, "crest_level": 2.6, "crest_width": 8.0,
             "discharge_coefficient": 1.1, "lateral_contraction": 0.95},
            {"id": "WS", "branch": "S", "chainage": 500.0, "crest_level": 3.3, "crest_width": 2.5},
        ],
        laterals=[
            {"id": "rainA", "branch": "A", "chainage": 1000.0, "series": {"file": csv, "column": "rain"}},
            {"id": "polder", "node": "j", "series": {"file": csv, "column": "rain"}},
            {"id": "intake", "branch": "O", "chainage": 2000.0, "value": -1.5},
        ],
        boundaries=[
            {"id": "Qa", "node": "a", "type": "discharge", "series": {"file": csv, "column": "flood"}},
            {"id": "Qs", "node": "s", "type": "discharge", "series": {"file": csv, "column": "side"}},
            {"id": "ho", "node": "o", "type": "level", "series": {"file": csv, "column": "tide"}},
        ],
        stations=[{"id": "WS", "structure": "WS", "quantities": ["h_up", "h_down", "Q"]},
                  {"id": "WA", "structure": "WA", "quantities": ["h_up", "h_down", "Q"]}],
    )
    sim = simulator(data, tmp_path)
    result, state = sim.simulate(snapshots=True)
    assert_balance_closes(result, sim)
    # the laterals: two rain pulses in, the full extraction out (the outlet reach never runs dry)
    forcing = pd.read_csv(tmp_path / csv)
    expected = 2.0 * 3600.0 * np.trapezoid(forcing["rain"]) - 1.5 * hours * 3600.0
    assert result.balance.laterals == pytest.approx(expected, rel=1e-9)

    bed = sim.compiled.arrays.hp_bed
    labels = result.levels.columns
    side = np.array([lab.startswith("S@") for lab in labels])
    chain = sim.compiled.hp_chainage
    depth_day1 = result.levels.loc[START + pd.Timedelta(hours=24)].to_numpy() - bed
    depth_end = state.z - bed
    above_pond = side & (chain < 300.0)
    below_weir = side & (chain > 550.0) & (bed > state.z[sim.compiled.hp_label.index("node:j")] + 0.1)
    assert above_pond.sum() >= 3 and below_weir.sum() >= 3
    # wet while the side inflow runs, dry at the end (depth at most a few times engine.min_depth)
    assert (depth_day1[above_pond | below_weir] > 0.1).all()
    assert (depth_end[above_pond | below_weir] < 0.01).all()
    # the pond behind the side weir: trapped water just below the crest, no more flow over it
    ws = result.series.iloc[-1]
    assert 3.2 < ws["WS.h_up"] <= 3.3 + 1e-3
    assert abs(ws["WS.Q"]) < 1e-3
