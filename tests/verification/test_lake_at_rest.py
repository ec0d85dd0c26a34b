"""Lake at rest: a still water surface over an uneven bed stays still (well-balancing).

Reference
---------
The exact solution of the De Saint-Venant equations for a horizontal water surface with no
inflow is u = 0 and ζ = constant, whatever the bed, the cross-sections, the junctions and the
structures (SWASHES "lake at rest" cases; reference note §D). A scheme that is not well balanced
turns bed-slope and cross-section changes into spurious currents; here every velocity must stay
below 1e-9 m/s over the whole run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.verification._support import case_dict, simulator

LAKE = 2.0  # m AD
U_TOL = 1e-9  # m/s


def _lake_case() -> dict:
    """A Y of three branches with bumps, mixed profiles, a drowned weir and an emerged sill."""
    profiles = [
        {"id": "rect", "type": "rectangular", "width": 6.0},
        {"id": "trap", "type": "trapezoidal", "bottom_width": 4.0, "side_slope": 1.5},
        {"id": "zw", "type": "zw", "heights": [0.0, 0.4, 1.0, 3.0], "flow_widths": [2.0, 5.0, 9.0, 12.0],
         "total_widths": [2.0, 6.0, 14.0, 20.0]},
    ]
    bumpy = [  # chainage, profile, bed (m AD): bumps, pits and profile changes
        (0.0, "trap", 0.2), (300.0, "rect", 1.4), (450.0, "zw", 0.1), (800.0, "trap", 1.1),
        (1100.0, "rect", -0.5), (1500.0, "zw", 0.6), (2000.0, "trap", 0.0),
    ]
    side = [  # the side branch has a sill above the lake: dry points between two wet reaches
        (0.0, "rect", 0.5), (400.0, "zw", 1.2), (600.0, "rect", 2.3), (700.0, "rect", 2.3),
        (900.0, "trap", 0.9), (1200.0, "zw", 0.3),
    ]

    def sections(rows):
        return [{"chainage": c, "profile": p, "bed_level": z} for c, p, z in rows]

    return case_dict(
        hours=48.0,
        engine={"dt": 60.0},
        initial={"depth": 0.0, "level": LAKE},
        profiles=profiles,
        nodes=[{"id": "a"}, {"id": "j", "storage_area": 50.0}, {"id": "b"}, {"id": "c"}],
        branches=[
            {"id": "A", "from_node": "a", "to_node": "j", "length": 2000.0, "dx": 50.0,
             "cross_sections": sections(bumpy)},
            {"id": "B", "from_node": "j", "to_node": "b", "length": 1500.0, "dx": 75.0,
             "friction": {"type": "manning", "value": 0.035},
             "cross_sections": sections([(0.0, "trap", 0.0), (700.0, "zw", 0.8), (1500.0, "rect", -0.3)])},
            {"id": "C", "from_node": "c", "to_node": "j", "length": 1200.0, "dx": 40.0,
             "cross_sections": sections(side)},
        ],
        weirs=[{"id": "drowned", "branch": "B", "chainage": 800.0, "crest_level": 1.6, "crest_width": 3.0,
                "discharge_coefficient": 1.1, "lateral_contraction": 0.9}],
        boundaries=[
            {"id": "Qa", "node": "a", "type": "discharge", "value": 0.0},
            {"id": "hb", "node": "b", "type": "level", "value": LAKE},
        ],
        stations=[{"id": "weir", "structure": "drowned", "quantities": ["h_up", "h_down", "Q"]}],
    )


def test_lake_at_rest_over_bumps_junction_and_drowned_weir(tmp_path: Path) -> None:
    sim = simulator(_lake_case(), tmp_path)
    bed = sim.compiled.arrays.hp_bed
    wet = bed < LAKE
    assert (~wet).sum() >= 2, "the sill must leave dry points"
    state = None
    peak_u = 0.0
    for hour in range(0, 48, 6):  # hot-started pieces: check the velocities along the run, not only at its end
        start = sim.start + np.timedelta64(hour, "h")
        result, state = sim.simulate(start=start, end=start + np.timedelta64(6, "h"), state=state,
                                     snapshots=True)
        peak_u = max(peak_u, float(np.abs(state.u).max()))
        assert np.isfinite(result.levels.to_numpy()).all()
        # every snapshot discharge, too (|Q| < 1e-9 m³/s is the stricter bound: wet flow areas exceed 1 m² here)
        assert np.abs(result.discharges.to_numpy()).max() < U_TOL
        np.testing.assert_allclose(result.levels.to_numpy()[:, wet], LAKE, rtol=0.0, atol=1e-9)
    assert peak_u < U_TOL
    np.testing.assert_allclose(state.z[wet], LAKE, rtol=0.0, atol=1e-9)
    # dry points stay dry: no water appears on the emerged sill
    assert np.all(state.z[~wet] <= bed[~wet] + 1e-9)
