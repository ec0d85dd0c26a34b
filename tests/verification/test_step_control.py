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

from tests.verification._support import START, case_dict, simulator, write_series

pytestmark = pytest.mark.slow


def _reach(hours: float, engine: dict, initial: dict, strickler: float, width: float, length: float, dx: float,
           bed_up: float, bed_down: float, inflow: dict, level: dict) -> dict:
    """One rectangular reach from ``up`` to ``down`` (m), Strickler friction (m^(1/3)/s), a discharge boundary
    upstream and a level downstream (``inflow``, ``level``: ``{"value": …}`` or ``{"series": …}``)."""
    return case_dict(
        hours=hours, engine=engine, initial=initial, friction={"type": "strickler", "value": strickler},
        profiles=[{"id": "r", "type": "rectangular", "width": width}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "A", "from_node": "up", "to_node": "down", "length": length, "dx": dx,
                   "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": bed_up},
                                      {"chainage": length, "profile": "r", "bed_level": bed_down}]}],
        boundaries=[{"id": "Q", "node": "up", "type": "discharge", **inflow},
                    {"id": "h", "node": "down", "type": "level", **level}],
    )


def steep(root: Path, dt: float, hours: float = 6.0, **engine):
    """A steep reach (slope 0.01, 2.6 m/s) on a 25 m grid: any step above ~20 s is divided."""
    data = _reach(hours, {"dt": dt, "output_interval": max(600.0, dt), **engine}, {"depth": 0.5}, 30.0, 7.0,
                  3000.0, 25.0, 30.0, 0.0, {"value": 20.0}, {"value": 1.0})
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


def _rising(root: Path, dt: float, **engine):
    """A 20 km river (100 m wide, slope 5e-5, 300 m³/s) whose downstream level rises 2 m along a cosine in 36 h."""
    root.mkdir(parents=True, exist_ok=True)
    t = np.arange(0.0, 40.25, 0.25)
    h = 3.0 + 1.0 * (1.0 - np.cos(np.pi * np.clip(t, 0.0, 36.0) / 36.0))
    write_series(root, "h.csv", START + pd.to_timedelta(t, unit="h"), h=h)
    data = _reach(40.0, {"dt": dt, "output_interval": 3600.0, **engine},
                  {"level": 3.0, "depth": 0.0, "spinup": 24.0}, 30.0, 100.0, 20000.0, 500.0, 1.0, 0.0,
                  {"value": 300.0}, {"series": {"file": "h.csv", "column": "h"}})
    return simulator(data, root)


def test_a_river_rising_5_cm_an_hour_keeps_its_conveyance_in_step_at_an_hour_long_step(tmp_path: Path) -> None:
    """The channels' flow area and friction follow the levels within a step (the Picard iterations' geometry).

    Reference: the same river at 60 s. Its level path bends too little for the step control to divide a step
    (the figure is the scheme's own); with the geometry of each step's start the upstream levels lagged the rise
    by up to 1.9 cm (measured), with the geometry of the iterate they are within 1.2 cm.
    """
    fine, _ = _rising(tmp_path / "fine", 60.0).simulate(snapshots=True)
    sim = _rising(tmp_path / "hour", 3600.0)
    hour, _ = sim.simulate(snapshots=True)
    assert sim.last_run_stats["divided_steps"] == 0
    assert np.abs(hour.levels.to_numpy() - fine.levels.to_numpy()).max() < 0.015


def test_a_courant_limit_divides_each_step_so_that_no_link_is_crossed_faster(tmp_path: Path) -> None:
    """``engine.courant``: the steps of a fast reach are divided until |u| Δt / Δx stays within the limit.

    The steep reach's flow runs at about 2.65 m/s on 25 m links: at a 600 s step, 63.6 links a step. Without a
    limit its steady flow takes 32 sub-steps a step (the stability control's); a limit of 1 takes the next power
    of two that keeps every link within it (128 here, just above 2.67 m/s somewhere), a limit of 0.5 twice as
    many. The run agrees with a 5 s one, and a run split in two equals the whole (the limit is taken from the
    state at each step's start).
    """
    reference, _ = steep(tmp_path / "fine", 5.0).simulate(snapshots=True)
    per_step = {}
    for limit in (None, 1.0, 0.5):
        sim = steep(tmp_path / f"limit{limit}", 600.0, **({"courant": limit} if limit else {}))
        whole, _ = sim.simulate(snapshots=True)
        mid = sim.start + pd.Timedelta(hours=3)
        first, state = sim.simulate(end=mid, snapshots=True)
        second, _ = sim.simulate(start=mid, state=state, snapshots=True)  # the steady half
        per_step[limit] = sim.last_run_stats["substeps"] / sim.last_run_stats["steps"]
        assert np.array_equal(pd.concat([first.levels, second.levels.iloc[1:]]).to_numpy(), whole.levels.to_numpy())
        after = whole.levels.index >= mid
        assert np.abs(whole.levels[after].to_numpy() - reference.levels[after].to_numpy()).max() < 0.01
    assert per_step[None] < 64 <= per_step[1.0] and per_step[0.5] == 2 * per_step[1.0]


def test_a_smooth_flood_wave_is_not_divided_where_its_forcing_changes_from_step_to_step(tmp_path: Path) -> None:
    """The sub-steps of a divided step follow the forcing's course between the step's edges.

    With the step's mean discharge in every sub-step, the levels bent at each step's start whatever the sub-step
    (an hourly flood wave on the Waal divided its steps into 128 to 1,024 sub-steps for days); a divided step's
    inflow now moves linearly between the step's edges, as the series does, and the same wave divides its steps
    only where its own course bends.
    """
    t = np.arange(0.0, 97.0)
    q = 1000.0 + 3000.0 * np.clip(np.minimum(t - 12.0, 72.0 - t) / 30.0, 0.0, 1.0)
    tmp_path.mkdir(parents=True, exist_ok=True)
    write_series(tmp_path, "q.csv", START + pd.to_timedelta(t, unit="h"), q=q)
    data = _reach(96.0, {"dt": 3600.0, "output_interval": 3600.0}, {"depth": 4.0}, 35.0, 300.0, 40000.0, 500.0,
                  4.0, 0.0, {"series": {"file": "q.csv", "column": "q"}}, {"value": 4.5})
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate()
    stats = sim.last_run_stats
    assert stats["substeps"] < 20 * stats["steps"]  # measured 1,271 over 120 hours; with the means, 32,836
    inflow = float(np.trapezoid(q, t * 3600.0))
    assert result.balance.boundaries["Q"] == pytest.approx(inflow, rel=1e-9)  # the divided steps keep the volume


def _held_inflow(root: Path, dt: float):
    """A pond-like reach fed by an inflow held over ten-minute intervals (a coupled rainfall-runoff model's): it
    switches between 3 m³/s and nothing from one interval to the next, each value held from its time to the
    next (1 s ramps), the way D-HYDRO's coupler hands it over (Dellen's rr_to_flow.nc)."""
    times, values = [START], [0.0]
    for k in range(1, 37):
        change = START + pd.Timedelta(seconds=600 * k)
        times += [change - pd.Timedelta(seconds=1), change]
        values += [values[-1], 3.0 * (k % 2) if k < 30 else 0.0]
    times.append(START + pd.Timedelta(hours=8))
    values.append(0.0)
    root.mkdir(parents=True, exist_ok=True)
    write_series(root, "q.csv", pd.DatetimeIndex(times), q=np.array(values))
    data = _reach(8.0, {"dt": dt, "output_interval": 1200.0}, {"depth": 1.0}, 30.0, 4.0, 2000.0, 100.0, 0.2, 0.0,
                  {"series": {"file": "q.csv", "column": "q"}}, {"value": 1.0})
    return simulator(data, root), (pd.DatetimeIndex(times) - START).total_seconds().to_numpy(), np.array(values)


def test_an_inflow_held_over_intervals_is_held_within_each_step(tmp_path: Path) -> None:
    """A step takes the series' own mean, not the mean of its values at the step's edges, and a divided step's
    sub-steps the value held within it.

    With the mean of the edges' values, a step that ends where the inflow switches on took half of it over the
    whole step, and a step of ten minutes saw an inflow switching every ten minutes as a constant 1.5 m³/s. The
    reference: the series integrated over each step by dense sampling (10 ms), and the same case at a 5 s step.
    """
    fine, t, q = _held_inflow(tmp_path / "fine", 5.0)
    reference, _ = fine.simulate(snapshots=True)
    dense = np.linspace(0.0, 8 * 3600.0, 8 * 360_000 + 1)
    sampled = np.interp(dense, t, q)
    for dt in (600.0, 400.0, 300.0):
        sim, _, _ = _held_inflow(tmp_path / f"dt{dt:g}", dt)
        n_steps = round(8 * 3600.0 / dt)
        means = sim.forcing_matrix(sim.start, n_steps)[:, 0]
        per_step = sampled[:-1].reshape(n_steps, -1).mean(axis=1)
        assert np.abs(means - per_step).max() < 2e-4  # m³/s: the dense sum's own error at the 1 s ramps
        result, _ = sim.simulate(snapshots=True)
        assert result.balance.boundaries["Q"] == pytest.approx(np.trapezoid(q, t), rel=1e-9)
        # measured 1.1, 0.65 and 0.99 cm (the first-order time integration at the switches: 0.24 cm at a 10 s
        # step); with the mean of the edges' values 31, 39 and 25 cm
        diff = np.abs(result.levels.to_numpy() - reference.levels.to_numpy()).max()
        assert diff < 0.015, dt
