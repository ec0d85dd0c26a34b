"""The embedded model's optional capability VirtualStations: places for new gauges, and a copy that measures them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.model import load_model
from rivercal.models import VirtualStations


@pytest.fixture(scope="module")
def model():
    return load_model("dommel")


def test_places_leave_out_what_the_stations_measure(model) -> None:
    assert isinstance(model, VirtualStations)
    points = model.candidate_locations("points", "level")
    c = model.compiled
    # every calculation point and connection node but the ten levels the five stations measure
    assert len(points) == c.n_hpoints - 10
    assert len({p.point for p in points}) == len(points)
    measured = {c.hp_label[int(k)] for k in c.arrays.ob_i1[c.arrays.ob_type == 0]}
    assert not measured & {p.point for p in points}
    sides = model.candidate_locations("structures", "level")
    weirs = len(c.structure_link)
    assert len(sides) == 2 * weirs - 10  # both sides of every structure but the five stations' weirs
    flows = model.candidate_locations("structures", "discharge")
    assert len(flows) == weirs - 1  # 0029 measures the discharge over ZL1-8052
    assert all(len(set(p.series)) == len(p.series) for p in [*points, *sides, *flows])
    with pytest.raises(ValueError, match="unknown kind of place 'bridges'"):
        model.candidate_locations("bridges", "level")
    with pytest.raises(ValueError, match="unknown measurement 'flow'"):
        model.candidate_locations("points", "flow")


def test_the_copy_simulates_the_engine_s_own_levels_and_discharges_there(model) -> None:
    points = model.candidate_locations("points", "both")[::40]
    sides = model.candidate_locations("structures", "both")[:4]
    copy = model.with_stations([*points, *sides])
    end = model.start + pd.Timedelta("1D")
    plain, _ = model.simulate(end=end, snapshots=True)
    extended, _ = copy.simulate(end=end)
    # the stations' series are unchanged (the places change what is written, not what is computed)
    assert np.array_equal(extended.series[plain.series.columns].to_numpy(), plain.series.to_numpy())
    c = model.compiled
    for p in points:
        if "h" in p.quantities:  # a level at a calculation point is the engine's level there
            assert np.array_equal(extended.series[f"{p.id}.h"].to_numpy(), plain.levels[p.point].to_numpy())
    for s in sides:
        li = c.structure_link[s.structure]
        k = c.arrays.lk_k1[li] if s.side == "up" else c.arrays.lk_k2[li]
        quantity = "h_up" if s.side == "up" else "h_down"
        if quantity in s.quantities:  # (a side a station measures offers only the discharge)
            assert np.array_equal(extended.series[f"{s.id}.{quantity}"].to_numpy(),
                                  plain.levels[c.hp_label[int(k)]].to_numpy())
        assert np.array_equal(extended.series[f"{s.id}.Q"].to_numpy(), plain.discharges[c.link_label[li]].to_numpy())


def test_a_place_at_a_chainage_and_bad_places(model) -> None:
    place = model.location_at("ZL12", 1000.0, id="bridge", measure="both", name="bridge")
    assert place.series == ("bridge.h", "bridge.Q") and place.branch == "ZL12" and place.chainage == 1000.0
    with pytest.raises(ValueError, match="unknown branch 'ZL99'"):
        model.location_at("ZL99", 10.0, id="x", measure="level")
    with pytest.raises(ValueError, match="outside branch 'ZL12'"):
        model.location_at("ZL12", 5001.0, id="x", measure="level")
    with pytest.raises(ValueError, match="cannot be a station id"):
        model.location_at("ZL12", 10.0, id="a.b", measure="level")
    inside = model.location_at("ZL12", 1882.0, id="inside", measure="level")
    with pytest.raises(ValueError, match="lies inside the segment of weir 'ZL12-1880'"):
        model.with_stations([inside])
    taken = model.location_at("ZL12", 10.0, id="0028", measure="level")
    with pytest.raises(ValueError, match="0028"):
        model.with_stations([taken])


def test_a_copy_with_only_some_stations_offers_the_others_places_and_computes_the_same(model) -> None:
    gauges = model.only_stations(["0029", "0031"])
    assert gauges.observables == ["0029.h_up", "0029.h_down", "0029.Q", "0031.h_up", "0031.h_down"]
    # the three stations left out give their six levels back to the candidate places; 0029, kept, still measures
    # the only discharge the stations measure
    assert len(gauges.candidate_locations("points", "level")) == len(model.candidate_locations("points", "level")) + 6
    flows = {p.structure for p in gauges.candidate_locations("structures", "discharge")}
    assert flows == {p.structure for p in model.candidate_locations("structures", "discharge")}
    assert "ZL1-8052" not in flows
    start = model.start + pd.Timedelta("2D")
    full, _ = model.simulate(None, start=model.start, end=start)
    part, _ = gauges.simulate(None, start=model.start, end=start)
    assert np.array_equal(part.series["0031.h_up"].to_numpy(), full.series["0031.h_up"].to_numpy())
    with pytest.raises(ValueError, match="'0099' is not a station of case 'dommel'"):
        model.only_stations(["0029", "0099"])
