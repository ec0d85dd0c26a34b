"""The SOBEK 3 import on a small model written here (tests/sobek3_models.py): every object, every refusal, and
every bad value reported with its file, line and key."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from rivercal.case import load_case
from rivercal.engine import Simulator
from rivercal.errors import CaseError
from rivercal.io.sobek3 import ImportOptions, import_sobek3
from rivercal.io.sobek3._ini import read_ini
from rivercal.io.sobek3._network import convert_value, law_of
from rivercal.network import MAX_DISCHARGE
from tests.sobek3_models import write_model


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> tuple[Path, dict, str]:
    root = tmp_path_factory.mktemp("sobek3")
    md1d = write_model(root / "model")
    result = import_sobek3(md1d, root / "case", ImportOptions(allow_partial=True))
    data = tomllib.loads((root / "case" / "case.toml").read_text(encoding="utf-8"))
    return result.folder, data, (root / "case" / "import.md").read_text(encoding="utf-8")


def _by_id(items: list[dict]) -> dict[str, dict]:
    return {i["id"]: i for i in items}


def test_network_and_grid_points(imported) -> None:
    _, data, _ = imported
    nodes = _by_id(data["nodes"])
    assert (nodes["E"]["x"], nodes["E"]["y"]) == (1000.0, 1000.0)
    branches = _by_id(data["branches"])
    assert branches["b1"]["points"] == [100.0 * k for k in range(11)]
    assert branches["b1"]["order"] == 1 and branches["b2"]["order"] == 1
    assert "order" not in branches["b3"]  # order -1: none
    assert branches["b4"]["geometry"] == [[1000.0, 0.0], [1000.0, 1000.0]]
    assert data["engine"] == {"dt": 60.0, "output_interval": 600.0, "cross_sections": "interpolated", "theta": 1.0,
                              "max_iterations": 8, "min_storage_area": 0.1, "courant": 0.7}


def test_profiles_of_every_type(imported) -> None:
    _, data, _ = imported
    profiles = _by_id(data["profiles"])
    river = profiles["river"]
    assert river["type"] == "zw"
    assert river["heights"] == pytest.approx([0.0, 1.5, 1.6, 3.0, 5.0])
    assert river["flow_widths"] == [6.0, 10.0, 30.0, 24.0, 40.0]  # narrowing kept: it only stores there
    assert river["total_widths"] == [6.0, 12.0, 36.0, 40.0, 50.0]
    assert river["section_widths"] == [10.0, 30.0]  # main 10 + floodplain 35 cut to the top flow width 40
    assert river["friction"] == ["Main", "FloodPlain1"]
    assert river["summer_dike"] == {"crest": pytest.approx(2.2), "flow_area": 5.0, "total_area": 8.0,
                                    "transition": 0.4, "base": pytest.approx(1.7)}
    assert profiles["rect"] == {"id": "rect", "type": "rectangular", "width": 5.0, "height": 3.0,
                                "friction": ["Main"]}
    assert profiles["trap"]["heights"] == [0.0, 2.0] and profiles["trap"]["flow_widths"] == [4.0, 10.0]
    assert profiles["pipe"]["diameter"] == 1.0
    yz = profiles["yz1"]
    assert yz["z"] == [3.0, 1.0, 0.0, 0.0, 1.0, 3.0] and yz["friction_positions"] == [0.0, 5.0, 10.0]
    assert yz["friction"] == ["Main", "FloodPlain1"]
    beds = {b["id"]: [(c["chainage"], c["profile"], c["bed_level"]) for c in b["cross_sections"]]
            for b in data["branches"]}
    assert beds["b1"] == [(100.0, "river", -1.0), (900.0, "river", -1.5)]
    assert beds["b2"] == [(500.0, "yz1", -2.0)]
    assert beds["b3"] == [(0.0, "trap", -2.1), (1000.0, "rect", -2.3)]
    assert beds["b4"] == [(500.0, "rect", -1.5)]  # the egg's cross-section refused


def test_roughness_of_every_function_type(imported) -> None:
    _, data, _ = imported
    groups = _by_id(data["friction_groups"])
    assert (groups["Main"]["type"], groups["Main"]["value"]) == ("chezy", 45.0)
    assert (groups["FloodPlain1"]["type"], groups["FloodPlain1"]["value"]) == ("strickler", 20.0)
    on = {e["branch"]: e for e in groups["Main"]["branches"]}
    assert on["b1"] == {"branch": "b1", "function": "waterlevel", "levels": [-1.0, 1.0, 3.0],
                        "chainages": [0.0, 1000.0], "table": [[30.0, 40.0, 50.0], [32.0, 42.0, 52.0]]}
    assert on["b2"] == {"branch": "b2", "type": "manning", "chainages": [0.0, 1000.0], "values": [0.03, 0.04]}
    # Strickler with k_n: C = 25 (R/k_n)^(1/6) is Strickler k_s = 25 k_n^(-1/6)
    assert on["b3"]["type"] == "strickler" and on["b3"]["value"] == pytest.approx(25.0 * 0.064 ** (-1 / 6))
    assert "b4" not in on  # the discharge table is refused


def test_structures_boundaries_laterals_stations_and_initial_state(imported) -> None:
    folder, data, _ = imported
    weir = data["weirs"][0]
    assert (weir["crest_level"], weir["crest_width"], weir["discharge_coefficient"], weir["lateral_contraction"],
            weir["allowed_flow"]) == (-1.0, 3.0, 1.1, 0.9, "both")
    culvert = data["culverts"][0]
    assert (culvert["profile"], culvert["invert_level"], culvert["invert_level_end"], culvert["length"],
            culvert["friction"], culvert["allowed_flow"]) == ("pipe", -1.9, -1.95, 12.0,
                                                              {"type": "manning", "value": 0.014}, "positive")
    orifice = data["orifices"][0]
    assert orifice["discharge_coefficient"] == pytest.approx(0.63 * 0.9)
    assert (orifice["gate_lower_edge_level"], orifice["allowed_flow"], orifice["max_flow_positive"]) == \
        (-0.5, "negative", 4.0)
    pump = data["pumps"][0]
    assert (pump["capacity"], pump["start_level"], pump["stop_level"], pump["direction"]) == (0.5, 0.2, -0.3,
                                                                                             "positive")
    uweir = data["universal_weirs"][0]
    assert uweir["crest_level"] == -1.5 and uweir["z"] == pytest.approx([0.7, 0.0, 0.0, 0.7])
    bridge = data["bridges"][0]
    assert (bridge["profile"], bridge["bed_level"], bridge["friction"]) == ("rect", -2.2,
                                                                            {"type": "strickler", "value": 40.0})
    bounds = _by_id(data["boundaries"])
    assert bounds["A"]["type"] == "discharge"
    series = pd.read_csv(folder / bounds["A"]["series"]["file"], index_col=0)[bounds["A"]["series"]["column"]]
    assert series.loc["2020-01-01T06:00:00Z"] == 6.0
    rating = bounds["D"]["rating"]  # outflow written negative: turned around, its ends held within 1 cm
    assert rating["levels"] == pytest.approx([-1.51, -1.5, -1.0, 0.5, 0.51])
    assert rating["discharges"] == [0.0, 1.0, 4.0, 20.0, MAX_DISCHARGE]
    assert (bounds["E"]["type"], bounds["E"]["value"]) == ("level", 0.4)
    lats = _by_id(data["laterals"])
    assert (lats["lat1"]["branch"], lats["lat1"]["chainage"], lats["lat1"]["value"]) == ("b1", 300.0, 0.2)
    assert lats["lat2"]["chainage"] == 700.0  # spread over 200 m from 600 m: at its middle
    assert (lats["lat3"]["node"], lats["lat3"]["value"]) == ("C", -0.05)
    stations = _by_id(data["stations"])
    assert stations["obs1"] == {"id": "obs1", "branch": "b1", "chainage": 200.0, "quantities": ["h", "Q"]}
    assert "obs_2" in stations and "weir1" in stations
    b1 = _by_id(data["branches"])["b1"]
    assert b1["initial_levels"] == {"chainages": [0.0, 1000.0], "levels": [1.0, 0.5]}
    assert data["initial"] == {"depth": 0.5, "level": 0.0}
    node_c = _by_id(data["nodes"])["C"]
    assert node_c["storage_table"] == {"levels": [-1.0, 0.0, 1.0], "areas": [50.0, 100.0, 100.0]}


def test_the_account_of_every_object(imported) -> None:
    _, _, text = imported
    assert text.startswith("# Import of a SOBEK 3 model")
    for fragment in ("| generalStructure | `general1` |", "functionType = 1", "`egg1` | cross-section type 'egg'",
                     "| station | `obs.2` | `obs_2` |", "**partial import**: 4 refused object(s)",
                     "not on a branch of the network ('b9')"):
        assert fragment in text, fragment


def test_a_strict_import_refuses_and_writes_no_case(tmp_path) -> None:
    md1d = write_model(tmp_path / "model")
    with pytest.raises(CaseError, match=r"4 object\(s\) that change the hydraulics.*--allow-partial") as info:
        import_sobek3(md1d, tmp_path / "case")
    assert "generalStructure 'general1'" in str(info.value)
    assert (tmp_path / "case" / "import.md").is_file() and not (tmp_path / "case" / "case.toml").exists()


def test_the_imported_case_runs(imported) -> None:
    folder, _, _ = imported
    sim = Simulator(load_case(folder))
    out, _ = sim.simulate(end=sim.start + pd.Timedelta(hours=3))
    assert out.series.notna().all().all()
    assert abs(out.balance.relative_error) < 1e-9
    # the initial levels along b1 (1 m AD at its start, 0.5 m at its end) were the cold start there
    z = dict(zip(sim.compiled.hp_label, sim.initial_state().z, strict=True))
    assert z["b1@500.0"] == pytest.approx(0.75)


# -- bad values ----------------------------------------------------------------------------------------------


def _line_of(folder: Path, name: str, text: str) -> int:
    lines = (folder / name).read_text(encoding="utf-8").splitlines()
    return next(k for k, line in enumerate(lines, start=1) if text in line)


@pytest.mark.parametrize(("file", "old", "new", "key", "words", "line_of"), [
    ("CrossSectionDefinitions.ini", "levels                = -1.0 0.5 0.6", "levels                = -1.0 0.5 x",
     "levels", "'x' is not a number", None),
    ("NetworkDefinition.ini", "fromNode = C", "fromNode = Q", "fromNode", "node 'Q' is not a [Node]", None),
    ("roughness-Main.ini", "functionType          = 2", "functionType          = 7", "functionType",
     "functionType 7 is none of", None),
    ("BoundaryConditions.bc", "unit                  = minutes since 2020-01-01 00:00:00\r\n    quantity              "
     "= water_discharge", "unit                  = furlongs since 2020-01-01 00:00:00\r\n    quantity              "
     "= water_discharge", "unit", "time unit 'furlongs since", "furlongs"),
    ("Structures.ini", "allowedFlowDir        = 0", "allowedFlowDir        = 7", "allowedFlowDir",
     "'7' is none of 0 (both)", None),
    ("Structures.ini", "crestWidth            = 3.0", "crestWidth            = 3.0\r\n    crestWidth = 4.0",
     "crestWidth", "'crestWidth' is given 2 times", "crestWidth = 4.0"),
    ("CrossSectionLocations.ini", "chainage              = 900.000", "chainage              = 1900.000", "chainage",
     "lies outside branch 'b1'", None),
    ("Flow1D.md1d", "StartTime             = 2020-01-01 00:00:00", "StartTime             = 2020-13-45 00:00:00",
     "StartTime", "is not a date", None),
    ("Flow1D.md1d", "networkFile           = NetworkDefinition.ini", "networkFile           = Missing.ini",
     "networkFile", "which does not exist", None),
    ("BoundaryConditions.bc", "    360 6.0", "    360 6.0 7.0", None, "has 3 value(s)", None),
    ("CrossSectionDefinitions.ini", "floodPlain1           = 35.0", "floodPlain1           = 5.0", "main",
     "narrower than the flow width at the top", "main                  = 10.0"),
    ("ObservationPoints.ini", "[General]", "garbage\r\n[General]", None, "before the first [section]", "garbage"),
    ("roughness-Main.ini", "values                = 30.0 40.0 50.0", "values                = 30.0 40.0", "values",
     "2 value(s) given but 3 expected", None),
])
def test_a_bad_value_names_its_file_line_and_key(tmp_path, file, old, new, key, words, line_of) -> None:
    key_name = file.replace(".", "_").replace("-", "_")
    md1d = write_model(tmp_path / "model", **{key_name: (old.replace("\r\n", "\n"), new.replace("\r\n", "\n"))})
    with pytest.raises(CaseError) as info:
        import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))
    message = str(info.value)
    assert words in message, message
    assert file in message, message
    if key is not None:
        assert f": {key}: " in message, message
    if file != "Flow1D.md1d" or key == "StartTime":
        line = _line_of(tmp_path / "model", file, line_of or new.strip())
        assert f"{file}:{line}:" in message, (message, line)
    assert "bug" not in message and "internal error" not in message


def test_a_discharge_table_of_both_signs_and_an_unknown_law_are_refused(tmp_path) -> None:
    md1d = write_model(tmp_path / "model", BoundaryConditions_bc=("    -1.0 -4.0", "    -1.0 4.0"),
                       roughness_Main_ini=("roughnessType         = 4", "roughnessType         = 8"))
    text = (tmp_path / "model" / "BoundaryConditions.bc").read_text(encoding="utf-8")
    (tmp_path / "model" / "BoundaryConditions.bc").write_text(text.replace(
        "name                  = E\n    function              = constant",
        "name                  = E\n    function              = astronomic"), encoding="utf-8")
    with pytest.raises(CaseError) as info:
        import_sobek3(md1d, tmp_path / "case")
    text = (tmp_path / "case" / "import.md").read_text(encoding="utf-8")
    assert "boundary 'D'" in str(info.value) or "`D`" in text
    assert "change sign" in text
    assert "roughness type engelund has no counterpart" in text
    assert "a boundary given as 'astronomic'" in text


# -- the INI reader and the laws ---------------------------------------------------------------------------------


def test_the_ini_reader_keeps_lines_and_strips_comments(tmp_path) -> None:
    path = tmp_path / "x.ini"
    path.write_bytes("\ufeff# header\r\n[Files]\r\n  a = b.ini# comment\r\n  c = #with blanks# rest\r\n"
                     "\r\n[Bc]\r\n  quantity = time\r\n  quantity = level\r\n  0 1.5\r\n  60 2.5d0\r\n".encode())
    files, bc = read_ini(path)
    assert (files.text("A"), files.find("a").line, files.text("c")) == ("b.ini", 3, "with blanks")
    assert [i.value for i in bc.all("quantity")] == ["time", "level"]
    assert bc.rows == [(9, "0 1.5"), (10, "60 2.5d0")]
    with pytest.raises(CaseError, match=r"x.ini:8: quantity: 'quantity' is given 2 times"):
        bc.text("quantity")


@pytest.mark.parametrize(("code", "law"), [("1", "chezy"), ("0", "chezy"), ("4", "manning"), ("6", "strickler"),
                                           ("5", "stricklernikuradse"), ("7", "white-colebrook"),
                                           ("Manning", "manning"), ("9", "bosbijkerk"), ("42", None)])
def test_roughness_codes(code, law) -> None:
    assert law_of(code) == law


def test_strickler_nikuradse_is_strickler_of_the_same_chezy() -> None:
    law, ks = convert_value("stricklernikuradse", 0.05)
    radius = 2.3
    assert law == "strickler"
    assert ks * radius ** (1 / 6) == pytest.approx(25.0 * (radius / 0.05) ** (1 / 6), rel=1e-12)
    assert math.isclose(convert_value("chezy", 40.0)[1], 40.0)
