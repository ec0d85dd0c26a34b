"""Uniform flow in a long prismatic trapezoidal channel: the depth is the normal depth.

Reference
---------
In steady uniform flow gravity balances friction, S_f = S_0, so the depth solves

    Q = K A(h) R(h)^(2/3) √S_0,   K = k_s (Strickler) or 1/n (Manning),

with A = (b + m h) h and R = A / (b + 2 h √(1 + m²)) for a trapezoid. The normal depth is found
here with ``scipy.optimize.brentq`` from the analytic geometry, independently of the engine's
tabulated cross-sections. The downstream level boundary holds the normal depth and the channel
starts from a different depth (1 m), so the engine has to reach the balance itself; every
calculation point must end within 1 mm of the normal depth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from tests.verification._support import case_dict, max_level_change, simulator

B, M, SLOPE, Q, LENGTH = 8.0, 1.5, 2e-4, 12.0, 10_000.0


def normal_depth(conveyance_factor: float) -> float:
    """Normal depth (m) for K = ``conveyance_factor`` (k_s or 1/n) in the trapezoidal channel."""

    def excess(h: float) -> float:
        area = (B + M * h) * h
        radius = area / (B + 2.0 * h * np.sqrt(1.0 + M * M))
        return conveyance_factor * area * radius ** (2.0 / 3.0) * np.sqrt(SLOPE) - Q

    return brentq(excess, 1e-4, 50.0, xtol=1e-12)


@pytest.mark.parametrize(
    ("friction", "factor"),
    [({"type": "strickler", "value": 30.0}, 30.0), ({"type": "manning", "value": 0.04}, 1.0 / 0.04)],
    ids=["strickler", "manning"],
)
def test_uniform_flow_depth_is_normal_depth(tmp_path: Path, friction: dict, factor: float) -> None:
    hn = normal_depth(factor)
    data = case_dict(
        hours=48.0,
        engine={"dt": 120.0},
        initial={"depth": 1.0},
        friction=friction,
        profiles=[{"id": "trap", "type": "trapezoidal", "bottom_width": B, "side_slope": M}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": LENGTH, "dx": 200.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": SLOPE * LENGTH},
                                      {"chainage": LENGTH, "profile": "trap", "bed_level": 0.0}]}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge", "value": Q},
                    {"id": "hout", "node": "down", "type": "level", "value": hn}],
        stations=[{"id": "mid", "branch": "B", "chainage": LENGTH / 2, "quantities": ["h", "Q"]}],
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert max_level_change(result.levels) < 1e-6  # steady
    depth = result.levels.iloc[-1].to_numpy() - sim.compiled.arrays.hp_bed
    worst = float(np.abs(depth - hn).max())
    assert worst < 1e-3, f"max depth error {worst:.2e} m (normal depth {hn:.4f} m)"
    assert result.series["mid.Q"].iloc[-1] == pytest.approx(Q, rel=1e-6)
