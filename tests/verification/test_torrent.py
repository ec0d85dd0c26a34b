"""A steep torrent of pools and riffles is steady at every time step with its cross-sections at the points.

Reference
---------
The steady state itself: a constant inflow of 12 m³/s through a 1 km torrent (slope 0.04, Manning 0.05, a narrow
pool and a wide riffle profile alternating every 50 m; Froude numbers 1.1-1.3, below the 1.5 at which uniform flow
with Manning friction breeds roll waves) must settle to the same discharge through every link and to levels that
no time step changes. With ``engine.cross_sections = "points"`` (each calculation point takes the cross-section
interpolated at it, for its storage and the flow of the links it feeds, as Mascaret's planimetry does) it does, at
every step from 0.5 to 20 s. With the cross-sections interpolated at the links' middles (D-Flow FM's placement) the
same reach never settled: its discharges swung between 3 and 36 m³/s at a 1 s step (measured), as the Oriège's
supercritical stretches did at every step from 0.5 to 10 s; with ``points`` the Oriège is steady at every step and
within 2.6 cm of Mascaret's levels at its 13 gauges.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.verification._support import case_dict, simulator

LENGTH, SLOPE, Q = 1000.0, 0.04, 12.0


def _torrent(root: Path, dt: float, mode: str = "points"):
    profiles = [{"id": "pool", "type": "yz", "y": [0.0, 0.5, 4.5, 5.0], "z": [2.0, 0.0, 0.0, 2.0]},
                {"id": "riffle", "type": "yz", "y": [0.0, 2.0, 14.0, 16.0], "z": [2.0, 0.0, 0.0, 2.0]}]
    sections = [{"chainage": float(c), "profile": "pool" if k % 2 == 0 else "riffle",
                 "bed_level": SLOPE * (LENGTH - float(c))} for k, c in enumerate(np.arange(0.0, LENGTH + 1.0, 50.0))]
    data = case_dict(
        hours=1.0, engine={"dt": dt, "output_interval": 60.0, "cross_sections": mode}, initial={"depth": 0.5},
        friction={"type": "manning", "value": 0.05}, profiles=profiles, nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "A", "from_node": "up", "to_node": "down", "length": LENGTH, "dx": 5.0,
                   "cross_sections": sections}],
        boundaries=[{"id": "Q", "node": "up", "type": "discharge", "value": Q},
                    {"id": "h", "node": "down", "type": "level", "value": 1.0}],
    )
    root.mkdir(parents=True, exist_ok=True)
    return simulator(data, root)


@pytest.mark.parametrize("dt", [0.5, 5.0, 20.0])
def test_a_pool_riffle_torrent_settles_at_every_step_with_its_cross_sections_at_the_points(tmp_path: Path,
                                                                                          dt: float) -> None:
    reference, _ = _torrent(tmp_path / "ref", 1.0).simulate(snapshots=True)
    sim = _torrent(tmp_path / f"dt{dt:g}", dt)
    result, _ = sim.simulate(snapshots=True)
    last = result.levels.to_numpy()[-10:]
    assert np.abs(last - last[-1]).max() < 1e-4  # steady over the last ten minutes
    assert np.allclose(result.discharges.to_numpy()[-1], Q, rtol=1e-4)  # the inflow through every link
    assert np.abs(last[-1] - reference.levels.to_numpy()[-1]).max() < 2e-3  # whatever the step


def test_points_place_each_links_tables_at_its_ends(tmp_path: Path) -> None:
    """A link conveys with the table of its upwind end, which is the table its end point stores with."""
    sim = _torrent(tmp_path, 1.0)
    a = sim.compiled.arrays
    ch = sim.compiled.link_chainage
    link = int(np.argmin(np.abs(ch - 512.5)))  # between two points, 25 m past a pool section
    assert a.lk_p1[link] != a.lk_p2[link]
    assert a.lk_b1[link] == pytest.approx(SLOPE * (LENGTH - 510.0))
    assert a.lk_b2[link] == pytest.approx(SLOPE * (LENGTH - 515.0))
    k1 = int(a.lk_k1[link])
    tables = a.sc_prof[a.sc_ptr[k1]:a.sc_ptr[k1 + 1]]
    assert a.lk_p1[link] in tables  # the k1 point stores its half of the link with the link's k1 table
