"""Fuzzed option values: every subcommand answers a malformed value with exit 2 and a message naming the option.

Each example takes a command line that would run (a valid case, window, parameters …), replaces one
option's value by a malformed one drawn by hypothesis — dates that are no dates or lie outside the case,
windows, parameter lists, ``--set`` / ``--twin`` / ``--start`` / ``--max-change`` assignments, numbers
out of range or not numbers, paths that cannot be read or written — and runs the real app in-process.
It must exit with status 2, name the option on stderr, and show no traceback and no "internal error".
The draws are bounded (``max_examples`` per command) and reproducible (the suite's hypothesis profile).
"""

from __future__ import annotations

import string
from pathlib import Path

import pandas as pd
import pytest
import typer.main
import typer.testing
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from rivercal.cli.main import app

pytestmark = pytest.mark.slow

def fuzz(examples: int) -> settings:
    """Bounded, reproducible draws (the suite's profile is derandomised); model loading is slow, so no deadline."""
    return settings(max_examples=examples, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
ALGORITHMS = {"dud", "sparse_dud", "trf", "sce_ua", "dds", "nelder_mead", "powell", "cg", "bfgs", "grid", "glue"}
CHOICES = {"none", "white", "gaussian", "pink", "raise", "penalty", "forward", "central", *ALGORITHMS}


def _not_a_time(text: str) -> bool:
    try:
        return pd.Timestamp(text) is pd.NaT
    except (ValueError, TypeError, OverflowError):
        return True


GARBAGE = st.text(alphabet=string.ascii_letters + string.digits + ":-/.,=_ ", min_size=1, max_size=14)
NOT_A_TIME = GARBAGE.filter(_not_a_time)
BAD_DATE = st.one_of(
    NOT_A_TIME,
    st.sampled_from(["2010-13-01", "2010-02-30", "2010-09-31T25:00", "", " "]),
    st.integers(1900, 2009).map(lambda y: f"{y}-06-01"),  # before the dommel case
    st.integers(2011, 2200).map(lambda y: f"{y}-06-01"),  # after it
)
BAD_WINDOW = st.one_of(
    NOT_A_TIME.filter(lambda s: "/" not in s),  # neither START/END nor a window of the case
    st.tuples(BAD_DATE, st.sampled_from(["2010-10-04", "2010-09-27"])).map("/".join),
    st.tuples(st.sampled_from(["2010-09-27"]), BAD_DATE).map("/".join),
    st.sampled_from(["2010-10-04/2010-09-27", "2010-09-27/2010-09-27", "2010-09-01/2010-09-03",
                     "2010-11-28/2010-12-02", "/", "2010-09-27/", "/2010-10-04"]),
)
NAME = st.text(alphabet=string.ascii_letters, min_size=1, max_size=5)
BAD_PARAMS = st.one_of(
    st.sampled_from(["", ",", " , ", "FA,FA", "fa", "FA;Wc", "FA Wc"]),
    NAME.filter(lambda n: n not in {"FA", "Wc", "Wd", "F1", "W1", "W2", "W3", "W4", "W5", "W6", "W7", "W8", "W9"}),
)
NUMBER_TEXT = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), GARBAGE)


def _assignments(names: list[str], bad_value) -> st.SearchStrategy[str]:
    """Malformed NAME=VALUE lists: no '=', no name, not a number, unknown name, a bad value."""
    return st.one_of(
        GARBAGE.filter(lambda s: "=" not in s and s.strip(" ,")),
        st.sampled_from(["=1", "FA=", "FA=x", "FA=nan", "FA=inf", "FA=1,FA=2", "FA==3"]),
        st.tuples(NAME.filter(lambda n: n not in names), st.floats(-10, 10)).map(lambda t: f"{t[0]}={t[1]}"),
        st.tuples(st.sampled_from(names), bad_value).map(lambda t: f"{t[0]}={t[1]}"),
    )


OUT_OF_BOUNDS = st.one_of(st.floats(-1e6, 7.9), st.floats(40.1, 1e6))  # FA lives in [8, 40]
BAD_SET = st.one_of(
    GARBAGE.filter(lambda s: "=" not in s and s.strip(" ,")),
    st.sampled_from(["friction:global=x", "friction:global=nan", "friction:global=0.01", "friction:global=1e9",
                     "weir:W99.crest_level=3", "weir:S1.crest_level=1e9", "nonsense=1", "friction:branch:zz=20"]),
)


def _bad_number(option: str) -> st.SearchStrategy[str]:
    """Out of range for the option, or not a number at all."""
    low = {"--workers": 0, "--seed": -1, "--max-nfev": 0, "--max-cycles": 0, "--repeats": 0, "--k": 0,
           "--cycles": 0, "--replay-repeats": 0}
    if option in low:
        return st.one_of(st.integers(-10**6, low[option]).map(str),
                         GARBAGE.filter(lambda s: not s.strip("-").isdigit()))
    ranges = {"--warmup": st.one_of(st.floats(-1e9, -1e-9), st.floats(1e4, 1e300)),
              "--deadline": st.floats(-1e9, 0), "--poll": st.floats(-1e9, 0), "--alert-k": st.floats(-1e9, 0),
              "--rel-step": st.one_of(st.floats(-1, 0), st.floats(0.5001, 1e9)),
              "--sv-threshold": st.one_of(st.floats(-1, 0), st.floats(1, 1e9)),
              "--corr-threshold": st.one_of(st.floats(-1, 0), st.floats(1, 1e9)),
              "--days": st.one_of(st.floats(-1e9, 0), st.floats(400, 1e9))}
    bad = ranges[option].map(repr)
    return st.one_of(bad, st.sampled_from(["nan", "inf", "-inf"]), GARBAGE.filter(_not_float))


def _not_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return True
    return False


@pytest.fixture(scope="module", autouse=True)
def _app_built_once():
    """Typer's test runner builds the click command of the app anew at every call (33 ms here, a third of an
    example's time); the fuzz runs the one command typer builds, as the console script runs it once per process."""
    command = typer.main.get_command(app)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(typer.testing, "_get_command", lambda typer_app: command if typer_app is app else
                      typer.main.get_command(typer_app))
        yield


@pytest.fixture(scope="module")
def paths(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("fuzz")
    (root / "a_file.txt").write_text("not a folder\n")
    (root / "garbage.csv").write_text("time,0028.h_up\nyesterday,1\n")
    (root / "notsqlite.sqlite").write_text("this is not a database\n")
    (root / "folder.csv").mkdir()
    return {"root": root, "file": root / "a_file.txt", "garbage_csv": root / "garbage.csv",
            "not_sqlite": root / "notsqlite.sqlite", "folder": root / "folder.csv"}


def _bad_path(kind: str, paths: dict[str, Path]) -> st.SearchStrategy[str]:
    """Paths that cannot serve: ``out`` (a folder to write), ``in`` (a file to read), ``db``, ``dir`` (watched)."""
    missing = st.text(alphabet=string.ascii_lowercase, min_size=1, max_size=8).map(lambda n: str(paths["root"] / "no" /
                                                                                                  f"{n}.csv"))
    if kind == "out":
        return st.sampled_from([str(paths["file"]), str(paths["file"] / "sub"), "/dev/null/x", "/proc/rivercal"])
    if kind == "db":
        return st.sampled_from([str(paths["not_sqlite"]), str(paths["root"]), str(paths["file"] / "x.sqlite")])
    if kind == "dir":
        return st.one_of(missing, st.just(str(paths["file"])))
    return st.one_of(missing, st.sampled_from([str(paths["garbage_csv"]), str(paths["folder"]),
                                               str(paths["file"])]))


def check(command: str, args: list[str], option: str) -> None:
    """Run the app; exit 2, the option named on stderr, no traceback, no internal error."""
    run = CliRunner().invoke(app, args)
    shown = f"{args}\nexit {run.exit_code}\nstdout: {run.stdout}\nstderr: {run.stderr}\n{run.exception!r}"
    assert run.exit_code == 2, shown
    assert option in run.stderr, shown
    assert "Traceback" not in run.output and "internal error" not in run.stderr, shown


def replace(base: list[str], option: str, value: str) -> list[str]:
    """``base`` with ``option``'s value replaced (or the option appended)."""
    out = list(base)
    if option in out:
        out[out.index(option) + 1] = value
    else:
        out += [option, value]
    return out


# -- the commands ------------------------------------------------------------------------------------------


@fuzz(40)
@given(data=st.data())
def test_simulate(data, paths, tmp_path_factory) -> None:
    base = ["simulate", "synthetic", "--end", "2020-01-02", "--out", str(paths["root"] / "sim")]
    option = data.draw(st.sampled_from(["--set", "--start", "--end", "--out"]))
    value = data.draw({"--set": BAD_SET, "--out": _bad_path("out", paths)}.get(option, BAD_DATE), label=option)
    check("simulate", replace(base, option, value), option)


CALIBRATE_BASE = ["calibrate", "dommel", "--params", "FA", "--window", "2010-09-27/2010-10-04", "--twin", "FA=20",
                  "--max-nfev", "1", "--workers", "1"]


@fuzz(80)
@given(data=st.data())
def test_calibrate(data, paths) -> None:
    strategies = {
        "--params": BAD_PARAMS, "--window": BAD_WINDOW,
        "--twin": _assignments(["FA"], OUT_OF_BOUNDS), "--start": _assignments(["FA"], OUT_OF_BOUNDS),
        "--bounds": st.sampled_from(["FA", "FA=1", "FA=9:8", "FA=a:b", "FA=nan:9", "Zz=1:2", "FA=30:40"]),
        "--option": st.sampled_from(["max_outer=-1", "max_outr=3", "abs_tol=x", "max_outer=2.5", "initial_step=1",
                                     "confirm_convergence=maybe", "=3", "rel_tol"]),
        "--algorithm": NAME, "--noise": NAME, "--on-failure": NAME,
        "--observations": _bad_path("in", paths), "--out": _bad_path("out", paths),
        **{o: _bad_number(o) for o in ("--seed", "--warmup", "--workers", "--max-nfev", "--deadline")},
    }
    option = data.draw(st.sampled_from(sorted(strategies)))
    value = data.draw(strategies[option], label=option)
    args = replace([*CALIBRATE_BASE, "--out", str(paths["root"] / "cal")], option, value)
    if option == "--observations":  # observations replace the twin
        args = [a for a in args if a not in ("--twin", "FA=20")]
    assume(value not in CHOICES)
    assume(not (option == "--twin" and _twin_ok(value)))
    check("calibrate", args, option)


def _twin_ok(value: str) -> bool:
    """A valid twin value of FA (in its bounds [8, 40]): not malformed."""
    try:
        return value.startswith("FA=") and 8 <= float(value[3:]) <= 40
    except ValueError:
        return False


@fuzz(50)
@given(data=st.data())
def test_analyse(data, paths) -> None:
    base = ["analyse", "dommel", "--params", "W2,FA", "--what", "identifiability", "--window",
            "2010-09-27/2010-09-28", "--workers", "1", "--out", str(paths["root"] / "an")]
    strategies = {
        "--params": BAD_PARAMS, "--window": BAD_WINDOW,
        "--what": st.one_of(NAME, st.sampled_from(["", ",", "sensitivity,,x", "identifiability,identifiability"])),
        "--twin": _assignments(["FA"], OUT_OF_BOUNDS), "--start": _assignments(["FA"], OUT_OF_BOUNDS),
        "--scheme": NAME, "--noise": NAME, "--bias-window": NOT_A_TIME.filter(_not_a_duration),
        "--observations": _bad_path("in", paths), "--out": _bad_path("out", paths),
        **{o: _bad_number(o) for o in ("--seed", "--warmup", "--workers", "--rel-step", "--sv-threshold",
                                       "--corr-threshold", "--k")},
    }
    option = data.draw(st.sampled_from(sorted(strategies)))
    value = data.draw(strategies[option], label=option)
    assume(value not in CHOICES)
    assume(not (option == "--twin" and _twin_ok(value)))
    check("analyse", replace(base, option, value), option)


def _not_a_duration(text: str) -> bool:
    try:
        return not pd.Timedelta(text) > pd.Timedelta(0)
    except (ValueError, TypeError, OverflowError):
        return True


@fuzz(80)
@given(data=st.data())
def test_online(data, paths) -> None:
    base = ["online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-09", "--to", "2010-11-10",
            "--db", str(paths["root"] / "online.sqlite"), "--max-cycles", "1", "--workers", "1", "--assimilate",
            "parameters"]
    strategies = {
        "--from": BAD_DATE, "--to": BAD_DATE, "--params": BAD_PARAMS,
        "--window": NOT_A_TIME.filter(_not_a_duration), "--cycle": NOT_A_TIME.filter(_not_a_duration),
        "--horizon": NOT_A_TIME.filter(_not_a_duration),
        "--warmup": st.sampled_from(["-1h", "x", "", "1 fortnight", "-24h"]),
        "--max-change": _assignments(["FA", "Wd"], st.floats(-1e6, 0)),
        "--scenario": NAME, "--noise": NAME, "--algorithm": NAME,
        "--db": _bad_path("db", paths), "--out": _bad_path("out", paths),
        "--follow": _bad_path("dir", paths), "--observations": _bad_path("in", paths),
        **{o: _bad_number(o) for o in ("--seed", "--workers", "--max-cycles", "--deadline", "--poll", "--alert-k")},
    }
    option = data.draw(st.sampled_from(sorted(strategies)))
    value = data.draw(strategies[option], label=option)
    args = replace(base, option, value)
    if option in ("--follow", "--observations"):  # these replace the scenario's twin observations
        args = [a for a in args if a not in ("--scenario", "PI-Fg")]
    assume(value not in CHOICES)
    check("online", args, option)


@fuzz(30)
@given(data=st.data())
def test_twin(data, paths) -> None:
    base = ["twin", "dommel", "--suite", "F1W0", "--scenarios", "H1", "--window", "2010-09-03/2010-09-04",
            "--workers", "1", "--out", str(paths["root"] / "twin")]
    strategies = {
        "--suite": st.one_of(NAME, st.sampled_from(["", ",", "F1W0,nonsense"])),
        "--scenarios": st.one_of(NAME.map(lambda n: n + "9"), st.sampled_from(["", ",", "H1,H1"])),
        "--window": BAD_WINDOW, "--params": BAD_PARAMS,
        "--workers": _bad_number("--workers"), "--out": _bad_path("out", paths),
    }
    option = data.draw(st.sampled_from(sorted(strategies)))
    value = data.draw(strategies[option], label=option)
    args = replace(base, option, value)
    if option == "--params":
        args = replace(args, "--suite", "sensitivity")
        args = [a for a in args if a not in ("--scenarios", "H1")]
    check("twin", args, option)


@fuzz(20)
@given(data=st.data())
def test_report_case_and_bench(data, paths) -> None:
    cases = {
        "report --db": (["report", "--out", str(paths["root"] / "rep")], "--db", _bad_path("db", paths)),
        "case plot --out": (["case", "plot", "dommel"], "--out",
                            st.one_of(_bad_path("out", paths), st.just(str(paths["root"] / "net.txt")))),
        "bench engine --days": (["bench", "engine"], "--days", _bad_number("--days")),
        "bench engine --repeats": (["bench", "engine"], "--repeats", _bad_number("--repeats")),
        "bench online --from": (["bench", "online"], "--from", BAD_DATE),
        "bench online --scenario": (["bench", "online"], "--scenario", NAME),
        "bench calibrate --algorithms": (["bench", "calibrate"], "--algorithms", st.one_of(NAME, st.just("dud,x"))),
    }
    key = data.draw(st.sampled_from(sorted(cases)))
    base, option, strategy = cases[key]
    value = data.draw(strategy, label=key)
    assume(value not in CHOICES)
    check(key.split()[0], replace(base, option, value), option)
