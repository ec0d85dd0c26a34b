"""``rivercal online`` refuses nonsense before it stores or issues anything, and says when no cycle succeeded.

The observations are the dommel case's own run (the DSS is the truth, as in scenario PI-0) written as the
CSV a gauge network delivers; the nonsense is made from them: the levels in cm, the station ids of
another network, a forecast horizon past the case's end, windows that no cycle's observations reach.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pandas as pd
import pytest

from rivercal.io import write_observations_csv
from rivercal.model import load_model
from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet
from tests.cli import rivercal

START, END = pd.Timestamp("2010-10-25", tz="UTC"), pd.Timestamp("2010-11-08", tz="UTC")


@pytest.fixture(scope="module")
def delivered(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """good.csv (levels in m AD, discharge in m³/s), cm.csv (the levels × 100), other.csv (unknown station ids)."""
    folder = tmp_path_factory.mktemp("gauges")
    result, _ = load_model("dommel").simulate(end=END, output_interval=3600.0)
    frame = result.series.loc[START:END]

    def write(name: str, scale, rename=lambda c: c) -> Path:
        obs = ObservationSet(tuple(ObservationSeries.from_series(
            frame[c] * scale(c), id=rename(c), sigma=DEFAULT_SIGMA[c.rpartition(".")[2]]) for c in frame.columns))
        return write_observations_csv(obs, folder / name)

    return {"good": write("good.csv", lambda c: 1.0),
            "cm": write("cm.csv", lambda c: 1.0 if c.endswith(".Q") else 100.0),
            "other": write("other.csv", lambda c: 1.0, lambda c: "NL" + c)}


def _online(db: Path, observations: Path, *extra: str):
    return rivercal("online", "dommel", "--observations", str(observations), "--db", str(db), "--workers", "1",
                    "--assimilate", "parameters",
                    "--quiet", *extra)


def _runs(db: Path) -> int:
    if not db.exists():
        return 0
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT count(*) FROM sqlite_master WHERE name = 'runs'").fetchone()[0] and \
            conn.execute("SELECT count(*) FROM runs").fetchone()[0]


def test_levels_in_cm_are_refused_before_anything_is_stored(delivered, tmp_path: Path) -> None:
    db = tmp_path / "run.sqlite"
    run = _online(db, delivered["cm"], "--from", "2010-11-05", "--to", "2010-11-06")
    assert run.returncode == 2, run.stderr
    assert "cm.csv: column '0028.h_up': 265 of 265 values lie outside the plausible range" in run.stderr
    assert "from 2010-10-28 00:00 to 2010-11-08 00:00, the period the model ran" in run.stderr  # the values judged
    assert "they look like cm (100 times the model's 10.56 m AD): give levels in m" in run.stderr
    assert _runs(db) == 0


def test_unknown_station_ids_are_refused_naming_the_known_ones(delivered, tmp_path: Path) -> None:
    db = tmp_path / "run.sqlite"
    run = _online(db, delivered["other"], "--from", "2010-11-05", "--to", "2010-11-06")
    assert run.returncode == 2, run.stderr
    assert ("other.csv: column 'NL0028.h_up': station 'NL0028' is not in model 'dommel'; its stations are 0028, "
            "0029, 0030, 0031, 0040") in run.stderr.replace("\n", " ")
    assert _runs(db) == 0


def test_a_horizon_past_the_cases_end_is_refused_with_the_allowed_range(delivered, tmp_path: Path) -> None:
    run = _online(tmp_path / "run.sqlite", delivered["good"], "--from", "2010-11-05", "--to", "2010-11-06",
                  "--horizon", "1000D")
    assert run.returncode == 2, run.stderr
    assert ("--horizon 1000D: the last cycle, issued at 2010-11-06 00:00, would forecast to 2013-08-02 00:00, after "
            "the end of the case (2010-12-01 00:00), where its forcing ends; the horizon can be 1h to 25D") in \
        run.stderr.replace("\n", " ")


def test_when_no_cycle_succeeds_it_says_so_and_exits_non_zero(delivered, tmp_path: Path) -> None:
    """The observations end on 2010-11-08; the windows of cycles issued on 11-20 and 11-21 hold none of them."""
    db = tmp_path / "run.sqlite"
    run = _online(db, delivered["good"], "--from", "2010-11-20", "--to", "2010-11-21")
    assert run.returncode == 1, run.stderr
    text = run.stderr.replace("\n", " ")
    assert "error: no cycle succeeded: the cycles run now all ended without an estimate (2 failed)" in text
    assert "no observations in the window 2010-11-13" in text and "internal error" not in text
    with sqlite3.connect(db) as conn:  # the failed cycles are stored, with the last accepted estimates kept
        assert conn.execute("SELECT status FROM cycles ORDER BY cycle").fetchall() == [("failed",), ("failed",)]
