"""The Mascaret import on a small model written for the test (tests/mascaret_models.py) and on the Oriège.

Each conversion is checked against the numbers put into the model and against Mascaret's own rules (its grid
of method 5, its distribution of an inflow over a length, the rating of uniform flow computed by hand).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.case import load_case
from rivercal.errors import CaseError
from rivercal.io.mascaret import ImportOptions, StationSpec, import_mascaret
from rivercal.models import load_model
from tests.mascaret_models import AXIS, MAJOR, MINOR, PROFILES, XCAS, write_model
from tests.shared_data import shared_model


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mascaret")
    xcas = write_model(folder / "model")
    result = import_mascaret(xcas, folder / "case", ImportOptions(allow_partial=True))
    data = tomllib.loads((folder / "case" / "case.toml").read_text(encoding="utf-8"))
    return result, data, folder


def _by_id(items: list[dict]) -> dict[str, dict]:
    return {item["id"]: item for item in items}


def _import(tmp_path: Path, xcas_text: str, **options):
    xcas = write_model(tmp_path / "model", xcas=xcas_text)
    result = import_mascaret(xcas, tmp_path / "case", ImportOptions(allow_partial=True, **options))
    return result, tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))


def test_reaches_become_branches_between_the_free_ends_and_the_confluence(imported) -> None:
    result, data, _ = imported
    branches = _by_id(data["branches"])
    assert {b: (v["from_node"], v["to_node"], v["length"]) for b, v in branches.items()} == {
        "amont1": ("up1", "node1", 250.0), "amont2": ("up2", "node1", 200.0), "aval": ("node1", "down", 1000.0)}
    nodes = _by_id(data["nodes"])
    assert (nodes["up1"]["x"], nodes["up1"]["y"]) == AXIS["P1a"]  # georeferenced axis points
    assert branches["amont1"]["geometry"] == [list(AXIS[n]) for n, *_ in PROFILES["amont1"]]
    assert "geometry" not in branches["aval"]
    assert result.summary["branches"] == 3 and result.summary["refused"] == 1


def test_the_calibration_parameters_are_listed_in_the_summary_and_in_import_md(imported) -> None:
    # as the D-HYDRO and SOBEK 3 imports list theirs: --json 'parameters', import.md '## Calibration parameters'
    result, data, folder = imported
    names = [p["name"] for p in data["parameters"]]
    assert names and result.summary["parameters"] == names
    text = (folder / "case" / "import.md").read_text(encoding="utf-8")
    section = text.split("## Calibration parameters", 1)[1].split("\n## ", 1)[0]
    for p in data["parameters"]:
        assert f"- `{p['name']}`: {p['targets'][0]}, {p['min']:g} .. {p['max']:g} {p['unit']}, initial " in section


def test_the_grid_is_mascarets_method_5(imported) -> None:
    """Between two profiles int(distance / step) equal cells (when more than one), as Mascaret's MAILLER lays them."""
    _, data, _ = imported
    points = {b["id"]: b["points"] for b in data["branches"]}
    assert points["amont1"] == [0.0, 50.0, 100.0, 150.0, 200.0, 250.0]  # 100/40 -> 2 cells, 150/40 -> 3 cells
    np.testing.assert_allclose(points["amont2"], [0.0, 200 / 3, 400 / 3, 200.0], atol=1e-6)  # 200/60 -> 3 cells
    assert points["aval"] == [float(x) for x in range(0, 1001, 100)]
    # and each of its points takes the profile interpolated at it, as Mascaret's planimetry of its sections does
    assert data["engine"]["cross_sections"] == "points"


def test_profiles_are_yz_with_their_beds_and_friction_sections(imported) -> None:
    _, data, folder = imported
    profiles = _by_id(data["profiles"])
    p1b = profiles["P1b"]
    assert p1b["y"] == [y for y, _, _ in MAJOR] and p1b["z"] == [h for _, h, _ in MAJOR]
    assert p1b["conveyance"] == "lumped"
    assert p1b["friction_positions"] == [0.0, 7.0, 11.0, 18.0]  # the minor bed runs from the first to the last B
    assert p1b["friction"] == ["zone1_major", "zone1_minor", "zone1_major"]
    assert profiles["P2a"]["friction"] == ["zone2_minor"] and "friction_positions" not in profiles["P2a"]
    assert profiles["P3a"]["y"] == [y for y, _, _ in MAJOR]  # the closing walls at 999 m are the case's own walls
    assert profiles["P3c"]["friction"] == ["zone4_minor"]  # aval's second zone starts at 500 m
    sections = {cs["profile"]: (cs["chainage"], cs["bed_level"]) for b in data["branches"]
                for cs in b["cross_sections"]}
    assert sections == {n: (x, bed) for reach in PROFILES.values() for n, x, bed, _ in reach}
    groups = {g["id"]: (g["type"], g["value"]) for g in data["friction_groups"]}
    assert groups == {"zone1_minor": ("strickler", 25.0), "zone1_major": ("strickler", 15.0),
                      "zone2_minor": ("strickler", 30.0), "zone3_minor": ("strickler", 35.0),
                      "zone3_major": ("strickler", 12.0), "zone4_minor": ("strickler", 28.0)}
    # a group is a calibration parameter where a change of it is exact: in profiles of one friction group only
    params = {p["name"]: p for p in data["parameters"]}
    assert sorted(params) == ["Kz2_minor", "Kz4_minor"]
    assert params["Kz4_minor"]["targets"] == ["friction:group:zone4_minor"]
    assert params["Kz4_minor"]["min"] < 28.0 < params["Kz4_minor"]["max"]
    report = (folder / "case" / "import.md").read_text(encoding="utf-8")
    assert "friction group zone3_minor is not offered as a calibration parameter: profile(s) P3a, P3b" in report


def test_boundaries_and_laws_keep_their_values_and_times(imported) -> None:
    _, data, folder = imported
    bounds = _by_id(data["boundaries"])
    assert bounds["up1"]["type"] == "discharge" and bounds["up1"]["series"]["column"] == "Q_up1"
    assert bounds["up2"] == {"id": "up2", "node": "up2", "type": "discharge", "value": 0.5}  # a constant law
    # a rating that starts above 0 m3/s gets the bed of the end profile with no outflow below it
    assert bounds["down"]["rating"] == {"levels": [8.8, 9.0, 9.5, 10.5], "discharges": [0.0, 0.5, 2.0, 8.0]}
    forcing = pd.read_csv(folder / "case" / "forcing.csv", index_col=0)
    # the law in hours: 0, 1 h, 10 h from the origin
    assert list(forcing["Q_up1"].dropna().items()) == [("2000-01-01T00:00:00Z", 1.0), ("2000-01-01T01:00:00Z", 2.0),
                                                        ("2000-01-01T10:00:00Z", 2.0)]
    series = load_case(folder / "case").forcing["boundary:up1"]
    seconds = (series.index - series.index[0]).total_seconds()
    assert np.interp(1800.0, seconds, series.to_numpy()) == pytest.approx(1.5)  # linear in between, as Mascaret


def test_a_point_inflow_and_an_inflow_over_a_length(imported) -> None:
    """Mascaret puts a linear inflow q (m3/s per m) at the points of the stretch, each q times its cell."""
    _, data, folder = imported
    laterals = _by_id(data["laterals"])
    assert laterals["point_inflow"]["branch"] == "aval" and laterals["point_inflow"]["chainage"] == 150.0
    forcing = pd.read_csv(folder / "case" / "forcing.csv", index_col=0)
    assert forcing["L_point_inflow"].iloc[[0, -1]].tolist() == [0.2, 0.4]
    bank = [v for k, v in laterals.items() if k.startswith("bank_inflow")]
    assert sum(v["value"] for v in bank) == pytest.approx(0.001 * 100.0)  # q times the length
    assert [v["chainage"] for v in bank] == [400.0]  # the points 400 and 500: the cell 400-500 goes to 400


def test_sites_become_stations_and_the_weir_is_refused(imported) -> None:
    result, data, folder = imported
    stations = {s["id"]: (s["branch"], s["chainage"]) for s in data["stations"]}
    assert stations == {"site1": ("amont1", 50.0), "site2": ("aval", 900.0)}
    assert result.ledger.status_of("weir", "barrage1") == "refused"
    report = (folder / "case" / "import.md").read_text(encoding="utf-8")
    assert "partial import" in report and "barrage1" in report
    assert (data["case"]["start"], data["case"]["end"]) == ("2000-01-01T00:00:00Z", "2000-01-01T10:00:00Z")
    assert (data["engine"]["dt"], data["engine"]["output_interval"]) == (30.0, 300.0)


def test_the_imported_model_carries_what_flows_in(imported) -> None:
    """Near the end of the period the discharge at site 2 is the sum of the inflows (mass is conserved)."""
    _, _, folder = imported
    model = load_model(folder / "case")
    result, _ = model.simulate({}, start=model.start, end=model.end)
    q = result.series["site2.Q"].iloc[-1]
    inflow = 2.0 + 0.5 + 0.4 + 0.1  # up1, up2, the point inflow at 10 h, the bank inflow
    assert q == pytest.approx(inflow, rel=0.03)


def test_a_refusal_blocks_the_import_unless_partial(tmp_path: Path) -> None:
    xcas = write_model(tmp_path / "model")
    with pytest.raises(CaseError) as err:
        import_mascaret(xcas, tmp_path / "case")
    message = str(err.value)
    assert "weir 'barrage1'" in message and "--allow-partial" in message and "no case was written" in message
    assert sorted(p.name for p in (tmp_path / "case").iterdir()) == ["import.md"]


@pytest.mark.parametrize(("method", "extra", "expected"), [
    (1, "", [0.0, 300.0, 600.0, 1000.0]),
    (2, "<nbZones>1</nbZones><numBrancheZone>3</numBrancheZone><absDebutZone>0</absDebutZone>"
        "<absFinZone>1000</absFinZone><nbSectionZone>4</nbSectionZone>", [0.0, 200.0, 400.0, 600.0, 800.0, 1000.0]),
    (3, "<nbSections>3</nbSections><branchesSection>3 3 3</branchesSection><absSection>0 450 1000</absSection>",
     [0.0, 450.0, 1000.0]),
])
def test_the_other_grid_methods(tmp_path: Path, method: int, extra: str, expected: list[float]) -> None:
    text = XCAS.replace("<methodeMaillage>5</methodeMaillage>", f"<methodeMaillage>{method}</methodeMaillage>")
    text = text.replace("<nbSections>0</nbSections>", extra)
    _, data = _import(tmp_path, text)
    assert _by_id(data["branches"])["aval"]["points"] == expected


def test_normal_depth_is_a_rating_of_uniform_flow(tmp_path: Path) -> None:
    """Q = K A R^(2/3) S^(1/2) in the end profile (a trapezoid here: A = 4d + d², P = 4 + 2√2 d below 2 m)."""
    text = XCAS.replace("<typeCond>1 1 4</typeCond>", "<typeCond>1 1 7</typeCond>")
    result, data = _import(tmp_path, text)
    rating = _by_id(data["boundaries"])["down"]["rating"]
    slope = (9.8 - 8.8) / 400.0
    for level, q in zip(rating["levels"][1:], rating["discharges"][1:], strict=True):
        d = level - 8.8
        if d > 2.0:
            continue
        area, perimeter = 4 * d + d * d, 4 + 2 * math.sqrt(2) * d
        assert q == pytest.approx(28.0 * area * (area / perimeter) ** (2 / 3) * math.sqrt(slope), rel=1e-9)
    assert result.ledger.status_of("boundary", "down") == "approximated"
    assert [p[1] for p in MINOR] == [2.0, 0.0, 0.0, 2.0]  # the trapezoid the formula above describes


@pytest.mark.parametrize(("types", "kind", "status"), [("1 1 6", "critical", "approximated"),
                                                       ("1 1 8", None, "refused")])
def test_free_outflow_and_imposed_level_and_discharge(tmp_path: Path, types: str, kind, status: str) -> None:
    text = XCAS.replace("<typeCond>1 1 4</typeCond>", f"<typeCond>{types}</typeCond>")
    if kind is None:  # level and discharge imposed need a limni-hydrograph
        text = text.replace("<numLoi>1 2 3</numLoi>", "<numLoi>1 2 1</numLoi>")
    result, data = _import(tmp_path, text)
    bounds = _by_id(data["boundaries"])
    assert (bounds["down"]["type"] if "down" in bounds else None) == kind
    assert result.ledger.status_of("boundary", "down") == status


@pytest.mark.parametrize(("old", "new", "words"), [
    ("<coefLitMin>25.0 30.0 35.0 28.0</coefLitMin>", "<coefLitMin>25.0 300.0 35.0 28.0</coefLitMin>",
     ["<parametresCalage/frottement/coefLitMin>", "zone 2", "300", "plausible range"]),
    ("<loi>1</loi>", "<loi>4</loi>", ["<parametresCalage/frottement/loi>", "Bazin"]),
    ("<absFinZone>250.0 200.0 500.0 1000.0</absFinZone>", "<absFinZone>250.0 200.0 500.0 1200.0</absFinZone>",
     ["friction zone 4", "outside reach 'aval'"]),
    ("<nb>3</nb>\n        <numeros>", "<nb>2</nb>\n        <numeros>", ["2 reach(es) here but 3"]),
    ("<fichier>hydro.loi</fichier>", "<fichier>missing.loi</fichier>", ["'missing.loi'", "does not exist"]),
    ("<format>2</format>", "<format>1</format>", ["LIDO 2.0", "format 2"]),
    ("<numLoi>1 2 3</numLoi>", "<numLoi>1 2 9</numLoi>", ["law number 9 does not exist"]),
    ("<typeCond>1 1 4</typeCond>", "<typeCond>2 1 4</typeCond>", ["imposes a level", "hydrograph"]),
])
def test_a_bad_value_of_the_model_names_the_file_line_and_element(tmp_path: Path, old: str, new: str,
                                                                  words: list[str]) -> None:
    assert old in XCAS
    text = XCAS.replace(old, new, 1)
    xcas = write_model(tmp_path / "model", xcas=text)
    with pytest.raises(CaseError) as err:
        import_mascaret(xcas, tmp_path / "case", ImportOptions(allow_partial=True))
    message = str(err.value)
    assert message.startswith(str(xcas) + ": line "), message
    for w in words:
        assert w in message, message


def test_stations_given_with_the_import(tmp_path: Path) -> None:
    xcas = write_model(tmp_path / "model")
    stations = (StationSpec("G1", "aval", 250.0), StationSpec("G2", "1", 125.0))
    import_mascaret(xcas, tmp_path / "case", ImportOptions(allow_partial=True, stations=stations))
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    found = _by_id(data["stations"])
    assert (found["G1"]["branch"], found["G1"]["chainage"]) == ("aval", 250.0)
    assert (found["G2"]["branch"], found["G2"]["chainage"]) == ("amont1", 125.0)
    with pytest.raises(CaseError, match=r"gauges.csv: line 3: station 'G3': no reach 'nowhere'"):
        import_mascaret(xcas, tmp_path / "case2", ImportOptions(
            allow_partial=True, stations=(StationSpec("G3", "nowhere", 1.0, file="gauges.csv", line=3),)))
    with pytest.raises(CaseError, match="lies outside reach 'aval'"):
        import_mascaret(xcas, tmp_path / "case3", ImportOptions(allow_partial=True,
                                                                stations=(StationSpec("G4", "aval", 2000.0),)))


def test_period_options(tmp_path: Path) -> None:
    result, data = _import(tmp_path, XCAS, origin="2021-06-01T12:00:00Z", hours=2.0, dt=20.0, output_interval=600.0,
                           cross_sections="nearest")
    assert (data["case"]["start"], data["case"]["end"]) == ("2021-06-01T12:00:00Z", "2021-06-01T14:00:00Z")
    assert (data["engine"]["dt"], data["engine"]["output_interval"]) == (20.0, 600.0)
    assert data["engine"]["cross_sections"] == "nearest"
    assert result.ledger.status_of("setting", "cross sections") == "approximated"


# -- the Oriège (Mascaret's test 19, GPL data read from ../shared/data) ---------------------------------------


def test_the_oriege_imports_exactly_where_it_can(tmp_path: Path) -> None:
    xcas = shared_model("oriege-mascaret-test19", "mascaret0.xcas")
    result = import_mascaret(xcas, tmp_path / "case")
    assert result.summary["refused"] == 0
    assert (result.summary["profiles"], result.summary["branches"], result.summary["points"]) == (84, 1, 885)
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    branch = data["branches"][0]
    assert branch["length"] == 5043.0
    # P__0 (0 m) to P__0A (40 m) in steps of at most 6.896 m: int(40 / 6.896) = 5 cells of 8 m
    assert branch["points"][:6] == [0.0, 8.0, 16.0, 24.0, 32.0, 40.0]
    assert data["friction_groups"] == [{"id": "zone1_minor", "type": "strickler", "value": 20.0}]
    assert {(b["type"], b["value"]) for b in data["boundaries"]} == {("discharge", 12.36), ("level", 817.45)}
    assert [(lat["chainage"], lat["value"]) for lat in data["laterals"]] == [(2938.0, 0.85)]
    assert data["case"]["end"] == "2000-01-01T02:13:20Z"  # 8000 steps of 1 s
    p0 = _by_id(data["profiles"])["P__0"]
    assert (p0["y"][0], p0["y"][-1], max(p0["z"])) == (0.0, 29.3, pytest.approx(2.12))  # no 999 m walls
    assert result.ledger.status_of("initial conditions", "mascaret0.lig") == "approximated"
