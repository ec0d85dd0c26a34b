"""Steep, fast flow: every combination of Δx and Δt is either right or stops with a clear error.

Reference
---------
Steady uniform flow in a prismatic channel: Q = A k_s R^(2/3) √S_0 (Manning–Strickler) fixes the normal
depth, and a reach fed with a constant discharge and held at normal depth downstream settles to it
everywhere, whatever the grid. The time step cannot change that steady state: a consistent scheme run to
rest gives the same levels at Δt = 300 s as at 5 s. On a bed slope of 0.01 the flow runs at 2.6 m/s
(Froude 0.81, still subcritical); with the scheme's explicit upwind depth a step longer than about twice
the time a link is crossed in (Courant numbers u Δt/Δx above 2) used to alternate between two states or
diverge, with exit status 0 (before the step control: 5 of the 20 runs below were silently wrong by up
to 0.2 m or reported levels 7 m below the bed, 4 diverged). Now a step that the forecast or the screen of
:mod:`rivercal.engine.kernels.timeloop` finds too long is divided; a run that cannot be made right stops
with :class:`~rivercal.errors.EngineDivergedError` naming the place and what to change.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from rivercal.errors import EngineDivergedError
from tests.verification._support import assert_balance_closes, case_dict, simulator

pytestmark = pytest.mark.slow

SLOPE, Q, WIDTH, KS, LENGTH = 0.01, 20.0, 7.0, 30.0, 3000.0


def normal_depth() -> float:
    def flow(h):
        return KS * (WIDTH * h / (WIDTH + 2.0 * h)) ** (2.0 / 3.0) * np.sqrt(SLOPE) * WIDTH * h - Q

    return brentq(flow, 1e-3, 20.0, xtol=1e-12)


def _run(root: Path, dx: float, dt: float, hours: float = 6.0):
    hn = normal_depth()
    data = case_dict(
        hours=hours,
        engine={"dt": dt, "output_interval": max(600.0, dt)},
        initial={"depth": hn},
        friction={"type": "strickler", "value": KS},
        profiles=[{"id": "r", "type": "rectangular", "width": WIDTH}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "A", "from_node": "up", "to_node": "down", "length": LENGTH, "dx": dx,
                   "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": SLOPE * LENGTH},
                                      {"chainage": LENGTH, "profile": "r", "bed_level": 0.0}]}],
        boundaries=[{"id": "Q", "node": "up", "type": "discharge", "value": Q},
                    {"id": "h", "node": "down", "type": "level", "value": hn}],
    )
    root.mkdir(parents=True, exist_ok=True)
    sim = simulator(data, root)
    result, _ = sim.simulate(snapshots=True)
    return sim, result


@pytest.mark.parametrize("dx", [25.0, 50.0, 100.0, 200.0])
def test_every_time_step_is_right_or_stops_with_a_clear_error(tmp_path: Path, dx: float) -> None:
    hn = normal_depth()
    sim, reference = _run(tmp_path / "dt5", dx, 5.0)
    z_ref = reference.levels.iloc[-1].to_numpy()
    # the reference itself is the uniform flow: normal depth everywhere, the inflow through every link
    depth = z_ref - sim.compiled.arrays.hp_bed
    assert np.abs(depth - hn).max() < 0.01
    assert np.allclose(reference.discharges.iloc[-1].to_numpy(), Q, rtol=1e-3)
    for dt in (10.0, 30.0, 60.0, 300.0):
        try:
            sim, result = _run(tmp_path / f"dt{dt:g}", dx, dt)
        except EngineDivergedError as exc:  # allowed, if it says where and what to do
            assert exc.location.startswith(("A@", "node:")), str(exc)
            assert "engine.dt" in exc.detail, str(exc)
            continue
        assert_balance_closes(result, sim)
        worst = float(np.abs(result.levels.iloc[-1].to_numpy() - z_ref).max())
        assert worst < 0.01, f"dx {dx:g} m, dt {dt:g} s: {worst:.4f} m from the dt = 5 s solution " \
                             f"({sim.last_run_stats})"
        if dt * 2.64 / dx > 4.0:  # Courant number above 4: only a divided step gets this right
            assert sim.last_run_stats["divided_steps"] > 0


def test_an_hour_long_step_on_a_10_m_grid_is_divided_until_it_is_right(tmp_path: Path) -> None:
    sim, reference = _run(tmp_path / "dt5", 10.0, 5.0, hours=24.0)
    sim, result = _run(tmp_path / "dt3600", 10.0, 3600.0, hours=24.0)  # Courant number ~1000
    worst = float(np.abs(result.levels.iloc[-1].to_numpy() - reference.levels.iloc[-1].to_numpy()).max())
    assert worst < 0.01
    assert sim.last_run_stats["max_division"] >= 256


def test_a_step_the_smallest_sub_step_cannot_save_stops_with_the_place_and_what_to_change() -> None:
    """The messages of a run that stops at the smallest sub-step (the step control's last resort) name the
    point, the sub-step, the Courant number there and what to change."""
    from rivercal.engine.diagnosis import divergence
    from rivercal.engine.kernels.codes import MAX_HALVINGS, STATUS_DRY, STATUS_FLICKER

    sim = simulator(case_dict(
        hours=1.0, engine={"dt": 3600.0, "output_interval": 3600.0}, initial={"depth": 1.0},
        profiles=[{"id": "r", "type": "rectangular", "width": WIDTH}], nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "A", "from_node": "up", "to_node": "down", "length": 100.0, "dx": 10.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 0.0}]}],
        boundaries=[{"id": "h", "node": "down", "type": "level", "value": 1.0}]), Path(__file__).parent)
    z = sim.compiled.arrays.hp_bed + 1.0
    u = np.full(sim.compiled.n_links, 2.0)
    smallest = f"{3600.0 / 2**MAX_HALVINGS:.3g} s"
    for status, words, levels in ((STATUS_DRY, "the level falls 0.2 m below the bed", z - 1.2),
                                  (STATUS_FLICKER, "goes up and down", z)):
        when, where, detail = divergence(sim, status, 0, 3, levels, u, sim.start, None)
        assert where == sim.compiled.hp_label[3] and when.startswith("2020")
        assert words in detail and f"sub-steps of {smallest}" in detail and "reduce engine.dt" in detail
        assert "Courant number u·dt/dx up to 0.0439" in detail  # 2 m/s × 0.22 s / 10 m
