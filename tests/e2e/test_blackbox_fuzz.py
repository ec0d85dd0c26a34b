"""Fuzzing the fields of a black box's ``model.toml``: a clean result or a clean error, nothing else.

A seeded generator mutates one to three fields of the toy model's valid ``model.toml`` (paths that lead
out of their folder, absolute paths, NUL characters, links and FIFOs in the model folder, numbers of the
wrong sign, size or type, format specs that would render megabytes, unknown placeholders, bad
environment variables, templates that do not render), sometimes the template's text or the model
folder's entries too, and runs each case: load, a cold-started run and, when it gives a state, a
hot-started run. Every case must end in a correct result (finite series on the requested grid) or a
clean error that names the file and field (a refused ``model.toml``) or the run folder and the cause (a
failed run) — never another exception, an overlong message or "a bug in rivercal". After each case:
nothing was written outside the case's folder, no file of the folder beside it (a canary) was opened
(an audit hook watches every ``open`` of this process), and no process is left (none below this one, none
carrying the run-folder marker).
"""

from __future__ import annotations

import copy
import json
import os
import random
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w

from rivercal.errors import CaseError
from rivercal.models import load_model
from rivercal.models.blackbox import BlackBoxRunError
from rivercal.models.blackbox.runs import MARKER
from rivercal.models.config import ModelFileError
from tests.blackbox_models import TEMPLATE, TOY
from tests.processes import descendants, kill_left, survivors

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process table in /proc")

SEED = 52
CASES = 100
START = pd.Timestamp("2020-01-01", tz="UTC")

#: Paths under watch: any open() of a file below one of them is recorded (the canaries).
_WATCHED: list[str] = []
_OPENED: list[str] = []
_HOOKED: list[bool] = []


def _audit(event: str, args: tuple) -> None:
    if event == "open" and _WATCHED and isinstance(args[0], str | bytes):
        path = os.fsdecode(args[0])
        real = os.path.realpath(path)
        if any(real.startswith(w) for w in _WATCHED):
            _OPENED.append(path)


def _watch(folder: Path) -> None:
    """Record every open() below ``folder`` from now on (an audit hook, installed once: it cannot be removed)."""
    if not _HOOKED:
        sys.addaudithook(_audit)
        _HOOKED.append(True)
    _WATCHED[:] = [str(folder.resolve())]

PATHS = ["../outside/canary.txt", "../../outside/canary.txt", "{canary}", "/etc/passwd", "", " ", ".", "..",
         "a/../../x", "sub/./x.txt", "x\0y", "n" * 300, "ü.txt", "stdout.txt", "toy.py", "input.json",
         "a\\..\\..\\x", "~/x", "$HOME/x", "link-out", "link-loop", "link-dangling", "fifo", "sub/", "C:/x",
         "input.json.tmpl", "restart.txt", "out.csv"]
RUNS = ["runs", "../runs-beside", "", "model.toml", "toy", "/proc/rivercal-fuzz", "runs\0", "link-out", "fifo",
        "deep/er/runs", "link-dangling"]
NUMBERS = [0, -1, 1e-9, 0.5, 1, 7, 3600, 1e9, 1e300, -1e300, 2**63, "x", True, "", [], {}]
STRINGS = ["", "x", "{", "}", "{{k}}", "%", ".3f", "1000000000", "s", "\0", "é", "a" * 10000, "{python}", "{nope}",
           "{k:.2f}", "{k:99999}", "{start:%Y}", "{run_dir}", "{hot:yes}", "level", "time", "flow"]
ENV_KEYS = ["", "A=B", "A\0B", "PATH", "TOY_MODE", "HOME", "X" * 5000]
TEMPLATES = ['{{k:1000000000}}', "{{nope}}", "{{k*1e308*1e308}}", "{{start:%Q}}", '{"k": {{k}}}{{hot:x}}{{cold:y}}',
             "{{k}", "{{start*2}}", b"\xff\xfe{{k}}", "{{k:s}}", "{{crest:%}}"]
FIELDS: list[tuple[tuple, list]] = [
    (("blackbox", "folder"), PATHS),
    (("blackbox", "templates", 0, "source"), PATHS),
    (("blackbox", "templates", 0, "target"), PATHS),
    (("blackbox", "templates", 1), [{"source": "input.json.tmpl", "target": "input.json"}, {"source": "toy.py"}]),
    (("blackbox", "state", "restart_out", 0), PATHS),
    (("blackbox", "state", "restart_in", 0), PATHS),
    (("blackbox", "state", "restart_in", 1), PATHS),
    (("blackbox", "outputs", 0, "file"), PATHS),
    (("blackbox", "outputs", 0, "time_column"), STRINGS),
    (("blackbox", "outputs", 0, "reader"), ["csv", "netcdf", "pixml", "swmm", "xml", ""]),
    (("blackbox", "outputs", 0, "series", "S.h"), STRINGS),
    (("blackbox", "outputs", 1), [{"reader": "csv", "file": "out.csv", "series": {"S.h": "level"}},
                                  {"reader": "netcdf", "file": "out.csv", "series": {"T.h": "level"}}]),
    (("blackbox", "runs_dir"), RUNS),
    (("blackbox", "timeout"), NUMBERS),
    (("blackbox", "keep_failed"), NUMBERS),
    (("blackbox", "keep"), [True, False, 1, "yes"]),
    (("blackbox", "command", 1), STRINGS + PATHS),
    (("blackbox", "command", 2), STRINGS),
    (("blackbox", "command", 0), ["", "/nonexistent/program", "toy.py", "{python}", "sh"]),
    (("blackbox", "env", "X"), STRINGS),
    (("blackbox", "quantities", "k", "format"), STRINGS),
    (("blackbox", "quantities", "k", "min"), NUMBERS),
    (("blackbox", "quantities", "k", "max"), NUMBERS),
    (("blackbox", "quantities", "k", "default"), NUMBERS),
    (("blackbox", "quantities", "crest", "format"), STRINGS),
    (("model", "dt"), NUMBERS),
    (("model", "output_interval"), NUMBERS),
    (("model", "spinup"), NUMBERS),
    (("model", "end"), ["2020-01-01T03:00:00Z", "2020-01-01T06:30:00Z", "9999-12-31T00:00:00Z", "x", 5]),
]


def base_doc() -> dict:
    return {
        "model": {"name": "toy", "kind": "blackbox", "start": "2020-01-01T00:00:00Z", "end": "2020-01-03T00:00:00Z",
                  "dt": 3600, "output_interval": 3600, "spinup": 0},
        "blackbox": {
            "folder": "toy", "command": ["{python}", "toy.py"], "env": {"TOY_MODE": ""}, "timeout": 30,
            "keep_failed": 2, "runs_dir": "runs", "templates": [{"source": "input.json.tmpl"}],
            "state": {"restart_out": ["restart.txt"], "restart_in": ["restart_in.txt"]},
            "quantities": {"k": {"unit": "m^3/s", "min": 0.5, "max": 20.0, "default": 3.0},
                           "crest": {"default": 10.0, "format": ".6f"}},
            "outputs": [{"reader": "csv", "file": "out.csv", "series": {"S.h": "level", "S.Q": "flow"}}],
        },
    }


def put(doc: dict, path: tuple, value: object) -> None:
    """Set ``value`` at ``path`` (an index one past a list's end appends)."""
    *parents, last = path
    here = doc
    for key in parents:
        here = here[key]
    if isinstance(here, list) and last == len(here):
        here.append(value)
    else:
        here[last] = value


def mutate(rng: random.Random, canary: Path) -> tuple[dict, list[str], dict]:
    """A mutated document, what was changed (for the failure message), and the changes to the files."""
    doc, changes = base_doc(), []
    for _ in range(rng.randint(1, 3)):
        path, pool = rng.choice(FIELDS)
        value = rng.choice(pool if rng.random() < 0.85 else PATHS + NUMBERS + STRINGS)
        if isinstance(value, str):
            value = value.replace("{canary}", str(canary))
        if path[:2] == ("blackbox", "env") and rng.random() < 0.5:
            path = ("blackbox", "env", rng.choice(ENV_KEYS))
        try:
            put(doc, path, copy.deepcopy(value))
        except (IndexError, KeyError):
            continue
        changes.append(f"{'.'.join(map(str, path))} = {str(value)[:60]!r}")
    files = {"special": [e for e in ("link-out", "link-loop", "link-dangling", "fifo") if rng.random() < 0.07],
             "template": rng.choice(TEMPLATES) if rng.random() < 0.12 else None}
    return doc, changes, files


def make_case(folder: Path, doc: dict, files: dict, canary: Path) -> Path | None:
    """Write the case's model folder; the model.toml's path (None when TOML cannot say the document)."""
    model = folder / "toy"
    model.mkdir(parents=True)
    shutil.copy(TOY, model / "toy.py")
    template = files["template"] if files["template"] is not None else TEMPLATE
    (model / "input.json.tmpl").write_bytes(template if isinstance(template, bytes) else template.encode())
    for where in (model, folder):  # names a field may hold, relative to either folder
        for entry in files["special"]:
            target = where / entry
            if entry == "fifo":
                os.mkfifo(target)
            else:
                os.symlink({"link-out": str(canary), "link-loop": entry, "link-dangling": "nowhere"}[entry], target)
    try:
        text = tomli_w.dumps(doc)
    except (TypeError, ValueError):
        return None
    (folder / "model.toml").write_text(text)
    return folder / "model.toml"


def run_case(toml: Path) -> str:
    """Load and run the case; the outcome (``refused``, ``failed``, ``ok`` …), or AssertionError for a bad end."""
    try:
        model = load_model(toml)
    except ModelFileError as exc:
        assert str(exc).startswith(f"{toml}: "), str(exc)[:500]
        assert exc.field or "TOML" in exc.reason, str(exc)[:500]
        assert len(str(exc)) < 1200, str(exc)[:500]
        return f"refused: {exc.field or 'toml'}"
    outcome = "ok"
    try:
        result, state = model.simulate({}, end=START + pd.Timedelta("6h"))
        series = result.series
        assert list(series.index) == list(pd.date_range(START, START + pd.Timedelta("6h"), freq="h"))
        assert np.isfinite(series.to_numpy()).all() and list(series.columns) == model.observables
        if state is not None:
            outcome = "ok, hot started"
            later, _ = model.simulate({}, start=START + pd.Timedelta("6h"), end=START + pd.Timedelta("9h"), state=state)
            assert np.isfinite(later.series.to_numpy()).all() and len(later.series) == 4
    except BlackBoxRunError as exc:
        assert str(exc).startswith(f"external model run in {exc.run_dir} failed: "), str(exc)[:500]
        assert len(str(exc)) < 1500, str(exc)[:500]
        return f"run failed: {exc.cause[:40]}"
    except CaseError as exc:
        return f"refused at run: {exc}"[:60]
    except ValueError as exc:  # a quantity without a default, a period off the grid: named in the message
        assert type(exc) is ValueError and len(str(exc)) < 500, repr(exc)[:500]
        return f"refused at run: {str(exc)[:40]}"
    return outcome


def test_fuzzed_model_toml_fields_end_in_a_result_or_a_clean_error(tmp_path: Path) -> None:
    rng = random.Random(SEED)
    outside = tmp_path / "outside"
    outside.mkdir()
    canary = outside / "canary.txt"
    canary.write_text("time,level,flow\n2020-01-01T00:00:00Z,1,1\n")
    before_outside = sorted(p.name for p in outside.iterdir())
    _watch(outside)
    outcomes: dict[str, int] = {}
    ours_before = descendants(os.getpid())  # a server or cluster an earlier test of this worker keeps alive
    try:
        for i in range(CASES):
            doc, changes, files = mutate(rng, canary)
            case = tmp_path / f"case-{i:03d}"
            toml = make_case(case / "m", doc, files, canary)
            if toml is None:
                continue
            where = f"case {i}: {'; '.join(changes)}; files {files}"
            _OPENED.clear()
            try:
                outcome = run_case(toml)
            except AssertionError as exc:
                raise AssertionError(f"{where}: {exc}") from None
            except Exception as exc:  # an internal error: what the fuzz is for
                raise AssertionError(f"{where}: internal error {type(exc).__name__}: {str(exc)[:500]}") from None
            outcomes[outcome.partition(":")[0]] = outcomes.get(outcome.partition(":")[0], 0) + 1
            assert _OPENED == [], f"{where}: opened outside its folders: {_OPENED}"
            assert sorted(p.name for p in outside.iterdir()) == before_outside, f"{where}: wrote into {outside}"
            written = {p.name for p in tmp_path.iterdir()} - {"outside"} - {f"case-{j:03d}" for j in range(i + 1)}
            assert written == set(), f"{where}: wrote {written} beside the cases"
            assert set(os.listdir(case)) <= {"m", "runs-beside"}, f"{where}: wrote {os.listdir(case)}"
            left = survivors((descendants(os.getpid()) - ours_before) | _marked(tmp_path), within_s=2.0)
            kill_left(left)
            assert left == [], f"{where}: processes left: {left}"
    finally:
        _WATCHED.clear()
    print(f"\n{CASES} cases: {json.dumps(outcomes, sort_keys=True)}")
    assert outcomes.get("ok", 0) + outcomes.get("ok, hot started", 0) >= 5  # the generator still reaches runs
    assert outcomes.get("refused", 0) >= 40 and outcomes.get("run failed", 0) >= 5


def _marked(folder: Path) -> set[int]:
    """Processes whose environment says they belong to a run folder below ``folder`` (this test's, no other's)."""
    prefix = f"{MARKER}={folder}{os.sep}".encode()
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if any(item.startswith(prefix) for item in (entry / "environ").read_bytes().split(b"\0")):
                    found.add(int(entry.name))
            except OSError:
                continue
    return found
