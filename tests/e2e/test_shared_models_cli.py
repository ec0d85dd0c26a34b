"""Every command a user runs, on the shared SOBEK 3 and Mascaret models as imported (the D-HYDRO ones are in
test_dhydro_cli.py), and the table of ``rivercal bench models`` on the cheap ones.

The model as imported is run with nothing edited: the calibration parameters and (for a model without
observation points) the stations are the ones the import wrote.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from tests.cli import rivercal
from tests.shared_data import shared_model

COMPOUND = ("sobek3-compound", "test_compound.dsproj_data", "Flow1D_output", "dflow1d", "Flow1D.md1d")


def test_every_command_runs_on_the_sobek3_compound_channel_as_imported(tmp_path: Path) -> None:
    """Import, simulate, calibrate (a twin of a parameter the import wrote), analyse, one on-line cycle, export.

    Its profiles name a main channel and a floodplain group side by side, which cannot be set alone: the import
    offers one factor on every friction coefficient instead."""
    case = tmp_path / "case"
    run = rivercal("import", "sobek3", str(shared_model(*COMPOUND)), "--out", str(case), "--json")
    assert run.returncode == 0, run.stderr
    imported = json.loads(run.stdout)
    assert imported["parameters"] == ["F_scale"] and imported["stations"] == 1
    # simulated up to the end of the on-line cycle's forecast (its observations), not the model's 38 days
    run = rivercal("simulate", str(case), "--end", "2001-01-21", "--out", str(tmp_path / "sim"), "--json")
    assert run.returncode == 0, run.stderr
    window = "2001-01-10/2001-01-12"
    run = rivercal("calibrate", str(case), "--params", "F_scale", "--window", window, "--twin", "F_scale=1.2",
                   "--warmup", "24", "--workers", "1", "--out", str(tmp_path / "cal"), "--json")
    assert run.returncode == 0, run.stderr
    assert abs(json.loads(run.stdout)["estimates"]["F_scale"] - 1.2) < 1e-3
    run = rivercal("analyse", str(case), "--params", "F_scale", "--window", window, "--workers", "1",
                   "--out", str(tmp_path / "analyse"), "--json")
    assert run.returncode == 0, run.stderr
    series = pd.read_csv(tmp_path / "sim" / "series.csv", index_col=0)
    series.to_csv(tmp_path / "observed.csv")
    run = rivercal("online", str(case), "--observations", str(tmp_path / "observed.csv"), "--params", "F_scale",
                   "--from", "2001-01-20", "--to", "2001-01-20", "--max-cycles", "1", "--window", "2D",
                   "--cycle", "1D", "--horizon", "1D", "--db", str(tmp_path / "run.sqlite"), "--workers", "1",
                   "--members", "8", "--out", str(tmp_path / "online"), "--quiet", "--json")
    # states and parameters (the default), a small ensemble
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["status"] == {"done": 1}
    # the report's parameter table has the factor the run estimated (the DSS keeps the model's own friction)
    table = pd.read_csv(tmp_path / "online" / "parameters.csv", index_col="parameter")
    assert table.loc["F_scale", "rivercal after"] == pytest.approx(1.0, abs=0.05)
    run = rivercal("export", "dhydro", str(case), "--out", str(tmp_path / "dflowfm"), "--json")
    assert run.returncode == 0, run.stderr


@pytest.mark.slow
def test_bench_models_scores_the_cheap_models_and_sweeps_one(tmp_path: Path) -> None:
    """The c01 steady state against the ODE and the compound channel against SOBEK 3, as ``bench models`` prints them;
    the compound channel within 1 cm of its 10 s run at 60, 300 and 600 s (measured: 0.03, 0.2, 0.5 cm)."""
    shared_model("sobek3-compound")
    run = rivercal("bench", "models", "--model", "dhydro-1d-steady-state-flow", "--model", "sobek3-compound",
                   "--sweep", "10,60,300,600", "--json")
    assert run.returncode == 0, run.stderr
    rows = {row["model"]: row for row in map(json.loads, run.stdout.splitlines())}
    c01, compound = rows["dhydro-1d-steady-state-flow"], rows["sobek3-compound"]
    for row in rows.values():
        assert row["runs_as_imported"] and row["points_compared"] > 0
        assert set(row) >= {"model", "format", "objects", "exact", "approximated", "refused", "runs_as_imported",
                            "dt_s", "points_compared", "level_rmse_m", "after_spinup", "wall_s", "solves_per_step"}
        assert row["solves_per_step"] >= 1.0  # each step at least one solve; more where the engine divided it
    assert c01["level_rmse_m"]["max"] < 0.01  # the ODE at every point
    assert compound["after_spinup"]["level_rmse_m"]["median"] <= 0.01  # SOBEK 3's own levels
    sweep = compound["sweep"]
    assert sweep["rmse_within_1cm"] and sweep["max_within_1cm"] and [s["ok"] for s in sweep["steps"]] == [True] * 4
    assert all(s["level_rmse_m"] <= s["max_diff_m"] for s in sweep["steps"])  # a mean never exceeds the largest
    assert all(s["solves_per_step"] >= 1.0 for s in compound["sweep"]["steps"])
