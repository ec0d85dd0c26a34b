"""A pipe that leaves a deep manhole above its bottom: a channel where its entry does not control the flow.

Reference
---------
A link whose bed lies above the bed of the point at one of its ends (a pipe leaving a manhole above its
bottom, a ditch above a deeper watercourse) may pass at most the critical flow over that brink (Chow 1959,
*Open-channel hydraulics*, §3-4 and §15-1; :mod:`rivercal.engine.kernels.overfall`). Where the channel itself
carries less than that, the brink is no control and the manhole's depth below the pipe is dead storage: the
steady levels must be those of the same pipe leaving a manhole whose bottom lies at the pipe's invert. Here
0.0111 m³/s (a sewer pump's delivery) flows through a flat pipe of 0.5 m, 37.65 m long, to an outfall whose
rating Q = 2.26 (h - 0.8)² (m³/s, h in m AD) puts the outfall's level at 0.8 + √(0.0111 / 2.26) m. Before the
brink was judged by the flow it can pass, the downstream level sat near the free-flow limit (2/3 of the depth
above the brink): the pipe switched between its channel law and the brink's critical flow every few steps, and
the levels swung by 1 cm with a period of 100 s for as long as the pump ran (a real sewer model, Korte Woerden).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.verification._support import G, case_dict, simulator

Q_PUMP, DIAMETER, INVERT, PIT_BOTTOM = 0.0111, 0.5, 0.8, -0.5
RATING_K = 2.26  # K of the outfall rating Q = K (h - INVERT)², m/s (m³/s per m² of head squared)


def _case(pit_bottom: float) -> dict:
    levels = INVERT + np.arange(0.0, 0.5001, 0.0125)
    rating = {"levels": levels.tolist(), "discharges": (RATING_K * (levels - INVERT) ** 2).tolist()}
    return case_dict(
        hours=6.0,
        engine={"dt": 10.0, "output_interval": 60.0},
        initial={"depth": 0.0, "level": INVERT + 0.1},
        friction={"type": "strickler", "value": 75.0},
        profiles=[{"id": "pipe", "type": "circular", "diameter": DIAMETER},
                  {"id": "sewer", "type": "rectangular", "width": 0.5}],
        nodes=[{"id": "s"}, {"id": "P", "storage_table": {"levels": [pit_bottom, 2.0], "areas": [1.0, 1.0]}},
               {"id": "O", "storage_table": {"levels": [0.95, 2.0], "areas": [1.0, 1.0]}}],
        branches=[
            {"id": "IN", "from_node": "s", "to_node": "P", "length": 20.0,
             "cross_sections": [{"chainage": 0.0, "profile": "sewer", "bed_level": pit_bottom},
                                {"chainage": 20.0, "profile": "sewer", "bed_level": pit_bottom}]},
            {"id": "C", "from_node": "P", "to_node": "O", "length": 37.65, "dx": 40.0,
             "cross_sections": [{"chainage": 0.0, "profile": "pipe", "bed_level": INVERT},
                                {"chainage": 37.65, "profile": "pipe", "bed_level": INVERT}]},
        ],
        boundaries=[{"id": "pump", "node": "s", "type": "discharge", "value": Q_PUMP},
                    {"id": "outfall", "node": "O", "type": "rating",
                     "rating": rating}],
    )


def _steady(tmp_path: Path, pit_bottom: float) -> tuple[np.ndarray, object]:
    sim = simulator(_case(pit_bottom), tmp_path)
    result, _ = sim.simulate(snapshots=True)
    cols = [sim.compiled.hp_label.index("node:P"), sim.compiled.hp_label.index("node:O")]
    return result.levels.iloc[-61:, cols].to_numpy(), sim


def _critical_flow(depth: float) -> float:
    """Critical discharge (m³/s) of the pipe at a depth (m): Q = A √(g A / T), from the circular segment."""
    r = DIAMETER / 2.0
    half = np.arccos(1.0 - depth / r)
    area = r * r * (half - np.sin(half) * np.cos(half))
    top = 2.0 * r * np.sin(half)
    return float(area * np.sqrt(G * area / top))


def test_a_pipe_leaving_a_deep_manhole_above_its_bottom_runs_steady_as_a_channel(tmp_path: Path) -> None:
    pit, sim = _steady(tmp_path / "pit", PIT_BOTTOM)
    assert sim.compiled.arrays.dl_link.size == 1  # the pipe's first link starts 1.3 m above the manhole's bottom
    assert np.ptp(pit, axis=0).max() < 1e-4  # steady over the last hour: no swing
    level_p, level_o = pit[-1]
    assert level_o == pytest.approx(INVERT + np.sqrt(Q_PUMP / RATING_K), abs=1e-3)  # the outfall's rating
    # the brink could pass more than the pipe carries: it does not control the flow ...
    assert _critical_flow((2.0 / 3.0) * (level_p - INVERT)) > Q_PUMP
    # ... and yet the outfall lies below the free-flow limit, where the brink's law used to take over
    assert level_o < INVERT + (2.0 / 3.0) * (level_p - INVERT)
    # so the manhole's depth below the pipe changes nothing: the levels of a manhole with its bottom at the invert
    flush, sim_flush = _steady(tmp_path / "flush", INVERT)
    assert sim_flush.compiled.arrays.dl_link.size == 0
    np.testing.assert_allclose(pit[-1], flush[-1], atol=1e-3)
