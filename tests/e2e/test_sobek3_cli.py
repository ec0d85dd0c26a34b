"""``rivercal import sobek3`` as a user runs it, and ``rivercal simulate`` of the case it writes."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from rivercal.bench.sobek3 import MODELS
from tests.cli import rivercal
from tests.shared_data import shared_model
from tests.sobek3_models import write_model


def test_import_then_simulate_the_compound_channel(tmp_path: Path) -> None:
    md1d = shared_model("sobek3-compound", *MODELS["sobek3-compound"].split("/"))
    run = rivercal("import", "sobek3", str(md1d), "--out", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert (summary["branches"], summary["points"], summary["profiles"], summary["boundaries"]) == (1, 62, 7, 2)
    assert summary["dt_s"] == 3600.0
    assert summary["objects"] == summary["exact"] + summary["approximated"] + summary["refused"]
    assert (tmp_path / "case" / "import.md").read_text(encoding="utf-8").startswith("# Import of a SOBEK 3 model")
    run = rivercal("simulate", str(tmp_path / "case"), "--out", str(tmp_path / "sim"), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["case"] == "test_compound"
    assert pd.read_csv(tmp_path / "sim" / "series.csv").shape[0] == 38 * 24 + 1  # every hour of 38 days


def test_a_refusal_is_an_error_naming_the_objects_and_the_way_out(tmp_path: Path) -> None:
    md1d = write_model(tmp_path / "model")
    run = rivercal("import", "sobek3", str(md1d), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "generalStructure 'general1'" in run.stderr and "--allow-partial" in run.stderr
    assert sorted(p.name for p in (tmp_path / "case").iterdir()) == ["import.md"]
    run = rivercal("import", "sobek3", str(md1d), "--out", str(tmp_path / "case"), "--allow-partial")
    assert run.returncode == 0, run.stderr
    assert "6 refused" in " ".join(run.stdout.split())
    # -q: the same import, nothing on the terminal (in this process: what the command prints is the point)
    from typer.testing import CliRunner

    from rivercal.cli.main import app

    quiet = CliRunner().invoke(app, ["import", "sobek3", str(md1d), "--out", str(tmp_path / "quiet"), "--allow-partial",
                                     "-q"])
    assert quiet.exit_code == 0 and quiet.stdout == "" and (tmp_path / "quiet" / "case.toml").is_file()
    run = rivercal("simulate", str(tmp_path / "case"), "--out", str(tmp_path / "sim"), "--json")
    assert run.returncode == 0, run.stderr


def test_a_bad_value_is_an_error_with_its_file_line_and_key(tmp_path: Path) -> None:
    md1d = write_model(tmp_path / "model", Structures_ini=("crestWidth            = 3.0",
                                                           "crestWidth            = wide"))
    run = rivercal("import", "sobek3", str(md1d), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "Structures.ini:" in run.stderr and "crestWidth: 'wide' is not a number" in run.stderr
    assert "bug" not in run.stderr
    run = rivercal("import", "sobek3", str(tmp_path / "nothing.md1d"), "--out", str(tmp_path / "case"))
    assert run.returncode == 2 and "nothing.md1d" in run.stderr


def test_a_time_step_below_the_shortest_is_an_option_error(tmp_path: Path) -> None:
    md1d = write_model(tmp_path / "model")
    for dt in ("-5", "0", "0.05"):
        run = rivercal("import", "sobek3", str(md1d), "--out", str(tmp_path / "case"), "--allow-partial", "--dt", dt)
        assert run.returncode == 2, (dt, run.stderr)
        assert "--dt" in run.stderr and "at least 0.1 s" in run.stderr and "bug" not in run.stderr
    run = rivercal("import", "sobek3", str(md1d), "--out", str(tmp_path / "case"), "--allow-partial", "--dt", "0.7",
                   "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["dt_s"] == 0.6  # the longest step of at most 0.7 s that divides the 600 s output
