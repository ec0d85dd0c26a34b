"""The command line on the packaged cases: JSON output, files, exit codes, error messages."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli import rivercal


def process(*args: str) -> subprocess.CompletedProcess:
    """``python -m rivercal.cli ARGS`` in a process of its own (what the compiled-kernel cache is for)."""
    return subprocess.run([sys.executable, "-m", "rivercal.cli", *args], capture_output=True, text=True)


def test_help_loads_no_numerics() -> None:
    """``rivercal --help`` and ``--version`` build the command tree without numpy or pandas (they are slow to load)."""
    code = ("import sys; from rivercal.cli.main import app; "
            "print(sorted(m for m in ('numpy', 'pandas', 'scipy', 'numba') if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"
    assert "deadline" in rivercal("fews", "--help").stdout  # the module's properties are still listed


def test_case_schema_is_json_schema() -> None:
    run = rivercal("case", "schema")
    assert run.returncode == 0
    schema = json.loads(run.stdout)
    assert {"case", "branches", "weirs", "parameters", "catchments"} <= set(schema["properties"])


def test_compile_fills_the_cache_that_the_next_process_loads(tmp_path: Path) -> None:
    """``rivercal compile`` leaves each variant of the time loop and the rainfall-runoff model in numba's cache: a
    second process compiles nothing, and a run of the default case (whose laterals come from the rainfall-runoff
    model, as the demo's do) that loads the cache says nothing of compiling, also under ``--json``."""
    first = rivercal("compile", "--json")  # fills the cache if it is cold; numba writes it from any process
    assert first.returncode == 0, first.stderr
    second = process("compile", "--json")
    assert second.returncode == 0, second.stderr
    ready = json.loads(second.stdout)
    assert set(ready) == {"plain", "structures", "controlled", "rainfall-runoff"}
    assert all(r["from_cache"] for r in ready.values()), ready
    run = process("simulate", "dommel", "--end", "2010-09-01T06:00", "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["volume_balance_relative_error"] < 1e-6
    assert "compiling" not in run.stderr


def test_simulate_writes_csv_and_cf_netcdf(tmp_path: Path) -> None:
    import xarray as xr

    run = rivercal("simulate", "synthetic", "--end", "2020-01-02T00:00:00Z", "--set", "friction:global=30",
                   "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["parameters"] == {"friction:global": 30.0}
    assert summary["volume_balance_relative_error"] < 1e-9
    ds = xr.open_dataset(tmp_path / "series.nc")
    assert ds.attrs["Conventions"] == "CF-1.8"
    assert ds["water_level"].attrs["units"] == "m" and ds["discharge"].attrs["units"] == "m3 s-1"
    assert ds.sizes["time"] == 25
    csv = (tmp_path / "series.csv").read_text().splitlines()
    assert csv[0].startswith("time,S1.h_up") and len(csv) == 26


@pytest.mark.parametrize(("args", "message"), [
    (["simulate", "no-such-case"], "neither a case folder nor a packaged case"),
    (["simulate", "synthetic", "--set", "weir:W99.crest_level=3"], "no weir 'W99'"),
    (["simulate", "synthetic", "--set", "friction:global=0.03"], "outside the plausible range"),
    (["calibrate", "dommel", "--params", "FA,Wx", "--window", "moderate", "--twin", "FA=20"], "unknown parameter 'Wx'"),
    (["calibrate", "dommel", "--params", "FA", "--window", "moderate", "--twin", "FA=20", "--start", "FA=99"],
     "outside its bounds"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2011-01-01/2011-01-08", "--twin", "FA=20"],
     "outside the case period"),
    # one weir's crest and the shift of all crests set the same quantity
    (["analyse", "dommel", "--params", "FA,W1,Wc", "--window", "moderate"],
     "--params: W1 and Wc both set weir:ZL1-5.crest_level; give only one of them"),
    (["online", "dommel", "--scenario", "PI-Fg", "--params", "Wc,W1", "--from", "2010-11-02", "--to", "2010-11-02"],
     "--params 'Wc,W1': Wc and W1 both set weir:ZL1-5.crest_level; give only one of them"),
    (["twin", "dommel", "--suite", "sensitivity", "--params", "W1,Wc"],
     "--params: W1 and Wc both set weir:ZL1-5.crest_level; give only one of them"),
])
def test_bad_input_exits_2_with_a_message(args: list[str], message: str) -> None:
    run = rivercal(*args)
    assert run.returncode == 2
    assert message in run.stderr and "Traceback" not in run.stderr


@pytest.mark.slow
def test_calibrate_twin_json_and_files(tmp_path: Path) -> None:
    run = rivercal("calibrate", "dommel", "--params", "FA", "--window", "moderate", "--twin", "FA=20",
                   "--start", "FA=14", "--workers", "1", "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert abs(summary["estimates"]["FA"] - 20.0) < 0.01
    assert summary["model_runs"] <= 15 and summary["success"]
    for name in ("history.csv", "evaluations.csv", "convergence.png", "cost.png", "result.json"):
        assert (tmp_path / name).stat().st_size > 0


def test_bench_engine_reports_the_network_and_a_second_call_does_not_compile() -> None:
    """Issue 2: the bench network has >= 400 points, >= 9 weirs and 10 laterals; a second CLI call loads
    every kernel from numba's cache (the first may compile, if nothing ran the engine before)."""
    args = ("bench", "engine", "--days", "0.25", "--repeats", "1", "--json")
    runs = [rivercal(*args), process(*args)]  # the first in this process: it fills the cache if it is cold
    assert all(r.returncode == 0 for r in runs), runs[-1].stderr
    first, second = (json.loads(r.stdout) for r in runs)
    assert first["points"] >= 400 and first["weirs"] >= 9 and first["laterals"] == 10 and first["dt_s"] == 60.0
    assert second["compiled"] is False
    assert 0 < second["wall_s_median"] and 0 < second["compile_s"]


def test_bench_engine_times_from_the_cold_state_or_from_the_spin_up_s() -> None:
    """``--spun-up`` starts the timed runs where every run without a given state begins, after the case's spin-up:
    the synthetic network's first six hours from its cold state divide steps (1.47 solves per step), from the
    spun-up state none (1.0)."""
    cold, spun = (json.loads(rivercal("bench", "engine", "--days", "0.25", "--repeats", "1", *extra, "--json").stdout)
                  for extra in ((), ("--spun-up",)))
    assert (cold["start"], spun["start"]) == ("cold", "spun-up")
    assert cold["solves_per_step"] > 1.2 and spun["solves_per_step"] == 1.0
