"""Checks that need another process: a fresh interpreter's imports, CSDMS's bmi-tester, worker processes.

Each was part of a unit file whose other tests run in the test's own process (tests/unit runs no process);
the unit files say where these went.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.analysis import fd_jacobian, sensitivity
from tests.unit.test_analysis_identifiability import linear_problem, random_a


def _fresh_interpreter(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)


def test_import_rivercal_loads_no_engine() -> None:
    """``import rivercal`` stays light: the heavy libraries load with the names that need them (test_api.py)."""
    run = _fresh_interpreter("import sys, rivercal; heavy = [m for m in ('numba', 'pandas', 'matplotlib', "
                             "'sqlite3', 'scipy') if m in sys.modules]; print(','.join(heavy) or 'none')")
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "none"


def test_import_rivercal_does_not_load_sqlite3() -> None:
    """Reading observations and files never loads the store's SQLite (test_store_schema.py)."""
    run = _fresh_interpreter("import sys, rivercal, rivercal.io, rivercal.observations; "
                             "bad = [m for m in ('sqlite3', '_sqlite3', 'rivercal.store') if m in sys.modules]; "
                             "assert not bad, bad")
    assert run.returncode == 0, run.stderr


def test_the_csdms_bmi_tester_passes(tmp_path: Path) -> None:
    """CSDMS's bmi-tester (its own command) passes the embedded engine as a BMI component (test_bmi.py)."""
    start, end = pd.Timestamp("2020-01-02", tz="UTC"), pd.Timestamp("2020-01-04", tz="UTC")
    config = tmp_path / "engine.toml"
    config.write_text(f'case = "synthetic"\nstart = "{start.isoformat()}"\nend = "{end.isoformat()}"\n')
    run = subprocess.run([str(Path(sys.executable).with_name("bmi-test")), "rivercal.models.bmi.engine:RivercalBmi",
                          "--root-dir", str(config.parent), "--config-file", config.name],
                         capture_output=True, text=True, cwd=config.parent, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert " passed" in run.stdout and " failed" not in run.stdout


def test_parallel_jacobian_equals_the_serial_one() -> None:
    """Two worker processes give the serial finite-difference Jacobian bit for bit (test_analysis_identifiability)."""
    problem = linear_problem(random_a())
    serial = fd_jacobian(problem, workers=1)
    parallel = fd_jacobian(problem, workers=2)
    np.testing.assert_array_equal(serial.matrix, parallel.matrix)


def test_parallel_sensitivity_equals_the_serial_one() -> None:
    """The sensitivity scenarios on two worker processes cost what they cost serially (test_analysis_sensitivity)."""
    problem = linear_problem(random_a(seed=9, m=40, p=2))
    serial = sensitivity(problem, workers=1)
    parallel = sensitivity(problem, workers=2)
    np.testing.assert_array_equal(serial.frame["cost"], parallel.frame["cost"])
