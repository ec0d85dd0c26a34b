"""Weir rating: steady discharge over a broad-crested weir against thesis Eq. 3-4.

Reference
---------
Thesis Eq. 3-4 (the SOBEK/D-Flow FM weir, reference note §A), with h1 the upstream and h2 the
downstream level, z_s the crest, W the crest width, c_e c_w the coefficients and g = 9.81 m/s²:

- submerged, h1 - z_s ≤ 1.5 (h2 - z_s):  Q = c_e c_w W √(2g (h1 - h2)) (h2 - z_s);
- free:                                   Q = c_e c_w W (2/3) √((2/3) g) (h1 - z_s)^1.5.

Both branches give the same Q, and the same dQ/dh2 = 0, at h1 - z_s = 1.5 (h2 - z_s), so the
rating is continuous (even C¹) across the switch. The reference is evaluated here from the
simulated ``h_up`` / ``h_down`` station series; the simulated ``Q`` must match it within 0.5 %.

Set-up: a 400 m channel with the weir in the middle, a constant upstream level boundary and a
downstream level boundary that steps through a staircase (a CSV series): free flow with the tail
water below and above the crest, a fine scan (5 mm steps) across the free/submerged switch,
deep submergence, and reverse flow (tail water above the head water, submerged and free). Each
step lasts 3 h and is sampled at its end, when the flow is steady.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.verification._support import START, G, case_dict, simulator, write_series

CREST, WIDTH, CE, CW = 1.0, 5.0, 1.05, 0.9
H_UP = 2.0  # m AD, upstream level boundary
STEP = pd.Timedelta(hours=3)
RATE_TOL = 0.005


def eq_3_4(h1: np.ndarray, h2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Thesis Eq. 3-4 for flow from the higher to the lower level: (Q signed with h1 - h2, free flags)."""
    high, low = np.maximum(h1, h2), np.minimum(h1, h2)
    head, tail = high - CREST, np.maximum(low - CREST, 0.0)
    free = head > 1.5 * tail
    q_free = CE * CW * WIDTH * (2.0 / 3.0) * np.sqrt((2.0 / 3.0) * G) * head**1.5
    q_sub = CE * CW * WIDTH * np.sqrt(2.0 * G * (high - low)) * tail
    return np.sign(h1 - h2) * np.where(free, q_free, q_sub), free


def _staircase_run(root: Path) -> pd.DataFrame:
    """One steady state per downstream level: the station series at the end of each step."""
    tail_levels = np.concatenate([
        [0.5, 1.2, 1.5],  # free, tail water below and above the crest
        np.round(np.arange(1.600, 1.7201, 0.005), 3),  # across the switch (near h2 = 1.667 m AD)
        [1.8, 1.9, 1.97],  # submerged
        [2.05, 2.3, 3.2],  # reverse: submerged, submerged, free
    ])
    times, values = [], []
    for i, level in enumerate(tail_levels):  # hold each level, ramp to the next over the last 10 minutes
        times += [START + i * STEP, START + (i + 1) * STEP - pd.Timedelta(minutes=10)]
        values += [level, level]
    times.append(START + len(tail_levels) * STEP)
    values.append(tail_levels[-1])
    write_series(root, "tail.csv", pd.DatetimeIndex(times), h=np.asarray(values))
    data = case_dict(
        hours=len(tail_levels) * STEP / pd.Timedelta(hours=1),
        engine={"dt": 30.0, "output_interval": 600.0},
        initial={"depth": 0.0, "level": 1.8},
        friction={"type": "strickler", "value": 40.0},
        profiles=[{"id": "rect", "type": "rectangular", "width": 10.0}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": 400.0, "dx": 20.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "rect", "bed_level": 0.0}]}],
        weirs=[{"id": "W", "branch": "B", "chainage": 200.0, "crest_level": CREST, "crest_width": WIDTH,
                "discharge_coefficient": CE, "lateral_contraction": CW}],
        boundaries=[{"id": "hup", "node": "up", "type": "level", "value": H_UP},
                    {"id": "tail", "node": "down", "type": "level", "series": {"file": "tail.csv", "column": "h"}}],
        stations=[{"id": "W", "structure": "W", "quantities": ["h_up", "h_down", "Q"]}],
    )
    result, _ = simulator(data, root).simulate()
    series = result.series
    ends = [START + (i + 1) * STEP - pd.Timedelta(minutes=10) for i in range(len(tail_levels))]
    before = [t - pd.Timedelta(minutes=20) for t in ends]
    out = series.loc[ends].reset_index(drop=True)
    out["dQ_last_20min"] = (series.loc[ends, "W.Q"].to_numpy() - series.loc[before, "W.Q"].to_numpy())
    out["tail"] = tail_levels
    return out


@pytest.fixture(scope="module")
def states(tmp_path_factory: pytest.TempPathFactory) -> pd.DataFrame:
    return _staircase_run(tmp_path_factory.mktemp("weir"))


def test_weir_rating_free_submerged_and_reverse(states: pd.DataFrame) -> None:
    h1, h2, q = states["W.h_up"].to_numpy(), states["W.h_down"].to_numpy(), states["W.Q"].to_numpy()
    assert np.isfinite(states.to_numpy(dtype=float)).all()
    assert np.abs(states["dQ_last_20min"].to_numpy()).max() < 1e-6 * np.abs(q).max()  # steady
    expected, free = eq_3_4(h1, h2)
    forward = h1 > h2
    # every regime is visited: free and submerged, both directions, tail water below the crest
    assert (free & forward).sum() >= 3 and (~free & forward).sum() >= 3
    assert (free & ~forward).sum() >= 1 and (~free & ~forward).sum() >= 1
    assert (h2 < CREST).any()
    np.testing.assert_allclose(q, expected, rtol=RATE_TOL, atol=0.0)


def test_weir_rating_is_continuous_across_the_switch(states: pd.DataFrame) -> None:
    scan = states[(states["tail"] >= 1.6) & (states["tail"] <= 1.72)]
    h1, h2, q = scan["W.h_up"].to_numpy(), scan["W.h_down"].to_numpy(), scan["W.Q"].to_numpy()
    expected, free = eq_3_4(h1, h2)
    # the scan crosses the switch once, from free to submerged flow
    assert free[0] and not free[-1]
    assert np.count_nonzero(np.diff(free.astype(int))) == 1
    # neighbouring steady states: no change in Q beyond what Eq. 3-4 itself changes
    jump = np.diff(q) - np.diff(expected)
    worst = float(np.abs(jump / q[:-1]).max())
    assert worst < RATE_TOL, f"largest unexplained jump in Q between neighbours {worst:.2e}"
    # and across the switch itself Eq. 3-4 is C¹, so a 5 mm step in the tail water moves Q very little
    k = int(np.flatnonzero(np.diff(free.astype(int)))[0])
    assert abs(q[k + 1] - q[k]) / q[k] < RATE_TOL
    assert np.all(np.diff(q) <= 1e-9)  # Q never rises when the tail water rises
