"""The D-HYDRO import on small D-Flow FM models built with hydrolib-core (tests/dhydro_models.py).

Each conversion is checked against the numbers put into the model: every profile type, every structure
type, boundaries, laterals, storage nodes, stations, friction groups and the initial state.
"""

from __future__ import annotations

import re
import tomllib

import numpy as np
import pandas as pd
import pytest

from rivercal.case import load_case
from rivercal.errors import CaseError
from rivercal.io.dhydro import ImportOptions, import_dhydro
from tests.dhydro_models import write_model


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dhydro")
    mdu = write_model(folder / "model")
    result = import_dhydro(mdu, folder / "case", ImportOptions(allow_partial=True))
    data = tomllib.loads((folder / "case" / "case.toml").read_text(encoding="utf-8"))
    return result, data, folder


def _copy_model(folder, tmp_path):
    """A copy of the test model in ``tmp_path / "model"`` (to change a file of it)."""
    model = tmp_path / "model"
    model.mkdir()
    for f in (folder / "model").iterdir():
        (model / f.name).write_bytes(f.read_bytes())
    return model


def _by_id(items: list[dict], key: str) -> dict:
    return next(i for i in items if i["id"] == key)


def test_profiles_of_every_type(imported) -> None:
    _, data, _ = imported
    p = {x["id"]: x for x in data["profiles"]}
    assert p["yz1"] == {"id": "yz1", "type": "yz", "y": [0.0, 2.0, 4.0, 6.0, 8.0, 10.0],
                        "z": [3.0, 1.0, 0.0, 0.0, 1.0, 3.0], "conveyance": "segmented",
                        "friction_positions": [0.0, 5.0, 10.0], "friction": ["Main", "Grass"]}
    assert p["zw1"]["heights"] == [0.0, 1.0, 3.0] and p["zw1"]["flow_widths"] == [4.0, 6.0, 10.0]
    assert p["zw1"]["total_widths"] == [4.0, 8.0, 20.0] and "friction" not in p["zw1"]  # Main: branch friction
    assert p["river1"]["section_widths"] == [10.0, 20.0] and p["river1"]["friction"] == ["Main", "Grass"]
    assert p["pipe1"] == {"id": "pipe1", "type": "circular", "diameter": 1.2, "friction": ["Concrete"]}
    assert p["box1"]["closed"] is True and p["box1"]["width"] == 3.0 and p["box1"]["height"] == 2.0
    assert "closed" not in p["open1"] and p["open1"]["width"] == 5.0
    # xyz: positions along the survey line (3-4-5 triangles: 5 m apart), heights above the lowest point
    assert p["xyz1"]["type"] == "yz" and p["xyz1"]["y"] == pytest.approx([0.0, 5.0, 10.0, 15.0])
    assert p["xyz1"]["z"] == [2.0, 0.0, 0.0, 2.0] and p["xyz1"]["conveyance"] == "lumped"
    assert p["egg"]["closed"] is True and p["egg"]["flow_widths"] == [0.0, 0.8, 0.6, 0.0]


def test_cross_sections_branches_and_points(imported) -> None:
    _, data, _ = imported
    b1 = _by_id(data["branches"], "b1")
    assert (b1["from_node"], b1["to_node"], b1["length"]) == ("A", "B", 1000.0)
    assert b1["points"] == pytest.approx(np.linspace(0, 1000, 11).tolist())
    # bed level = the definition's lowest level + shift
    assert b1["cross_sections"] == [{"chainage": 0.0, "profile": "yz1", "bed_level": 0.0},
                                    {"chainage": 1000.0, "profile": "zw1", "bed_level": -1.5}]
    b2 = _by_id(data["branches"], "b2")
    assert [c["bed_level"] for c in b2["cross_sections"]] == [-1.5, -0.8]


def test_friction_groups_and_the_default_group(imported) -> None:
    _, data, _ = imported
    assert data["friction"] == {"type": "chezy", "value": 45.0}  # group Main is the case's global friction
    assert _by_id(data["branches"], "b4")["friction"] == {"type": "manning", "value": 0.03}
    groups = {g["id"]: g for g in data["friction_groups"]}
    assert groups["Grass"]["type"] == "strickler" and groups["Grass"]["value"] == 20.0
    # values along the branch, exactly (linear between the chainages, as D-Flow FM interpolates them)
    assert groups["Grass"]["branches"] == [{"branch": "b2", "chainages": [0.0, 1000.0], "values": [22.0, 26.0]}]
    # group Main keeps b4's own law too, for the profiles that name Main beside another group (yz1)
    assert groups["Main"]["branches"] == [{"branch": "b4", "type": "manning", "value": 0.03}]
    assert groups["Concrete"] == {"id": "Concrete", "type": "white-colebrook", "value": 0.003}


def test_structures_of_every_type(imported) -> None:
    _, data, _ = imported
    weir = _by_id(data["weirs"], "weir1")
    assert (weir["crest_level"], weir["crest_width"], weir["discharge_coefficient"]) == (0.5, 4.0, 0.9)
    u = _by_id(data["universal_weirs"], "uweir1")
    assert u["crest_level"] == pytest.approx(0.3) and u["z"] == pytest.approx([0.7, 0.0, 0.0, 0.7])
    assert u["allowed_flow"] == "positive" and u["discharge_coefficient"] == 0.85
    o = _by_id(data["orifices"], "orifice1")
    assert (o["crest_level"], o["gate_lower_edge_level"], o["crest_width"]) == (-0.2, 0.6, 3.0)
    assert o["discharge_coefficient"] == 0.63 and o["max_flow_positive"] == 5.0
    g = _by_id(data["orifices"], "general1")  # approximated: the free-gate coefficient x contraction
    assert g["discharge_coefficient"] == pytest.approx(0.63) and g["gate_lower_edge_level"] == 1.5
    c1 = _by_id(data["culverts"], "culvert1")
    assert (c1["shape"], c1["diameter"], c1["invert_level"], c1["invert_level_end"]) == ("circular", 0.8, -0.4, -0.45)
    assert c1["friction"] == {"type": "manning", "value": 0.014} and c1["length"] == 12.0
    c2 = _by_id(data["culverts"], "culvert2")
    assert (c2["shape"], c2["width"], c2["height"], c2["allowed_flow"]) == ("rectangular", 1.5, 1.0, "negative")
    s = _by_id(data["culverts"], "siphon1")
    assert (s["shape"], s["profile"], s["bend_loss"]) == ("profile", "egg", 0.4)
    bridge = _by_id(data["bridges"], "bridge1")
    assert (bridge["profile"], bridge["bed_level"], bridge["length"]) == ("bridge_opening", -1.15, 10.0)
    assert bridge["friction"] == {"type": "strickler", "value": 40.0}
    pump = _by_id(data["pumps"], "pump1")
    assert (pump["capacity"], pump["start_level"], pump["stop_level"]) == (0.5, 1.2, 0.9)


def test_settings_series_boundaries_and_laterals(imported) -> None:
    result, data, folder = imported
    case = load_case(folder / "case")
    crest = case.forcing["crest:weir1"]
    t = (crest.index - case.start).total_seconds().to_numpy()
    assert np.interp([0, 7200, 9000, 10800, 86400], t, crest.to_numpy()) == pytest.approx([0.5, 0.5, 0.65, 0.8, 0.8])
    bounds = {b["id"]: b for b in data["boundaries"]}
    assert bounds["D"] == {"id": "D", "node": "D", "type": "level", "value": 0.4}
    assert bounds["E"]["rating"] == {"levels": [0.8, 1.1, 1.6], "discharges": [0.0, 1.0, 4.0]}
    q = case.forcing["boundary:A"]
    t = (q.index - case.start).total_seconds().to_numpy()
    assert np.interp([0, 10800, 21600, 43200, 86400], t, q.to_numpy()) == pytest.approx([2.0, 4.0, 6.0, 3.0, 3.0])
    lat = {x["id"]: x for x in data["laterals"]}
    assert lat["lat_const"] == {"id": "lat_const", "branch": "b1", "chainage": 300.0, "value": 0.2}
    assert "lat_node" not in lat  # realtime without an exchange file: refused
    assert result.ledger.status_of("lateral", "lat_node") == "refused"


def test_storage_nodes_stations_and_initial_state(imported) -> None:
    _, data, _ = imported
    nodes = {n["id"]: n for n in data["nodes"]}
    assert nodes["B"]["storage_table"] == {"levels": [-1.0, 2.0, 2.001], "areas": [20.0, 20.0, 500.0]}
    assert nodes["C"]["storage_table"] == {"levels": [-1.5, 0.0, 1.0], "areas": [5.0, 10.0, 50.0]}
    stations = {s["id"]: s for s in data["stations"]}
    assert stations["obs_b1"] == {"id": "obs_b1", "branch": "b1", "chainage": 200.0, "quantities": ["h"]}
    assert stations["obs_xy"]["branch"] == "b2" and stations["obs_xy"]["chainage"] == pytest.approx(500.0)
    assert "obs_nowhere" not in stations
    assert stations["culvert1"] == {"id": "culvert1", "structure": "culvert1", "quantities": ["h_up", "h_down", "Q"]}
    assert data["initial"] == {"depth": 0.7}
    assert data["case"]["start"] == "2020-01-01T00:00:00Z" and data["case"]["end"] == "2020-01-02T00:00:00Z"
    assert data["engine"]["output_interval"] == 600.0 and data["engine"]["dt"] == 30.0


def test_every_block_of_every_file_is_accounted_for(imported) -> None:
    """Each [Definition], [CrossSection], [Structure], [Global], [Branch], [StorageNode], [Boundary], [Lateral] and
    [ObservationPoint] block of the model appears in import.md with its status."""
    from hydrolib.core.dflowfm.ini.parser import Parser

    result, _, folder = imported
    text = (folder / "case" / "import.md").read_text(encoding="utf-8")
    model = folder / "model"
    ids = []
    for path in model.glob("*.ini"):
        for section in Parser.parse(path).sections:
            data = {k.lower(): v for k, v in section.flatten(duplicate_key_as_list=False, with_comments=False).items()}
            if section.header.lower() in ("general", "initial"):
                continue
            key = (data.get("id") or data.get("name") or data.get("frictionid") or data.get("branchid")
                   or data.get("quantity"))
            ids.append(str(key))
    for path in model.glob("*.ext"):
        for section in Parser.parse(path).sections:
            data = {k.lower(): v for k, v in section.flatten(duplicate_key_as_list=False, with_comments=False).items()}
            if section.header.lower() in ("boundary", "lateral"):
                ids.append(str(data.get("id") or data.get("nodeid")))
    assert len(ids) > 40
    missing = [i for i in ids if f"`{i}`" not in text and f"`{i} in " not in text]
    assert not missing, f"objects not accounted for in import.md: {missing}"
    assert result.summary["refused"] == 4  # dambreak (2D), realtime lateral, an observation point off the map, unused
    assert "**partial import**" in text


def test_refusals_that_change_the_hydraulics_stop_the_import(imported, tmp_path) -> None:
    _, _, folder = imported
    with pytest.raises(CaseError, match=r"lateral 'lat_node'.*realtime.*--allow-partial"):
        import_dhydro(folder / "model" / "test.mdu", tmp_path / "case")
    assert (tmp_path / "case" / "import.md").is_file()  # the account is written all the same
    result = import_dhydro(folder / "model" / "test.mdu", tmp_path / "case2", ImportOptions(realtime_lateral=0.05))
    assert result.ledger.status_of("lateral", "lat_node") == "approximated"
    assert load_case(tmp_path / "case2").forcing["lateral:lat_node"].iloc[0] == 0.05


def test_unknown_keywords_are_read_past_with_a_warning(imported, tmp_path) -> None:
    _, _, folder = imported
    model = _copy_model(folder, tmp_path)
    mdu = model / "test.mdu"
    text = mdu.read_text(encoding="utf-8")
    text = re.sub(r"(\[geometry\]\n)", r"\1SomeNewerKeyword = 3\n", text, count=1, flags=re.I)
    mdu.write_text(text, encoding="utf-8")
    structures = model / "structures.ini"
    structures.write_text(structures.read_text(encoding="utf-8").replace(
        "[Structure]", "[Structure]\n    otherToolsExtra = 1", 1), encoding="utf-8")
    result = import_dhydro(mdu, tmp_path / "case", ImportOptions(allow_partial=True))
    warnings = "\n".join(result.ledger.warnings)
    assert "somenewerkeyword" in warnings.lower()
    assert "othertoolsextra" in warnings.lower()


def test_a_broken_block_costs_that_block_only(imported, tmp_path) -> None:
    """hydrolib-core keeps a file it cannot validate as an opaque DiskOnlyFileModel: the import reads it block by
    block, refuses the broken block by name and converts the others."""
    _, _, folder = imported
    model = _copy_model(folder, tmp_path)
    structures = model / "structures.ini"
    text = structures.read_text(encoding="utf-8")
    text = re.sub(r"(id\s*=\s*culvert2\b[^\[]*?)length\s*=\s*8\.0\n", r"\1", text, flags=re.S)  # a required key
    structures.write_text(text, encoding="utf-8")
    result = import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(allow_partial=True))
    assert result.ledger.status_of("culvert", "culvert2") == "refused"
    assert result.ledger.status_of("culvert", "culvert1") == "exact"
    assert any("block by block" in w for w in result.ledger.warnings)


def test_the_period_from_start_and_stop_datetimes(imported, tmp_path) -> None:
    _, _, folder = imported
    model = _copy_model(folder, tmp_path)
    mdu = model / "test.mdu"
    text = mdu.read_text(encoding="utf-8")
    text = re.sub(r"(?im)^(startdatetime\s*=).*$", r"\1 20200101060000", text)
    text = re.sub(r"(?im)^(stopdatetime\s*=).*$", r"\1 20200101180000", text)
    mdu.write_text(text, encoding="utf-8")
    result = import_dhydro(mdu, tmp_path / "case", ImportOptions(allow_partial=True))
    case = load_case(result.folder)
    assert (case.start, case.end) == (pd.Timestamp("2020-01-01T06:00Z"), pd.Timestamp("2020-01-01T18:00Z"))


def test_a_missing_model_is_a_clear_error(tmp_path) -> None:
    with pytest.raises(CaseError, match="does not exist"):
        import_dhydro(tmp_path / "nothing.mdu", tmp_path / "case")


def test_exchange_files_supply_realtime_values(imported, tmp_path) -> None:
    """A DIMR exchange file (item<k>_values with 'source -> target' long names, seconds from the reference date)."""
    import xarray as xr

    _, _, folder = imported
    seconds = np.arange(0.0, 86400.0, 600.0)
    ds = xr.Dataset({
        "item1_values": (("time_offset", "item1_nValues"), (0.1 + seconds / 86400.0)[:, None],
                         {"long_name": "catchments/x/water_discharge -> laterals/lat_node/water_discharge"}),
        "item2_values": (("time_offset", "item2_nValues"), np.where(seconds < 3600, 0.5, 0.7)[:, None],
                         {"long_name": "[Output]weir1/Crest level (s) -> weirs/weir1/crestLevel"}),
    }, coords={"time_offset": seconds})
    ds.to_netcdf(tmp_path / "exchange.nc")
    result = import_dhydro(folder / "model" / "test.mdu", tmp_path / "case",
                           ImportOptions(realtime=(tmp_path / "exchange.nc",)))
    case = load_case(result.folder)
    lat = case.forcing["lateral:lat_node"]
    t = (lat.index - case.start).total_seconds().to_numpy()
    # each value holds from its coupling time to the next, as DIMR hands it to D-Flow FM
    assert np.interp([0.0, 300.0, 599.0, 600.0, 6300.0, 86000.0], t, lat.to_numpy()) == pytest.approx(
        0.1 + np.array([0.0, 0.0, 0.0, 600.0, 6000.0, 85800.0]) / 86400.0, rel=1e-12)
    crest = case.forcing["crest:weir1"]
    t = (crest.index - case.start).total_seconds().to_numpy()
    assert np.interp([3598.0, 3600.0, 80000.0], t, crest.to_numpy()) == pytest.approx([0.5, 0.7, 0.7])


def test_polyline_observation_cross_sections_go_on_the_link_they_cross(imported, tmp_path) -> None:
    """D-Flow FM observes the flow links whose segment between their two calculation points the polyline crosses;
    through a calculation point, the crossing's direction picks one of its two links (Deltares delft3d,
    crspath_on_singlelink). Branch b2 runs from x = 1000 to 2000 m along y = 0, calculation points every 100 m."""
    _, _, folder = imported
    model = _copy_model(folder, tmp_path)
    (model / "obscrs.ini").write_text(
        "[General]\nfileVersion = 2.00\nfileType = obsCross\n\n"
        "[ObservationCrossSection]\nname = across\nnumCoordinates = 2\nxCoordinates = 1550 1550\n"
        "yCoordinates = -20 20\n\n"
        "[ObservationCrossSection]\nname = northward\nnumCoordinates = 3\nxCoordinates = 1500 1500 1500\n"
        "yCoordinates = -20 -5 20\n\n"
        "[ObservationCrossSection]\nname = southward\nnumCoordinates = 2\nxCoordinates = 1500 1500\n"
        "yCoordinates = 20 -20\n\n"
        "[ObservationCrossSection]\nname = beside\nnumCoordinates = 2\nxCoordinates = 1550 1550\n"
        "yCoordinates = 20 40\n", encoding="utf-8")
    mdu = model / "test.mdu"
    mdu.write_text(re.sub(r"(?im)^(obsFile\s*=.*\n)", r"\1crsFile = obscrs.ini\n", mdu.read_text(encoding="utf-8")),
                   encoding="utf-8")
    result = import_dhydro(mdu, tmp_path / "case", ImportOptions(allow_partial=True))
    stations = {s.id: s for s in load_case(result.folder).network.stations}
    assert (stations["across"].branch, stations["across"].chainage) == ("b2", 550.0)
    assert (stations["northward"].branch, stations["northward"].chainage) == ("b2", 450.0)  # the link ending there
    assert (stations["southward"].branch, stations["southward"].chainage) == ("b2", 550.0)  # the link starting there
    assert "beside" not in stations and result.ledger.status_of("observation cross-section", "beside") == "refused"


def _with_structures(folder, tmp_path, blocks: str, compound_members: str | None = None):
    """A copy of the test model with structure blocks added (and compound1's members replaced)."""
    model = _copy_model(folder, tmp_path)
    path = model / "structures.ini"
    text = path.read_text(encoding="utf-8") + "\n" + blocks
    if compound_members is not None:
        n = len(compound_members.split(";"))
        text = re.sub(r"(id\s*=\s*compound1\b[^\[]*?numStructures\s*=\s*)1(\s*\n\s*structureIds\s*=\s*)pump1",
                      rf"\g<1>{n}\g<2>{compound_members}", text, flags=re.S)
    path.write_text(text, encoding="utf-8")
    return model


def _weir_block(name: str, width: float, chainage: float = 350.0) -> str:
    return (f"[Structure]\nid = {name}\ntype = weir\nbranchId = b4\nchainage = {chainage}\nallowedFlowDir = both\n"
            f"crestLevel = 0.2\ncrestWidth = {width}\ncorrCoeff = 1.0\nuseVelocityHeight = 0\n\n")


def test_every_member_of_a_compound_is_converted(imported, tmp_path) -> None:
    """A universal weir as the second member (once refused): the stretch between the calculation points around the
    compound (D-Flow FM's flow link, 600-700 m on b4) becomes two parallel branches of half its length, one per
    member, with its cross-sections and its branch's own friction."""
    _, _, folder = imported
    uweir = ("[Structure]\nid = uweir2\ntype = universalWeir\nbranchId = b4\nchainage = 650.0\nallowedFlowDir = both\n"
             "numLevels = 3\nyValues = 0.0 2.0 4.0\nzValues = 1.5 1.0 1.5\ncrestLevel = 1.0\ndischargeCoeff = 0.9\n\n")
    model = _with_structures(folder, tmp_path, uweir, "pump1;uweir2")
    result = import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(allow_partial=True))
    net = load_case(result.folder).network
    assert result.ledger.status_of("compound", "compound1") == "approximated"
    assert result.ledger.status_of("universalWeir", "uweir2") == "exact"
    pump = next(p for p in net.pumps if p.id == "pump1")
    uweir = next(u for u in net.universal_weirs if u.id == "uweir2")
    stretch = next(b for b in net.branches if b.id == pump.branch)
    beside = next(b for b in net.branches if b.id == uweir.branch)
    assert (stretch.from_node, stretch.to_node) == (beside.from_node, beside.to_node)
    assert stretch.length == pytest.approx(50.0) and beside.length == pytest.approx(50.0)
    assert beside.cross_sections == stretch.cross_sections
    pieces = [b for b in net.branches if b.id.startswith("b4") and b is not stretch]
    assert sum(b.length for b in pieces) == pytest.approx(900.0)  # b4 cut at 600 and 700 m
    assert all(b.friction.type == "manning" and b.friction.value == 0.03 for b in [*pieces, stretch, beside])


def test_a_compound_of_two_weirs_flows_as_one_weir_of_both_widths(imported, tmp_path) -> None:
    """D-Flow FM sets the members of a compound on one flow link; two equal weirs of width 2 m side by side pass
    what one weir of 4 m passes (the weir formula is linear in the width). The two imports run the same day; the
    flows are equal once the filling of the first hours (where each member's shorter link follows faster) is over."""
    from rivercal.model import load_model

    _, _, folder = imported
    (tmp_path / "pair").mkdir()
    (tmp_path / "single").mkdir()
    pair = _with_structures(folder, tmp_path / "pair", _weir_block("wa", 2.0) + _weir_block("wb", 2.0) +
                            "[Structure]\nid = pairc\ntype = compound\nnumStructures = 2\nstructureIds = wa;wb\n\n")
    single = _with_structures(folder, tmp_path / "single", _weir_block("wa", 4.0))
    for model, out in ((pair, "pair_case"), (single, "single_case")):
        import_dhydro(model / "test.mdu", tmp_path / out, ImportOptions(allow_partial=True, realtime_lateral=0.2))
    a, _ = load_model(tmp_path / "pair_case").simulate()
    b, _ = load_model(tmp_path / "single_case").simulate()
    np.testing.assert_allclose(a.series["wa.Q"].to_numpy(), a.series["wb.Q"].to_numpy(), rtol=0, atol=1e-9)
    settled = a.series.index >= a.series.index[0] + pd.Timedelta(hours=5)
    q = (a.series["wa.Q"] + a.series["wb.Q"])[settled]
    assert float(b.series["wa.Q"][settled].abs().min()) > 0.5  # the weir carries flow
    np.testing.assert_allclose(q.to_numpy(), b.series["wa.Q"][settled].to_numpy(), rtol=1e-3, atol=0)
    levels = [c for c in b.series.columns if c.endswith((".h", ".h_up", ".h_down")) and c in a.series.columns]
    assert len(levels) > 10
    np.testing.assert_allclose(a.series[levels][settled].to_numpy(), b.series[levels][settled].to_numpy(), rtol=0,
                               atol=1e-3)


def test_a_dead_end_stores_the_water_of_its_whole_end_link(imported, tmp_path) -> None:
    """dxDoubleAt1DEndNodes (on in the test model, D-Flow FM's default): the flow node at a dead end gets the volume
    of the whole end link instead of half of it. Without its Q(h) boundary, node E (the end of b4, 100 m calculation
    points, one zw cross-section: bed 0.2 - 1.0 = -0.8 m AD, total widths 4, 8, 20 m at 0, 1, 3 m) is a dead end:
    its extra half link of 50 m stores 50 m x the total width."""
    _, data, folder = imported
    assert "storage_table" not in next(n for n in data["nodes"] if n["id"] == "E")  # a boundary node: not an end
    model = _copy_model(folder, tmp_path)
    ext = model / "forcing.ext"
    ext.write_text(re.sub(r"\[Boundary\][^\[]*?nodeId\s*=\s*E\b[^\[]*", "", ext.read_text(encoding="utf-8"),
                          flags=re.S), encoding="utf-8")
    result = import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(allow_partial=True))
    node = next(n for n in load_case(result.folder).network.nodes if n.id == "E")
    assert node.storage_table.levels == pytest.approx([-0.8, 0.2, 2.2])
    assert node.storage_table.areas == pytest.approx([200.0, 400.0, 1000.0])
    assert result.ledger.status_of("setting", "dxDoubleAt1DEndNodes") == "exact"


def test_an_exchange_series_holds_each_value_until_the_next_with_one_second_ramps() -> None:
    """DIMR hands a value at each coupling time and D-Flow FM keeps it until the next: change points only."""
    from types import SimpleNamespace

    from rivercal.io.dhydro._forcing import held_series

    t = pd.date_range("2000-06-01", periods=5, freq="10min", tz="UTC", unit="s")
    ctx = SimpleNamespace(start=t[0] - pd.Timedelta("10min"), end=t[-1] + pd.Timedelta("1h"))
    held = held_series(ctx, pd.Series([1.0, 1.0, 2.0, 2.0, 0.5], index=t))
    second = pd.Timedelta(seconds=1)
    assert list(held.index) == [ctx.start, t[0], t[2] - second, t[2], t[4] - second, t[4], ctx.end]
    assert held.tolist() == [1.0, 1.0, 1.0, 2.0, 2.0, 0.5, 0.5]
    steady = held_series(ctx, pd.Series([3.0] * 5, index=t))  # no change: its first value over the period
    assert list(steady.index) == [ctx.start, t[0], ctx.end] and steady.tolist() == [3.0] * 3
