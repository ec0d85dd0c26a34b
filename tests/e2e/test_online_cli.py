"""``rivercal online`` and ``rivercal report`` on the dommel case: a short PI-Fg run end to end.

The run starts after the global friction of the truth changed 16 → 25 m^(1/3)/s (thesis §5-2-1), with
the DSS at 16: the estimate must find 25 and its forecasts must beat the DSS's at the stations.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from tests.cli import rivercal
from tests.run_artefacts import PIFG_REPLAY, dommel_dependency_map, pifg_replay

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def pifg() -> tuple[Path, dict]:
    """The replay (:data:`tests.run_artefacts.PIFG_REPLAY`), run once in the test run: the store, report and summary
    that ``tests/e2e/test_online_one_set_of_numbers.py`` reads too."""
    return pifg_replay()


def test_online_finds_the_new_friction_and_beats_the_dss(pifg) -> None:
    _, summary = pifg
    assert summary["cycles"] == 2 and summary["status"] == {"done": 2}
    for e in summary["estimates"]:
        assert e["FA"] == pytest.approx(25.0, rel=0.02) and e["Wd"] == pytest.approx(0.0, abs=0.005)
        assert e["held"] == []
    # the first cycle starts from the DSS's values and has no earlier estimate to jump from; the window
    # holds no change (it starts after the mowing), so there is nothing to alert
    assert summary["alerts"] == []
    fe = summary["forecast_errors"]
    assert fe["n"] > 0 and fe["ratio"] > 5 and fe["dss_mae_m"] > 0.02


def test_the_report_holds_the_tables_and_figures(pifg) -> None:
    folder, summary = pifg
    files = summary["files"]
    html = Path(files["report"]).read_text(encoding="utf-8")
    assert "Tables 5-1" in html and "Fig. 5-4" in html and "PI-Fg" in html
    for kind in ("estimates_figure", "scores_figure", "weir_figure", "error_map_after", "error_time_figure",
                 "estimates_csv", "forecasts_csv", "netcdf"):
        assert Path(files[kind]).is_file(), kind
        if kind.endswith("figure") or kind.startswith("error_map"):
            assert Path(files[kind]).name in html
    table = pd.read_csv(folder / "report" / "parameters.csv", index_col="parameter")
    assert table.loc["FA", "true after"] == 25.0 and table.loc["FA", "DSS"] == 16.0
    assert table.loc["FA", "rivercal after"] == pytest.approx(25.0, rel=0.02)
    assert table.loc["W4", "rivercal after"] == pytest.approx(7.145, abs=0.005)  # Wd ≈ 0: crests stay


def test_report_command_rewrites_from_the_store_alone(pifg, tmp_path: Path) -> None:
    folder, _ = pifg
    run = rivercal("report", "--db", str(folder / "run.sqlite"), "--out", str(tmp_path), "--json")
    assert run.returncode == 0, run.stderr
    assert Path(json.loads(run.stdout)["files"]["report"]).is_file()


def test_restart_with_the_same_arguments_computes_nothing_again(pifg, tmp_path: Path) -> None:
    folder, _ = pifg_replay(tmp_path / "replay")  # a copy: the shared store stays as the replay left it
    run = rivercal(*PIFG_REPLAY, "--db", str(folder / "run.sqlite"))
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["cycles_done_now"] == 0 and summary["cycles"] == 2


@pytest.mark.parametrize(("args", "message"), [
    (["--scenario", "PI-X"], "--scenario 'PI-X': unknown practical scenario"),
    (["--scenario", "PI-Fg", "--to", "2010-11-01"], "--to 2010-11-01: before --from"),
    (["--params", "FA,Zz"], "unknown parameter 'Zz'"),
    (["--max-change", "FA"], "--max-change 'FA': expected NAME=VALUE"),
    (["--observations", "nothing.csv"], "--observations nothing.csv: no such file"),
])
def test_bad_input_exits_2_and_names_the_problem(tmp_path: Path, args: list[str], message: str) -> None:
    base = {"--from": "2010-11-09", "--to": "2010-11-10"}
    for flag, value in zip(args[::2], args[1::2], strict=True):
        base[flag] = value
    argv = [x for kv in base.items() for x in kv]
    run = rivercal("online", "dommel", *argv, "--db", str(tmp_path / "x.sqlite"))
    assert run.returncode == 2, run.stderr
    assert message in run.stderr and "Traceback" not in run.stderr


def test_realistic_crest_lowering_is_dated_once_and_its_value_taken(tmp_path: Path) -> None:
    """PI-Wg under realistic errors: the cycle two days after the change dates it and takes −0.15 m, one alert."""
    run = rivercal("online", "dommel", "--scenario", "PI-Wg", "--realism", "realistic", "--from", "2010-11-01",
                   "--to", "2010-11-03", "--db", str(tmp_path / "run.sqlite"), "--workers", "2", "--assimilate",
                   "parameters", "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["realism"] == "realistic" and summary["status"] == {"done": 3}
    jumps = [a for a in summary["alerts"] if a["kind"] == "jump"]
    assert [a["parameter"] for a in jumps] == ["Wd"]
    assert "at about 2010-10-31 2" in jumps[0]["message"] or "at about 2010-11-01 0" in jumps[0]["message"]
    last = summary["estimates"][-1]
    assert last["Wd"] == pytest.approx(-0.15, abs=0.01) and summary["time_to_correct_cycles"] == 2
    # the twin's spikes were flagged at ingestion and kept
    assert summary["observations_flagged"].get("outlier", 0) > 0 and summary["observations_flagged"]["ok"] > 1000
    # the first cycle had nothing scored and issued the DSS's forecast; none fell back since
    assert summary["unscored_cycles"] == 1 and summary["fallbacks"] == 0


def test_sparse_dud_with_the_dependency_map_of_analyse_finds_the_local_friction(tmp_path: Path) -> None:
    """PI-Fl (the friction of one reach 16 → 25 m^(1/3)/s): Sparse DuD on the map ``rivercal analyse`` measured.

    The map is this run's one measurement (:func:`tests.run_artefacts.dommel_dependency_map`: the same command
    that ``tests/unit/test_analysis_cli.py`` calibrates with), made by whichever of the two asks first."""
    dependency = dommel_dependency_map()
    run = rivercal("online", "dommel", "--scenario", "PI-Fl", "--from", "2010-11-09", "--to", "2010-11-09",
                   "--window", "3D", "--params", "FA,F1,FL,W2", "--algorithm", "sparse_dud", "--dependency",
                   str(dependency), "--db", str(tmp_path / "run.sqlite"), "--workers", "2", "--assimilate",
                   "parameters", "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["status"] == {"done": 1}
    last = summary["estimates"][-1]
    assert last["FL"] == pytest.approx(25.0, abs=0.5) and last["FA"] == pytest.approx(16.0, abs=0.5)


def test_a_dependency_map_is_checked_before_any_run(tmp_path: Path) -> None:
    good = tmp_path / "dependency.csv"
    good.write_text("series,W2\n0028.h_up,1.0\n", encoding="utf-8")
    bad = tmp_path / "bad.csv"
    bad.write_text("station,FA\n0028.h_up,1.0\n", encoding="utf-8")
    base = ["online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-09", "--to", "2010-11-10",
            "--db", str(tmp_path / "x.sqlite")]
    for args, message in ((["--dependency", str(good)], "serves the algorithm sparse_dud only, not dud"),
                          (["--algorithm", "sparse_dud", "--dependency", str(bad)], f"{bad}: a dependency map has"),
                          (["--algorithm", "sparse_dud", "--dependency", str(good), "--params", "FA"],
                           "names none of the parameters estimated (FA); it names W2")):
        run = rivercal(*base, *args)
        assert run.returncode == 2, run.stderr
        assert message in run.stderr and "Traceback" not in run.stderr
