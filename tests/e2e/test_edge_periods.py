"""Edge periods on the dommel case (2010-09-01 … 2010-12-01): short replays, single cycles, case start and end.

- the replay of 2010-11-02 … 2010-11-03 on 3-day windows (two cycles, neither of whose windows has left the change of
  2010-11-01) ends with exit 0, a summary that says why no forecast of a window past the change could
  be compared yet (and gives the errors of the cycles issued after the change), and a report;
- a single cycle on observations that end at its issue time: its forecasts cannot be scored, and the
  summary says that the observations end before the forecasts' first lead time;
- the earliest first cycle (its window and warm-up start exactly at the case start) runs; an hour
  earlier is refused naming --from;
- a replay whose last forecast ends at the case end runs; a cycle whose forecast would run past the end
  (the forcing ends there) is refused naming --horizon, and a cycle issued after the end naming --to;
- a calibration window whose runs start exactly at the case start runs and finds the twin truth; one
  whose warm-up would start before the case is refused naming --window.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import pytest

from tests.cli import rivercal

pytestmark = pytest.mark.slow


def test_a_replay_before_the_change_left_the_window(tmp_path: Path) -> None:
    db, out = tmp_path / "run.sqlite", tmp_path / "x"
    args = ("online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-02", "--to", "2010-11-03", "--window", "3D",
            "--params", "FA", "--no-transition", "--assimilate", "parameters", "--db", str(db), "--out", str(out),
            "--workers", "2")
    run = rivercal(*args, "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles"] == 2 and summary["status"] == {"done": 2}
    fe = summary["forecast_errors"]
    assert fe["n"] == 0 and fe["updated_mae_m"] is None
    assert "starts at or after the change at 2010-11-01 00:00" in fe["reason"]
    assert "the first such cycle is issued at 2010-11-04 00:00" in fe["reason"]
    page = html.unescape((out / "index.html").read_text(encoding="utf-8"))
    # the report gives the headline's figure, over the cycles issued after the change, and says so
    covers = "forecasts issued by cycles 0–1 (the cycles issued after the change at 2010-11-01 00:00)"
    assert covers in " ".join(page.split()) and "nothing to compare yet" not in page
    assert "'rivercal after' is empty" in page
    # the change leaves a window only at 2010-11-04, after the replay: no figure to show, and no "nan" either
    assert "What the stations see of the change: not yet measurable here" in page and "nan cm" not in page
    again = rivercal(*args)  # the same command resumes: nothing left to run, the summary is printed
    assert again.returncode == 0, again.stderr
    # the headline counts the cycles issued after the change, whose windows still hold it
    assert covers in " ".join(again.stdout.split())
    assert summary["forecast_values"] > 0 and summary["forecast_mae_ratio"] > 1 and "report:" in again.stdout


def test_a_single_cycle_on_observations_that_end_at_its_issue_time(tmp_path: Path) -> None:
    # a 2-day window (the default is a week): what is checked is where the observations end, not the window
    sim = rivercal("simulate", "dommel", "--start", "2010-11-01", "--end", "2010-11-10", "--out", str(tmp_path / "o"))
    assert sim.returncode == 0, sim.stderr
    run = rivercal("online", "dommel", "--observations", str(tmp_path / "o" / "series.csv"), "--from", "2010-11-10",
                   "--to", "2010-11-10", "--window", "2D", "--db", str(tmp_path / "run.sqlite"), "--out",
                   str(tmp_path / "r"), "--workers", "2", "--assimilate", "parameters", "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles"] == 1 and summary["status"] == {"done": 1}
    assert summary["forecast_errors"]["reason"] == ("the observations end at 2010-11-10 00:00, before the forecasts' "
                                                    "first lead time (2010-11-10 01:00)")
    assert (tmp_path / "r" / "index.html").is_file()


def test_the_first_window_touching_the_case_start(tmp_path: Path) -> None:
    # a 2-day window and the 24 h warm-up: issued on 4 September, the first run starts at the case start
    run = rivercal("online", "dommel", "--scenario", "PI-0", "--from", "2010-09-04", "--to", "2010-09-04", "--window",
                   "2D", "--db", str(tmp_path / "run.sqlite"), "--workers", "2", "--assimilate", "parameters", "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles"] == 1 and summary["status"] == {"done": 1}
    early = rivercal("online", "dommel", "--scenario", "PI-0", "--from", "2010-09-03T23:00", "--to", "2010-09-04",
                     "--window", "2D", "--db", str(tmp_path / "early.sqlite"))
    assert early.returncode == 2
    assert "--from 2010-09-03T23:00" in early.stderr and "issue the first cycle at 2010-09-04 00:00 or later" in \
        early.stderr


def test_a_replay_whose_last_forecast_ends_at_the_case_end(tmp_path: Path) -> None:
    run = rivercal("online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-29", "--to", "2010-11-29", "--window",
                   "3D", "--db", str(tmp_path / "run.sqlite"), "--out", str(tmp_path / "r"), "--workers", "2",
                   "--assimilate", "parameters", "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles"] == 1 and summary["status"] == {"done": 1}
    assert summary["forecast_errors"]["n"] > 0  # its forecast, to the case end, is observed
    assert [round(e["FA"]) for e in summary["estimates"]] == [25]
    # the report of that run says the same: the forecast to the case end, scored on the same values
    page = " ".join((tmp_path / "r" / "index.html").read_text().split())
    n, dss = summary["forecast_errors"]["n"], summary["forecast_errors"]["dss_mae_m"]
    assert f"n = {n} values" in page and f"the fixed DSS {100 * dss:.2f} cm" in page
    # a cycle issued at the case's end would forecast 48 h on forcing the case does not have: refused
    last = rivercal("online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-30", "--to", "2010-12-01", "--db",
                    str(tmp_path / "last.sqlite"))
    assert last.returncode == 2
    assert ("--horizon 48h: the last cycle, issued at 2010-12-01 00:00, would forecast to 2010-12-03 00:00, after the "
            "end of the case (2010-12-01 00:00), where its forcing ends; issue every cycle (--from and --to) at "
            "2010-11-29 00:00 or earlier") in " ".join(last.stderr.split())
    late = rivercal("online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-28", "--to", "2010-12-01T01:00",
                    "--db", str(tmp_path / "late.sqlite"))
    assert late.returncode == 2 and "--to 2010-12-01T01:00: after the end of the case" in late.stderr


def test_a_calibration_window_whose_runs_start_at_the_case_start(tmp_path: Path) -> None:
    run = rivercal("calibrate", "dommel", "--params", "FA", "--window", "2010-09-02/2010-09-03", "--twin", "FA=20",
                   "--workers", "2", "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["estimates"]["FA"] == pytest.approx(20.0, abs=0.01)
    early = rivercal("calibrate", "dommel", "--params", "FA", "--window", "2010-09-01/2010-09-03", "--twin", "FA=20",
                     "--out", str(tmp_path))
    assert early.returncode == 2
    assert "--window '2010-09-01/2010-09-03': the runs start 24 h (--warmup) before the window" in early.stderr
