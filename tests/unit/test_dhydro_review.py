"""The D-HYDRO import on the variants a reviewer made of real models: each defect found, fixed at its root.

Each test edits the small test model (tests/dhydro_models.py) the way the reviewer edited the shared models
(/work/probe-dhydro: a boundary given twice, a gate series that starts closed, a Tzone, block-to interpolation,
...) and checks that the import converts the feature right, records it in the ledger, or stops with an error that
names the file and line — never an internal error, never a silent change.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import CaseError
from rivercal.io.dhydro import ImportOptions, import_dhydro
from tests.unit import test_dhydro_hardening as hardening

base = hardening.base  # the test model, written once per module
_model = hardening._model
_import = hardening._import
_error = hardening._error


def _append(path: Path, text: str) -> int:
    """Append text to a file; returns the 1-based line of its first non-blank line."""
    old = path.read_text(encoding="utf-8")
    if not old.endswith("\n"):
        old += "\n"
    path.write_text(old + text, encoding="utf-8")
    return old.count("\n") + 1 + (len(text) - len(text.lstrip("\n")))


def _line_of(path: Path, pattern: str, nth: int = 0) -> int:
    text = path.read_text(encoding="utf-8")
    matches = list(re.finditer(pattern, text, flags=re.I | re.M))
    assert len(matches) > nth, f"{pattern!r} not in {path.name}"
    return text[:matches[nth].start()].count("\n") + 1


def _case(tmp_path: Path) -> dict:
    return tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))


def _entry(result, kind: str, ident: str):
    return next(e for e in result.ledger.entries if e.kind == kind and e.id == ident)


# -- 1. a boundary node or a lateral id given twice ----------------------------------------------------------


def test_two_boundaries_on_one_node_are_an_error_naming_both_blocks(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    ext = model / "forcing.ext"
    first = _line_of(ext, r"^\[Boundary\]", 1)
    second = _append(ext, "\n[Boundary]\nquantity = waterlevelbnd\nnodeId = D\nforcingFile = boundaries.bc\n")
    message = _error(model, tmp_path)
    assert f"forcing.ext, line {second}" in message and f"forcing.ext, line {first}" in message
    assert "'D'" in message


def test_two_laterals_with_one_id_are_an_error_naming_both_blocks(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    ext = model / "forcing.ext"
    first = _line_of(ext, r"^\[Lateral\]", 0)
    second = _append(ext, "\n[Lateral]\nid = lat_const\nbranchId = b2\nchainage = 100.0\ndischarge = 0.5\n")
    message = _error(model, tmp_path, allow_partial=True)
    assert f"forcing.ext, line {second}" in message and f"forcing.ext, line {first}" in message
    assert "'lat_const'" in message


# -- 2, 3. a gate series that is closed at some times and open at others ------------------------------------


def _gate_bc(model: Path, name: str) -> None:
    """A gate series for ``name``: on the crest of orifice1 (-0.2 m AD) until 00:30, 0.6 m AD from 00:31."""
    (model / "gate.bc").write_text(
        "[General]\nfileVersion = 1.01\nfileType = boundConds\n\n[forcing]\nname = " + name + "\n"
        "function = timeseries\ntimeInterpolation = linear\nquantity = time\n"
        "unit = minutes since 2020-01-01 00:00:00\nquantity = gateLowerEdgeLevel\nunit = m\n"
        "0 -0.2\n30 -0.2\n31 0.6\n1440 0.6\n", encoding="utf-8")


def test_an_orifice_whose_gate_series_starts_closed_opens_when_its_series_does(base, tmp_path) -> None:
    from rivercal.model import load_model

    model = _model(base, tmp_path)
    structures = model / "structures.ini"
    text = structures.read_text(encoding="utf-8")
    structures.write_text(text.replace("gateLowerEdgeLevel = 0.6", "gateLowerEdgeLevel = gate.bc", 1),
                          encoding="utf-8")
    _gate_bc(model, "orifice1")
    result = _import(model, tmp_path)
    orifice = next(o for o in _case(tmp_path)["orifices"] if o["id"] == "orifice1")
    assert orifice["allowed_flow"] == "both" and orifice["gate_series"]["column"] == "orifice1.gateLowerEdgeLevel"
    assert orifice["gate_lower_edge_level"] > orifice["crest_level"]
    run, _ = load_model(result.folder).simulate()
    series = run.series
    q = series["orifice1.Q"].abs()
    start = series.index[0]
    assert q[q.index <= start + pd.Timedelta(minutes=30)].max() < 1e-6  # closed: no water passes
    assert q[q.index >= start + pd.Timedelta(hours=2)].min() > 0.01  # open from 00:31


def test_a_general_structure_gate_series_is_kept_as_the_gate_of_an_orifice(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    structures = model / "structures.ini"
    text = structures.read_text(encoding="utf-8")
    head = text.index("id                             = general1")
    at = text.index("gateLowerEdgeLevel", head)
    end = text.index("\n", at)
    structures.write_text(text[:at] + "gateLowerEdgeLevel = gate.bc" + text[end:], encoding="utf-8")
    _gate_bc(model, "general1")
    result = _import(model, tmp_path)
    general = next(o for o in _case(tmp_path)["orifices"] if o["id"] == "general1")
    assert general["gate_series"]["column"] == "general1.gateLowerEdgeLevel"
    assert not any(w["id"] == "general1" for w in _case(tmp_path).get("weirs", []))
    assert "out of the water" not in _entry(result, "generalStructure", "general1").note


def _exchange(tmp_path: Path, target: str, values: list[float]) -> Path:
    """A DIMR exchange file with one series from RTC to ``target``, hourly from the reference date."""
    import xarray as xr

    exchange = tmp_path / "rtc_to_flow.nc"
    data = xr.DataArray(np.array(values)[:, None], dims=("time", "n"), attrs={"long_name": f"rtc -> {target}"})
    hours = 3600.0 * np.arange(len(values))
    xr.Dataset({"item1_values": data}, coords={"time_offset": ("time", hours)}).to_netcdf(exchange)
    return exchange


def test_an_exchanged_general_structure_gate_is_kept(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    exchange = _exchange(tmp_path, "generalStructures/general1/gateLowerEdgeLevel", [0.4, 0.5, 1.2])
    _import(model, tmp_path, realtime=(exchange,))
    general = next(o for o in _case(tmp_path)["orifices"] if o["id"] == "general1")
    assert general["gate_series"]["column"] == "general1.gateLowerEdgeLevel"


def test_an_orifice_gate_from_rtc_that_starts_closed_opens_when_the_series_does(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    structures = model / "structures.ini"  # the file's gate down on the crest (-0.2 m AD), as RTC starts it
    structures.write_text(structures.read_text(encoding="utf-8").replace("gateLowerEdgeLevel = 0.6",
                                                                         "gateLowerEdgeLevel = -0.2", 1),
                          encoding="utf-8")
    exchange = _exchange(tmp_path, "orifices/orifice1/gateLowerEdgeLevel", [-0.2, -0.2, 0.6])
    _import(model, tmp_path, realtime=(exchange,))
    orifice = next(o for o in _case(tmp_path)["orifices"] if o["id"] == "orifice1")
    assert orifice["allowed_flow"] == "both" and orifice["gate_series"]["column"] == "orifice1.gateLowerEdgeLevel"
    assert orifice["gate_lower_edge_level"] > orifice["crest_level"]


# -- 4. Tzone and the time unit of a .bc file --------------------------------------------------------------


@pytest.mark.parametrize(("unit", "six_hours"), [
    ("minutes since 2020-01-01 00:00:00", "2020-01-01T06:00:00Z"),  # no zone: GMT, as D-Flow FM's EC module
    ("minutes since 2020-01-01 00:00:00 +01:00", "2020-01-01T05:00:00Z"),  # its own zone
])
def test_a_bc_time_without_a_zone_is_gmt_whatever_the_tzone(base, tmp_path, unit, six_hours) -> None:
    model = _model(base, tmp_path)
    mdu = model / "test.mdu"
    mdu.write_text(re.sub(r"(?m)^(tZone\s*=\s*)0\.0", r"\g<1>1.0", mdu.read_text(encoding="utf-8")),
                   encoding="utf-8")
    bc = model / "boundaries.bc"
    bc.write_text(bc.read_text(encoding="utf-8").replace("minutes since 2020-01-01 00:00:00", unit, 1),
                  encoding="utf-8")
    _import(model, tmp_path)
    case = _case(tmp_path)
    assert case["case"]["start"] == "2019-12-31T23:00:00Z"  # RefDate and TStart in Tzone = +1 h
    csv = pd.read_csv(tmp_path / "case" / "boundaries.csv", index_col=0)
    assert csv.loc[six_hours, "A"] == pytest.approx(6.0)  # the .bc row 360 min -> 6 m³/s


# -- 5. block-to and block-from interpolation --------------------------------------------------------------


@pytest.mark.parametrize(("spelling", "expected"), [
    # block-To: each interval takes the value at its end, from the second after its start
    ("block-To", {"00:00:00": 2.0, "00:00:01": 6.0, "03:00:00": 6.0, "06:00:00": 6.0, "06:00:01": 3.0,
                  "09:00:00": 3.0}),
    ("BLOCK-TO", {"00:00:00": 2.0, "00:00:01": 6.0, "06:00:00": 6.0, "06:00:01": 3.0}),
    # block-From: each value holds from its time to the next
    ("block-From", {"00:00:00": 2.0, "03:00:00": 2.0, "05:59:59": 2.0, "06:00:00": 6.0, "11:59:59": 6.0,
                    "12:00:00": 3.0}),
])
def test_block_interpolation_changes_at_the_right_end_of_each_interval(base, tmp_path, spelling, expected) -> None:
    model = _model(base, tmp_path)
    bc = model / "boundaries.bc"
    bc.write_text(bc.read_text(encoding="utf-8").replace("timeInterpolation = linear",
                                                         f"timeInterpolation = {spelling}", 1), encoding="utf-8")
    _import(model, tmp_path)
    csv = pd.read_csv(tmp_path / "case" / "boundaries.csv", index_col=0, parse_dates=True)["A"]
    seconds = (csv.index - csv.index[0]).total_seconds().to_numpy()
    for clock, value in expected.items():
        at = pd.Timedelta(clock).total_seconds()
        assert float(np.interp(at, seconds, csv.to_numpy())) == pytest.approx(value), clock


# -- 6. a storage table that narrows upward ----------------------------------------------------------------


def test_a_storage_table_that_narrows_is_approximated_with_its_extra_volume(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    nodes = model / "nodes.ini"
    nodes.write_text(nodes.read_text(encoding="utf-8").replace("storageArea = 5.0 10.0 50.0",
                                                               "storageArea = 5.0 50.0 2.0"), encoding="utf-8")
    result = _import(model, tmp_path)
    entry = _entry(result, "storage node", "sC")
    assert entry.status == "approximated"
    # kept at 50 m² from 0 to 1 m AD instead of narrowing to 2 m²: 0.5 · 1 m · 48 m² more
    assert "narrows upward" in entry.note and "24 m³ more storage up to 1 m AD" in entry.note
    assert "48 m² more area above it" in entry.note


# -- 8. a lateral beyond the end of its branch -------------------------------------------------------------


def test_a_lateral_beyond_its_branch_end_is_an_error_at_its_chainage(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    ext = model / "forcing.ext"
    ext.write_text(ext.read_text(encoding="utf-8").replace("chainage     = 300.0", "chainage     = 2500.0"),
                   encoding="utf-8")
    line = _line_of(ext, r"^chainage\s*=\s*2500")
    message = _error(model, tmp_path, allow_partial=True)
    assert f"forcing.ext, line {line}: lateral 'lat_const': chainage 2500 m lies beyond the end of branch b1" in message


# -- 9. refusals at the right block; a structure id given twice ---------------------------------------------


def test_a_refusal_names_the_block_of_its_kind_when_another_kind_has_the_same_id(base, tmp_path) -> None:
    """A sewer model names a lateral after its storage node: the refusal of the lateral points at the lateral."""
    model = _model(base, tmp_path)
    nodes = model / "nodes.ini"
    nodes.write_text(re.sub(r"(?m)^(id\s*=\s*)sB\b", r"\g<1>lat_node", nodes.read_text(encoding="utf-8")),
                     encoding="utf-8")
    line = _line_of(model / "forcing.ext", r"^id\s*=\s*lat_node") - 1  # its [Lateral] header
    with pytest.raises(CaseError) as info:
        import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions())
    assert f"forcing.ext, line {line}: lateral 'lat_node'" in str(info.value)
    assert "nodes.ini" not in str(info.value)


_SECOND_ORIFICE = ("\n[Structure]\nid = orifice1\ntype = weir\nbranchId = b1\nchainage = 100.0\n"
                   "allowedFlowDir = both\ncrestLevel = 0.2\ncrestWidth = 2.0\ncorrCoeff = 1.0\n")


def test_a_structure_id_given_twice_in_one_file_is_an_error_naming_both_blocks(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    structures = model / "structures.ini"
    first = _line_of(structures, r"^id\s*=\s*orifice1") - 1
    second = _append(structures, _SECOND_ORIFICE)
    message = _error(model, tmp_path, allow_partial=True)
    assert f"structures.ini, line {second}: a second structure with id 'orifice1' (weir)" in message
    assert f"the first (orifice) is at structures.ini, line {first}" in message


def test_a_structure_id_given_in_two_structure_files_is_an_error_naming_both(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (model / "extra.ini").write_text("[General]\nfileVersion = 3.00\nfileType = structure\n" + _SECOND_ORIFICE,
                                     encoding="utf-8")
    mdu = model / "test.mdu"
    mdu.write_text(re.sub(r"(?m)^(structureFile\s*=\s*)structures\.ini", r"\g<1>structures.ini;extra.ini",
                          mdu.read_text(encoding="utf-8")), encoding="utf-8")
    message = _error(model, tmp_path, allow_partial=True)
    assert "extra.ini, line 5: a second structure with id 'orifice1'" in message
    assert "the first (orifice) is at structures.ini, line" in message


# -- 10. a stop time between two his times -----------------------------------------------------------------


def test_a_stop_time_between_two_his_times_ends_the_period_at_the_last_one(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    mdu = model / "test.mdu"
    mdu.write_text(re.sub(r"(?m)^(tStop\s*=\s*)86400\.0", r"\g<1>86399.0", mdu.read_text(encoding="utf-8")),
                   encoding="utf-8")
    result = _import(model, tmp_path)
    case = _case(tmp_path)
    assert case["engine"]["output_interval"] == 600.0 and case["engine"]["dt"] == 30.0  # not 1 s
    assert case["case"]["end"] == "2020-01-01T23:50:00Z"
    entry = _entry(result, "setting", "TStop")
    assert entry.status == "approximated" and "599 s before D-Flow FM would" in entry.note


# -- 11. a long culvert on a branch ------------------------------------------------------------------------


_LONG_CULVERT = ("\n[Structure]\nid = long1\ntype = longCulvert\nbranchId = b1\nchainage = 100.0\n"
                 "allowedFlowDir = both\nnumCoordinates = 2\nxCoordinates = 100 110\nyCoordinates = 0 0\n"
                 "zCoordinates = -0.5 -0.55\nwidth = 1\nheight = 1\nfrictionType = Manning\nfrictionValue = 0.014\n"
                 "valveRelativeOpening = 1\n")
_DAMBREAK = ("\n[Structure]\nid = breach1\ntype = dambreak\nbranchId = b1\nchainage = 100.0\n"
             "startLocationX = 100.0\nstartLocationY = 0.0\nnumCoordinates = 2\nxCoordinates = 100 100\n"
             "yCoordinates = -10 10\nwaterLevelUpstreamLocationX = 90\nwaterLevelUpstreamLocationY = 0\n"
             "waterLevelDownstreamLocationX = 110\nwaterLevelDownstreamLocationY = 0\nalgorithm = 2\n"
             "crestLevelIni = 1.0\nbreachWidthIni = 1.0\ncrestLevelMin = 0.0\nt0 = 3600\n"
             "timeToBreachToMaximumDepth = 3600\nf1 = 1.3\nf2 = 0.04\nuCrit = 0.2\n")


@pytest.mark.parametrize(("block", "kind", "sid", "reason"), [
    (_LONG_CULVERT, "longCulvert", "long1", "a long culvert"),
    (_DAMBREAK, "dambreak", "breach1", "a dam break"),  # carries water once it breaks: the way out is named
])
def test_a_structure_a_case_cannot_carry_on_a_branch_is_a_hydraulic_refusal_with_its_reason(
        base, tmp_path, block, kind, sid, reason) -> None:
    model = _model(base, tmp_path)
    line = _append(model / "structures.ini", block)
    message = _error(model, tmp_path)
    assert f"structures.ini, line {line}: {kind} {sid!r}: {reason}" in message
    assert "2D or morphological" not in message
    if kind == "dambreak":
        assert "crest_series" in message
    result = _import(model, tmp_path, allow_partial=True)  # a hydraulic refusal: --allow-partial goes on
    entry = _entry(result, kind, sid)
    assert entry.status == "refused" and entry.hydraulic


# -- 12. a UTF-8 byte order mark ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["structures.ini", "test.mdu", "forcing.ext"])
def test_a_file_with_a_utf8_byte_order_mark_is_read(base, tmp_path, name) -> None:
    model = _model(base, tmp_path)
    path = model / name
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    result = _import(model, tmp_path)
    assert {o["id"] for o in _case(tmp_path)["orifices"]} == {"orifice1", "general1"}
    assert len(_case(tmp_path)["boundaries"]) == 3
    assert not any("not INI text" in w for w in result.ledger.warnings)


# -- 13. a lateral fed by a .tim file ----------------------------------------------------------------------


def test_a_lateral_fed_by_a_tim_file_is_refused_as_such(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (model / "inflow.tim").write_text("0 0.1\n60 0.2\n", encoding="utf-8")
    ext = model / "forcing.ext"
    ext.write_text(ext.read_text(encoding="utf-8").replace("discharge    = 0.2", "discharge    = inflow.tim"),
                   encoding="utf-8")
    line = _line_of(ext, r"^id\s*=\s*lat_const") - 1
    message = _error(model, tmp_path)
    assert f"forcing.ext, line {line}: lateral 'lat_const': discharge = inflow.tim is a .tim file" in message
    assert "no forcing block" not in message


# -- 14. two storage nodes on one node ---------------------------------------------------------------------


def test_two_storage_nodes_on_one_node_are_an_error_naming_both(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    nodes = model / "nodes.ini"
    first = _line_of(nodes, r"^id\s*=\s*sC") - 1
    second = _append(nodes, "\n[StorageNode]\nid = sC2\nname = sC2\nnodeId = C\nuseTable = 0\nbedLevel = -1.0\n"
                            "area = 30.0\nstreetLevel = 2.0\nstreetStorageArea = 100.0\nstorageType = reservoir\n")
    message = _error(model, tmp_path, allow_partial=True)
    assert f"nodes.ini, line {second}: storage node 'sC2' is a second storage node on node 'C'" in message
    assert f"the first, 'sC', is at nodes.ini, line {first}" in message
