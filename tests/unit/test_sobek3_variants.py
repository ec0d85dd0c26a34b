"""The SOBEK 3 import on variants of the small model (tests/sobek3_models.py) that once went wrong: a closed gate,
ids used twice, sub-second time steps, block-wise and periodic series, a universal weir whose crest is not its
lowest z value, comments where a value is empty, and renamed ids that took a valid one's name."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.case import load_case
from rivercal.engine import Simulator
from rivercal.errors import CaseError, OptionError
from rivercal.io.sobek3 import ImportOptions, import_sobek3
from rivercal.io.sobek3._ini import read_ini
from tests.sobek3_models import write_model


def _import(tmp_path: Path, **replace: tuple[str, str]) -> tuple[dict, str, Path]:
    """Import the model with the replacements (partially: the model has refused objects); the case and import.md."""
    md1d = write_model(tmp_path / "model", **replace)
    import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    return data, (tmp_path / "case" / "import.md").read_text(encoding="utf-8"), tmp_path / "case"


def _by_id(items: list[dict]) -> dict[str, dict]:
    return {i["id"]: i for i in items}


# -- a closed orifice --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("open_level", ["-1.2", "-1.5"])  # at the crest, below it
def test_a_closed_orifice_lets_no_water_through(tmp_path, open_level) -> None:
    data, md, _ = _import(tmp_path, Structures_ini=("openLevel             = -0.5",
                                                    f"openLevel             = {open_level}"))
    orifice = _by_id(data["orifices"])["orifice1"]
    assert orifice["allowed_flow"] == "none"
    assert orifice["gate_lower_edge_level"] > orifice["crest_level"] == -1.2
    row = next(line for line in md.splitlines() if "`orifice1`" in line)
    assert "closed" in row and "no water" in row


@pytest.mark.parametrize(("old", "new", "key", "words"), [
    ("crestWidth            = 2.0", "crestWidth            = 0.0", "crestWidth", "at least 1 mm wide"),
    ("contractionCoeff      = 0.63", "contractionCoeff      = -0.63", "contractionCoeff", "above 0 and at most 2"),
    ("limitFlowPos          = 4.0", "limitFlowPos          = -4.0", "limitFlowPos", "must not be negative"),
])
def test_a_bad_orifice_value_names_its_file_line_and_key(tmp_path, old, new, key, words) -> None:
    md1d = write_model(tmp_path / "model", Structures_ini=(old, new))
    with pytest.raises(CaseError) as info:
        import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))
    line = next(k for k, text in enumerate((tmp_path / "model" / "Structures.ini").read_text(
        encoding="utf-8").splitlines(), start=1) if new in text)
    assert f"Structures.ini:{line}: {key}: " in str(info.value) and words in str(info.value), str(info.value)


# -- ids used twice ----------------------------------------------------------------------------------------------


_ID = "    id                    = "
_SECOND = {  # file: (text, the text with a block of the same id before it, kind)
    "Structures.ini": ("[Structure]\n" + _ID + "weir1",
                       "[Structure]\n" + _ID + "weir1\n    branchid = b1\n    chainage = 50.0\n    type = weir\n"
                       "    crestLevel = -1.0\n    crestWidth = 3.0\n\n[Structure]\n" + _ID + "weir1", "structure"),
    "ObservationPoints.ini": ("[ObservationPoint]\n" + _ID + "obs1",
                              "[ObservationPoint]\n" + _ID + "obs1\n    branchid = b2\n    chainage = 20.0\n\n"
                              "[ObservationPoint]\n" + _ID + "obs1", "observation point"),
    "LateralDischargeLocations.ini": ("[LateralDischarge]\n" + _ID + "lat1",
                                      "[LateralDischarge]\n" + _ID + "lat1\n    branchid = b2\n    chainage = 20.0\n\n"
                                      "[LateralDischarge]\n" + _ID + "lat1", "lateral"),
    "BoundaryLocations.ini": ("[Boundary]\n    nodeId                = A",
                              "[Boundary]\n    nodeId                = A\n    type = 2\n\n"
                              "[Boundary]\n    nodeId                = A", "boundary"),
    "CrossSectionLocations.ini": (_ID + "cs_b1_down", _ID + "cs_b1_up", "cross-section"),
}


@pytest.mark.parametrize("file", sorted(_SECOND))
def test_an_id_used_twice_is_an_input_error_naming_both_places(tmp_path, file) -> None:
    old, new, kind = _SECOND[file]
    key = file.replace(".", "_")
    md1d = write_model(tmp_path / "model", **{key: (old, new)})
    with pytest.raises(CaseError) as info:
        import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))
    message = str(info.value)
    path = tmp_path / "model" / file
    ident = "nodeId" if kind == "boundary" else "id"
    lines = [k for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
             if line.strip().startswith(ident) and line.split("=")[1].strip() == message.split("'")[1]]
    assert len(lines) == 2, (message, lines)
    assert f"{file}:{lines[1]}: {ident}: {kind} id " in message and "used twice" in message, message
    assert f"{file}:{lines[0]}" in message, message
    assert "bug" not in message


def test_a_valid_id_keeps_its_name_when_a_renamed_one_would_take_it(tmp_path) -> None:
    # obs.2 becomes obs_2 (a station id has no dot), but obs_2 is the genuine id of another point
    data, md, _ = _import(tmp_path, ObservationPoints_ini=(
        "[ObservationPoint]\n    id                    = nowhere",
        "[ObservationPoint]\n    id                    = obs_2\n    branchid              = b2\n"
        "    chainage              = 300.000\n\n[ObservationPoint]\n    id                    = nowhere"))
    stations = _by_id(data["stations"])
    assert stations["obs_2"]["branch"] == "b2"
    assert stations["obs_2_2"]["branch"] == "b3"
    assert "| station | `obs.2` | `obs_2_2` |" in md


# -- time steps --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [0.0, -5.0, 0.05, float("nan")])
def test_a_time_step_option_below_the_shortest_is_an_option_error(dt) -> None:
    with pytest.raises(OptionError, match=r"dt .*at least 0\.1 s"):
        ImportOptions(dt=dt)


@pytest.mark.parametrize(("step", "option", "dt", "words"), [
    ("0.700", None, 0.6, "time step 0.6 s instead of 0.7 s"),  # 0.7 s does not divide the 600 s output interval
    ("0.500", None, 0.5, None),  # exact
    ("0.050", None, 0.1, "raised to 0.1 s"),
    ("60.000", 0.7, 0.6, "time step 0.6 s instead of 0.7 s"),
    ("60.000", 45.0, 40.0, "time step 40 s instead of 45 s"),  # whole seconds when a whole divisor exists
    ("60.000", 7200.0, 600.0, "cut to 3600 s"),
])
def test_a_sub_second_step_becomes_a_divisor_of_the_output_interval(tmp_path, step, option, dt, words) -> None:
    md1d = write_model(tmp_path / "model", Flow1D_md1d=("TimeStep              = 60.000",
                                                        f"TimeStep              = {step}"))
    result = import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True, dt=option))
    assert result.case.spec.engine.dt == pytest.approx(dt)
    assert result.case.spec.engine.output_interval == 600.0
    md = (tmp_path / "case" / "import.md").read_text(encoding="utf-8")
    rows = [line for line in md.splitlines() if line.startswith("| setting | `TimeStep`")]
    if words is None:
        assert not rows and "`TimeStep`" in md
    else:
        assert words in rows[0]


# -- block-wise and periodic series -----------------------------------------------------------------------------


def _lateral(folder: Path, column: str) -> pd.Series:
    frame = pd.read_csv(folder / "laterals.csv", index_col="time")
    frame.index = pd.to_datetime(frame.index)
    return frame[column]


def _at(series: pd.Series, when: str) -> float:
    """The value of a case series at a time, interpolated linearly as the engine reads it."""
    seconds = (series.index - series.index[0]).total_seconds()
    return float(np.interp((pd.Timestamp(when) - series.index[0]).total_seconds(), seconds, series.to_numpy()))


@pytest.mark.parametrize("spelling", ["block-to", "blockTo", "Block-To", "BLOCKTO"])
def test_a_block_to_series_holds_the_value_at_the_end_of_each_interval(tmp_path, spelling) -> None:
    # lat2: 0.1 at 0 h, 0.3 at 12 h; block-to: 0.3 from just after 0 h through 12 h
    _, md, folder = _import(tmp_path, BoundaryConditions_bc=("time-interpolation    = block-from",
                                                             f"time-interpolation    = {spelling}"))
    lat = _lateral(folder, "lat2")
    assert _at(lat, "2020-01-01T00:00:00Z") == pytest.approx(0.1)
    for when in ("2020-01-01T00:00:01Z", "2020-01-01T06:00:00Z", "2020-01-01T12:00:00Z", "2020-01-01T18:00:00Z"):
        assert _at(lat, when) == pytest.approx(0.3), when
    assert "block-to series taken as steps" in md


@pytest.mark.parametrize("spelling", ["block-from", "blockFrom", "BlockFrom"])
def test_a_block_from_series_holds_each_value_until_the_next_time(tmp_path, spelling) -> None:
    _, md, folder = _import(tmp_path, BoundaryConditions_bc=("time-interpolation    = block-from",
                                                             f"time-interpolation    = {spelling}"))
    lat = _lateral(folder, "lat2")
    for when, value in (("2020-01-01T06:00:00Z", 0.1), ("2020-01-01T11:59:59Z", 0.1),
                        ("2020-01-01T12:00:00Z", 0.3), ("2020-01-01T18:00:00Z", 0.3)):
        assert _at(lat, when) == pytest.approx(value), when
    assert "block-from series taken as steps" in md


def test_an_unknown_time_interpolation_names_its_file_line_and_key(tmp_path) -> None:
    md1d = write_model(tmp_path / "model", BoundaryConditions_bc=("time-interpolation    = block-from",
                                                                  "time-interpolation    = cubic"))
    with pytest.raises(CaseError, match=r"BoundaryConditions.bc:\d+: time-interpolation: 'cubic' is none of"):
        import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))


@pytest.mark.parametrize(("rows", "interpolation", "expect"), [
    # linear over 12 h, repeated: 0.1 at 0, 12 and 24 h, 0.3 at 6 and 18 h
    ("    0 0.1\n    6 0.3\n    12 0.1", "linear", {"06:00": 0.3, "12:00": 0.1, "15:00": 0.2, "18:00": 0.3}),
    # block-from over 8 h: 0.1 from 0 h, 0.3 from 4 h, again 0.1 from 8 h
    ("    0 0.1\n    4 0.3\n    8 0.7", "block-from", {"02:00": 0.1, "06:00": 0.3, "09:00": 0.1, "13:00": 0.3,
                                                       "17:00": 0.1}),
])
def test_a_periodic_series_repeats_over_the_simulated_period(tmp_path, rows, interpolation, expect) -> None:
    _, md, folder = _import(tmp_path, BoundaryConditions_bc=(
        "time-interpolation    = block-from\n    quantity              = time\n"
        "    unit                  = hours since 2020-01-01 00:00:00\n    quantity              = water_discharge\n"
        "    unit                  = m³/s\n    0 0.1\n    12 0.3",
        f"time-interpolation    = {interpolation}\n    periodic              = true\n    quantity              = time\n"
        "    unit                  = hours since 2020-01-01 00:00:00\n    quantity              = water_discharge\n"
        f"    unit                  = m³/s\n{rows}"))
    lat = _lateral(folder, "lat2")
    for when, value in expect.items():
        assert _at(lat, f"2020-01-01T{when}:00Z") == pytest.approx(value), when
    row = next(line for line in md.splitlines() if "`lat2`" in line)
    assert "periodic: repeated every" in row and "last value held" not in row


# -- universal weir ----------------------------------------------------------------------------------------------


def test_a_universal_weir_has_its_crest_at_crest_level_and_its_shape_above_it(tmp_path) -> None:
    # flow1d's readUniversalWeir: the z values are heights relative to the crest, shifted so that the lowest is 0
    data, md, _ = _import(tmp_path, Structures_ini=("crestLevel            = -1.5",
                                                    "crestLevel            = -1.2"))
    weir = _by_id(data["universal_weirs"])["uweir1"]
    assert weir["crest_level"] == -1.2
    assert weir["z"] == pytest.approx([0.7, 0.0, 0.0, 0.7])
    assert "- universalWeir (1): `uweir1`" in md  # exact


# -- the INI reader -------------------------------------------------------------------------------------------


def test_an_empty_value_followed_by_a_comment_is_empty(tmp_path) -> None:
    path = tmp_path / "x.ini"
    path.write_text("[Files]\n  a = # Name and location of the file\n  b = #with blanks# rest\n  c =#\n"
                    "  d = file.ini # a comment\n", encoding="utf-8")
    (files,) = read_ini(path)
    assert [files.find(k).value for k in "abcd"] == ["", "with blanks", "", "file.ini"]


def test_an_empty_file_name_followed_by_a_comment_names_no_file(tmp_path) -> None:
    _, md, _ = _import(tmp_path, Flow1D_md1d=("initialWaterDepthFile = InitialWaterDepth.ini",
                                                 "initialWaterDepthFile = # Name and location of the file"))
    assert "Name and location" not in md


# -- roughness ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("code", "law"), [("9", "bosbijkerk"), ("8", "engelund")])
def test_a_global_roughness_a_case_cannot_take_is_refused_not_an_error(tmp_path, code, law) -> None:
    replace = {"roughness_FloodPlain1_ini": ("globalType            = 6", f"globalType            = {code}")}
    md1d = write_model(tmp_path / "strict", **replace)
    with pytest.raises(CaseError, match=rf"friction group 'FloodPlain1': .*global roughness type {law}.*"
                                        r"--allow-partial"):
        import_sobek3(md1d, tmp_path / "strict-case")
    data, md, _ = _import(tmp_path, **replace)
    group = _by_id(data["friction_groups"])["FloodPlain1"]
    assert (group["type"], group["value"]) == ("chezy", 45.0)
    row = next(line for line in md.splitlines() if line.startswith("| friction group | `FloodPlain1`"))
    assert "refused" in md and f"global roughness type {law}" in row and "Chézy 45" in row


def test_an_unknown_global_roughness_type_is_an_error_at_its_line(tmp_path) -> None:
    md1d = write_model(tmp_path / "model", roughness_FloodPlain1_ini=("globalType            = 6",
                                                                      "globalType            = 42"))
    with pytest.raises(CaseError, match=r"roughness-FloodPlain1.ini:\d+: globalType: roughness type '42' is none"):
        import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))


# -- compound structures -----------------------------------------------------------------------------------------


def _two_weirs(compound: str) -> dict[str, tuple[str, str]]:
    """Two weirs on b1 at 550 m (between the grid points at 500 and 600 m), members of compound C1 or not."""
    block = ("[Structure]\n    id = {id}\n    branchid = b1\n    chainage = 550.0\n    type = weir\n"
             "    crestLevel = {crest}\n    crestWidth = 2.0\n" + compound + "\n")
    weirs = block.format(id="cw1", crest=-1.0) + block.format(id="cw2", crest=-0.5)
    return {"Structures_ini": ("[Structure]\n    id                    = weir1",
                               weirs + "[Structure]\n    id                    = weir1")}


def test_a_compound_structure_becomes_parallel_branches_with_the_stretch_s_data(tmp_path) -> None:
    data, md, folder = _import(tmp_path, **_two_weirs("    compound = 1\n    compoundName = C1"))
    weirs = _by_id(data["weirs"])
    branches = _by_id(data["branches"])
    stretch, beside = weirs["cw1"]["branch"], weirs["cw2"]["branch"]
    assert stretch != beside and stretch not in ("b1",)
    # b1 is cut at the grid points around 550 m (500 and 600 m); the 100 m between become two branches of 50 m
    assert [branches[b]["length"] for b in ("b1", stretch, beside)] == [500.0, 50.0, 50.0]
    assert (branches[stretch]["from_node"], branches[stretch]["to_node"]) == (
        branches[beside]["from_node"], branches[beside]["to_node"]) == (branches["b1"]["to_node"],
                                                                        branches[stretch]["to_node"])
    assert weirs["cw1"]["chainage"] == weirs["cw2"]["chainage"] == 25.0
    # the initial levels along b1 (1 m AD at 0, 0.5 m at 1000 m) and its water-level friction table at 0 and
    # 1000 m carried over to each part for the stretch of b1 it stands for
    assert branches["b1"]["initial_levels"] == {"chainages": [0.0, 500.0], "levels": [1.0, 0.75]}
    for bid in (stretch, beside):
        assert branches[bid]["initial_levels"]["chainages"] == [0.0, 50.0]
        assert branches[bid]["initial_levels"]["levels"] == pytest.approx([0.75, 0.7])
    main = {e["branch"]: e for e in _by_id(data["friction_groups"])["Main"]["branches"]}
    assert main["b1"]["chainages"] == [0.0, 500.0]
    assert np.allclose(main["b1"]["table"], [[30.0, 40.0, 50.0], [31.0, 41.0, 51.0]])
    for bid in (stretch, beside):
        assert main[bid]["chainages"] == [0.0, 50.0]
        assert np.allclose(main[bid]["table"], [[31.0, 41.0, 51.0], [31.2, 41.2, 51.2]])
    assert "| compound | `C1` | 2 structures side by side" in md
    sim = Simulator(load_case(folder))
    out, _ = sim.simulate(end=sim.start + pd.Timedelta(hours=2))
    assert (out.series["cw1.h_up"] == out.series["cw2.h_up"]).all()


def test_a_compound_whose_members_lie_apart_is_refused_naming_it_its_file_and_line(tmp_path) -> None:
    replace = _two_weirs("    compound = 1\n    compoundName = C1")
    old, new = replace["Structures_ini"]
    replace["Structures_ini"] = (old, new.replace("chainage = 550.0\n    type = weir\n    crestLevel = -0.5",
                                                  "chainage = 750.0\n    type = weir\n    crestLevel = -0.5"))
    md1d = write_model(tmp_path / "model", **replace)
    with pytest.raises(CaseError) as info:
        import_sobek3(md1d, tmp_path / "strict")
    message = str(info.value)
    line = next(k for k, text in enumerate((tmp_path / "model" / "Structures.ini").read_text(
        encoding="utf-8").splitlines(), start=1) if "id = cw1" in text)
    assert "compound structure 'C1'" in message and f"Structures.ini:{line};" in message, message
    assert "members 'cw1', 'cw2'" in message and "do not lie at one branch and chainage" in message


def test_two_structures_between_the_same_grid_points_are_refused_naming_the_file_and_line(tmp_path) -> None:
    data, md, _ = _import(tmp_path, **_two_weirs(""))
    assert "cw1" in _by_id(data["weirs"]) and "cw2" not in _by_id(data["weirs"])
    row = next(line for line in md.splitlines() if "`cw2`" in line and line.startswith("|"))
    line = next(k for k, text in enumerate((tmp_path / "model" / "Structures.ini").read_text(
        encoding="utf-8").splitlines(), start=1) if "id = cw2" in text)
    assert f"Structures.ini:{line}: it lies between the same two grid points as 'cw1'" in row, row


# -- closed tabulated profiles -----------------------------------------------------------------------------------


_PIPE = ("[Definition]\n    id                    = pipe\n    type                  = circle\n"
         "    diameter              = 1.0")


def test_a_circle_with_a_table_stays_a_circle(tmp_path) -> None:
    # DeltaShell writes a circle's table beside its diameter; the table closes at the top
    data, _, _ = _import(tmp_path, CrossSectionDefinitions_ini=(_PIPE, _PIPE + (
        "\n    numLevels = 5\n    levels = 0 0.146 0.5 0.854 1.0\n    flowWidths = 0 0.707 1.0 0.707 0"
        "\n    totalWidths = 0 0.707 1.0 0.707 0")))
    assert _by_id(data["profiles"])["pipe"] == {"id": "pipe", "type": "circular", "diameter": 1.0,
                                                "friction": ["Main"]}
    assert _by_id(data["culverts"])["culvert1"]["profile"] == "pipe"


def test_a_closed_table_under_a_culvert_is_a_closed_profile(tmp_path) -> None:
    closed = "[Definition]\n    id = box\n    type = tabulated\n    numLevels = 3\n    levels = 0 2 2.5\n" \
             "    flowWidths = 4 4 0\n    totalWidths = 4 4 0\n\n"
    data, md, folder = _import(tmp_path, CrossSectionDefinitions_ini=(_PIPE, closed + _PIPE),
                               Structures_ini=("csDefId               = pipe", "csDefId               = box"))
    box = _by_id(data["profiles"])["box"]
    assert (box["heights"], box["flow_widths"], box.get("closed")) == ([0.0, 2.0, 2.5], [4.0, 4.0, 0.0], True)
    assert _by_id(data["culverts"])["culvert1"]["profile"] == "box"
    assert not any(line.startswith("| profile | `box`") for line in md.splitlines())  # exact: no note, no refusal
    sim = Simulator(load_case(folder))
    out, _ = sim.simulate(end=sim.start + pd.Timedelta(hours=2))
    assert out.series.notna().all().all()


def test_an_open_table_whose_flow_width_closes_at_the_top_keeps_a_sliver(tmp_path) -> None:
    # the flow width closes but the total width does not: an open profile (flow1d closes on the total width)
    data, md, _ = _import(tmp_path, CrossSectionDefinitions_ini=(
        "flowWidths            = 6.0 10.0 30.0 24.0 40.0", "flowWidths            = 6.0 10.0 30.0 24.0 0.0"))
    prof = _by_id(data["profiles"])["river"]
    assert prof["flow_widths"][-1] == 0.001 and not prof.get("closed")
    assert "the top keeps 1 mm of flow width" in md
