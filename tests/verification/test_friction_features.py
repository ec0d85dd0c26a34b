"""Friction that varies along a branch, with the water level, or in a law of its own, against independent references.

Reference
---------
Steady, gradually varied flow in a prismatic trapezoidal channel obeys

    dh/dx = (S_0 - S_f) / (1 - Fr²),   S_f = Q² n² / (A² R^(4/3)),   Fr² = Q² T / (g A³),

here with Manning's n a function of the place, n(x) (values at chainages, linear between them), or of the water
level z = z_b(x) + h (a table of levels, linear between them), as SOBEK 3 and D-Flow FM 1D give it. The ODE is
integrated with ``scipy.integrate.solve_ivp`` (LSODA) upstream from the level boundary; the simulated levels at
every calculation point must lie within 5 mm of it (the engine's constant-friction M1 curve at Δx = 100 m is
within 2.9 mm, ``test_backwater.py``), or 1 cm with ``cross_sections = "interpolated"``, whose links take the bed
of their middle (the same curve with a constant n: 8.6 mm, measured).

A branch whose friction group value is given in a law of its own (a Strickler k_s inside a Manning group) conveys
exactly as a group of that law: the uniform-flow depth of the same discharge is the same to the tenth of a mm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.verification._support import G, branch_points, case_dict, max_level_change, simulator

B, M, SLOPE, Q, LENGTH, H_DOWN = 8.0, 1.5, 2e-4, 12.0, 15_000.0, 3.0
LEVELS = [0.0, 2.0, 4.0, 6.0]  # m AD: the water level of the tables below
N_OF_LEVEL = [0.045, 0.040, 0.030, 0.026]  # s/m^(1/3): rougher when the water is low
CHAINAGES = [0.0, 6000.0, 15000.0]  # m
N_ALONG = [0.040, 0.025, 0.030]  # s/m^(1/3)


def _area(h):
    return (B + M * h) * h


def _radius(h):
    return _area(h) / (B + 2.0 * h * np.sqrt(1.0 + M * M))


def _top(h):
    return B + 2.0 * M * h


def _bed(x):
    return SLOPE * (LENGTH - x)


def _gvf(manning, chainage: np.ndarray) -> np.ndarray:
    """Depth (m) at ``chainage`` from the GVF ODE with Manning's n = manning(x, h), integrated upstream."""

    def slope(x, y):
        h = y[0]
        n = manning(x, h)
        friction = Q * Q * n * n / (_area(h) ** 2 * _radius(h) ** (4.0 / 3.0))
        froude2 = Q * Q * _top(h) / (G * _area(h) ** 3)
        return [(SLOPE - friction) / (1.0 - froude2)]

    sol = solve_ivp(slope, (LENGTH, 0.0), [H_DOWN], method="LSODA", rtol=1e-10, atol=1e-12, dense_output=True)
    assert sol.success
    return sol.sol(chainage)[0]


def _case(entry: dict) -> dict:
    data = case_dict(
        hours=48.0,
        engine={"dt": 60.0},
        initial={"depth": H_DOWN},
        profiles=[{"id": "trap", "type": "trapezoidal", "bottom_width": B, "side_slope": M, "friction": ["bed"]}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": LENGTH, "dx": 100.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": _bed(0.0)},
                                      {"chainage": LENGTH, "profile": "trap", "bed_level": 0.0}]}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge", "value": Q},
                    {"id": "hout", "node": "down", "type": "level", "value": H_DOWN}],
    )
    data["friction_groups"] = [{"id": "bed", "type": "manning", "value": 0.03, "branches": [{"branch": "B", **entry}]}]
    return data


def _steady_levels(tmp_path: Path, data: dict) -> tuple[np.ndarray, np.ndarray]:
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert max_level_change(result.levels) < 1e-6  # steady
    chain, idx = branch_points(sim, "B")
    return chain, result.levels.iloc[-1].to_numpy()[idx]


@pytest.mark.parametrize(("mode", "tolerance"), [("nearest", 5e-3), ("interpolated", 1e-2)])
def test_water_level_dependent_manning_matches_the_gvf_ode(tmp_path: Path, mode: str, tolerance: float) -> None:
    entry = {"function": "waterlevel", "levels": LEVELS, "table": [N_OF_LEVEL]}
    data = _case(entry)
    data["engine"]["cross_sections"] = mode
    chain, level = _steady_levels(tmp_path, data)
    reference = _bed(chain) + _gvf(lambda x, h: np.interp(_bed(x) + h, LEVELS, N_OF_LEVEL), chain)
    n_seen = np.interp(reference, LEVELS, N_OF_LEVEL)
    assert n_seen.max() - n_seen.min() > 0.004  # the friction really varies over the reach
    worst = float(np.abs(level - reference).max())
    assert worst < tolerance, f"max level error {worst:.4f} m"
    # with the group's own constant n the curve lies elsewhere: the table is what the engine used
    constant = _bed(chain) + _gvf(lambda x, h: 0.03, chain)
    assert np.abs(constant - reference).max() > 0.05


def test_manning_along_the_branch_matches_the_gvf_ode(tmp_path: Path) -> None:
    chain, level = _steady_levels(tmp_path, _case({"chainages": CHAINAGES, "values": N_ALONG}))
    reference = _bed(chain) + _gvf(lambda x, h: np.interp(x, CHAINAGES, N_ALONG), chain)
    worst = float(np.abs(level - reference).max())
    assert worst < 5e-3, f"max level error {worst:.4f} m"
    constant = _bed(chain) + _gvf(lambda x, h: 0.03, chain)
    assert np.abs(constant - reference).max() > 0.1


def test_a_law_of_its_own_conveys_as_the_group_of_that_law(tmp_path: Path) -> None:
    ks = 1.0 / 0.03 * 1.1  # a Strickler k_s inside a Manning group, 10 % smoother than the group
    own = _case({"type": "strickler", "value": ks})
    plain = _case({"value": 0.03})
    plain["friction_groups"] = [{"id": "bed", "type": "strickler", "value": ks}]
    _, level_own = _steady_levels(tmp_path, own)
    _, level_plain = _steady_levels(tmp_path, plain)
    assert np.abs(level_own - level_plain).max() < 1e-4
    # and not the group's Manning value
    _, level_group = _steady_levels(tmp_path, _case({"value": 0.03}))
    assert np.abs(level_own - level_group).max() > 0.05


def test_calibrating_the_group_scales_its_water_level_table(tmp_path: Path) -> None:
    data = _case({"function": "waterlevel", "levels": LEVELS, "table": [N_OF_LEVEL]})
    sim = simulator(data, tmp_path)
    scaled, _ = sim.simulate({"friction:group:bed": 0.03 * 1.1}, snapshots=True)
    by_hand = _case({"function": "waterlevel", "levels": LEVELS, "table": [[1.1 * n for n in N_OF_LEVEL]]})
    chain, level = _steady_levels(tmp_path, by_hand)
    _, idx = branch_points(sim, "B")
    assert np.abs(scaled.levels.iloc[-1].to_numpy()[idx] - level).max() < 1e-6
    reference = _bed(chain) + _gvf(lambda x, h: 1.1 * np.interp(_bed(x) + h, LEVELS, N_OF_LEVEL), chain)
    assert np.abs(level - reference).max() < 5e-3
