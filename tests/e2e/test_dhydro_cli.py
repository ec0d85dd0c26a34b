"""``rivercal import dhydro`` and ``rivercal export dhydro`` as a user runs them, and the round trip of dommel."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.model import load_model
from tests.cli import rivercal
from tests.dhydro_models import write_model
from tests.run_artefacts import dellen as shared_dellen
from tests.run_artefacts import dellen_summary
from tests.shared_data import shared_model


@pytest.fixture(scope="module")
def dellen(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """``rivercal import dhydro`` of Dellen with its real-time forcing, as a user runs it: the case and the summary.

    One import serves the summary's test and the commands run on the model as imported: the test run's one
    (:func:`tests.run_artefacts.dellen`, the same command, made once for every module that starts from Dellen);
    this module works on a copy of its case."""
    return shared_dellen(tmp_path_factory.mktemp("dellen") / "case"), dellen_summary()


def test_import_prints_the_summary_as_json(dellen) -> None:
    case, summary = dellen
    assert set(summary) == {"branches", "points", "profiles", "structures", "boundaries", "laterals", "stations",
                            "approximated", "refused", "parameters"}
    assert (summary["branches"], summary["points"], summary["laterals"]) == (171, 653, 143)
    assert summary["structures"] == {"weir": 19, "culvert": 147, "pump": 2, "bridge": 7}
    assert summary["refused"] == 0
    assert (case / "import.md").is_file()


def test_a_refusal_is_an_error_naming_the_objects_and_the_way_out(tmp_path: Path) -> None:
    mdu = write_model(tmp_path / "model")
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "lateral 'lat_node'" in run.stderr and "--allow-partial" in run.stderr and "import.md" in run.stderr
    assert "no case was written" in run.stderr
    # only the report: no case folder that would run without the refused objects
    assert sorted(p.name for p in (tmp_path / "case").iterdir()) == ["import.md"]
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"), "--allow-partial")
    assert run.returncode == 0, run.stderr
    assert "refused" in run.stdout


def test_a_file_that_is_not_a_model_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "model.mdu"
    bad.write_text("[geometry]\nNetFile = missing_net.nc\n", encoding="utf-8")
    run = rivercal("import", "dhydro", str(bad), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "model.mdu" in run.stderr


@pytest.mark.slow
def test_import_of_the_export_of_dommel_reproduces_its_series(tmp_path: Path) -> None:
    run = rivercal("export", "dhydro", "dommel", "--out", str(tmp_path / "model"), "--json")
    assert run.returncode == 0, run.stderr
    mdu = json.loads(run.stdout)["mdu"]
    run = rivercal("import", "dhydro", mdu, "--out", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["refused"] == 0
    original, again = load_model("dommel"), load_model(tmp_path / "case")
    a, _ = original.simulate()
    b, _ = again.simulate()
    b_series = b.series.loc[a.series.index]  # the export starts the spin-up earlier
    compared = 0
    for st in original.case.network.stations:
        for q in st.quantities or ["h_up", "h_down"]:
            np.testing.assert_allclose(b_series[f"{st.structure}.{q}"].to_numpy(), a.series[f"{st.id}.{q}"].to_numpy(),
                                       rtol=0, atol=1e-9)
            compared += 1
    assert compared == 11


def test_the_export_of_a_packaged_case_imports_again(tmp_path: Path) -> None:
    """An export with one observation cross-section (synthetic's S6) once failed to import: hydrolib-core does not
    take a file with a single [ObservationCrossSection] block, so the import reads such a file block by block."""
    run = rivercal("export", "dhydro", "synthetic", "--out", str(tmp_path / "model"), "--json")
    assert run.returncode == 0, run.stderr
    run = rivercal("import", "dhydro", json.loads(run.stdout)["mdu"], "--out", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["refused"] == 0
    stations = {s.id: s for s in load_model(tmp_path / "case").case.network.stations}
    assert stations["S6"].quantities == ["h", "Q"]  # an observation point and a cross-section of one name


@pytest.mark.slow
def test_the_export_of_the_controlled_case_imports_again(tmp_path: Path) -> None:
    run = rivercal("export", "dhydro", "dommel-controlled", "--out", str(tmp_path / "model"), "--json")
    assert run.returncode == 0, run.stderr
    run = rivercal("import", "dhydro", json.loads(run.stdout)["mdu"], "--out", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["refused"] == 0


def test_bad_options_are_clean_errors(tmp_path: Path) -> None:
    mdu = write_model(tmp_path / "model")
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"), "--realtime-lateral", "nan")
    assert run.returncode == 2 and "--realtime-lateral" in run.stderr and "internal error" not in run.stderr
    (tmp_path / "taken").write_text("a file of the user's", encoding="utf-8")
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "taken"), "--realtime-lateral", "0.01")
    assert run.returncode == 2 and "--out" in run.stderr and "exists and is not a folder" in run.stderr
    assert (tmp_path / "taken").read_text(encoding="utf-8") == "a file of the user's"


def test_an_mdu_with_a_key_given_twice_imports_with_a_warning(tmp_path: Path) -> None:
    """As published from a real project: the key given twice once ended in an internal error."""
    mdu = write_model(tmp_path / "model")
    text = mdu.read_text(encoding="utf-8")
    mdu.write_text(text.replace("[Time]\n", "[Time]\nDtMax = 30.0\n", 1), encoding="utf-8")
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"), "--realtime-lateral", "0.01",
                   "--allow-partial")
    assert run.returncode == 0, run.stderr
    assert "more than once" in (tmp_path / "case" / "import.md").read_text(encoding="utf-8")


def test_observation_cross_sections_given_as_polylines_are_stations(tmp_path: Path) -> None:
    """c01 has two observation cross-sections given by a polyline x = 1000 m across branches T2 and T4, which run
    from x = 2000 to 0 with calculation points every 50 m. The polyline passes through the point at chainage 1000 m;
    by D-Flow FM's rule (the crossing's direction picks one of the two links there) it observes the link
    950-1000 m."""
    mdu = shared_model("dhydro-1d-steady-state-flow", "Boundary.mdu")
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["refused"] == 0
    stations = {s.id: s for s in load_model(tmp_path / "case").case.network.stations}
    for name, branch in (("ObservCross_xy_T2", "T2"), ("ObservCross_xy_T4", "T4")):
        assert (stations[name].branch, stations[name].chainage, stations[name].quantities) == (branch, 975.0, ["Q"])


#: Each shared model as imported, a parameter the import wrote, a short calibration window (with the warm-up
#: before it, h) and an on-line cycle (issue time, window = cycle = horizon, warm-up).
_SHARED = {
    "dellen": (("dhydro-dellen", "dflowfm", "Flow1D.mdu"), ("--realtime", "rr_to_flow.nc", "--realtime",
                                                            "rtc_to_flow.nc"),
               "F_Manning_0_03", 0.036, "2000-06-03/2000-06-03T06:00", "6", ("2000-06-03T12:00", "6h", "6h")),
    "c01": (("dhydro-1d-steady-state-flow", "Boundary.mdu"), (), "F_T2", 50.0, "2015-01-02/2015-01-02T06:00", "6",
            ("2015-01-02T12:00", "6h", "6h")),
    "korte-woerden": (("dhydro-korte-woerden-1d", "dflowfm", "FlowFM.mdu"), ("--realtime-lateral", "0.001"),
                      "W_OVS1", 2.2, "2020-01-01T01:00/2020-01-01T02:00", "1", ("2020-01-01T01:00", "1h", "0h")),
}


@pytest.mark.parametrize("name", [pytest.param("dellen", marks=pytest.mark.slow), "c01", "korte-woerden"])
def test_every_command_runs_on_a_shared_model_as_imported(tmp_path: Path, name: str,
                                                          request: pytest.FixtureRequest) -> None:
    """Import, simulate, calibrate (a twin of one parameter the import wrote), one on-line cycle, analyse and
    export, exit 0 each (Dellen's import is the module's, that of the summary's test)."""
    parts, extra, param, truth, window, warmup, (issue, span, online_warmup) = _SHARED[name]
    if name == "dellen":
        case, summary = request.getfixturevalue("dellen")
    else:
        mdu = shared_model(*parts)
        extra = tuple(str(mdu.parents[1] / x) if x.endswith(".nc") else x for x in extra)
        case = tmp_path / "case"
        run = rivercal("import", "dhydro", str(mdu), "--out", str(case), *extra, "--json")
        assert run.returncode == 0, run.stderr
        summary = json.loads(run.stdout)
    assert param in summary["parameters"]
    # simulate to the end of the on-line cycle's forecast (Dellen's week: its first two days and three quarters)
    until = (pd.Timestamp(issue) + pd.Timedelta(span)).strftime("%Y-%m-%dT%H:%M")
    run = rivercal("simulate", str(case), "--end", until, "--out", str(tmp_path / "sim"), "--json")
    assert run.returncode == 0, run.stderr
    run = rivercal("calibrate", str(case), "--params", param, "--window", window, "--twin", f"{param}={truth}",
                   "--warmup", warmup, "--workers", "1", "--option", "max_outer=2", "--json")
    assert run.returncode == 0, run.stderr
    estimate = json.loads(run.stdout)["estimates"][param]
    initial = json.loads(run.stdout)["initial"][param]
    assert abs(estimate - truth) < 0.5 * abs(initial - truth)  # two outer iterations move it most of the way
    series = pd.read_csv(tmp_path / "sim" / "series.csv", index_col=0)
    series.iloc[:, :12].to_csv(tmp_path / "observed.csv")  # a few stations, as a monitoring network has
    run = rivercal("online", str(case), "--observations", str(tmp_path / "observed.csv"), "--params", param,
                   "--from", issue, "--to", issue, "--max-cycles", "1", "--window", span, "--cycle", span,
                   "--horizon", span, "--warmup", online_warmup, "--db", str(tmp_path / "run.sqlite"),
                   "--workers", "1", "--assimilate", "parameters", "--quiet", "--json",
                   "--out", str(tmp_path / "report"))
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["status"] == {"done": 1}
    # the report of a run on a water board's model: no thesis twin, so its parameter table is not named after
    # the thesis' tables of true values
    html = (tmp_path / "report" / "index.html").read_text(encoding="utf-8")
    assert "The model&#x27;s parameters: DSS and rivercal" in html and "Tables 5-1" not in html
    # against the same few gauges (a twin of every station drew a panel for each of Dellen's 200 stations)
    run = rivercal("analyse", str(case), "--params", param, "--window", window, "--warmup", warmup, "--workers", "1",
                   "--observations", str(tmp_path / "observed.csv"), "--out", str(tmp_path / "analyse"), "--json")
    assert run.returncode == 0, run.stderr
    run = rivercal("export", "dhydro", str(case), "--out", str(tmp_path / "exported"), "--json")
    assert run.returncode == 0, run.stderr
