"""Exit statuses and messages: bad input (2) is told apart from rivercal's own bugs (1); --version; --debug.

An internal error is injected by replacing a library function the command calls with one that fails
the way a programming error does (a KeyError, a ValueError), in-process on the real app.
"""

from __future__ import annotations

import json
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rivercal.cli.main import app
from rivercal.evaluate import default_workers


def rivercal(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rivercal.cli", *args], capture_output=True, text=True, env=env)


def test_version_and_versions_of_the_numeric_stack() -> None:
    run = rivercal("--version")
    assert run.returncode == 0 and run.stdout.strip() == f"rivercal {version('rivercal')}"
    run = rivercal("--version", "--verbose")
    assert run.returncode == 0
    lines = dict(line.split(" ", 1) for line in run.stdout.strip().splitlines())
    assert lines["rivercal"] == version("rivercal")
    assert lines["numpy"] == version("numpy") and lines["numba"] == version("numba")
    assert lines["python"].startswith(".".join(map(str, sys.version_info[:2])))


@pytest.mark.parametrize(("args", "message"), [
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--start",
      "FA=999"], "--start: the start value 999 of FA lies outside its bounds [8, 40]"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=99"],
     "--twin FA=99: outside the bounds [8, 40] of FA"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--option",
      "max_outer=-1"], "--option: dud refuses its options: max_outer must be an integer >= 0"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--seed",
      "-3"], "--seed -3: must be at least 0"),
    (["simulate", "synthetic", "--set", "weir:W99.crest_level=3"], "--set weir:W99.crest_level=3: no weir 'W99'"),
    # the case's own rule, as case.toml applies it: a crest not below the bed at the weir
    (["simulate", "synthetic", "--set", "weir:W1.crest_level=-100"], "--set weir:W1.crest_level=-100: the crest of "
     "weir 'W1' (-100 m AD) lies below the bed (13.250 m AD at chainage 1500 m of branch 'M'); case.toml refuses the "
     "same value at weirs[0].crest_level"),
    # a Dutch user's 10 November, which pandas reads as October 11
    (["simulate", "synthetic", "--start", "10-11-2010"], "--start '10-11-2010' is ambiguous: day first it is "
     "2010-11-10, month first 2010-10-11; write the date in ISO 8601"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--workers",
      str(default_workers() + 1)], f"--workers {default_workers() + 1}: give 1 to {default_workers()} worker "
     "processes"),
    (["case", "plot", "dommel", "--out", "/proc/x.png"], "--out /proc/x.png: cannot write into /proc"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27T00:00/2010-09-27T00:30", "--twin", "FA=20"],
     "--window '2010-09-27T00:00/2010-09-27T00:30': 2010-09-27 00:30:00 is not one of the model's output times (every "
     "1h from 2010-09-01 00:00)"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--bounds",
      "FA=-50:100"], "--bounds FA=-50:100: parameter FA: its range [-50, 100] m^(1/3)/s reaches outside the model's "
     "bounds (friction:global: value -50 m^(1/3)/s is outside its range [1, 200] m^(1/3)/s)"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--dask",
      f"local:{default_workers() + 1}"], f"--dask local:{default_workers() + 1}: N = {default_workers() + 1}: give 1 "
     f"to {default_workers()} worker processes"),
    (["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20", "--algorithm",
      "lm"], "--algorithm 'lm': it is now called trf (scipy's trust-region reflective method"),
])
def test_bad_values_exit_2_naming_the_option(args: list[str], message: str) -> None:
    run = CliRunner().invoke(app, args)
    assert run.exit_code == 2, run.output
    assert message in run.stderr
    assert "internal error" not in run.stderr and "Traceback" not in run.output


@pytest.mark.parametrize("error", [KeyError(2), ValueError("could not convert string to float: 'x'")])
def test_an_internal_error_exits_1_and_says_so(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                               error: Exception) -> None:
    import rivercal.workflows.simulate as workflow

    def broken(*args, **kwargs):
        raise error

    monkeypatch.setattr(workflow, "simulate_case", broken)
    monkeypatch.delenv("RIVERCAL_DEBUG", raising=False)
    args = ["simulate", "synthetic", "--end", "2020-01-02", "--out", str(tmp_path)]
    run = CliRunner().invoke(app, args)
    assert run.exit_code == 1, run.output
    assert f"internal error: {type(error).__name__}: {error}" in run.stderr
    assert "--debug" in run.stderr and "RIVERCAL_DEBUG=1" in run.stderr
    assert "Traceback" not in run.stderr
    debug = CliRunner().invoke(app, ["--debug", *args])
    assert debug.exit_code == 1
    assert "Traceback (most recent call last)" in debug.stderr and "in broken" in debug.stderr
    monkeypatch.setenv("RIVERCAL_DEBUG", "1")
    env = CliRunner().invoke(app, args)
    assert env.exit_code == 1 and "Traceback (most recent call last)" in env.stderr


def test_a_failed_model_run_exits_3(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from rivercal.engine.simulator import Simulator
    from rivercal.errors import EngineDivergedError

    def diverge(self, *args, **kwargs):
        raise EngineDivergedError("2020-01-01T01:00:00+00:00", "branch B1 at 100 m", "non-finite level")

    monkeypatch.setattr(Simulator, "simulate", diverge)
    run = CliRunner().invoke(app, ["simulate", "synthetic", "--end", "2020-01-02", "--out", str(tmp_path)])
    assert run.exit_code == 3
    assert "model run failed: engine diverged at 2020-01-01T01:00:00+00:00 at branch B1 at 100 m" in run.stderr


def test_the_compile_notice_follows_numba_compilations(capsys: pytest.CaptureFixture) -> None:
    """The notice is numba's compile event for a rivercal kernel: printed at the first compilation of each kind
    (the engine, the rainfall-runoff model, others), once, and naming what is compiled."""
    import numba

    from rivercal.cli import common

    common._COMPILE["shown"] = set()
    common.watch_compilation(True)
    kernels = {}
    for module in ("rivercal.engine.probe", "rivercal.hydrology.probe", "rivercal.probe"):
        def add_one(x):
            return x + 1

        add_one.__module__ = module
        kernels[module] = numba.njit(add_one)  # no cache: compiles on the first call
    for kernel in kernels.values():
        assert kernel(1) == 2
        assert kernel(2.5) == 3.5  # a second signature compiles again: still one notice
    err = capsys.readouterr().err
    assert err.count("compiling the engine's time loop (once per version of rivercal") == 1
    assert err.count("compiling the rainfall-runoff model (") == 1
    assert err.count("compiling rivercal's numerical kernels (") == 1
    assert err.count("compiling") == 3


def test_the_cases_calibration_options_take_words_and_a_bad_one_is_named_with_its_table(tmp_path: Path) -> None:
    from rivercal.case.generate import generate_case

    case = generate_case(tmp_path / "case", 500, dt=300.0).path / "case.toml"
    text = case.read_text(encoding="utf-8")
    assert '[calibration]\nalgorithm = "dud"\n' in text
    args = ["calibrate", str(case.parent), "--params", "F1", "--window", "2020-01-04/2020-01-07", "--twin", "F1=28",
            "--workers", "1", "--json"]
    for word, code in (("secnt", 2), ("secant", 0)):
        case.write_text(text.replace('[calibration]\nalgorithm = "dud"\n', '[calibration]\nalgorithm = "sparse_dud"\n'
                                     f'options = {{final_jacobian = "{word}"}}\n'),
                        encoding="utf-8")
        run = CliRunner().invoke(app, args)
        assert run.exit_code == code, run.output
        if code == 2:  # the message keeps "[calibration]" (console markup once ate it)
            assert ("the case's [calibration] options: sparse_dud refuses its options: final_jacobian must be one of "
                    "'auto', 'fresh', 'secant'; got 'secnt'") in run.stderr
    fit = json.loads(run.stdout)
    assert abs(fit["estimates"]["F1"] - 28.0) < 3 * fit["std"]["F1"] < 1.0  # the twin's noise: within 3 σ


def test_an_empty_file_is_not_a_store(tmp_path: Path) -> None:
    """Not "schema version 0 is older than 6": an empty file never held a run."""
    empty = tmp_path / "run.sqlite"
    empty.write_bytes(b"")
    run = CliRunner().invoke(app, ["report", "--db", str(empty), "--out", str(tmp_path / "report")])
    assert run.exit_code == 2, run.output
    assert f"--db {empty}: an empty file, not a store (no run was ever written to it)" in run.stderr
    from rivercal.store import Store, StoreError

    with pytest.raises(StoreError, match="not a rivercal store: an empty database"):
        Store(empty, readonly=True)
