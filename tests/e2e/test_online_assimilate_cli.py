"""``rivercal online --assimilate``: the ensemble filter from the command line, and its option errors."""

from __future__ import annotations

import json

import pytest

from tests.cli import rivercal

pytestmark = pytest.mark.slow


def test_online_assimilate_states_prints_the_error_by_lead_and_the_band_coverage(tmp_path) -> None:
    run = rivercal("online", "dommel", "--scenario", "PI-0", "--from", "2010-10-18", "--to", "2010-10-18",
                   "--window", "2D", "--warmup", "12h", "--horizon", "12h", "--assimilate", "states", "--members", "8",
                   "--noise", "gaussian", "--rain-error", "0.3", "--db", str(tmp_path / "run.sqlite"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
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
