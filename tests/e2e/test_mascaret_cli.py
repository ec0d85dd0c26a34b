"""``rivercal import mascaret`` and ``rivercal bench oriege`` as a user runs them."""

from __future__ import annotations

import json
from pathlib import Path

from tests.cli import rivercal
from tests.mascaret_models import XCAS, write_model
from tests.shared_data import shared_model


def test_the_oriege_imports_with_its_gauges_and_prints_the_summary(tmp_path: Path) -> None:
    xcas = shared_model("oriege-mascaret-test19", "mascaret0.xcas")
    gauges = tmp_path / "gauges.csv"
    gauges.write_text("id,reach,abscissa\nG01,Bief_1,0\nG05,Bief_1,2119\nG13,1,5007\n", encoding="utf-8")
    run = rivercal("import", "mascaret", str(xcas), "--out", str(tmp_path / "case"), "--stations", str(gauges),
                   "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert set(summary) == {"folder", "branches", "points", "profiles", "friction_groups", "boundaries", "laterals",
                            "stations", "start", "end", "approximated", "refused", "parameters"}
    assert summary["parameters"] == ["Kz1_minor"]
    assert (summary["profiles"], summary["stations"], summary["refused"]) == (84, 84 + 3, 0)
    run = rivercal("case", "check", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    assert "G05.h" in run.stdout


def test_a_refusal_stops_the_import_and_names_the_way_out(tmp_path: Path) -> None:
    xcas = write_model(tmp_path / "model")  # it has a weir
    run = rivercal("import", "mascaret", str(xcas), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "weir 'barrage1'" in run.stderr and "--allow-partial" in run.stderr and "import.md" in run.stderr
    run = rivercal("import", "mascaret", str(xcas), "--out", str(tmp_path / "case"), "--allow-partial")
    assert run.returncode == 0, run.stderr
    assert "1 refused" in " ".join(run.stdout.split())  # the console wraps long lines


def test_bad_input_is_an_error_naming_the_file_and_line(tmp_path: Path) -> None:
    xcas = write_model(tmp_path / "model", xcas=XCAS.replace("<pasTemps>30.0</pasTemps>", "<pasTemps>3O</pasTemps>"))
    run = rivercal("import", "mascaret", str(xcas), "--out", str(tmp_path / "case"), "--allow-partial")
    assert run.returncode == 2
    assert "model.xcas: line" in run.stderr and "<parametresTemporels/pasTemps>: '3O' is not a number" in run.stderr
    good = write_model(tmp_path / "good")
    stations = tmp_path / "gauges.csv"
    stations.write_text("id,reach,abscissa\nG1,aval,x\n", encoding="utf-8")
    run = rivercal("import", "mascaret", str(good), "--out", str(tmp_path / "case"), "--stations", str(stations))
    assert run.returncode == 2
    assert "gauges.csv: line 2: abscissa of station 'G1': 'x' is not a number" in run.stderr
    run = rivercal("import", "mascaret", str(good), "--out", str(tmp_path / "case"), "--cross-sections", "linear")
    assert run.returncode == 2 and "--cross-sections" in run.stderr
    run = rivercal("import", "mascaret", str(tmp_path / "none.xcas"), "--out", str(tmp_path / "case"))
    assert run.returncode == 2 and "none.xcas" in run.stderr and "cannot read" in run.stderr
    assert "internal error" not in run.stderr


def test_the_benchmark_says_where_the_data_should_be(tmp_path: Path) -> None:
    run = rivercal("bench", "oriege", "--json", env={"RIVERCAL_ORIEGE_DIR": str(tmp_path / "nowhere")})
    assert run.returncode == 1
    assert "nowhere" in run.stderr and "RIVERCAL_ORIEGE_DIR" in run.stderr and "internal error" not in run.stderr
