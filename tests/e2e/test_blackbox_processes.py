"""Stopping a black-box run stops the program and everything it started, however the run ends.

The program is the toy of tests/data/blackbox/toy.py: in mode ``escape`` it hangs with a helper in its
process group and a grandchild that starts a session of its own (out of reach of a process-group kill),
in mode ``background`` it succeeds and leaves the same helpers running, and with ``TOY_DAEMON=1`` every
run leaves a ``sleep`` in a session of its own. The checks read the process table (/proc): the processes
below rivercal before it was stopped, the pids the toy wrote, and every process whose environment carries
the run-folder marker rivercal gives a program (which its descendants inherit).

The on-line kill test is the embedded model's (tests/e2e/test_online_kills.py) on a black box: a short
replay (four daily cycles estimating k from a twin of the toy) runs once uninterrupted, then is SIGKILLed
at random moments and resumed until it finishes; the store must equal the uninterrupted run's, and no
program, helper or run folder may be left behind.
"""

from __future__ import annotations

import io
import json
import os
import random
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pandas as pd
import pytest

from rivercal.models import load_model
from rivercal.models.blackbox import BlackBoxRunError
from rivercal.models.blackbox.runs import MARKER
from tests.blackbox_models import START, make_model
from tests.cli import rivercal
from tests.e2e.test_online_kills import contents, cycles_done, differences, phase
from tests.processes import alive, descendants, kill_left, survivors

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process table in /proc")


def marked(runs: Path) -> set[int]:
    """Live processes whose environment says they belong to a run folder under ``runs``."""
    prefix = f"{MARKER}={runs}{os.sep}".encode()
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            env = (entry / "environ").read_bytes()
        except OSError:
            continue
        if any(item.startswith(prefix) for item in env.split(b"\0")) and alive(int(entry.name)):
            found.add(int(entry.name))
    return found


def session(pid: int) -> int:
    """The session id of a process (/proc/<pid>/stat)."""
    return int(Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[3])


def wait_for(pattern: str, root: Path, proc: subprocess.Popen | None = None, within_s: float = 60.0) -> Path:
    """The first file matching ``pattern`` under ``root`` once it exists."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        found = sorted(root.glob(pattern))
        if found:
            return found[0]
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"rivercal ended ({proc.returncode}) before {pattern} appeared: "
                                 f"{proc.stderr.read()[-2000:] if proc.stderr else ''}")
        time.sleep(0.05)
    raise AssertionError(f"no {pattern} under {root} within {within_s} s")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=lambda s: s.name)
def test_stopping_rivercal_simulate_stops_the_program_and_all_it_started(tmp_path: Path, sig: signal.Signals) -> None:
    make_model(tmp_path, mode="escape", timeout=120.0, runs_dir="runs")
    runs = tmp_path / "runs"
    # A shell's background job (CI started with `&`) ignores SIGINT, and a process inherits that: rivercal
    # would rightly ignore Ctrl-C too. It is started as from a terminal, with SIGINT's default action.
    proc = subprocess.Popen([sys.executable, "-m", "rivercal.cli", "simulate", str(tmp_path / "model.toml"),
                             "--end", "2020-01-02T00:00:00Z", "--out", str(tmp_path / "out")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    tracked: set[int] = set()
    try:
        pids_file = wait_for("run-*/pids.txt", runs, proc)
        program, helper, escaper, grandchild = (int(p) for p in pids_file.read_text().split())
        assert session(grandchild) != session(program) == session(helper)  # out of reach of a process-group kill
        tracked = descendants(proc.pid) | {program, helper, escaper, grandchild}
        os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=60)
        left = survivors(tracked | marked(runs), within_s=5.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        kill_left(tracked | marked(runs))
    assert left == [], f"alive 5 s after rivercal got {sig.name}: {left}"
    if sig == signal.SIGINT:
        assert proc.returncode == 130 and "interrupted" in err
        assert not list(runs.glob("run-*"))  # an interrupted run's folder is removed
    else:
        assert proc.returncode == -sig
        (stale,) = runs.glob("run-*")  # the killed process could not remove its folder ...
        load_model(tmp_path / "model.toml")  # ... the next one to load the model does
        assert not stale.exists()


def test_the_timeout_stops_a_grandchild_that_left_the_process_group(tmp_path: Path) -> None:
    model = make_model(tmp_path, mode="escape", timeout=2.0, runs_dir="runs")
    t0 = time.perf_counter()
    with pytest.raises(BlackBoxRunError, match="did not finish within its timeout of 2 s and was stopped") as info:
        model.simulate({}, end=START + pd.Timedelta("1D"))
    assert time.perf_counter() - t0 < 10
    pids = {int(p) for p in (Path(info.value.run_dir) / "pids.txt").read_text().split()}
    assert len(pids) == 4
    try:
        assert survivors(pids, within_s=1.0) == []
    finally:
        kill_left(pids)


def test_background_processes_do_not_outlive_a_successful_run(tmp_path: Path) -> None:
    model = make_model(tmp_path, mode="background", runs_dir="runs")
    model.runs.keep = True
    result, _ = model.simulate({}, end=START + pd.Timedelta("1D"))
    assert len(result.series) == 25
    (pids_file,) = (tmp_path / "runs").glob("run-*/pids.txt")
    pids = {int(p) for p in pids_file.read_text().split()}
    try:
        assert survivors(pids, within_s=1.0) == [] and marked(tmp_path / "runs") == set()
    finally:
        kill_left(pids)


# -- rivercal online on a black box, killed at random ----------------------------------------------------------

SEED = 20200103
#: Each kill lands at a drawn moment of what the start has left (start-up, a program run, a commit, between
#: cycles) and the last is sure to come while a program runs; the fixed points of a cycle are each hit by
#: tests/integration/test_store_crash.py. Each kill is a restart that pays rivercal's start-up again.
KILLS = 3
PARAMETER = '''
[[parameters]]
name = "k"
targets = ["k"]
min = 0.5
max = 10.0
initial = 3.0
perturbation = 0.5
'''


def online(model: Path, history: Path, db: Path) -> list[str]:
    return [sys.executable, "-m", "rivercal.cli", "online", str(model), "--observations", str(history), "--params", "k",
            "--from", "2020-01-03", "--to", "2020-01-06", "--window", "1D", "--horizon", "12h", "--warmup", "6h",
            "--workers", "1", "--db", str(db), "--quiet"]


def comparable(rows: dict[str, list[tuple]]) -> dict[str, list[tuple]]:
    """The store's rows with each stored state's zip archive replaced by its files (zip stamps the time), and
    without the folder each run's model lay in (the reference run's model is another folder's)."""
    out = dict(rows)

    def located(value: object) -> object:
        if isinstance(value, str) and '"model_source"' in value:
            config = json.loads(value)
            config.pop("model_source")
            return json.dumps(config, sort_keys=True)
        return value

    out["runs"] = [tuple(located(v) for v in row) for row in rows["runs"]]

    def files(data: bytes) -> tuple:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            return tuple(sorted((n, z.read(n)) for n in z.namelist()))

    out["model_states"] = sorted(((*row[:-1], files(row[-1])) for row in rows["model_states"]), key=repr)
    return out


@pytest.mark.slow
def test_random_sigkills_of_rivercal_online_on_a_black_box(tmp_path: Path) -> None:
    make_model(tmp_path / "ref", runs_dir="runs")
    make_model(tmp_path / "killed", runs_dir="runs")
    for folder in ("ref", "killed"):
        toml = tmp_path / folder / "model.toml"
        # every run also leaves a daemon in a session of its own: the supervisor must stop it
        toml.write_text(toml.read_text().replace('TOY_MODE = ""', 'TOY_MODE = "", TOY_DAEMON = "1"') + PARAMETER)
    history = tmp_path / "history"  # the twin's observations (made in this process: no interpreter to start)
    twin = rivercal("simulate", str(tmp_path / "ref" / "model.toml"), "--set", "k=5", "--out", str(history), "--quiet")
    assert twin.returncode == 0, twin.stderr[-3000:]

    reference = tmp_path / "ref" / "run.sqlite"
    started = time.monotonic()
    run = subprocess.run(online(tmp_path / "ref" / "model.toml", history / "series.csv", reference),
                         capture_output=True, text=True, timeout=600)
    wall = time.monotonic() - started
    assert run.returncode == 0, run.stderr[-3000:]
    assert marked(tmp_path / "ref" / "runs") == set() and not list((tmp_path / "ref" / "runs").glob("run-*"))

    killed = tmp_path / "killed"
    model, db, runs = killed / "model.toml", killed / "run.sqlite", killed / "runs"
    rng = random.Random(SEED)
    phases, orphans, tracked, starts = [], [], 0, 0
    proc = None
    try:
        while len(phases) < KILLS:
            assert starts < 3 * KILLS, f"{starts} starts but only {len(phases)} kills: the runs end too soon"
            done = cycles_done(str(db))
            since = time.time()
            proc = subprocess.Popen(online(model, history / "series.csv", db), stdout=subprocess.DEVNULL,
                                    stderr=subprocess.PIPE, text=True)
            starts += 1
            seen: set[int] = set()
            deadline = time.monotonic() + rng.uniform(0.05, 1.0) * wall * (1 - done / 4)
            last_chance = len(phases) == KILLS - 1 and tracked == 0  # no kill has yet come while a program ran
            while (time.monotonic() < deadline or (last_chance and not seen)) and proc.poll() is None:
                seen |= descendants(proc.pid)
                time.sleep(0.02)
            if proc.poll() is not None:  # it ended before its kill came: start again
                assert proc.returncode == 0, proc.stderr.read()[-3000:]
                proc.stderr.close()
                continue
            seen |= descendants(proc.pid) | marked(runs)
            tracked += len(seen)
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
            proc.stderr.close()
            phases.append(phase(str(db), since))
            try:
                orphans += survivors(seen | marked(runs), within_s=5.0)
            finally:
                kill_left(seen | marked(runs))
    finally:
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait()
    final = subprocess.run(online(model, history / "series.csv", db), capture_output=True, text=True, timeout=600)
    starts += 1
    assert final.returncode == 0, final.stderr[-3000:]

    want = comparable(contents(str(reference)))
    diff = differences(comparable(contents(str(db))), want)
    print(f"\nreference {wall:.1f} s; {len(phases)} kills ({', '.join(phases)}); {tracked} processes below killed "
          f"runs, {len(orphans)} alive 5 s later; {starts - 1} resumes; {len(diff)} differences")
    assert want["cycles"] and want["model_states"] and want["forecasts"]
    assert orphans == [], f"processes of a killed run still alive 5 s after the kill: {orphans}"
    assert tracked > 0, "no kill came while a program ran"
    assert marked(runs) == set(), "a program or its daemon outlived the runs"
    assert not list(runs.glob("run-*")), "run folders of killed runs were left behind"
    assert diff == []
