"""The command line on a model.toml: the packaged SWMM case dommel-swmm wherever a CASE is taken.

The on-line replay is the acceptance run: three daily cycles of scenario PI-Wg (the nine adjustable
crests drop 15 cm on 2010-11-01, thesis §5-2-1) on EPA SWMM, every cycle after the first hot-started from
the SWMM hotstart file the previous cycle stored in the run's store. It takes the packaged case's model.toml
with a later start (:func:`_dommel_swmm_from`): the same network, .inp and parameters.
"""

from __future__ import annotations

import json
import sqlite3
from importlib import resources
from pathlib import Path

import pandas as pd
import pytest

from tests.cli import rivercal


def test_model_schema_and_check() -> None:
    run = rivercal("model", "schema")
    assert run.returncode == 0
    assert {"model", "blackbox", "swmm", "bmi", "parameters"} <= set(json.loads(run.stdout)["properties"])
    run = rivercal("model", "check", "dommel-swmm", "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["kind"] == "SwmmModel" and summary["dt_s"] == 30.0 and "FR" in summary["parameters"]
    run = rivercal("case", "plot", "dommel-swmm", "--out", "x.png")
    assert run.returncode == 2 and "draws a case's network" in run.stderr


def test_a_bad_model_toml_names_file_and_field(tmp_path) -> None:
    (tmp_path / "model.toml").write_text('[model]\nname = "x"\nkind = "swmm"\nstart = "2020-01-01"\n'
                                         'end = "2020-01-02"\n\n[swmm]\ninp = "none.inp"\n'
                                         'stations = { "a.h" = "node:J1" }\n')
    run = rivercal("simulate", str(tmp_path / "model.toml"))
    assert run.returncode == 2
    assert "model.toml: swmm.inp: no such file" in run.stderr


@pytest.mark.slow
def test_simulate_and_calibrate_a_swmm_twin(tmp_path) -> None:
    run = rivercal("simulate", "dommel-swmm", "--end", "2010-09-21T00:00:00Z", "--set", "roughness:factor=1.2",
                   "--out", str(tmp_path / "sim"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["case"] == "dommel-swmm" and summary["volume_balance_relative_error"] is None
    assert pd.read_csv(tmp_path / "sim" / "series.csv").shape == (25, 12)
    run = rivercal("calibrate", "dommel-swmm", "--params", "FR,Wd", "--window", "2010-09-28/2010-09-29",
                   "--twin", "FR=1.0,Wd=-0.05", "--start", "FR=1.3,Wd=0.15", "--workers", "1",
                   "--out", str(tmp_path / "cal"), "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    assert abs(result["estimates"]["FR"] - 1.0) < 0.01 and abs(result["estimates"]["Wd"] + 0.05) < 0.001


def _dommel_swmm_from(start: str, folder: Path) -> Path:
    """The packaged dommel-swmm's model.toml with its period starting at ``start`` (on its .inp; no window before).

    A cold start (the twin's truth, the first cycle's model and the DSS) then spins SWMM up from ``start`` instead
    of from 20 September: days instead of six weeks of routing before the replay.
    """
    packaged = Path(str(resources.files("rivercal.cases") / "dommel-swmm"))
    inp = packaged / "dommel.inp"
    text, *windows = (packaged / "model.toml").read_text(encoding="utf-8").split("[[windows]]")
    for old, new in (('start = "2010-09-20T00:00:00+00:00"', f'start = "{start}"'),
                     ('inp = "dommel.inp"', f'inp = "{inp.as_posix()}"')):
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    later = [w for w in windows if 'name = "moderate"' not in w]  # the week ending 4 October
    assert len(later) == len(windows) - 1
    folder.mkdir()
    (folder / "model.toml").write_text("[[windows]]".join([text, *later]), encoding="utf-8")
    return folder / "model.toml"


@pytest.mark.slow
def test_online_replays_daily_cycles_on_swmm_from_hotstart_files(tmp_path) -> None:
    """Three daily cycles: the first cold, its window before the crests drop; the others hot from the last one.

    On dommel-swmm with its period starting on 30 October (the cold starts spin up from there; measured: the
    estimates of every cycle are those of the packaged case's period, to the last digit).
    """
    db = tmp_path / "run.sqlite"
    case = _dommel_swmm_from("2010-10-30T00:00:00+00:00", tmp_path / "case")
    run = rivercal("online", str(case), "--scenario", "PI-Wg", "--params", "FR,Wd", "--from", "2010-11-01",
                   "--to", "2010-11-03", "--window", "1D", "--warmup", "12h", "--horizon", "12h", "--workers", "1",
                   "--no-transition", "--assimilate", "parameters", "--db", str(db), "--out", str(tmp_path / "report"),
                   "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles"] == 3 and summary["status"] == {"done": 3} and summary["case"] == "dommel-swmm"
    wd = {e["issue_time"][:10]: e["Wd"] for e in summary["estimates"]}
    assert abs(wd["2010-11-01"]) < 0.005  # its one-day window ends as the crests drop
    # its window after the drop, hot-started from a state that was itself hot-started (a hand-over of a hand-over)
    assert abs(wd["2010-11-03"] + 0.15) < 0.005
    # a one-day window never holds the change inside it, so the transition estimator cannot date it; without
    # it (--no-transition) the jump of the one-value estimate alerts
    assert any(a["kind"] == "jump" and a["parameter"] == "Wd" for a in summary["alerts"])
    with sqlite3.connect(db) as con:
        messages = [m for (m,) in con.execute("SELECT message FROM cycles ORDER BY cycle")]
        formats = {f for (f,) in con.execute("SELECT format FROM model_states")}
    assert "cold start" in messages[0] and not any("cold start" in m for m in messages[1:])  # hot from cycle 1 on
    assert formats == {"rivercal-swmm-hotstart-1"}
    assert Path(summary["files"]["report"]).is_file()


@pytest.mark.slow
def test_analyse_and_a_thesis_twin_suite_run_on_swmm(tmp_path) -> None:
    run = rivercal("analyse", "dommel-swmm", "--params", "FR,Wd", "--what", "sensitivity", "--window",
                   "2010-09-28/2010-09-29", "--workers", "1", "--out", str(tmp_path / "an"), "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    ranking = json.loads(run.stdout)["sensitivity"]["ranking"]
    assert [r["parameter"] for r in ranking] == ["Wd", "FR"]  # the crests move the levels more than the roughness
    run = rivercal("twin", "dommel-swmm", "--suite", "F0W1", "--scenarios", "H1", "--window", "2010-09-28/2010-09-29",
                   "--workers", "1", "--out", str(tmp_path / "twin"), "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    suite = json.loads(run.stdout)["suites"]["F0W1"]
    assert suite["succeeded"] == 1 and suite["max_abs_error"]["W2"] < 1e-3
