"""``rivercal bench ensemble``: the JSON keys, on a short period (the timing itself is a benchmark, not a test)."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from rivercal.cli.main import app


def test_bench_ensemble_prints_members_wall_single_run_and_speedup():
    out = CliRunner().invoke(app, ["bench", "ensemble", "--members", "3", "--days", "0.25", "--repeats", "1",
                                   "--threads", "1", "--json"])
    assert out.exit_code == 0, out.output
    result = json.loads(out.stdout)
    assert {"members", "wall_s", "single_run_wall_s", "speedup", "cpu_s", "load_average_1min",
            "first_call_s"} <= set(result)
    assert result["first_call_s"] > 0.0
    assert result["members"] == 3 and result["threads"] == 1
    assert result["speedup"] == result["members"] * result["single_run_wall_s"] / result["wall_s"]


def test_bench_ensemble_names_a_bad_option():
    out = CliRunner().invoke(app, ["bench", "ensemble", "--members", "0"])
    assert out.exit_code != 0 and "--members" in out.output
