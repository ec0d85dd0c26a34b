"""Steady backwater curves M1 and M2 in a trapezoidal channel against the gradually-varied-flow ODE.

Reference
---------
Steady, gradually varied flow in a prismatic channel obeys

    dh/dx = (S_0 - S_f) / (1 - Fr²),   S_f = Q² / (k_s² A² R^(4/3)),   Fr² = Q² T / (g A³),

with A, R and the top width T of the trapezoid evaluated analytically. It is integrated with
``scipy.integrate.solve_ivp`` (LSODA, rtol 1e-10) from the downstream control — the level
boundary — upstream. M1: the downstream depth lies above the normal depth (a backwater);
M2: below the normal depth but above the critical depth (a drawdown towards an outfall). The
simulated levels at every calculation point must lie within 5 mm of the ODE.

The engine takes the flow area of a link from its upwind point (first order in Δx, reference note §A) and,
where the depth varies along the link, its friction from the mean depth; what is left grows with Δx and
the surface's curvature: the gentle M1 meets 5 mm at Δx = 100 m (measured 2.9 mm), the steeper M2
drawdown at Δx = 10 m (measured: 5.8 mm at 100 m, 5.3 mm at 50 m, 4.5 mm at 25 m, 2.5 mm at 10 m; with the
friction of the upwind depth it was 21, 12, 6 and 2.5 mm).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from tests.verification._support import G, branch_points, case_dict, max_level_change, simulator

B, M, SLOPE, Q, KS = 8.0, 1.5, 2e-4, 12.0, 30.0


def _area(h):
    return (B + M * h) * h


def _radius(h):
    return _area(h) / (B + 2.0 * h * np.sqrt(1.0 + M * M))


def _top(h):
    return B + 2.0 * M * h


def _froude2(h):
    return Q * Q * _top(h) / (G * _area(h) ** 3)


def normal_depth() -> float:
    return brentq(lambda h: KS * _area(h) * _radius(h) ** (2 / 3) * np.sqrt(SLOPE) - Q, 1e-4, 50.0, xtol=1e-12)


def critical_depth() -> float:
    return brentq(lambda h: _froude2(h) - 1.0, 1e-4, 50.0, xtol=1e-12)


def gvf_depth(length: float, h_down: float, chainage: np.ndarray) -> np.ndarray:
    """Depth (m) at ``chainage`` from the GVF ODE integrated upstream from depth ``h_down`` at ``length``."""

    def slope(_x, y):
        h = y[0]
        friction = Q * Q / (KS * KS * _area(h) ** 2 * _radius(h) ** (4.0 / 3.0))
        return [(SLOPE - friction) / (1.0 - _froude2(h))]

    sol = solve_ivp(slope, (length, 0.0), [h_down], method="LSODA", rtol=1e-10, atol=1e-12, dense_output=True)
    assert sol.success
    return sol.sol(chainage)[0]


@pytest.mark.parametrize(
    ("curve", "h_down", "length", "dx"),
    [("M1", 3.0, 15_000.0, 100.0), ("M2", 1.2, 5_000.0, 10.0)],
    ids=["M1", "M2"],
)
def test_backwater_curve_matches_gvf_ode(tmp_path: Path, curve: str, h_down: float, length: float, dx: float) -> None:
    hn, hc = normal_depth(), critical_depth()
    if curve == "M1":
        assert h_down > hn
    else:
        assert hc < h_down < hn
    data = case_dict(
        hours=48.0,
        engine={"dt": 60.0},
        initial={"depth": hn},
        friction={"type": "strickler", "value": KS},
        profiles=[{"id": "trap", "type": "trapezoidal", "bottom_width": B, "side_slope": M}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": length, "dx": dx,
                   "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": SLOPE * length},
                                      {"chainage": length, "profile": "trap", "bed_level": 0.0}]}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge", "value": Q},
                    {"id": "hout", "node": "down", "type": "level", "value": h_down}],
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert max_level_change(result.levels) < 1e-6  # steady
    chain, idx = branch_points(sim, "B")
    level = result.levels.iloc[-1].to_numpy()[idx]
    reference = SLOPE * (length - chain) + gvf_depth(length, h_down, chain)
    # the curve is a real backwater/drawdown: at least 10 cm off normal depth over the first kilometre upstream
    assert np.abs(reference - SLOPE * (length - chain) - hn)[chain > length - 1000.0].min() > 0.1
    worst = float(np.abs(level - reference).max())
    assert worst < 5e-3, f"max level error {worst:.4f} m"
