"""The black box: an external program behind the model contract (tests/data/blackbox/toy.py is the program).

Known truth: the toy's level relaxes to crest + (q/k)^0.6 of a known inflow q, so a twin calibration must
find k and crest back. Every failure mode of a real program is played by the toy (TOY_MODE) and must give
a BlackBoxRunError that names the run folder (kept) and the cause; argv items reach the program literally.
"""

from __future__ import annotations

import json
import os
import re
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.models import load_model
from rivercal.models.blackbox import BlackBoxRunError
from rivercal.models.config import ModelFileError
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from tests.blackbox_models import START, TEMPLATE, make_model


def params(k0: float = 2.0, crest0: float = 10.2) -> ParameterSet:
    return ParameterSet([
        Parameter(name="k", targets=["k"], min=0.5, max=10.0, initial=k0, perturbation=0.5),
        Parameter(name="crest", targets=["crest"], min=9.0, max=11.0, initial=crest0, perturbation=0.1),
    ])


def test_a_twin_through_the_black_box_finds_the_truth(tmp_path) -> None:
    model = make_model(tmp_path)
    assert model.quantities["k"].unit == "m^3/s" and model.observables == ["S.h", "S.Q"]
    truth, _ = model.simulate({"k": 3.0, "crest": 10.0}, end=START + pd.Timedelta("3D"))
    assert len(truth.series) == 73 and truth.series.index[0] == START
    obs = ObservationSet.from_frame(truth.series[["S.h"]].iloc[12:], sigma={"h": 0.01})
    problem = CalibrationProblem(model, params(), obs, (START + pd.Timedelta("12h"), START + pd.Timedelta("3D")),
                                 warmup="12h")
    cal = calibrate(problem, "dud", workers=1)
    # DuD stops once the cost is negligible against one initial perturbation's (1e-6 of it), which leaves a
    # noise-free twin about 1e-3 of the initial step from the truth: within 1 % of k's step and 1 mm of the crest
    assert cal.estimates["k"] == pytest.approx(3.0, abs=0.005)
    assert cal.estimates["crest"] == pytest.approx(10.0, abs=1e-3)
    assert not any((tmp_path / "runs").glob("run-*"))  # successful runs leave nothing behind


def test_a_hot_started_run_continues_the_whole_run(tmp_path) -> None:
    model = make_model(tmp_path)
    whole, _ = model.simulate({"k": 4.0}, end=START + pd.Timedelta("2D"))
    first, state = model.simulate({"k": 4.0}, end=START + pd.Timedelta("1D"))
    again = model.load_state(model.save_state(state), model.state_format)
    second, _ = model.simulate({"k": 4.0}, start=START + pd.Timedelta("1D"), end=START + pd.Timedelta("2D"),
                               state=again)
    joined = pd.concat([first.series, second.series.iloc[1:]])
    np.testing.assert_allclose(joined.to_numpy(), whole.series.to_numpy(), rtol=0, atol=1e-8)
    # the toy omits its first row after a hot start: it comes from the state
    np.testing.assert_allclose(second.series.iloc[0].to_numpy(), first.series.iloc[-1].to_numpy())
    with pytest.raises(ValueError, match="the state is at"):
        model.simulate({}, start=START, end=START + pd.Timedelta("1D"), state=state)


def test_a_spinup_runs_before_a_cold_start(tmp_path) -> None:
    plain = make_model(tmp_path / "a")
    spun = make_model(tmp_path / "b", spinup=48.0)
    later = START + pd.Timedelta("3D")
    a, _ = plain.simulate({}, start=later, end=later + pd.Timedelta("1D"))
    b, _ = spun.simulate({}, start=later, end=later + pd.Timedelta("1D"))
    c, _ = plain.simulate({}, start=later - pd.Timedelta("2D"), end=later + pd.Timedelta("1D"))
    pd.testing.assert_frame_equal(b.series, c.series.loc[later:])
    assert not np.allclose(a.series.to_numpy(), b.series.to_numpy())


@pytest.mark.parametrize(("mode", "cause"), [
    ("fail", r"exited with status 3; stderr: toy: the input makes no sense"),
    ("nan", r"non-finite value of S\.h at 2020-01-01 12:00:00\+00:00"),
    ("nothing", r"the program wrote no out\.csv"),
    ("truncated", r"no value of S\.h at 2020-01-01 12:00:00\+00:00: the output covers .* \(truncated\?\)"),
    ("text", r"out\.csv line 14: column 'level' holds 'high', not a number"),
    ("duplicate", r"out\.csv: the time 2020-01-01T12:00:00\+00:00 is written more than once"),
    ("fifo", r"out\.csv is a FIFO \(named pipe\), not a file"),
    ("selfkill", r"the program was ended by signal SIGKILL"),
])
def test_a_failed_run_names_the_kept_run_folder_and_the_cause(tmp_path, mode, cause) -> None:
    model = make_model(tmp_path, mode=mode, runs_dir="runs")
    with pytest.raises(BlackBoxRunError, match=cause) as info:
        model.simulate({}, end=START + pd.Timedelta("1D"))
    kept = Path(info.value.run_dir)
    assert kept.is_dir() and kept.name.startswith("failed-") and kept.parent == tmp_path / "runs"
    assert (kept / "input.json").is_file() and (kept / "stderr.txt").is_file()
    # the message names the kept folder, and files relative to it (never the folder's name before the rename)
    assert str(info.value).startswith(f"external model run in {kept} failed: ")
    assert str(tmp_path / "runs") not in info.value.cause


def test_an_output_that_links_outside_the_run_folder_is_not_read(tmp_path) -> None:
    secret = tmp_path / "secret.csv"
    secret.write_text("time,level,flow\n2020-01-01T00:00:00Z,1,1\n")
    model = make_model(tmp_path, runs_dir="runs")
    model.spec = model.spec.model_copy(update={"env": {"TOY_MODE": "link", "TOY_LINK": str(secret)}})
    with pytest.raises(BlackBoxRunError, match=r"failed: out\.csv leads outside the run folder \(a link to "
                                               + re.escape(str(secret)) + r"\)"):
        model.simulate({}, end=START + pd.Timedelta("1D"))


def test_a_hanging_program_is_stopped_with_its_children(tmp_path) -> None:
    model = make_model(tmp_path, mode="hang", timeout=1.0, runs_dir="runs")
    t0 = time.perf_counter()
    with pytest.raises(BlackBoxRunError, match="did not finish within its timeout of 1 s and was stopped") as info:
        model.simulate({}, end=START + pd.Timedelta("1D"))
    assert time.perf_counter() - t0 < 10
    child = int((Path(info.value.run_dir) / "child.pid").read_text())
    time.sleep(0.2)
    assert not _alive(child)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/stat")
    return status.exists() and status.read_text().split()[2] != "Z"


def test_the_failure_policy_applies_to_black_box_runs(tmp_path) -> None:
    model = make_model(tmp_path, runs_dir="runs")
    model.spec = model.spec.model_copy(update={"env": {"TOY_FAIL_ABOVE": "5"}})
    truth, _ = model.simulate({"k": 3.0}, end=START + pd.Timedelta("1D"))
    obs = ObservationSet.from_frame(truth.series[["S.h"]].iloc[6:], sigma={"h": 0.01})
    window = (START + pd.Timedelta("6h"), START + pd.Timedelta("1D"))
    for policy in ("raise", "penalty"):
        problem = CalibrationProblem(model, params(), obs, window, warmup="6h", on_failure=policy, penalty=1e6)
        assert problem.cost(np.array([3.0, 10.0])) == pytest.approx(0.0, abs=1e-10)
        if policy == "raise":
            with pytest.raises(BlackBoxRunError, match="exited with status 4; stderr: toy: k = 6 is too large"):
                problem.residuals(np.array([6.0, 10.0]))
        else:
            assert problem.cost(np.array([6.0, 10.0])) == pytest.approx(1e6)


def test_failed_run_folders_are_pruned_to_the_newest(tmp_path) -> None:
    model = make_model(tmp_path, mode="fail", runs_dir="runs", keep_failed=2)
    kept = []
    for _ in range(4):
        with pytest.raises(BlackBoxRunError) as info:
            model.simulate({}, end=START + pd.Timedelta("1D"))
        kept.append(Path(info.value.run_dir))
        time.sleep(0.01)
    left = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert len(left) == 2 and kept[-1].name in left and kept[0].name not in left


def test_no_shell_is_involved_argv_items_and_paths_pass_literally(tmp_path) -> None:
    nasty = ("; touch pwned1", "$(touch pwned2)", "`touch pwned3`", "it's \"quoted\"", "a | b > c", "{run_dir}")
    odd = tmp_path / "runs; $(touch pwned4) 'x'"
    model = make_model(tmp_path, mode="argv", extra_argv=nasty, runs_dir=str(odd))
    model.runs.keep = True
    model.simulate({"k": 2.5}, end=START + pd.Timedelta("1D"))
    (run_dir,) = list(odd.iterdir())
    seen = json.loads((run_dir / "argv.json").read_text())
    assert seen == [*nasty[:-1], str(run_dir)]
    assert not list(tmp_path.rglob("pwned*")) and not list(Path.cwd().glob("pwned*"))


def test_netcdf_and_pixml_outputs_are_read(tmp_path) -> None:
    """The toy's CSV converted by a second program step into CF NetCDF and PI-XML gives the same series."""
    converter = tmp_path / "toy" / "convert.py"
    (tmp_path / "toy").mkdir(parents=True)
    converter.write_text(textwrap.dedent('''\
        import pandas as pd
        from rivercal.engine.state import SimulationResult
        from rivercal.io import write_pixml
        frame = pd.read_csv("out.csv", index_col=0, parse_dates=True)
        frame.columns = ["S.h", "S.Q"]
        SimulationResult(series=frame, balance=None).to_netcdf("out.nc")
        write_pixml("out.xml", frame[["S.h"]], ids={"S.h": ("S", "H.obs")})
        '''))
    outputs = '''[[blackbox.outputs]]
reader = "netcdf"
file = "out.nc"
series = { "S.h" = "water_level@S.h" }

[[blackbox.outputs]]
reader = "pixml"
file = "out.xml"
series = { "S.Q" = "S/H.obs" }'''
    model = make_model(tmp_path, outputs=outputs)
    csv_model = make_model(tmp_path / "csv")
    # the toy runs, then the converter: a two-step program without a shell is a tiny Python wrapper
    (tmp_path / "toy" / "both.py").write_text("import runpy\nrunpy.run_path('toy.py')\nrunpy.run_path('convert.py')\n")
    model.spec = model.spec.model_copy(update={"command": ["{python}", "both.py"]})
    got, _ = model.simulate({"k": 5.0}, end=START + pd.Timedelta("1D"))
    want, _ = csv_model.simulate({"k": 5.0}, end=START + pd.Timedelta("1D"))
    np.testing.assert_allclose(got.series["S.h"], want.series["S.h"], atol=1e-6)
    np.testing.assert_allclose(got.series["S.Q"], want.series["S.h"], atol=1e-3)  # PI-XML holds S.h as H.obs


def test_model_toml_errors_name_the_file_and_field(tmp_path) -> None:
    make_model(tmp_path)
    toml = tmp_path / "model.toml"
    text = toml.read_text()
    (tmp_path / "toy" / "input.json.tmpl").write_text(TEMPLATE.replace("{{k:.12g}}", "{{kk}}"))
    with pytest.raises(ModelFileError, match=r"model\.toml: blackbox\.templates\[0\]: .*placeholder \{\{kk\}\} is "
                                             r"neither a quantity"):
        load_model(toml)
    (tmp_path / "toy" / "input.json.tmpl").write_text(TEMPLATE)
    toml.write_text(text.replace('kind = "blackbox"', 'kind = "swmm"'))
    with pytest.raises(ModelFileError, match=r"model\.kind is 'swmm': give the table \[swmm\]"):
        load_model(toml)
    toml.write_text(text.replace("timeout = 30.0", "timeout = -1"))
    with pytest.raises(ModelFileError, match=r"model\.toml: blackbox\.timeout"):
        load_model(toml)
    toml.write_text(text.replace('command = ["{python}", "toy.py"]', 'command = ["{python}", "toy.py", "{nope}"]'))
    with pytest.raises(ModelFileError, match=r"blackbox\.command: .*\{nope\} is not a quantity"):
        load_model(toml)
    toml.write_text(text.replace('"S.h" = "level"', '"S.level" = "level"'))
    with pytest.raises(ModelFileError, match=r"'S\.level' is not '<station>\.<quantity>'"):
        load_model(toml)
    toml.write_text(text + '\n[[parameters]]\nname = "K"\ntargets = ["kk"]\nmin = 1\nmax = 2\ninitial = 1.5\n'
                    'perturbation = 0.1\n')
    with pytest.raises(ModelFileError, match=r"parameters: parameter K: model 'toy' has no settable quantity 'kk'"):
        load_model(toml)


def test_values_are_checked_against_the_declared_bounds(tmp_path) -> None:
    model = make_model(tmp_path)
    with pytest.raises(ValueError, match=r"k: value 50 m\^3/s is outside its range \[0.5, 20\]"):
        model.simulate({"k": 50.0}, end=START + pd.Timedelta("1D"))
    with pytest.raises(ValueError, match="no settable quantity 'K'"):
        model.simulate({"K": 5.0}, end=START + pd.Timedelta("1D"))
    with pytest.raises(ValueError, match="reports every 3600 s"):
        model.simulate({}, end=START + pd.Timedelta("1D"), output_interval=60.0)


def test_the_transition_adapter_wraps_a_black_box(tmp_path) -> None:
    """k jumps from 2 to 5 at τ = 6 h: the adapter's run equals two runs of the program, hot-started between."""
    from rivercal.models.transition import AFTER, BEFORE, TIME, TransitionModel

    model = make_model(tmp_path)
    tm = TransitionModel(model, "k", reference=START)
    assert tm.quantities[BEFORE].unit == "m^3/s" and tm.quantities[BEFORE].max == 20.0
    joined, state = tm.simulate({BEFORE: 2.0, AFTER: 5.0, TIME: 6.0}, end=START + pd.Timedelta("1D"))
    first, mid = model.simulate({"k": 2.0}, end=START + pd.Timedelta("6h"))
    second, _ = model.simulate({"k": 5.0}, start=START + pd.Timedelta("6h"), end=START + pd.Timedelta("1D"), state=mid)
    expected = pd.concat([first.series, second.series.iloc[1:]])
    np.testing.assert_allclose(joined.series.to_numpy(), expected.to_numpy(), atol=1e-9)
    assert state.time == START + pd.Timedelta("1D")
