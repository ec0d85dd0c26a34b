"""``rivercal online --assimilate``: the ensemble filter from the command line, and its option errors."""

from __future__ import annotations

import json

import pytest

from tests.cli import rivercal

pytestmark = pytest.mark.slow


def test_online_updates_states_and_parameters_by_default_and_prints_the_error_by_lead(tmp_path) -> None:
    run = rivercal("online", "dommel", "--scenario", "PI-0", "--from", "2010-10-18", "--to", "2010-10-18",
                   "--window", "2D", "--warmup", "12h", "--horizon", "12h", "--members", "8",
                   "--noise", "gaussian", "--rain-error", "0.3", "--db", str(tmp_path / "run.sqlite"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["assimilate"] == "both"   # the default where the model can update its states
    mae = summary["forecast_mae_by_lead"]
    assert mae["against"] == "truth"
    assert set(mae["updated"]) == {"0-6h", "6-12h", "12-24h", "24-48h"}
    assert mae["updated"]["24-48h"] is None and mae["updated"]["0-6h"] > 0   # a 12 h horizon
    cover = summary["band_coverage_90"]
    assert 0 < cover["n"] <= 12 * 10 and 0 < cover["fraction"] <= 1   # 12 leads x 10 levels, less screened


def test_online_assimilate_option_errors_name_the_option(tmp_path) -> None:
    db = str(tmp_path / "run.sqlite")
    bad = rivercal("online", "dommel", "--from", "2010-10-18", "--to", "2010-10-18", "--assimilate", "all", "--db", db)
    assert bad.returncode != 0 and "--assimilate" in bad.stderr
    bad = rivercal("online", "dommel", "--from", "2010-10-18", "--to", "2010-10-18", "--rain-error", "0.3", "--db", db)
    assert bad.returncode != 0 and "--rain-error applies to the twin observations of --scenario" in bad.stderr


def test_a_model_that_cannot_update_its_states_is_refused_by_name_and_defaults_to_parameters(tmp_path) -> None:
    from rivercal.model import load_model
    from tests.unit.test_bmi import _bmi_model

    _bmi_model(tmp_path, load_model("synthetic"))   # a BMI model.toml without [bmi.assimilate]
    args = ("online", str(tmp_path / "model.toml"), "--params", "W2", "--from", "2020-01-04", "--to", "2020-01-04",
            "--window", "1D", "--warmup", "12h", "--db", str(tmp_path / "run.sqlite"))
    refused = rivercal(*args, "--assimilate", "states")
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert "--assimilate states needs a model with 'state arrays' and 'perturbable forcing'" in refused.stderr
    assert "lacks 'state arrays' and 'perturbable forcing'; use --assimilate parameters" in refused.stderr


def test_state_updating_on_swmm_runs_the_members_on_worker_processes(tmp_path) -> None:
    """SWMM keeps one project per process: its members run one per worker process, each from its hotstart file."""
    run = rivercal("online", "dommel-swmm", "--scenario", "PI-0", "--rain-error", "0.3", "--params", "FR",
                   "--from", "2010-09-22", "--to", "2010-09-22", "--window", "1D", "--warmup", "12h", "--horizon", "6h",
                   "--members", "4", "--workers", "2", "--db", str(tmp_path / "run.sqlite"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["assimilate"] == "both" and summary["status"] == {"done": 1}
    assert summary["band_coverage_90"]["n"] > 0
    from rivercal.store import Store

    with Store(tmp_path / "run.sqlite", readonly=True) as store:   # the members' hotstart files, stored for the next
        when, cycle, members, fmt, _ = store.ensemble(store.get_run(summary["run"]))
    assert (str(when), cycle, members, fmt) == ("2010-09-22 00:00:00+00:00", 0, 4, "rivercal-ensemble-zip-2")
