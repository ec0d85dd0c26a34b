"""The embedded engine beside EPA SWMM on one network: a chain of free weirs.

Independent reference: SWMM 5's dynamic-wave solver (swmm-toolkit) on the same network (same trapezoids,
Manning n = 1/k_s, a transverse weir whose coefficient gives the engine's free-weir formula). In steady
flow both solve the same backwater curves and weir rating: they must agree within 1 cm. In a flood wave the
two discretisations differ; halving Δx and Δt must bring the embedded engine towards its own converged
answer at first order and the two engines closer together.
"""

from __future__ import annotations

import pandas as pd
import pytest

from rivercal.bench.engines import compare_engines, refinement, weir_chain_case
from rivercal.models.swmm.convert import weir_coefficient

pytestmark = pytest.mark.slow


def test_steady_flow_agrees_within_a_centimetre(tmp_path) -> None:
    case = weir_chain_case(tmp_path, points=100, weirs=3, days=3.0, steady=True)
    pair = compare_engines(case, variable_step=0.0, folder=tmp_path)
    end = pair.embedded.index[-1]
    assert pair.level_difference(since=end) < 0.01
    # the level above each weir is the weir rating of the steady discharge (thesis Eq. 3-4), in both engines
    for w in case.network.weirs:
        station = f"S{w.id[1:]}"
        head = (2.0 / (weir_coefficient() * w.crest_width)) ** (2.0 / 3.0)
        assert pair.embedded.loc[end, f"{station}.h_up"] == pytest.approx(w.crest_level + head, abs=2e-3)
        assert pair.swmm.loc[end, f"{station}.h_up"] == pytest.approx(w.crest_level + head, abs=2e-3)
        assert pair.swmm.loc[end, f"{station}.Q"] == pytest.approx(2.0, rel=1e-3)


def test_refining_a_flood_wave_brings_the_engines_together(tmp_path) -> None:
    rows = refinement(tmp_path, levels=((400.0, 240.0, 40.0), (200.0, 120.0, 20.0), (100.0, 60.0, 10.0)))
    print(pd.DataFrame(rows).to_string())  # the table of the closing note
    emb = [r["embedded_vs_finest_m"] for r in rows[:-1]]
    assert emb[1] < 0.7 * emb[0]  # the embedded engine converges (first order: about half per halving)
    gap = [r["embedded_vs_swmm_m"] for r in rows]
    assert gap[0] > gap[1] > gap[2] and gap[2] < 0.01
