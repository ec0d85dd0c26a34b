"""Sidecars on the command line: calibrate and online take gauge files as delivered; a bad one is named."""

from __future__ import annotations

import json
from pathlib import Path

from rivercal.bench.westerscheldt import case_folder
from tests.cli import rivercal


def test_calibrate_reads_the_matroos_exports_through_their_sidecar(tmp_path: Path) -> None:
    run = rivercal("calibrate", "westerscheldt", "--params", "KS", "--window", "calm", "--observations",
                   str(case_folder() / "gauges.toml"), "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    # four gauges, every 10 minutes from 02:00 to 15:00: 79 readings each
    assert result["observations"] == {"series": 4, "values": 316, "missing_dropped": 0}
    assert 40.0 < result["estimates"]["KS"] < 60.0 and result["std"]["KS"] < 3.0


def test_online_ingests_the_sidecars_series_at_their_ten_minute_stamps(tmp_path: Path) -> None:
    run = rivercal("online", "westerscheldt", "--observations", str(case_folder() / "assimilate.toml"), "--params",
                   "KS", "--assimilate", "states", "--members", "4", "--cycle", "1h", "--horizon", "6h", "--window",
                   "6h", "--warmup", "6h", "--from", "2013-12-05T12:00", "--to", "2013-12-05T13:00", "--skill-cycles",
                   "0", "--db", str(tmp_path / "run.sqlite"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["status"] == {"done": 2}
    assert summary["observations_flagged"] == {"ok": 3 * 289}   # all three gauges, every reading stored
    # the 10-minute readings are scored against the forecasts at their times
    assert summary["forecast_mae_by_lead"]["updated"]["0-6h"] is not None and summary["forecast_errors"]["n"] > 0
    # Bath, a station of the case, is never observed: named once, not a data alert every cycle
    data = [a for a in summary["alerts"] if a["kind"] == "data"]
    assert len(data) == 1 and "bath.h" in data[0]["message"]


def test_a_depth_series_without_its_sensor_zero_is_refused_naming_option_file_and_line(tmp_path: Path) -> None:
    (tmp_path / "p.csv").write_text("time,depth\n2013-12-05T02:00Z,120\n", encoding="utf-8")
    side = tmp_path / "p.toml"
    side.write_text('[[series]]\nid = "bath.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "depth"\nunit = "cm"\n'
                    'measures = "depth"\n', encoding="utf-8")
    run = rivercal("calibrate", "westerscheldt", "--params", "KS", "--window", "calm", "--observations", str(side),
                   "--out", str(tmp_path / "out"))
    assert run.returncode == 2, run.stdout
    message = " ".join(run.stderr.split())
    assert f"--observations {side}: series[0].measures: line 7:" in message and "datum_offset" in message
