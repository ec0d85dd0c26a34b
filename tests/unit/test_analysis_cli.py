"""``rivercal analyse``: exit codes and messages for bad input, and one run on the dommel case (slow).

Both run in-process on the real app (see :mod:`tests.cli`).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from rivercal.cli.main import app
from tests.cli import rivercal
from tests.run_artefacts import dommel_dependency_map


@pytest.mark.parametrize(("args", "message"), [
    (["analyse", "dommel", "--what", "sensitivity,nonsense"], "--what 'nonsense'"),
    (["analyse", "dommel", "--params", "W2,Wx"], "unknown parameter 'Wx'"),
    (["analyse", "dommel", "--params", "W2", "--twin", "FA=20"], "'FA' is not in --params"),
    (["analyse", "dommel", "--params", "W2", "--window", "2011-01-01/2011-01-08"], "outside the case period"),
    (["analyse", "dommel", "--params", "W2", "--sv-threshold", "2"], "--sv-threshold 2: must be in (0, 1)"),
])
def test_bad_input_exits_2_with_a_message(args: list[str], message: str) -> None:
    run = CliRunner().invoke(app, args)
    assert run.exit_code == 2, run.output
    assert message in run.stderr
    assert "Traceback" not in run.output


def test_the_default_window_on_a_model_without_named_windows_says_so_and_gives_the_period() -> None:
    # 'rivercal analyse' defaults to --window moderate; an imported model names no windows
    from types import SimpleNamespace

    from rivercal.cli.options import parse_window
    from rivercal.errors import OptionError

    model = SimpleNamespace(name="test_compound", calibration=SimpleNamespace(windows={}),
                            start=pd.Timestamp("2001-01-01", tz="UTC"), end=pd.Timestamp("2001-02-08", tz="UTC"))
    with pytest.raises(OptionError) as caught:
        parse_window(model, "moderate")
    assert str(caught.value) == ("--window 'moderate': not a window of 'test_compound', which names none (an imported "
                                 "model has none); give a date range START/END or START/DURATION in its period "
                                 "2001-01-01 00:00 .. 2001-02-08 00:00, e.g. 2001-01-01/1D")
    model.calibration.windows = {"calm": ("2001-01-02", "2001-01-03")}
    with pytest.raises(OptionError, match=r"window of the case \(calm\); its period is 2001-01-01 00:00 .. 2001-02-08"):
        parse_window(model, "moderate")
    assert parse_window(model, "2001-01-20/2D") == (pd.Timestamp("2001-01-20", tz="UTC"),
                                                    pd.Timestamp("2001-01-22", tz="UTC"))


@pytest.mark.slow
def test_analyse_dommel_json_and_files(tmp_path: Path) -> None:
    run = rivercal("analyse", "dommel", "--params", "W2,FA", "--what", "identifiability,residuals", "--twin",
                   "FA=17", "--workers", "2", "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    ident = summary["identifiability"]
    assert ident["verdict"] == {"W2": "identifiable", "FA": "identifiable"}
    assert ident["model_runs"] == 3 and summary["model_runs"] == 4
    assert "0028" in ident["explanations"]["W2"]
    assert summary["observations_source"]["twin"] == {"W2": 10.45, "FA": 17.0}
    residuals = summary["residuals"]["weighted"]["total"]
    assert residuals["n"] == 1859 and residuals["cost"] > 1.0  # the model at FA = 16 misses the truth at 17
    assert summary["residuals"]["bias"]["0028.h_down"]["significant"] is True
    for name in ("jacobian", "singular_values", "singular_vectors", "covariance", "correlation", "identifiability",
                 "residual_statistics", "moving_bias", "bias_significance", "svd_figure", "correlation_figure",
                 "bias_figure", "summary"):
        assert Path(summary["files"][name]).is_file(), name
    assert json.loads((tmp_path / "analysis.json").read_text()) == summary
    # the dependency map is the Jacobian's: per series the largest |∂r/∂x| times the first DuD step (σ)
    jac = pd.read_csv(summary["files"]["jacobian"]).drop(columns="row")
    steps = {"W2": 0.1, "FA": 1.5}  # the first DuD steps (perturbations) of dommel's case.toml
    expected = jac.groupby("series", sort=False).agg(lambda col: col.abs().max()) * pd.Series(steps)
    dependency = pd.read_csv(summary["files"]["dependency"], index_col="series")
    pd.testing.assert_frame_equal(dependency, expected[dependency.columns], rtol=1e-5)
    assert ident["dependency"]["threshold_sigma"] == 0.1
    seen = (dependency > 0.1).sum(axis=1)
    assert ident["dependency"]["parameters_per_series"] == {s: int(n) for s, n in seen.items()}
    assert next(iter(ident["dependency"]["widest"].values())) == ident["dependency"]["most_parameters_per_series"]


@pytest.mark.slow
def test_calibrate_with_the_dependency_map_of_analyse(tmp_path: Path) -> None:
    """The map of ``rivercal analyse dommel --params FA,F1,FL,W2 --what identifiability``, measured once in the test
    run (:func:`tests.run_artefacts.dommel_dependency_map`; ``tests/e2e/test_online_cli.py`` replays with it too)."""
    dependency = dommel_dependency_map()
    run = rivercal("calibrate", "dommel", "--params", "FA,F1,FL,W2", "--window", "moderate", "--twin", "FL=20",
                   "--algorithm", "sparse_dud", "--dependency", str(dependency),
                   "--workers", "2", "--out", str(tmp_path / "calibrate"), "--json")
    assert run.returncode == 0, run.stderr
    estimates = json.loads(run.stdout)["estimates"]
    assert estimates["FL"] == pytest.approx(20.0, abs=0.05) and estimates["FA"] == pytest.approx(16.0, abs=0.05)
    refused = rivercal("calibrate", "dommel", "--params", "FA", "--window", "moderate", "--twin", "FA=20",
                       "--dependency", str(dependency), "--out", str(tmp_path / "x"))
    assert refused.returncode == 2 and "serves --algorithm sparse_dud only, not dud" in refused.stderr
