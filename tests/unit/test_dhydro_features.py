"""The friction and cross-section features of real water-board models, in and out of D-HYDRO.

The model of ``tests/dhydro_models.write_feature_model`` has them all: per-branch friction laws, friction along a
branch and as a function of the water level, branch orders (with a connector branch without cross-sections), a
zwRiver profile with a summer dike, an open zw profile that narrows, initial levels along a branch. Each is checked
against the numbers put into the files, the bed levels across a node against D-Flow FM's rule computed by hand,
and the round trip both ways: case → D-Flow FM → case (the same case, the same station series) and D-Flow FM →
case → D-Flow FM (the same roughness tables, branch orders, levee and initial field in the files).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from rivercal.case import load_case
from rivercal.errors import CaseError
from rivercal.io.dhydro import ImportOptions, export_dhydro, import_dhydro
from tests.dhydro_models import (
    FEATURE_ORDERS,
    GRASS_CHAINAGES,
    GRASS_LEVELS,
    GRASS_TABLE,
    write_feature_model,
)


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("features")
    mdu = write_feature_model(folder / "model")
    result = import_dhydro(mdu, folder / "case")
    data = tomllib.loads((folder / "case" / "case.toml").read_text(encoding="utf-8"))
    return result, data, folder


def _by_id(items: list[dict], key: str) -> dict:
    return next(i for i in items if i["id"] == key)


def _copy(folder: Path, tmp_path: Path) -> Path:
    model = tmp_path / "model"
    model.mkdir()
    for f in (folder / "model").iterdir():
        (model / f.name).write_bytes(f.read_bytes())
    return model


def test_friction_of_any_law_along_a_branch_and_with_the_level_is_exact(imported) -> None:
    result, data, _ = imported
    groups = {g["id"]: g for g in data["friction_groups"]}
    # Main varies along b2, so it stays a group that every profile using it names, in its law (Chezy)
    assert groups["Main"]["type"] == "chezy" and groups["Main"]["value"] == 40.0
    assert groups["Main"]["branches"] == [
        {"branch": "b1", "type": "manning", "value": 0.03},  # a law of its own in a Chezy group
        {"branch": "b2", "chainages": [0.0, 1000.0], "values": [35.0, 45.0]},
    ]
    assert data["friction"] == {"type": "chezy", "value": 40.0}
    assert all("friction" not in b for b in data["branches"])
    grass_b1 = groups["Grass"]["branches"][0]
    assert grass_b1 == {"branch": "b1", "type": "manning", "function": "waterlevel", "levels": GRASS_LEVELS,
                        "chainages": GRASS_CHAINAGES, "table": GRASS_TABLE}
    assert groups["Grass"]["branches"][1] == {"branch": "b3", "value": 30.0}
    profiles = {p["id"]: p for p in data["profiles"]}
    assert profiles["plain"]["friction"] == ["Main"] and profiles["river"]["friction"] == ["Main", "Grass"]
    statuses = {e.id: e.status for e in result.ledger.entries if e.kind == "friction on a branch"}
    assert statuses == dict.fromkeys(["b1 in roughness-Main.ini", "b2 in roughness-Main.ini",
                                      "b1 in roughness-Grass.ini", "b3 in roughness-Grass.ini"], "exact")
    assert result.summary["refused"] == 0
    # profile "river" names Main and Grass side by side: neither can be set alone, so one factor scales them all
    assert [p["targets"] for p in data["parameters"]] == [["friction:scale"]]


def test_the_level_table_gives_the_coefficient_d_flow_fm_interpolates(imported) -> None:
    """D-Flow FM reads frictionValues level by level and interpolates in chainage and level; so does the case."""
    result, _, _ = imported
    case = load_case(result.folder)
    entry = next(g for g in case.network.friction_groups if g.id == "Grass").entry("b1")
    levels, values = entry.coefficient_at(250.0)
    # by hand: a quarter of the way from the row at 0 m to the row at 1000 m
    assert values == pytest.approx([0.04 + 0.25 * 0.005, 0.035 + 0.25 * 0.005, 0.03 + 0.25 * 0.002], rel=1e-12)
    assert list(levels) == GRASS_LEVELS


def test_a_discharge_dependent_friction_is_refused_with_its_reason(tmp_path: Path) -> None:
    mdu = write_feature_model(tmp_path / "model", discharge_dependent=True)
    with pytest.raises(CaseError, match="absDischarge") as err:
        import_dhydro(mdu, tmp_path / "case")
    assert "roughness-Grass.ini" in str(err.value) and "--allow-partial" in str(err.value)
    text = (tmp_path / "case" / "import.md").read_text(encoding="utf-8")
    assert "function of the discharge (functionType = absDischarge)" in text
    assert not (tmp_path / "case" / "case.toml").exists()
    import_dhydro(mdu, tmp_path / "partial", ImportOptions(allow_partial=True))
    data = tomllib.loads((tmp_path / "partial" / "case.toml").read_text(encoding="utf-8"))
    grass = _by_id(data["friction_groups"], "Grass")
    assert [b["branch"] for b in grass["branches"]] == ["b1"]  # b3 takes the group's own value


def test_branch_orders_are_mapped_and_a_connector_takes_the_sections_across_its_nodes(imported) -> None:
    _, data, _ = imported
    assert {b["id"]: b.get("order") for b in data["branches"]} == FEATURE_ORDERS
    assert [b["id"] for b in data["branches"]] == ["b1", "bc", "b2", "b3"]  # the net file's order
    # bc has no cross-section: D-Flow FM continues river (b1, 200 m, bed 0.5) and plain (b2, 500 m, bed -0.5)
    # into it; the line between them is 1,400 m long, and bc runs from 800 m to 900 m along it
    bc = _by_id(data["branches"], "bc")
    assert [c["bed_level"] for c in bc["cross_sections"]] == pytest.approx([0.5 - 800 / 1400, 0.5 - 900 / 1400],
                                                                           abs=1e-12)


def test_bed_levels_across_a_node_of_one_order_follow_d_flow_fm(imported) -> None:
    """A link takes the bed interpolated at its middle between the cross-sections on either side of the node.

    D-Flow FM 1D (flow1d ``useBranchOrdersCrs``): the last cross-section of b1 is continued onto the next branch of
    its order at node B, the first of b2 onto the branch before it, through the connector bc that has none. So along
    the line A-D the bed runs linearly from 0.5 m AD (b1, 200 m) to -0.5 m AD (b2 at 500 m, 1,600 m from A), and a
    calculation point takes the lowest bed of its links (D-Flow FM's flow-node bed: ``bl(n) = min(bl(n), bob(L))``
    over its links, ``setbobs_1d`` in ``oned_functions.f90``).
    """
    from rivercal.engine.compile import compile_network

    result, _, _ = imported
    case = load_case(result.folder)
    net = compile_network(case.network, case.spec.engine)
    start = {"b1": 0.0, "bc": 1000.0, "b2": 1100.0}

    def hand(s: float) -> float:
        return float(np.interp(s, [200.0, 1600.0], [0.5, -0.5]))

    link_beds = {}
    for li, (bid, ch) in enumerate(zip(net.link_branch, net.link_chainage, strict=True)):
        if bid in start:
            link_beds[(bid, float(ch))] = (float(net.arrays.lk_b1[li]), hand(start[bid] + float(ch)))
    for (bid, ch), (bed, expected) in link_beds.items():
        assert bed == pytest.approx(expected, abs=1e-9), (bid, ch)
    # the calculation points near node B: each takes the lower of its two links
    for bid, ch in (("b1", 900.0), ("b1", 950.0), ("bc", 50.0), ("b2", 50.0)):
        i = next(k for k, (b, c) in enumerate(zip(net.hp_branch, net.hp_chainage, strict=True))
                 if b == bid and abs(c - ch) < 1e-9)
        s = start[bid] + ch
        assert net.arrays.hp_bed[i] == pytest.approx(min(hand(s - 25.0), hand(s + 25.0)), abs=1e-9)
    # without the orders the bed beyond b1's last cross-section would stay at 0.5 m AD: 0.46 m higher at 950 m
    assert hand(975.0) < 0.5 - 0.4


def test_narrowing_zw_profiles_stay_open(imported, tmp_path: Path) -> None:
    _, data, folder = imported
    narrowing = _by_id(data["profiles"], "narrowing")
    assert "closed" not in narrowing
    assert narrowing["flow_widths"] == [4.0, 6.0, 5.0] and narrowing["total_widths"] == [4.0, 8.0, 9.0]
    # without total widths, the storage width narrows with the flow width: the case keeps its widest (approximated)
    model = _copy(folder, tmp_path)
    crsdef = model / "crsdef.ini"
    text = crsdef.read_text(encoding="utf-8")
    crsdef.write_text(text.replace("totalWidths = 4.0 8.0 9.0", "").replace("totalWidths  = 4.0 8.0 9.0", ""),
                      encoding="utf-8")
    assert "4.0 8.0 9.0" not in crsdef.read_text(encoding="utf-8")
    result = import_dhydro(model / "features.mdu", tmp_path / "case")
    again = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    narrowing = _by_id(again["profiles"], "narrowing")
    assert "closed" not in narrowing
    assert narrowing["flow_widths"] == [4.0, 6.0, 5.0] and narrowing["total_widths"] == [4.0, 6.0, 6.0]
    entry = next(e for e in result.ledger.entries if e.kind == "profile" and e.id == "narrowing")
    assert entry.status == "approximated" and "narrows above level 1 m" in entry.note


def test_a_zwriver_levee_is_a_summer_dike(imported, tmp_path: Path) -> None:
    result, data, folder = imported
    river = _by_id(data["profiles"], "river")
    # crest 0.9 m above the table's lowest level (0 m); D-Flow FM's transition height is 0.5 m
    assert river["summer_dike"] == {"crest": 0.9, "flow_area": 6.0, "total_area": 15.0, "transition": 0.5}
    assert result.ledger.status_of("profile", "river") == "exact"  # base level = crest: the same filling curve
    model = _copy(folder, tmp_path)
    crsdef = model / "crsdef.ini"
    text = crsdef.read_text(encoding="utf-8")
    assert "leveeBaseLevel  = 0.9" in text
    crsdef.write_text(text.replace("leveeBaseLevel  = 0.9", "leveeBaseLevel  = 0.4"), encoding="utf-8")
    again = import_dhydro(model / "features.mdu", tmp_path / "case")
    entry = next(e for e in again.ledger.entries if e.kind == "profile" and e.id == "river")
    assert entry.status == "exact"  # a base below the crest: drained by flow1d's falling curve, as the case does
    case = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    assert _by_id(case["profiles"], "river")["summer_dike"]["base"] == 0.4


def test_initial_levels_along_a_branch(imported) -> None:
    result, data, _ = imported
    assert data["initial"] == {"depth": 0.0, "level": 1.0}
    assert _by_id(data["branches"], "b1")["initial_levels"] == {"chainages": [0.0, 1000.0], "levels": [1.6, 1.2]}
    assert result.ledger.status_of("initial field", "waterlevel on b1") == "exact"


def test_case_to_dflowfm_to_case_reproduces_the_case(imported, tmp_path: Path) -> None:
    from rivercal.model import load_model

    result, data, _ = imported
    case = load_case(result.folder)
    exported = export_dhydro(case, tmp_path / "model")
    again = import_dhydro(exported.mdu, tmp_path / "case")
    back = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    assert again.summary["refused"] == 0
    for key in ("friction", "friction_groups", "profiles", "nodes", "branches", "boundaries", "stations", "initial",
                "parameters"):
        assert back[key] == data[key], key
    a, _ = load_model(result.folder).simulate()
    b, _ = load_model(again.folder).simulate()
    assert list(a.series.columns) == list(b.series.columns)
    assert np.abs(a.series.to_numpy() - b.series.loc[a.series.index].to_numpy()).max() <= 1e-6
    # the exported time step comes back from rivercal.ini, and a time step given to the import wins over it
    assert "timeStep = 60.0" in (tmp_path / "model" / "rivercal.ini").read_text(encoding="utf-8")
    import_dhydro(exported.mdu, tmp_path / "other", ImportOptions(dt=30.0))
    assert tomllib.loads((tmp_path / "other" / "case.toml").read_text(encoding="utf-8"))["engine"]["dt"] == 30.0


def test_dflowfm_to_case_to_dflowfm_keeps_every_feature_in_the_files(imported, tmp_path: Path) -> None:
    from hydrolib.core.dflowfm.crosssection.models import CrossDefModel
    from hydrolib.core.dflowfm.friction.models import FrictionModel
    from hydrolib.core.dflowfm.net.models import NetworkModel
    from hydrolib.core.dflowfm.onedfield.models import OneDFieldModel

    result, _, folder = imported
    out = tmp_path / "model"
    export_dhydro(load_case(result.folder), out)

    def blocks(path: Path) -> dict[str, dict]:
        model = FrictionModel(path)
        return {b.branchid: {"type": str(b.frictiontype), "function": str(b.functiontype).lower(),
                             "chainage": b.chainage, "levels": b.levels, "values": b.frictionvalues}
                for b in model.branch}

    for name in ("roughness-Main.ini", "roughness-Grass.ini"):
        assert blocks(out / name) == blocks(folder / "model" / name), name
    orders = NetworkModel(out / "network_net.nc").network._mesh1d
    assert dict(zip(map(str, orders.network1d_branch_id), map(int, orders.network1d_branch_order),
                    strict=True)) == FEATURE_ORDERS
    defs = {d.id: d for d in CrossDefModel(out / "crsdef.ini").definition}
    text = (out / "crsdef.ini").read_text(encoding="utf-8")
    assert type(defs["river"]).__name__ == "ZWRiverCrsDef"
    for key, value in (("leveeCrestlevel", "0.9"), ("leveeBaseLevel", "0.9"), ("leveeFlowArea", "6.0"),
                       ("leveeTotalArea", "15.0")):
        assert any(line.split("#")[0].split() == [key, "=", value] for line in text.splitlines()), key
    assert defs["narrowing"].flowwidths == [4.0, 6.0, 5.0] and defs["narrowing"].totalwidths == [4.0, 8.0, 9.0]
    field = OneDFieldModel(out / "initial_waterlevel.ini")
    assert field.global_.value == 1.0
    assert [(b.branchid, b.chainage, b.values) for b in field.branch] == [("b1", [0.0, 1000.0], [1.6, 1.2])]


def _edit_block(path: Path, branch: str, key: str, value: str) -> int:
    """Set ``key = value`` in the [Branch] block of ``branch`` of a roughness file; returns the line number."""
    lines = path.read_text(encoding="utf-8").splitlines()
    inside = False
    for k, line in enumerate(lines):
        text = line.split("#")[0].strip()
        if text.startswith("["):
            inside = False
        if text.replace(" ", "") == f"branchId={branch}":
            inside = True
        if inside and text.split("=")[0].strip() == key:
            lines[k] = f"{key} = {value}"
            path.write_text("\n".join(lines) + "\n", encoding="utf-8")
            return k + 1
    raise AssertionError(f"{key} not found in the block of {branch}")


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("chainage", "1000.0 0.0", "chainage must increase"),
    ("functionType", "sometimes", "is none of constant, waterLevel, absDischarge, timeSeries"),
    ("numLocations", "3", "chainage should be equal to the numLocations value"),  # hydrolib-core's own check
])
def test_a_roughness_block_that_cannot_be_right_is_an_error_at_its_line(imported, tmp_path, key, value,
                                                                         expected) -> None:
    _, _, folder = imported
    model = _copy(folder, tmp_path)
    line = _edit_block(model / "roughness-Main.ini", "b2", key, value)
    with pytest.raises(CaseError) as err:
        import_dhydro(model / "features.mdu", tmp_path / "case")
    text = (tmp_path / "case" / "import.md").read_text(encoding="utf-8")
    assert expected in text, text
    assert "roughness-Main.ini" in str(err.value)
    # at the line of the key (hydrolib-core names the chainage line when the count of chainages is off)
    assert f"roughness-Main.ini, line {line if key != 'numLocations' else line + 1}" in text


def test_a_chainage_given_twice_is_a_step_and_time_series_friction_is_refused(imported, tmp_path) -> None:
    _, _, folder = imported
    model = _copy(folder, tmp_path)
    _edit_block(model / "roughness-Main.ini", "b2", "chainage", "300.0 300.0")
    _edit_block(model / "roughness-Grass.ini", "b3", "functionType", "timeSeries")
    with pytest.raises(CaseError, match="time series"):
        import_dhydro(model / "features.mdu", tmp_path / "case")
    result = import_dhydro(model / "features.mdu", tmp_path / "case", ImportOptions(allow_partial=True))
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    main = _by_id(data["friction_groups"], "Main")
    # D-Flow FM: the value of the first below 300 m, of the second from 300 m on; the case steps over 1 mm
    assert main["branches"][1] == {"branch": "b2", "chainages": [300.0, 300.001], "values": [35.0, 45.0]}
    assert result.ledger.status_of("friction on a branch", "b2 in roughness-Main.ini") == "approximated"
    assert result.ledger.status_of("friction on a branch", "b3 in roughness-Grass.ini") == "refused"


def test_a_group_named_main_beside_the_global_friction_is_exported_under_two_ids(imported, tmp_path) -> None:
    """A case with a friction group ``Main`` and a profile that takes the global friction: D-Flow FM's default group
    is ``Main``, so the global friction is written as another group, which that profile names."""
    import tomli_w

    from rivercal.model import load_model

    _, data, _ = imported
    data = {k: v for k, v in data.items() if k != "parameters"}
    plain = _by_id(data["profiles"], "plain")
    del plain["friction"]  # b2 now takes the global friction, Chezy 40
    folder = tmp_path / "case"
    folder.mkdir()
    (folder / "case.toml").write_text(tomli_w.dumps(data), encoding="utf-8")
    exported = export_dhydro(load_case(folder), tmp_path / "model")
    assert any("written as roughness group 'Main_global'" in n for n in exported.notes)
    from hydrolib.core.dflowfm.crosssection.models import CrossDefModel

    defs = {d.id: d for d in CrossDefModel(tmp_path / "model" / "crsdef.ini").definition}
    assert defs["plain"].frictionid == "Main_global" and defs["narrowing"].frictionid == "Grass"
    again = import_dhydro(exported.mdu, tmp_path / "again")
    back = tomllib.loads((tmp_path / "again" / "case.toml").read_text(encoding="utf-8"))
    assert _by_id(back["friction_groups"], "Main_global") == {"id": "Main_global", "type": "chezy", "value": 40.0}
    a, _ = load_model(folder).simulate()
    b, _ = load_model(again.folder).simulate()
    assert np.abs(a.series.to_numpy() - b.series.loc[a.series.index].to_numpy()).max() <= 1e-6
