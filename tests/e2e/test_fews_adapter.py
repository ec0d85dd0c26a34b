"""The Delft-FEWS General Adapter module end to end: a module folder laid out as FEWS lays it out.

FEWS is played by this test: before each run it exports the observations (PI-XML, in its own time
zone, with missing values and flags), the state the previous run wrote (copied from the write location
to the read location, as FEWS imports and re-exports it) and a run file; after the run it reads the
time series, the state description and the diagnostics. The PI files are written and read here with
plain ``xml.etree`` (independently of rivercal's reader and writer) and every file rivercal writes is
validated against the official PI schemas.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.fews import run_module
from rivercal.io import read_pixml_series
from rivercal.store import Store
from tests.conftest import PI_SCHEMA_DIR, assert_valid_pi

NS = "http://www.wldelft.nl/fews/PI"
FEWS_TZ = 1.0  # FEWS exports in CET; rivercal converts
#: Three daily forecasts as the change of PI-Fg (11-01) leaves the 2-day window: the first window holds the change,
#: the last (11-02 to 11-04) lies wholly after it; two hand-overs of the state between them.
FIRST_T0 = pd.Timestamp("2010-11-02T00:00Z")
N_RUNS = 3


def _q(tag: str) -> str:
    return f"{{{NS}}}{tag}"


def _local(t: pd.Timestamp) -> dict[str, str]:
    loc = (t + pd.Timedelta(hours=FEWS_TZ)).tz_localize(None)
    return {"date": loc.strftime("%Y-%m-%d"), "time": loc.strftime("%H:%M:%S")}


def _utc(node: ET.Element, zone: float) -> pd.Timestamp:
    return (pd.Timestamp(f"{node.get('date')}T{node.get('time')}") - pd.Timedelta(hours=zone)).tz_localize("UTC")


def export_series(path: Path, frame: pd.DataFrame, *, miss: float = -999.0, flags: dict | None = None) -> Path:
    """FEWS's export: one <series> per column '<location>.<parameter>', local times, missVal for NaN."""
    root = ET.Element(_q("TimeSeries"), version="1.2")
    ET.SubElement(root, _q("timeZone")).text = f"{FEWS_TZ:.1f}"
    for col in frame.columns:
        loc, _, par = col.rpartition(".")
        s = ET.SubElement(root, _q("series"))
        h = ET.SubElement(s, _q("header"))
        for tag, text in (("type", "instantaneous"), ("locationId", loc), ("parameterId", par)):
            ET.SubElement(h, _q(tag)).text = text
        ET.SubElement(h, _q("timeStep"), unit="second", multiplier="3600")
        ET.SubElement(h, _q("startDate"), _local(frame.index[0]))
        ET.SubElement(h, _q("endDate"), _local(frame.index[-1]))
        ET.SubElement(h, _q("missVal")).text = str(miss)
        ET.SubElement(h, _q("units")).text = "m3/s" if par == "Q" else "m"
        for t, v in frame[col].items():
            flag = (flags or {}).get((col, t), 0)
            ET.SubElement(s, _q("event"), {**_local(t), "value": str(miss if np.isnan(v) else round(float(v), 6)),
                                            "flag": str(flag)})
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path


def write_run_file(module: Path, t0: pd.Timestamp, *, state: bool, properties: dict[str, str],
                   inputs: list[str] | None = None) -> Path:
    root = ET.Element(_q("Run"), version="1.8")
    ET.SubElement(root, _q("logLevel")).text = "info"
    ET.SubElement(root, _q("timeZone")).text = f"{FEWS_TZ:.1f}"
    ET.SubElement(root, _q("startDateTime"), _local(t0 - pd.Timedelta("9D")))
    ET.SubElement(root, _q("endDateTime"), _local(t0 + pd.Timedelta("48h")))
    ET.SubElement(root, _q("time0"), _local(t0))
    ET.SubElement(root, _q("workDir")).text = str(module)
    if state:
        ET.SubElement(root, _q("inputStateDescriptionFile")).text = str(module / "input" / "state.xml")
    for name in inputs if inputs is not None else ["input/observations.xml"]:
        ET.SubElement(root, _q("inputTimeSeriesFile")).text = str(module / name)
    ET.SubElement(root, _q("outputDiagnosticFile")).text = str(module / "output" / "diag.xml")
    ET.SubElement(root, _q("outputStateDescriptionFile")).text = str(module / "output" / "state.xml")
    ET.SubElement(root, _q("outputTimeSeriesFile")).text = str(module / "output" / "forecasts.xml")
    ET.SubElement(root, _q("outputTimeSeriesFile")).text = str(module / "output" / "estimates.xml")
    props = ET.SubElement(root, _q("properties"))
    for key, value in properties.items():
        ET.SubElement(props, _q("string"), key=key, value=value)
    path = module / "run_info.xml"
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path


def read_series(path: Path) -> dict[tuple[str, str, tuple[str, ...]], pd.DataFrame]:
    """Independent reader: (location, parameter, qualifiers) -> events (UTC time, value, flag, comment)."""
    root = ET.parse(path).getroot()
    zone = float(root.findtext(_q("timeZone"), "0"))
    out = {}
    for s in root.findall(_q("series")):
        h = s.find(_q("header"))
        key = (h.findtext(_q("locationId")), h.findtext(_q("parameterId")),
               tuple(q.text for q in h.findall(_q("qualifierId"))))
        miss = float(h.findtext(_q("missVal")))
        rows = [(_utc(e, zone), float(e.get("value")), int(e.get("flag", -1)), e.get("comment", ""))
                for e in s.findall(_q("event"))]
        frame = pd.DataFrame(rows, columns=["time", "value", "flag", "comment"]).set_index("time")
        frame.loc[frame["value"] == miss, "value"] = np.nan
        out[key] = frame
    return out


def diag_lines(path: Path) -> list[tuple[int, str]]:
    return [(int(n.get("level")), n.get("description")) for n in ET.parse(path).getroot().findall(_q("line"))]


@pytest.fixture(scope="module")
def truth():
    """Hourly twin observations of scenario PI-Fg at every station (friction 16 -> 25 on 2010-11-01)."""
    from rivercal.model import load_model
    from rivercal.twin.practical import practical_truth

    model = load_model("dommel")
    start = FIRST_T0 - pd.Timedelta("8D")
    return practical_truth(model, "PI-Fg", start, FIRST_T0 + pd.Timedelta(days=N_RUNS)).observations.to_frame()


PROPS = {"case": "dommel", "parameters": "FA,Wd", "window": "2D", "horizon": "48h", "warmup": "24h",
         "deadline": "120", "run": "fews-test", "piSchemaDir": str(PI_SCHEMA_DIR)}


def _fews_run(module: Path, truth: pd.DataFrame, t0: pd.Timestamp, first: bool) -> Path:
    """FEWS's side before a run: export observations of the last 8 days and the previous state."""
    (module / "input").mkdir(parents=True, exist_ok=True)
    obs = truth.loc[t0 - pd.Timedelta("8D"):t0].copy()
    station = obs.columns[0]
    obs.loc[obs.index[5], station] = np.nan  # missing (missVal) ...
    flags = {(station, obs.index[6]): 6}  # ... and unreliable (flag 6): both dropped
    obs.loc[obs.index[6], station] = 99.0
    export_series(module / "input" / "observations.xml", obs, flags=flags)
    if not first:  # FEWS imported the written state and exports it again to the read location
        root = ET.parse(module / "output" / "state.xml").getroot()
        loc = root.find(_q("stateLoc"))
        written, read = Path(loc.findtext(_q("writeLocation"))), Path(loc.findtext(_q("readLocation")))
        shutil.copyfile(written, module / "exported.sqlite")  # through FEWS's database ...
        shutil.copyfile(module / "exported.sqlite", read)  # ... to the read location
        shutil.copyfile(module / "output" / "state.xml", module / "input" / "state.xml")
    for f in (module / "output").glob("*") if (module / "output").exists() else []:
        f.unlink()  # FEWS deletes the module's outputs before a run
    return write_run_file(module, t0, state=not first, properties=PROPS)


@pytest.mark.slow
def test_consecutive_forecasts_hand_the_state_on(tmp_path: Path, truth: pd.DataFrame, pi_schema) -> None:
    module = tmp_path / "Modules" / "rivercal"
    series_schema, state_schema, diag_schema = (pi_schema(n) for n in ("pi_timeseries.xsd", "pi_state.xsd",
                                                                       "pi_diag.xsd"))
    # the state description FEWS starts from: the module's state locations, no state file yet
    (module / "state").mkdir(parents=True)
    for k in range(N_RUNS):
        t0 = FIRST_T0 + pd.Timedelta(days=k)
        run_file = _fews_run(module, truth, t0, first=(k == 0))
        outcome = run_module(run_file)
        out = module / "output"
        levels = [lvl for lvl, _ in diag_lines(out / "diag.xml")]
        assert outcome.exit_code == 0, outcome.diagnostics
        assert min(levels) >= 2 and 3 in levels
        for name, schema in (("forecasts.xml", series_schema), ("estimates.xml", series_schema),
                             ("state.xml", state_schema), ("diag.xml", diag_schema)):
            assert_valid_pi(schema, out / name)
        state_root = ET.parse(out / "state.xml").getroot()
        assert _utc(state_root.find(_q("dateTime")), float(state_root.findtext(_q("timeZone")))) == t0
        write_loc = Path(state_root.find(_q("stateLoc")).findtext(_q("writeLocation")))
        assert write_loc.is_file() and not Path(f"{write_loc}-wal").exists()  # one self-contained file
        assert any("validate against the PI schemas" in text for _, text in diag_lines(out / "diag.xml"))
        if k == 0:  # FEWS's state description for the next runs
            assert any("no state handed over" in text for _, text in diag_lines(out / "diag.xml"))
        # the outputs, read twice (independently and with rivercal's reader), equal the store
        forecasts, estimates = read_series(out / "forecasts.xml"), read_series(out / "estimates.xml")
        ours = {(s.location_id, s.parameter_id, s.qualifier_ids): s for s in read_pixml_series(out / "forecasts.xml")}
        with Store(write_loc, readonly=True) as store:
            run = store.get_run("fews-test")
            cycles = store.cycles(run)
            assert len(cycles) == k + 1 and cycles["issue_time"].iloc[-1] == t0
            assert (cycles["status"] == "done").all()
            fc = store.forecasts(run, cycle=k)
            assert len(forecasts) == fc.groupby(["kind", "series"]).ngroups == 2 * truth.shape[1]
            for (kind, series), part in fc.groupby(["kind", "series"]):
                station, _, quantity = series.rpartition(".")
                got = forecasts[(station, quantity, (kind,))]
                assert got.index.equals(pd.DatetimeIndex(part["time"]))
                assert got["value"].to_numpy() == pytest.approx(part["value"].to_numpy(), rel=1e-9, abs=1e-9)
                mine = ours[(station, quantity, (kind,))]
                assert mine.times.equals(got.index) and np.allclose(mine.values, got["value"], rtol=1e-9)
            assert got.index[0] == t0 and got.index[-1] == t0 + pd.Timedelta("48h")
            est = store.estimates(run)
            est = est[est["cycle"] == k].set_index("parameter")
            obs_stored = store.observations(["0028.h_up"], t0 - pd.Timedelta("8D"), t0)
        for name, row in est.iterrows():
            value = estimates[("dommel", name, ())]
            assert value.index.tolist() == [t0]
            assert value["value"].iloc[0] == pytest.approx(row["value"], rel=1e-9)
            assert value["flag"].iloc[0] == (0 if row["accepted"] else 3)
            assert value["comment"].iloc[0] == ("" if row["accepted"] else row["reason"])
            sigma = estimates[("dommel", name, ("sigma",))]["value"].iloc[0]
            assert (np.isnan(sigma) and np.isnan(row["std"])) or sigma == pytest.approx(row["std"], rel=1e-9)
        # the missing and the unreliable value were dropped, the rest stored exactly (time zone undone)
        assert len(obs_stored["0028.h_up"]) >= 8 * 24 + 1 - 2
        expected = truth["0028.h_up"].loc[obs_stored["0028.h_up"].times]
        assert np.allclose(obs_stored["0028.h_up"].values, expected.round(6), atol=1e-9)
    # the state was handed on: later cycles started hot from the stored model state, and the history is whole
    with Store(write_loc, readonly=True) as store:
        cycles = store.cycles(store.get_run("fews-test"))
        est = store.estimates(store.get_run("fews-test"))
    assert cycles["cycle"].tolist() == list(range(N_RUNS))
    assert not any("cold start" in m for m in cycles["message"].iloc[1:])
    fa = est[est["parameter"] == "FA"].set_index("cycle")["value"]
    assert fa.iloc[-1] == pytest.approx(25.0, abs=0.5)  # the window lies after the mowing: the true friction
    assert fa.iloc[0] < fa.iloc[-1]


def _problem(tmp_path: Path, truth: pd.DataFrame, **change) -> tuple[int, list[tuple[int, str]]]:
    module = tmp_path / "m"
    (module / "input").mkdir(parents=True, exist_ok=True)
    t0 = FIRST_T0
    obs = change.pop("obs", truth.loc[t0 - pd.Timedelta("8D"):t0])
    export_series(module / "input" / "observations.xml", obs)
    run_file = write_run_file(module, t0, state=False, properties={**PROPS, **change.pop("props", {})},
                              inputs=change.pop("inputs", None))
    if "run_text" in change:
        run_file.write_text(change.pop("run_text"), encoding="utf-8")
    outcome = run_module(run_file)
    lines = diag_lines(module / "output" / "diag.xml")
    return outcome.exit_code, lines


@pytest.mark.parametrize(("change", "words"), [
    ({"inputs": ["input/nothere.xml"]}, "nothere.xml does not exist"),
    ({"props": {"parameters": "FA,XX"}}, "unknown parameter 'XX'"),
    ({"props": {"parameters": "FA,W1,Wc"}}, "W1 and Wc both set weir:ZL1-5.crest_level; give only one of them"),
    ({"props": {"case": ""}}, "property 'case' is required"),
    ({"props": {"window": "seven days"}}, "property 'window' 'seven days': not a positive duration"),
    ({"obs": "unknown_location"}, "unknown location 'NOPE'"),
    ({"obs": "unknown_parameter"}, "unknown parameter 'WQ' at station 0028"),
    ({"obs": "no_data"}, "no observations of"),
    ({"run_text": "bad time zone"}, "'CET' is not a time zone"),
])
def test_every_problem_goes_to_the_diagnostics_with_an_error_and_a_nonzero_exit(tmp_path, truth, pi_schema, change,
                                                                                  words) -> None:
    if change.get("obs") == "unknown_location":
        change["obs"] = truth.loc[FIRST_T0 - pd.Timedelta("8D"):FIRST_T0].rename(columns={"0028.h_up": "NOPE.h"})
    elif change.get("obs") == "unknown_parameter":
        change["obs"] = truth.loc[FIRST_T0 - pd.Timedelta("8D"):FIRST_T0].rename(columns={"0028.h_up": "0028.WQ"})
    elif change.get("obs") == "no_data":  # data, but all before the window
        change["obs"] = truth.loc[FIRST_T0 - pd.Timedelta("8D"):FIRST_T0 - pd.Timedelta("7D1h")]
    if change.get("run_text") == "bad time zone":
        module = tmp_path / "m"
        module.mkdir()
        good = write_run_file(module, FIRST_T0, state=False, properties=PROPS).read_text(encoding="utf-8")
        change["run_text"] = good.replace("timeZone>1.0</", "timeZone>CET</")
        assert change["run_text"] != good
    code, lines = _problem(tmp_path, truth, **change)
    assert code != 0
    errors = [text for level, text in lines if level == 1]
    assert errors and any(words in text for text in errors), lines
    assert not any("Traceback" in text for _, text in lines)
    assert_valid_pi(pi_schema("pi_diag.xsd"), tmp_path / "m" / "output" / "diag.xml")


def test_the_command_line_runs_as_fews_calls_it(tmp_path: Path) -> None:
    """FEWS runs the program with the run file as its argument: a missing input file, exit 2, no traceback."""
    module = tmp_path / "m"
    module.mkdir()
    run_file = write_run_file(module, FIRST_T0, state=False, properties=PROPS, inputs=["input/none.xml"])
    proc = subprocess.run([sys.executable, "-m", "rivercal.cli", "fews", str(run_file)], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "none.xml does not exist" in proc.stderr
    assert diag_lines(module / "output" / "diag.xml")[-1][0] == 1
    help_text = subprocess.run([sys.executable, "-m", "rivercal.cli", "fews", "--help"], capture_output=True, text=True,
                               timeout=120, check=True, env={"COLUMNS": "200", "PATH": ""}).stdout
    for key in ("case", "parameters", "window", "horizon", "warmup", "period", "stateFile", "estimatesLocationId"):
        assert f"{key}:" in help_text


def _session_processes(pgid: int) -> list[int]:
    """Processes still in a process group (the session ``rivercal fews`` was started in)."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rpartition(")")[2].split()
            except OSError:
                continue
            if int(fields[2]) == pgid:
                out.append(int(entry.name))
    return out


def _hostile(folder: Path, what: str) -> tuple[Path, list[str]]:
    """A module folder with one hostile change, and the words its error must carry."""
    from tests.fews_support import hand_over_state, module, set_element

    run_file = module(folder)
    if what == "write location":
        (folder / "victim.txt").write_text("keep me\n", encoding="utf-8")
        hand_over_state(run_file, "nothere.sqlite", "victim.txt")
        return run_file, ["stateLoc/writeLocation", "victim.txt is not a rivercal store"]
    if what == "flag":
        path = folder / "input" / "observations.xml"
        path.write_text(path.read_text(encoding="utf-8").replace('flag="0"', 'flag="²"', 1), encoding="utf-8")
        return run_file, ["observations.xml", "series locationId=", "flag '²' is not a FEWS flag"]
    (folder / "blocker").write_text("a file\n", encoding="utf-8")
    set_element(run_file, "outputDiagnosticFile", "blocker/diag.xml")
    return run_file, ["outputDiagnosticFile", "cannot be written"]


@pytest.mark.parametrize("what", ["write location", "flag", "diagnostics"])
def test_the_command_line_refuses_hostile_input_cleanly(tmp_path: Path, what: str) -> None:
    """As FEWS calls it: exit 2, the error on stderr naming file and field, nothing touched, no process left.

    (The other refusals, and many more, run in-process: ``tests/unit/test_fews_safety.py`` and the fuzz.)
    """
    run_file, words = _hostile(tmp_path / "m", what)
    proc = subprocess.Popen([sys.executable, "-m", "rivercal.cli", "fews", str(run_file)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    _, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 2, stderr
    assert all(w in stderr for w in words), stderr
    assert "Traceback" not in stderr and "internal error" not in stderr
    assert _session_processes(proc.pid) == []
    assert not (tmp_path / "m" / "state").exists()  # the state never advanced
    if what == "write location":
        assert (tmp_path / "m" / "victim.txt").read_text(encoding="utf-8") == "keep me\n"
    if what == "diagnostics":
        assert "no diagnostics file that could be written" in stderr


def test_the_command_line_runs_a_cycle_from_the_example(tmp_path: Path, pi_schema) -> None:
    """The how-to's module folder (quick properties) as FEWS calls it: exit 0, the true friction, valid outputs."""
    from tests.fews_support import TRUE_FA, module

    run_file = module(tmp_path / "m")
    proc = subprocess.Popen([sys.executable, "-m", "rivercal.cli", "fews", "--json", "--quiet", str(run_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    summary = json.loads(stdout)
    assert summary["exit_code"] == 0 and summary["estimates"]["FA"] == pytest.approx(TRUE_FA, abs=0.5)
    assert _session_processes(proc.pid) == []
    out = tmp_path / "m" / "output"
    for name, schema in (("forecasts.xml", "pi_timeseries.xsd"), ("estimates.xml", "pi_timeseries.xsd"),
                         ("state.xml", "pi_state.xsd"), ("diag.xml", "pi_diag.xsd")):
        assert_valid_pi(pi_schema(schema), out / name)
