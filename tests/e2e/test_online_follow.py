"""``rivercal online --follow DIR``: the service waits for observations and runs each cycle when they are in.

The observations are the dommel case's own run (the DSS is the truth, as in scenario PI-0), delivered as
two CSV files: the first reaches the issue time of cycle 0, the second, dropped into the folder while the
service waits, that of cycle 1. A file that is not an observation file is reported and skipped. The
windows are 3 days long (the waiting does not depend on it; half the model time of the default week).
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from rivercal.io import write_observations_csv
from rivercal.model import load_model
from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet

FIRST, LAST = pd.Timestamp("2010-11-08", tz="UTC"), pd.Timestamp("2010-11-09", tz="UTC")


def _observations(start: pd.Timestamp, end: pd.Timestamp) -> ObservationSet:
    model = load_model("dommel")
    result, _ = model.simulate(end=end, output_interval=3600.0)
    frame = result.series.loc[start:end]
    return ObservationSet(tuple(
        ObservationSeries.from_series(frame[c], id=c, sigma=DEFAULT_SIGMA[c.rpartition(".")[2]], source="gauge")
        for c in frame.columns))


def _done(db: Path) -> int:
    if not db.is_file():
        return 0
    with sqlite3.connect(db) as conn:
        try:
            return conn.execute("select count(*) from cycles where status = 'done'").fetchone()[0]
        except sqlite3.OperationalError:  # the schema is not there yet
            return 0


@pytest.mark.slow
def test_follow_runs_each_cycle_when_its_data_arrive(tmp_path: Path) -> None:
    inbox, db = tmp_path / "inbox", tmp_path / "run.sqlite"
    inbox.mkdir()
    obs = _observations(FIRST - pd.Timedelta("8D"), LAST)
    frame = obs.to_frame()
    part1 = ObservationSet(tuple(
        ObservationSeries.from_series(frame.loc[:FIRST, c], id=c, sigma=s.sigma, source="gauge")
        for c, s in zip(frame, obs, strict=True)))
    write_observations_csv(part1, inbox / "part1.csv")
    (inbox / "notes.csv").write_text("this is not an observation file\n", encoding="utf-8")
    proc = subprocess.Popen(
        [sys.executable, "-m", "rivercal.cli", "online", "dommel", "--from", str(FIRST.date()), "--to",
         str(LAST.date()), "--window", "3D", "--assimilate", "parameters", "--db", str(db), "--follow", str(inbox),
         "--poll", "0.5", "--workers", "2",
         "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 240
        while _done(db) < 1 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.5)
        assert _done(db) == 1 and proc.poll() is None  # cycle 0 ran; cycle 1 waits for its data
        time.sleep(2.0)
        assert _done(db) == 1
        write_observations_csv(obs, inbox / "part2.csv")
        out, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    summary = json.loads(out)
    assert summary["cycles"] == 2 and summary["status"] == {"done": 2}
    assert "skipped notes.csv" in err.replace("\n", " ")
    for e in summary["estimates"]:  # the truth is the DSS: nothing changes
        assert e["FA"] == pytest.approx(16.0, abs=0.05) and e["Wd"] == pytest.approx(0.0, abs=0.002)
