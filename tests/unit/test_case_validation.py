"""A bad case fails at load with one line naming the file, the field and the problem.

One test per kind of mistake. :func:`mini_case` builds a small but complete valid case (a
bifurcation, weirs, a culvert, a pump, boundaries of each type, laterals with CSV series, stations)
that the property test in ``test_case_properties.py`` mutates as well.
"""

from __future__ import annotations

import copy
import json
import math
import re
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.case import load_case
from rivercal.case.series import read_series_csv
from rivercal.engine import Simulator
from rivercal.errors import CaseError

START = pd.Timestamp("2020-01-01T00:00:00Z")
END = pd.Timestamp("2020-01-02T00:00:00Z")


# -- a small complete case -----------------------------------------------------------------------


def mini_case() -> dict:
    """A valid case as the dict that ``case.toml`` parses to.

    ::

        U1 --b1--> J1 --b2 (W1)--> J2 --b4 (W2)--> D   level boundary (series)
                    \\                ^
                     b3 (C1)         b5 (P1)
                      v               \\
                      R  rating        U2  discharge boundary (value)
        U1: discharge boundary (series)
    """
    return {
        "case": {"name": "mini", "description": "test network", "start": "2020-01-01T00:00:00Z",
                 "end": "2020-01-02T00:00:00Z"},
        "engine": {"dt": 60.0, "output_interval": 3600.0, "structure_length": 10.0},
        "initial": {"depth": 0.8, "spinup": 1.0},
        "friction": {"type": "strickler", "value": 30.0},
        "profiles": [
            {"id": "rect", "type": "rectangular", "width": 4.0, "height": 3.0},
            {"id": "trap", "type": "trapezoidal", "bottom_width": 3.0, "side_slope": 1.5, "height": 2.5},
            {"id": "zw", "type": "zw", "heights": [0.0, 0.5, 1.5, 3.0], "flow_widths": [1.0, 3.0, 5.0, 6.0],
             "total_widths": [1.0, 4.0, 8.0, 10.0]},
        ],
        "nodes": [
            {"id": "U1", "x": 0.0, "y": 0.0},
            {"id": "J1", "x": 2000.0, "y": 0.0,
             "storage_table": {"levels": [4.0, 5.0, 6.0], "areas": [0.0, 50.0, 80.0]}},
            {"id": "J2", "x": 3500.0, "y": 0.0, "storage_area": 30.0},
            {"id": "D", "x": 5000.0, "y": 0.0},
            {"id": "R", "x": 3500.0, "y": -1000.0},
            {"id": "U2", "x": 3500.0, "y": 1200.0},
        ],
        "branches": [
            {"id": "b1", "from_node": "U1", "to_node": "J1", "length": 2000.0, "dx": 250.0,
             "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": 5.0},
                                {"chainage": 2000.0, "profile": "trap", "bed_level": 4.0}]},
            {"id": "b2", "from_node": "J1", "to_node": "J2", "length": 1500.0, "dx": 250.0,
             "friction": {"type": "manning", "value": 0.035},
             "cross_sections": [{"chainage": 0.0, "profile": "rect", "bed_level": 4.0},
                                {"chainage": 1500.0, "profile": "zw", "bed_level": 3.2}]},
            {"id": "b3", "from_node": "J1", "to_node": "R", "length": 1800.0, "dx": 300.0,
             "geometry": [[2000.0, 0.0], [2800.0, -600.0], [3500.0, -1000.0]],
             "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": 4.0},
                                {"chainage": 1800.0, "profile": "trap", "bed_level": 3.0}]},
            {"id": "b4", "from_node": "J2", "to_node": "D", "length": 1500.0, "dx": 250.0,
             "cross_sections": [{"chainage": 0.0, "profile": "zw", "bed_level": 3.2},
                                {"chainage": 1500.0, "profile": "zw", "bed_level": 2.5}]},
            {"id": "b5", "from_node": "U2", "to_node": "J2", "length": 1200.0, "dx": 200.0,
             "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": 4.5},
                                {"chainage": 1200.0, "profile": "trap", "bed_level": 3.2}]},
        ],
        "weirs": [
            {"id": "W1", "branch": "b2", "chainage": 600.0, "crest_level": 4.3, "crest_width": 3.0,
             "discharge_coefficient": 1.0, "lateral_contraction": 0.9},
            {"id": "W2", "branch": "b4", "chainage": 700.0, "crest_level": 3.3, "crest_width": 4.0,
             "allowed_flow": "both"},
        ],
        "culverts": [
            {"id": "C1", "branch": "b3", "chainage": 900.0, "shape": "circular", "diameter": 1.0,
             "invert_level": 3.55, "length": 15.0, "inlet_loss": 0.5, "outlet_loss": 1.0,
             "friction": {"type": "manning", "value": 0.015}},
        ],
        "pumps": [
            {"id": "P1", "branch": "b5", "chainage": 600.0, "capacity": 0.3, "start_level": 4.6,
             "stop_level": 4.2, "direction": "positive"},
        ],
        "boundaries": [
            {"id": "Qin", "node": "U1", "type": "discharge", "series": {"file": "forcing.csv", "column": "Q_U1"}},
            {"id": "Qtrib", "node": "U2", "type": "discharge", "value": 0.2},
            {"id": "hD", "node": "D", "type": "level", "series": {"file": "forcing.csv", "column": "h_D"}},
            {"id": "out", "node": "R", "type": "rating",
             "rating": {"levels": [3.0, 3.5, 4.0, 5.0], "discharges": [0.0, 0.5, 1.5, 5.0]}},
        ],
        "laterals": [
            {"id": "L1", "branch": "b1", "chainage": 1000.0, "series": {"file": "forcing.csv", "column": "L1"}},
            {"id": "L2", "node": "J1", "value": 0.05},
            {"id": "L3", "branch": "b4", "chainage": 400.0, "series": {"file": "forcing.csv", "column": "L3"}},
        ],
        "stations": [
            {"id": "SW1", "structure": "W1", "quantities": ["h_up", "h_down", "Q"]},
            {"id": "SC1", "structure": "C1", "quantities": ["h_up", "h_down", "Q"]},
            {"id": "SP1", "structure": "P1", "quantities": ["Q", "h_up"]},
            {"id": "Sb4", "branch": "b4", "chainage": 1000.0, "quantities": ["h", "Q"]},
            {"id": "Sb1", "branch": "b1", "chainage": 500.0},
        ],
    }


def mini_forcing() -> pd.DataFrame:
    """Hourly forcing of :func:`mini_case`, two hours beyond the period on either side."""
    times = pd.date_range(START - pd.Timedelta("2h"), END + pd.Timedelta("2h"), freq="h")
    hours = np.arange(times.size, dtype=float)
    return pd.DataFrame(
        {
            "Q_U1": 1.0 + 0.5 * np.sin(hours / 4.0),
            "h_D": np.full(times.size, 3.3),
            "L1": np.full(times.size, 0.05),
            "L3": np.full(times.size, -0.02),
        },
        index=pd.Index(times.strftime("%Y-%m-%dT%H:%M:%SZ"), name="time"),
    )


def forcing_csv(frame: pd.DataFrame | None = None) -> str:
    """The forcing as CSV text."""
    return (mini_forcing() if frame is None else frame).to_csv(float_format="%.4f")


def toml_value(value) -> str:
    """A Python value as a TOML value (inline tables and arrays; nan and inf as TOML writes them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, datetime):
        return value.isoformat()
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML for {value!r}")


def toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def to_toml(data: dict) -> str:
    """A case dict as ``case.toml`` text (tables as ``[name]``, lists of tables as ``[[name]]``)."""
    lines = []
    for key, value in data.items():
        if isinstance(value, dict):
            lines.append(f"[{toml_key(key)}]")
            lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()]
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for item in value:
                lines.append(f"[[{toml_key(key)}]]")
                lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in item.items()]
        else:
            lines.insert(0, f"{toml_key(key)} = {toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def write_case(folder: Path, data: dict, csv: str | None = None) -> Path:
    """Write ``case.toml`` and ``forcing.csv`` into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "case.toml").write_text(to_toml(data), encoding="utf-8")
    (folder / "forcing.csv").write_text(forcing_csv() if csv is None else csv, encoding="utf-8")
    return folder


def load_error(tmp_path: Path, data: dict, csv: str | None = None) -> str:
    """Write a case, load it, and return the message of the CaseError it must raise."""
    write_case(tmp_path, data, csv)
    with pytest.raises(CaseError) as info:
        load_case(tmp_path)
    message = str(info.value)
    assert message and "\n" not in message, message
    return message


def expect(message: str, file: str, field: str, *phrases: str) -> None:
    assert file in message, message
    assert f": {field}: " in message, message
    for phrase in phrases:
        assert phrase in message, message


# -- the valid case --------------------------------------------------------------------------------


def test_mini_case_loads_and_runs(tmp_path: Path) -> None:
    case = load_case(write_case(tmp_path, mini_case()))
    assert set(case.forcing) == {"boundary:Qin", "boundary:Qtrib", "boundary:hD", "lateral:L1", "lateral:L2",
                                 "lateral:L3"}
    sim = Simulator(case)
    result, _ = sim.simulate(end=sim.start + pd.Timedelta("2h"))
    assert np.isfinite(result.series.to_numpy()).all()
    assert "SP1.Q" in result.series.columns


def test_toml_writer_round_trips(tmp_path: Path) -> None:
    import tomllib

    data = mini_case()
    assert tomllib.loads(to_toml(data)) == json.loads(json.dumps(data))


# -- unknown ids -----------------------------------------------------------------------------------


def test_unknown_node_of_a_branch(tmp_path: Path) -> None:
    data = mini_case()
    data["branches"][2]["to_node"] = "RR"
    expect(load_error(tmp_path, data), "case.toml", "branches[2].to_node", "unknown node 'RR'", "did you mean 'R'?")
    data["branches"][2]["to_node"] = "nowhere"
    expect(load_error(tmp_path, data), "case.toml", "branches[2].to_node", "unknown node 'nowhere'",
           "(known: 'D', 'J1', 'J2', 'R', 'U1', 'U2')")


def test_unknown_node_of_a_boundary(tmp_path: Path) -> None:
    data = mini_case()
    data["boundaries"][1]["node"] = "U3"
    expect(load_error(tmp_path, data), "case.toml", "boundaries[1].node", "unknown node 'U3'")


def test_unknown_branch_of_a_weir(tmp_path: Path) -> None:
    data = mini_case()
    data["weirs"][1]["branch"] = "b9"
    expect(load_error(tmp_path, data), "case.toml", "weirs[1].branch", "unknown branch 'b9'")


def test_unknown_branch_of_a_lateral(tmp_path: Path) -> None:
    data = mini_case()
    data["laterals"][2]["branch"] = "B4"
    expect(load_error(tmp_path, data), "case.toml", "laterals[2].branch", "unknown branch 'B4'",
           "did you mean 'b4'? (ids are case-sensitive)")


def test_unknown_branch_of_a_station(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][3]["branch"] = "nowhere"
    expect(load_error(tmp_path, data), "case.toml", "stations[3].branch", "unknown branch 'nowhere'")


def test_unknown_structure_of_a_station(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][0]["structure"] = "W3"
    expect(load_error(tmp_path, data), "case.toml", "stations[0].structure", "unknown structure 'W3'")


def test_unknown_profile_of_a_cross_section(tmp_path: Path) -> None:
    data = mini_case()
    data["branches"][1]["cross_sections"][1]["profile"] = "ZW"
    expect(load_error(tmp_path, data), "case.toml", "branches[1].cross_sections[1].profile",
           "unknown profile 'ZW'")


def test_duplicate_id(tmp_path: Path) -> None:
    data = mini_case()
    data["pumps"][0]["id"] = "W1"
    expect(load_error(tmp_path, data), "case.toml", "pumps[0].id", "'W1' is used twice", "weirs[0]")


# -- topology ----------------------------------------------------------------------------------------


def test_disconnected_network_loads_as_two_parts(tmp_path: Path) -> None:
    data = mini_case()
    # J2 - D and U2 lose their link to the rest when b2 is gone: the network has two parts, each solved alike
    data["branches"] = [b for b in data["branches"] if b["id"] != "b2"]
    data["weirs"] = [w for w in data["weirs"] if w["branch"] != "b2"]
    data["stations"] = [s for s in data["stations"] if s["id"] != "SW1"]
    write_case(tmp_path, data)
    parts = load_case(tmp_path).network.parts()
    assert sorted(sorted(p) for p in parts) == [["D", "J2", "U2"], ["J1", "R", "U1"]]


def test_node_referenced_by_nothing(tmp_path: Path) -> None:
    data = mini_case()
    data["nodes"].append({"id": "orphan"})
    expect(load_error(tmp_path, data), "case.toml", "nodes[6].id", "'orphan' is not the end of any branch")


def test_boundary_at_a_junction(tmp_path: Path) -> None:
    data = mini_case()
    data["boundaries"][1]["node"] = "J2"
    expect(load_error(tmp_path, data), "case.toml", "boundaries[1].node", "joins 3 branches", "end nodes")


# -- cross-section, storage and rating tables ------------------------------------------------------


def test_non_monotone_zw_heights(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["heights"] = [0.0, 1.5, 0.5, 3.0]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].heights[2]", "must increase strictly")


def test_zw_widths_narrowing_upward(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["total_widths"] = [1.0, 4.0, 3.0, 10.0]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].total_widths[2]", "must not decrease",
           "cannot narrow upward")
    data = mini_case()
    del data["profiles"][2]["total_widths"]
    data["profiles"][2]["flow_widths"] = [1.0, 3.0, 2.0, 6.0]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].flow_widths[2]", "must not decrease",
           "cannot narrow upward")


def test_zw_flow_widths_may_narrow_below_the_total_widths(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["flow_widths"] = [1.0, 3.0, 2.0, 6.0]  # part of the width stops conveying, and stores
    write_case(tmp_path, data)
    assert load_case(tmp_path).network.profiles[2].flow_widths[2] == 2.0


def test_negative_width(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["flow_widths"] = [-1.0, 3.0, 5.0, 6.0]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].flow_widths[0]", "must not be negative")


def test_negative_rectangular_width(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][0]["width"] = -4.0
    expect(load_error(tmp_path, data), "case.toml", "profiles[0].width", "must be at least 0.001", "-4")


def test_zw_heights_not_from_the_bed(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["heights"] = [3.2, 3.7, 4.7, 6.2]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].heights[0]", "must start at 0")


def test_zw_total_width_below_flow_width(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["total_widths"] = [1.0, 2.0, 8.0, 10.0]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].total_widths[1]", "smaller than the flow width")


def test_zw_table_lengths_differ(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][2]["flow_widths"] = [1.0, 3.0, 5.0]
    expect(load_error(tmp_path, data), "case.toml", "profiles[2].flow_widths", "3 values but heights has 4")


def test_unknown_profile_type(tmp_path: Path) -> None:
    data = mini_case()
    data["profiles"][0]["type"] = "circle"
    expect(load_error(tmp_path, data), "case.toml", "profiles[0].type", "unknown profile type 'circle'")


def test_cross_sections_out_of_order(tmp_path: Path) -> None:
    data = mini_case()
    data["branches"][0]["cross_sections"].reverse()
    expect(load_error(tmp_path, data), "case.toml", "branches[0].cross_sections[1].chainage",
           "ordered by increasing chainage")


def test_storage_table_shrinking(tmp_path: Path) -> None:
    data = mini_case()
    data["nodes"][1]["storage_table"]["areas"] = [0.0, 80.0, 50.0]
    expect(load_error(tmp_path, data), "case.toml", "nodes[1].storage_table.areas[2]", "cannot shrink")


def test_rating_table_not_monotone(tmp_path: Path) -> None:
    data = mini_case()
    data["boundaries"][3]["rating"]["discharges"] = [0.0, 1.5, 0.5, 5.0]
    expect(load_error(tmp_path, data), "case.toml", "boundaries[3].rating.discharges[2]", "must not decrease")


def test_rating_table_not_starting_at_zero(tmp_path: Path) -> None:
    data = mini_case()
    data["boundaries"][3]["rating"]["discharges"] = [0.2, 0.5, 1.5, 5.0]
    expect(load_error(tmp_path, data), "case.toml", "boundaries[3].rating.discharges[0]",
           "first discharge must be 0")


# -- structures --------------------------------------------------------------------------------------


def test_crest_below_the_bed(tmp_path: Path) -> None:
    data = mini_case()
    data["weirs"][0]["crest_level"] = 3.0
    expect(load_error(tmp_path, data), "case.toml", "weirs[0].crest_level", "lies below the bed", "3.680")


def test_culvert_invert_below_the_bed(tmp_path: Path) -> None:
    data = mini_case()
    data["culverts"][0]["invert_level"] = 3.0
    expect(load_error(tmp_path, data), "case.toml", "culverts[0].invert_level", "lies below the bed")


def test_a_pump_may_stop_below_the_bed_as_in_d_flow_fm(tmp_path: Path) -> None:
    data = mini_case()
    data["pumps"][0]["stop_level"] = 3.5  # below the bed: the engine stops it when its suction point runs dry
    write_case(tmp_path, data)
    assert load_case(tmp_path).network.pumps[0].stop_level == 3.5


def test_pump_stop_above_start(tmp_path: Path) -> None:
    data = mini_case()
    data["pumps"][0]["stop_level"] = 4.8
    expect(load_error(tmp_path, data), "case.toml", "pumps[0].stop_level", "must be below start_level")


def test_structures_too_close_to_each_other(tmp_path: Path) -> None:
    data = mini_case()
    data["culverts"][0].update(branch="b2", chainage=606.0, invert_level=3.8)
    expect(load_error(tmp_path, data), "case.toml", "culverts[0].chainage", "too close to weir 'W1'",
           "engine.structure_length = 10 m")


def test_structures_too_close_only_for_a_longer_structure_length(tmp_path: Path) -> None:
    data = mini_case()
    data["culverts"][0].update(branch="b2", chainage=630.0, invert_level=3.8)
    write_case(tmp_path, data)
    load_case(tmp_path)  # 30 m apart: fine with 10 m segments
    data["engine"]["structure_length"] = 40.0
    expect(load_error(tmp_path, data), "case.toml", "culverts[0].chainage", "too close")


def test_culvert_without_its_dimensions(tmp_path: Path) -> None:
    data = mini_case()
    data["culverts"][0]["shape"] = "rectangular"
    expect(load_error(tmp_path, data), "case.toml", "culverts[0].width", "needs width")


# -- boundaries, laterals and stations ---------------------------------------------------------------


def test_lateral_at_a_level_boundary_node(tmp_path: Path) -> None:
    data = mini_case()
    data["laterals"][1] = {"id": "L2", "node": "D", "value": 0.05}
    expect(load_error(tmp_path, data), "case.toml", "laterals[1].node", "level boundary 'hD'",
           "inflow would be lost")


def test_lateral_next_to_a_level_boundary_node(tmp_path: Path) -> None:
    data = mini_case()
    data["laterals"][2]["chainage"] = 1450.0  # nearest calculation point: node D
    expect(load_error(tmp_path, data), "case.toml", "laterals[2].chainage", "lands on node 'D'")


def test_station_quantity_that_cannot_exist(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][3]["quantities"] = ["h", "h_up"]
    expect(load_error(tmp_path, data), "case.toml", "stations[3].quantities[1]", "'h_up' exists only at a structure")


def test_station_quantity_h_at_a_structure(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][0]["quantities"] = ["h"]
    expect(load_error(tmp_path, data), "case.toml", "stations[0].quantities[0]", "does not exist at a structure")


def test_station_unknown_quantity(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][0]["quantities"] = ["level"]
    expect(load_error(tmp_path, data), "case.toml", "stations[0].quantities[0]", "'level' is not allowed")


def test_level_station_inside_a_structure(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][4] = {"id": "Sb2", "branch": "b2", "chainage": 602.0}
    expect(load_error(tmp_path, data), "case.toml", "stations[4].chainage", "inside the segment of weir 'W1'")


def test_station_id_with_a_dot(tmp_path: Path) -> None:
    data = mini_case()
    data["stations"][0]["id"] = "S.W1"
    expect(load_error(tmp_path, data), "case.toml", "stations[0].id", "contains a '.'")


# -- numbers and types in case.toml ------------------------------------------------------------------


def test_nan_in_toml(tmp_path: Path) -> None:
    data = mini_case()
    data["branches"][3]["cross_sections"][1]["bed_level"] = float("nan")
    expect(load_error(tmp_path, data), "case.toml", "branches[3].cross_sections[1].bed_level",
           "expected a finite number", "nan")


def test_inf_in_toml(tmp_path: Path) -> None:
    data = mini_case()
    data["weirs"][0]["crest_width"] = float("inf")
    expect(load_error(tmp_path, data), "case.toml", "weirs[0].crest_width", "expected a finite number", "inf")


def test_number_written_as_text(tmp_path: Path) -> None:
    data = mini_case()
    data["weirs"][1]["crest_level"] = "3.3"
    expect(load_error(tmp_path, data), "case.toml", "weirs[1].crest_level", "expected a number",
           "remove the quotes")


def test_missing_field(tmp_path: Path) -> None:
    data = mini_case()
    del data["branches"][4]["length"]
    expect(load_error(tmp_path, data), "case.toml", "branches[4].length", "required field is missing")


def test_misspelt_field(tmp_path: Path) -> None:
    data = mini_case()
    data["weirs"][0]["crest_levle"] = data["weirs"][0].pop("crest_level")
    expect(load_error(tmp_path, data), "case.toml", "weirs[0].crest_levle", "unknown field 'crest_levle'",
           "did you mean 'crest_level'?")


def test_friction_of_the_wrong_kind(tmp_path: Path) -> None:
    data = mini_case()
    data["friction"] = {"value": 0.035}  # a Manning n, read as a Strickler k_s (the default type)
    expect(load_error(tmp_path, data), "case.toml", "friction.value", "outside the plausible range",
           'type = "manning"')


def test_invalid_toml(tmp_path: Path) -> None:
    write_case(tmp_path, mini_case())
    path = tmp_path / "case.toml"
    path.write_text(path.read_text(encoding="utf-8") + "\n[[weirs]\n", encoding="utf-8")
    with pytest.raises(CaseError, match=r"case\.toml: not valid TOML"):
        load_case(tmp_path)


# -- the simulated period and engine settings --------------------------------------------------------


def test_end_before_start(tmp_path: Path) -> None:
    data = mini_case()
    data["case"]["end"] = "2019-12-31T00:00:00Z"
    expect(load_error(tmp_path, data), "case.toml", "case.end", "before or when it starts")


def test_period_not_a_multiple_of_the_output_interval(tmp_path: Path) -> None:
    data = mini_case()
    data["case"]["end"] = "2020-01-01T23:30:00Z"
    expect(load_error(tmp_path, data), "case.toml", "case.end", "not a whole multiple of engine.output_interval")


def test_output_interval_not_a_multiple_of_dt(tmp_path: Path) -> None:
    data = mini_case()
    data["engine"]["dt"] = 70.0
    expect(load_error(tmp_path, data), "case.toml", "engine.output_interval", "not a whole multiple")


# -- time series -------------------------------------------------------------------------------------


def test_series_with_a_gap(tmp_path: Path) -> None:
    frame = mini_forcing().drop(index="2020-01-01T05:00:00Z")
    msg = load_error(tmp_path, mini_case(), forcing_csv(frame))
    expect(msg, "forcing.csv", "time", "line 9", "gap", "2020-01-01T04:00:00Z and 2020-01-01T06:00:00Z",
           "boundaries[0].series")


def test_series_with_an_empty_cell(tmp_path: Path) -> None:
    frame = mini_forcing().astype(object)
    frame.loc["2020-01-01T03:00:00Z", "L3"] = ""
    msg = load_error(tmp_path, mini_case(), forcing_csv(frame))
    expect(msg, "forcing.csv", "L3", "line 7", "empty cell", "laterals[2].series")


def test_series_with_a_duplicate_time(tmp_path: Path) -> None:
    lines = forcing_csv().splitlines()
    lines.insert(6, lines[5])
    msg = load_error(tmp_path, mini_case(), "\n".join(lines) + "\n")
    expect(msg, "forcing.csv", "time", "line 7", "appears twice")


def test_series_out_of_order(tmp_path: Path) -> None:
    lines = forcing_csv().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    msg = load_error(tmp_path, mini_case(), "\n".join(lines) + "\n")
    expect(msg, "forcing.csv", "time", "line 7", "earlier than", "time order")


def test_series_with_text_in_a_number(tmp_path: Path) -> None:
    frame = mini_forcing().astype(object)
    frame.loc["2020-01-01T10:00:00Z", "Q_U1"] = "n/a"
    msg = load_error(tmp_path, mini_case(), forcing_csv(frame))
    expect(msg, "forcing.csv", "Q_U1", "line 14", "'n/a' is not a number", "boundaries[0].series")


def test_series_with_a_decimal_comma(tmp_path: Path) -> None:
    frame = mini_forcing().astype(object)
    frame.loc["2020-01-01T10:00:00Z", "L1"] = "0,05"
    msg = load_error(tmp_path, mini_case(), forcing_csv(frame))
    expect(msg, "forcing.csv", "L1", "'0,05' is not a number", "decimal separator")


def test_series_with_nan(tmp_path: Path) -> None:
    frame = mini_forcing()
    frame.loc["2020-01-01T10:00:00Z", "h_D"] = np.nan
    msg = load_error(tmp_path, mini_case(), forcing_csv(frame).replace(",,", ",nan,"))
    expect(msg, "forcing.csv", "h_D", "'nan' is not a finite number")


def test_series_with_a_bad_time(tmp_path: Path) -> None:
    csv = forcing_csv().replace("2020-01-01T07:00:00Z", "2020-01-01 7h")
    expect(load_error(tmp_path, mini_case(), csv), "forcing.csv", "time", "line 11", "is not a time")


def test_boundary_series_starting_after_the_period(tmp_path: Path) -> None:
    frame = mini_forcing().iloc[4:]  # starts 2020-01-01T02:00
    msg = load_error(tmp_path, mini_case(), forcing_csv(frame))
    expect(msg, "forcing.csv", "Q_U1", "starts 2 h too late", "boundaries[0].series", "simulated period")


def test_lateral_series_ending_before_the_period(tmp_path: Path) -> None:
    data = mini_case()
    data["boundaries"][0] = {"id": "Qin", "node": "U1", "type": "discharge", "value": 1.0}
    data["boundaries"][2] = {"id": "hD", "node": "D", "type": "level", "value": 3.3}
    frame = mini_forcing()
    frame.loc[frame.index > "2020-01-01T20:00:00Z", "L1"] = np.nan
    csv = forcing_csv(frame[["L1", "L3"]].dropna())
    msg = load_error(tmp_path, data, csv)
    expect(msg, "forcing.csv", "L1", "ends 4 h too early", "laterals[0].series")


def test_series_column_missing(tmp_path: Path) -> None:
    data = mini_case()
    data["laterals"][0]["series"]["column"] = "L9"
    expect(load_error(tmp_path, data), "forcing.csv", "L9", "no column 'L9'", "laterals[0].series")


def test_series_file_missing(tmp_path: Path) -> None:
    data = mini_case()
    data["boundaries"][2]["series"]["file"] = "levels.csv"
    expect(load_error(tmp_path, data), "case.toml", "boundaries[2].series.file", "'levels.csv' not found")


def test_unused_columns_may_hold_anything(tmp_path: Path) -> None:
    frame = mini_forcing().astype(object)
    frame["remark"] = "checked"
    frame.loc["2020-01-01T03:00:00Z", "remark"] = ""
    case = load_case(write_case(tmp_path, mini_case(), forcing_csv(frame)))
    assert "lateral:L3" in case.forcing


def test_read_series_csv_checks_every_column(tmp_path: Path) -> None:
    frame = mini_forcing().astype(object)
    frame["remark"] = "checked"
    (tmp_path / "f.csv").write_text(forcing_csv(frame), encoding="utf-8")
    with pytest.raises(CaseError, match=r"f\.csv: remark: line 2 .*'checked' is not a number"):
        read_series_csv(tmp_path / "f.csv")


def test_error_carries_file_and_field(tmp_path: Path) -> None:
    data = mini_case()
    data["weirs"][0]["crest_level"] = 3.0
    write_case(tmp_path, data)
    with pytest.raises(CaseError) as info:
        load_case(tmp_path)
    assert info.value.file == str(tmp_path / "case.toml")
    assert info.value.field == "weirs[0].crest_level"
    assert "crest" in info.value.reason


def test_mini_case_is_not_modified_by_tests() -> None:
    assert mini_case() == copy.deepcopy(mini_case())


# -- the schema's own errors ------------------------------------------------------------------------


def test_schema_errors_belong_to_the_rivercal_hierarchy() -> None:
    """A broken rule and an overlap of structures are rivercal errors that keep their fields across processes."""
    import pickle

    from pydantic import ValidationError

    from rivercal.errors import FieldProblem, RivercalError, StructureOverlap
    from rivercal.network import Branch, Network, Weir
    from rivercal.network.grid import branch_layout

    data = mini_case()
    data["weirs"][0]["crest_level"] = 3.0
    fields = {k: v for k, v in data.items() if k in Network.model_fields}
    with pytest.raises(ValidationError) as info:
        Network.model_validate(fields)
    problem = info.value.errors()[0]["ctx"]["error"]
    assert isinstance(problem, FieldProblem) and isinstance(problem, RivercalError)
    assert problem.path == "weirs[0].crest_level" and "below the bed" in problem.reason
    again = pickle.loads(pickle.dumps(problem))
    assert (again.path, again.reason, str(again)) == (problem.path, problem.reason, str(problem))

    branch = Branch.model_validate(data["branches"][1])
    weirs = [Weir(id=f"W{k}", branch=branch.id, chainage=500.0 + k, crest_level=5.0, crest_width=3.0) for k in (0, 1)]
    with pytest.raises(StructureOverlap) as overlap:
        branch_layout(branch, weirs, 10.0)
    assert isinstance(overlap.value, RivercalError)
    assert (overlap.value.structure.id, overlap.value.previous.id) == ("W1", "W0")
    again = pickle.loads(pickle.dumps(overlap.value))
    assert (again.structure, again.previous) == (overlap.value.structure, overlap.value.previous)
