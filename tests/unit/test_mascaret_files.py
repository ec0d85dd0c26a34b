"""Mascaret's files read as Mascaret reads them, and every bad value an error naming the file, the line and the key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rivercal.errors import CaseError
from rivercal.io.mascaret import read_geometry, read_law, read_station_list, read_xcas
from tests.mascaret_models import AXIS, MAJOR, MINOR, PROFILES, XCAS, geometry_text


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# -- geometry ---------------------------------------------------------------------------------------------


def test_the_geometry_is_read_reach_by_reach_with_its_beds_and_axis(tmp_path: Path) -> None:
    geo = read_geometry(_write(tmp_path, "m.georef", geometry_text()))
    reaches = geo.reaches()
    assert [name for name, _ in reaches] == list(PROFILES)
    for (_, profiles), expected in zip(reaches, PROFILES.values(), strict=True):
        assert [(p.name, p.abscissa, p.bed_level) for p in profiles] == [(n, x, b) for n, x, b, _ in expected]
    p1b = reaches[0][1][1]
    assert [(q.y, round(q.z - 11.6, 6), q.bed) for q in p1b.points] == MAJOR
    assert p1b.minor_bed() == (2, 4)  # the run of B points
    assert reaches[1][1][0].minor_bed() == (0, len(MINOR) - 1)
    assert [p.axis for p in reaches[0][1]] == [AXIS[n] for n, *_ in PROFILES["amont1"]]
    assert reaches[1][1][0].axis is None
    p3a = reaches[2][1][0]  # the survey's closing walls are read as they are
    assert (p3a.points[0].z, p3a.points[-1].z) == (999.0, 999.0)


@pytest.mark.parametrize(("text", "line", "words"), [
    ("PROFIL r p 0.0\n0 1 B\n2 x B\n", 3, ["'x' is not a number"]),
    ("PROFIL r p 0.0\n0 1 B\n2 0 Q\n", 3, ["bed mark", "'Q'", "B", "T"]),
    ("PROFIL r p 0.0\n0 1 B\n2 0 B\n", 1, ["needs at least two"]),  # a reach with one profile: its header
    ("0 1 B\nPROFIL r p 0.0\n", 1, ["before the first"]),
    ("PROFIL r p 0.0\n0 1 B\n1 0\n", 3, ["'<y> <z> <B|T>'"]),
    ("PROFIL r a 10.0\n0 1 B\n2 0 B\nPROFIL r b 5.0\n0 1 B\n2 0 B\n", 4, ["abscissa of profile 'b'", "increase"]),
    ("PROFIL r a 0.0\n0 1 B\n1 0 T\n2 0 B\n3 1 B\nPROFIL r b 5.0\n0 1 B\n2 0 B\n", 4, ["two separate runs"]),
    ("PROFIL r a 0.0\n0 1 B\nPROFIL r b 5.0\n0 1 B\n2 0 B\n", 1, ["1 point(s)"]),
    ("PROFIL r a 0.0\n0 1 B\n2 0 B\nPROFIL r b 5.0\n0 1 B\n2 0 B\nPROFIL s c 0\n0 1 B\n2 0 B\nPROFIL s d 1\n0 1 B\n"
     "2 0 B\nPROFIL r e 9\n0 1 B\n2 0 B\nPROFIL r f 10\n0 1 B\n2 0 B\n", 13, ["reach 'r' comes back"]),
    ("PROFIL r\n", 1, ["'PROFIL <reach> <profile> <abscissa>'"]),
])
def test_a_bad_geometry_line_is_named(tmp_path: Path, text: str, line: int, words: list[str]) -> None:
    path = _write(tmp_path, "bad.geo", "# comment\n" + text)
    with pytest.raises(CaseError) as err:
        read_geometry(path)
    message = str(err.value)
    assert str(path) in message and f"line {line + 1}" in message, message
    for w in words:
        assert w in message, message


def test_an_empty_geometry_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(CaseError, match="no profile"):
        read_geometry(_write(tmp_path, "empty.geo", "# nothing\n"))
    with pytest.raises(CaseError, match="cannot read the geometry file"):
        read_geometry(tmp_path / "missing.geo")


# -- laws -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("unit", "seconds"), [("S", 1.0), ("M", 60.0), ("H", 3600.0), ("J", 86400.0), ("h", 3600.0)])
def test_a_law_in_time_is_converted_to_seconds(tmp_path: Path, unit: str, seconds: float) -> None:
    law = read_law(_write(tmp_path, "q.loi", f"# Q(t)\n {unit}\n 0 1.5\n 2 2.5\n 3.5 1.0\n"), 1)
    np.testing.assert_allclose(law["time"], np.array([0.0, 2.0, 3.5]) * seconds)
    np.testing.assert_allclose(law["discharge"], [1.5, 2.5, 1.0])


@pytest.mark.parametrize(("law_type", "columns"), [
    (2, {"time": [0.0, 10.0], "level": [1.0, 2.0]}),
    (3, {"time": [0.0, 10.0], "level": [1.0, 2.0], "discharge": [3.0, 4.0]}),
    (4, {"discharge": [0.0, 10.0], "level": [1.0, 2.0]}),
    (5, {"level": [0.0, 10.0], "discharge": [1.0, 2.0]}),
])
def test_each_law_type_has_its_columns(tmp_path: Path, law_type: int, columns: dict) -> None:
    rows = list(zip(*columns.values(), strict=True))
    head = " S\n" if "time" in columns else ""
    text = "# law\n" + head + "".join(" " + " ".join(f"{v:g}" for v in row) + "\n" for row in rows)
    law = read_law(_write(tmp_path, "a.loi", text), law_type)
    assert list(law.columns) == list(columns)
    for name, values in columns.items():
        np.testing.assert_allclose(law[name], values)


@pytest.mark.parametrize(("text", "law_type", "line", "words"), [
    ("# no unit\n 0 1\n 10 2\n", 1, 2, ["time unit"]),
    (" S\n 0 1\n 10\n", 1, 3, ["2 values", "got 1"]),
    (" S\n 0 1\n 0 2\n", 1, 3, ["increase strictly"]),
    (" S\n 0 1\n 10 2,5\n", 1, 3, ["'2,5' is not a number"]),
    ("1 0\n2 5\n2.5 4\n", 5, 3, ["discharges of the rating", "increase"]),
])
def test_a_bad_law_line_is_named(tmp_path: Path, text: str, law_type: int, line: int, words: list[str]) -> None:
    path = _write(tmp_path, "bad.loi", text)
    with pytest.raises(CaseError) as err:
        read_law(path, law_type)
    message = str(err.value)
    assert str(path) in message and f"line {line}" in message, message
    for w in words:
        assert w in message, message


# -- the case file ------------------------------------------------------------------------------------------


def test_the_case_file_values_are_typed_and_paths_may_skip_levels(tmp_path: Path) -> None:
    x = read_xcas(_write(tmp_path, "m.xcas", XCAS))
    assert x.number("parametresTemporels/pasTemps") == 30.0
    assert x.integers("parametresGeometrieReseau/listeBranches/numExtremFin", 3) == [2, 4, 6]
    assert x.strings("parametresGeometrieReseau/extrLibres/noms") == ["up1", "up2", "down"]
    assert x.boolean("parametresTemporels/pasTempsVar") is False
    # Mascaret's reader finds parametresCalage/coefLitMin below parametresCalage/frottement
    assert x.numbers("parametresCalage/coefLitMin") == [25.0, 30.0, 35.0, 28.0]
    assert x.number("parametresTemporels/absent", 7.0) == 7.0


def test_a_bad_value_in_the_case_file_names_its_line_and_element(tmp_path: Path) -> None:
    text = XCAS.replace("<pasTemps>30.0</pasTemps>", "<pasTemps>thirty</pasTemps>")
    path = _write(tmp_path, "m.xcas", text)
    line = next(k for k, t in enumerate(text.splitlines(), start=1) if "thirty" in t)
    with pytest.raises(CaseError) as err:
        read_xcas(path).number("parametresTemporels/pasTemps")
    assert str(err.value) == f"{path}: line {line}, <parametresTemporels/pasTemps>: 'thirty' is not a number"


@pytest.mark.parametrize(("text", "words"), [
    ("<fichierCas><parametresCas><a>1</b></parametresCas></fichierCas>", ["not well-formed XML", "line 1"]),
    ("<?xml version='1.0'?>\n<case>\n</case>\n", ["<case>", "expected <fichierCas>", "line 2"]),
    ("<fichierCas>\n</fichierCas>\n", ["no <parametresCas>"]),
    ('<!DOCTYPE x [<!ENTITY a "aaaa">]><fichierCas><parametresCas>&a;</parametresCas></fichierCas>',
     ["refused for safety"]),
])
def test_a_file_that_is_not_a_case_file_is_a_clear_error(tmp_path: Path, text: str, words: list[str]) -> None:
    path = _write(tmp_path, "bad.xcas", text)
    with pytest.raises(CaseError) as err:
        read_xcas(path)
    for w in [str(path), *words]:
        assert w in str(err.value), str(err.value)


# -- station lists ------------------------------------------------------------------------------------------


def test_a_station_list_is_read_with_its_lines(tmp_path: Path) -> None:
    path = _write(tmp_path, "gauges.csv", "# gauges\nid,reach,abscissa\nG1,Bief_1,0\nG2,2,340.5\n")
    assert read_station_list(path) == [("G1", "Bief_1", 0.0, 3), ("G2", "2", 340.5, 4)]


@pytest.mark.parametrize(("text", "line", "words"), [
    ("id,reach\nG1,r\n", 1, ["no abscissa column"]),
    ("id,reach,abscissa\nG1,r\n", 2, ["expected 3 values"]),
    ("id,reach,abscissa\nG.1,r,5\n", 2, ["station id 'G.1'"]),
    ("id,reach,abscissa\nG1,r,5\nG1,r,6\n", 3, ["listed twice"]),
    ("id,reach,abscissa\nG1,r,five\n", 2, ["'five' is not a number"]),
])
def test_a_bad_station_list_names_the_line(tmp_path: Path, text: str, line: int, words: list[str]) -> None:
    path = _write(tmp_path, "gauges.csv", text)
    with pytest.raises(CaseError) as err:
        read_station_list(path)
    message = str(err.value)
    assert str(path) in message and f"line {line}" in message, message
    for w in words:
        assert w in message, message
