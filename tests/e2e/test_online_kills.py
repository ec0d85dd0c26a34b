"""SIGKILL ``rivercal online`` at random moments, resume it each time: the store ends as if never killed.

A short PI-Fg replay of the dommel case (three daily cycles estimating the friction over 2-day windows,
runs of three days with the warm-up where the default week takes eight; one finds the change and dates it,
the next carries it, so every table a cycle writes gets rows) runs once uninterrupted (the reference). Then the
same command is started, killed with SIGKILL after a random delay, and started again with the same
arguments, over and over; the last start runs to its end. Each delay is drawn (seeded) uniformly over the time the start
would take to finish, judged from the reference's timeline and the cycles already stored, so that kills
land anywhere in it: in the start-up, in cycles, in commits, between cycles. The store must then hold
exactly what the reference holds, apart from wall-clock stamps, owners and attempt counts; and after
every kill, every process of the killed run (its evaluation workers) must be gone within seconds (if no
random kill came while workers were alive, the last one waits for them). The
same test runs against a real PostgreSQL server (a fresh database; one kill, to keep the suite short).
Both compare with the one uninterrupted run on SQLite: the PostgreSQL store, killed and resumed, must hold
what the SQLite store holds, which also checks that the two stores keep the same records.
The engine is compiled before the reference: a first compile inside it would make its start-up minutes
long, and every delay drawn from it too long to land before the run ends.
"""

from __future__ import annotations

import contextlib
import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import pytest

from tests.processes import descendants, kill_left, survivors

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process table in /proc")]

SEED = 20101101
#: Kills per backend. Each kill lands at a uniformly drawn moment of what the start has left to do (its start-up,
#: a cycle's calibration or commit, the time between cycles), and the last one is sure to come while the
#: evaluation workers live. The points of a cycle a kill must survive (in the computation, in a commit, in an
#: ingest, between cycles) are each also hit deterministically, on both backends, by a service's cycles through
#: the store in tests/integration/test_store_crash.py; so two random kills on SQLite and one on PostgreSQL
#: (each a restart that pays the start-up again) prove the resume from wherever a kill lands.
KILLS = 2
KILLS_POSTGRESQL = 1
#: Content of each table: columns compared, with the cycle index in place of internal row ids. Left out:
#: wall-clock stamps (created, started, finished, ingested, scored, applied), owners, attempt counts and
#: the cycles' wall time.
CONTENT = {
    "runs": "SELECT name, case_name, config, status FROM runs",
    "cycles": "SELECT cycle, window_start, window_end, issue_time, status, algorithm, model_runs, cost_before, "
              "cost_after, message, issued_forecast, issued_reason, skill_updated, skill_dss FROM cycles",
    "estimates": "SELECT c.cycle, e.parameter, e.value, e.std, e.unit, e.accepted, e.reason FROM estimates e "
                 "JOIN cycles c ON c.id = e.cycle_id",
    "alerts": "SELECT c.cycle, a.parameter, a.kind, a.message, a.magnitude FROM alerts a JOIN cycles c "
              "ON c.id = a.cycle_id",
    "observations": "SELECT series, time, source, value, flag FROM observations",
    "observation_gaps": "SELECT series, source, gap_start, gap_end FROM observation_gaps",
    "transitions": "SELECT c.cycle, t.parameter, t.time, t.value_before, t.value_after, t.unit, t.found_cycle, "
                   "t.cost_single, t.cost_transition, t.p_value FROM transitions t JOIN cycles c ON c.id = t.cycle_id",
    "forecasts": "SELECT c.cycle, f.kind, f.series, f.time, f.lead_h, f.value FROM forecasts f JOIN cycles c "
                 "ON c.id = f.cycle_id",
    "forecast_scores": "SELECT c.cycle, s.kind, s.series, s.lead_from_h, s.lead_to_h, s.rmse, s.bias, s.n "
                       "FROM forecast_scores s JOIN cycles c ON c.id = s.cycle_id",
    "model_states": "SELECT c.cycle, m.name, m.time, m.format, m.data FROM model_states m JOIN cycles c "
                    "ON c.id = m.cycle_id",
    "forecast_bands": "SELECT c.cycle, b.series, b.time, b.lead_h, b.probability, b.low, b.high FROM forecast_bands b "
                      "JOIN cycles c ON c.id = b.cycle_id",
    "ensembles": "SELECT c.cycle, e.time, e.members, e.format, e.data FROM ensembles e JOIN cycles c "
                 "ON c.id = e.cycle_id",
    "run_products": "SELECT r.name, p.name, p.format, p.data FROM run_products p JOIN runs r ON r.id = p.run_id",
    "schema_version": "SELECT version, description, rivercal_version FROM schema_version",
}


def command(db: str) -> list[str]:
    return [sys.executable, "-m", "rivercal.cli", "online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-02",
            "--to", "2010-11-04", "--window", "2D", "--params", "FA", "--db", db, "--workers", "2", "--quiet",
            "--assimilate", "parameters"]


@contextlib.contextmanager
def reading(db: str):
    """A plain read connection to the store (sqlite3 or psycopg), outside rivercal."""
    if db.startswith("postgresql://"):
        import psycopg

        with psycopg.connect(db, autocommit=True) as con:
            yield con
        return
    if not Path(db).exists():
        raise FileNotFoundError(db)
    with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True)) as con:
        yield con


_MISSING = (sqlite3.OperationalError, FileNotFoundError)  # killed before, or while, the tables were made


def contents(db: str) -> dict[str, list[tuple]]:
    """Every table's rows (see CONTENT), sorted."""
    with reading(db) as con:
        if db.startswith("postgresql://"):
            tables = {name for (name,) in con.execute("SELECT table_name FROM information_schema.tables WHERE "
                                                       "table_schema = current_schema()").fetchall()}
        else:
            tables = {name for (name,) in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        assert tables == set(CONTENT), f"tables changed: compare {sorted(tables ^ set(CONTENT))} too"
        return {table: sorted((tuple(bytes(v) if isinstance(v, memoryview) else v for v in row)
                               for row in con.execute(sql).fetchall()), key=repr) for table, sql in CONTENT.items()}


def differences(got: dict[str, list[tuple]], want: dict[str, list[tuple]]) -> list[str]:
    """One line per row that is in one store and not the other."""
    out = []
    for table, rows in want.items():
        mine, theirs = set(got[table]), set(rows)
        out += [f"{table}: missing {row!r}"[:300] for row in sorted(theirs - mine, key=repr)]
        out += [f"{table}: extra {row!r}"[:300] for row in sorted(mine - theirs, key=repr)]
        if len(got[table]) != len(rows):
            out.append(f"{table}: {len(got[table])} rows, the reference has {len(rows)}")
    return out


def stamp(text: str) -> float:
    """A stored wall-clock stamp as Unix seconds."""
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


def timeline(db: str, started: float, ended: float) -> tuple[float, list[float]]:
    """The reference's start-up (s from its start to its first cycle) and the time left after each cycle, s."""
    with reading(db) as con:
        rows = con.execute("SELECT started, finished FROM cycles ORDER BY cycle").fetchall()
    return stamp(rows[0][0]) - started, [ended - stamp(finished) for _, finished in rows]


def cycles_done(db: str) -> int:
    try:
        with reading(db) as con:
            return con.execute("SELECT count(*) FROM cycles WHERE status = 'done'").fetchone()[0]
    except (*_MISSING, *_pg_errors()):
        return 0


def _pg_errors() -> tuple[type[BaseException], ...]:
    import psycopg

    return (psycopg.errors.UndefinedTable,)


def phase(db: str, since: float) -> str:
    """Where a start killed at wall time ``since`` or later stopped: in its start-up, in a cycle, after one."""
    try:
        with reading(db) as con:
            rows = con.execute("SELECT cycle, status, started FROM cycles ORDER BY cycle").fetchall()
    except (*_MISSING, *_pg_errors()):
        return "start-up"
    begun = [(cycle, status) for cycle, status, started in rows if started and stamp(started) >= since]
    if not begun:
        return "start-up"
    cycle, status = begun[-1]
    return f"in cycle {cycle}" if status == "running" else f"after cycle {cycle}"


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory: pytest.TempPathFactory, compiled_engine) -> tuple[str, float, list[float], float]:
    """The replay run once to its end on SQLite: its store, start-up (s), time left after each cycle (s), wall (s)."""
    reference = str(tmp_path_factory.mktemp("reference") / "run.sqlite")
    started = time.time()
    run = subprocess.run(command(reference), capture_output=True, text=True, timeout=600)
    ended = time.time()
    assert run.returncode == 0, run.stderr[-3000:]
    startup, left = timeline(reference, started, ended)
    return reference, startup, left, ended - started


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_random_sigkills_then_resume_store_equals_an_uninterrupted_run(tmp_path: Path, backend: str, request,
                                                                      uninterrupted) -> None:
    reference, startup, left, wall = uninterrupted
    if backend == "postgresql":
        killed, kills = request.getfixturevalue("postgres_server").new_database(), KILLS_POSTGRESQL
    else:
        killed, kills = str(tmp_path / "killed" / "run.sqlite"), KILLS

    log = tmp_path / "stderr.txt"
    rng = random.Random(SEED)
    phases, orphans, tracked, starts = [], [], 0, 0
    while len(phases) < kills:
        assert starts < 3 * kills, f"{starts} starts but only {len(phases)} kills: the runs end too soon"
        done = cycles_done(killed)
        with log.open("w") as err:
            since = time.time()
            proc = subprocess.Popen(command(killed), stdout=subprocess.DEVNULL, stderr=err)
        starts += 1
        seen: set[int] = set()
        expected = startup + left[done - 1] if done else wall  # how long this start would take
        deadline = time.monotonic() + rng.uniform(0.02, 1.0) * expected
        last_chance = len(phases) == kills - 1 and tracked == 0  # no kill has yet come while workers were alive
        while (time.monotonic() < deadline or (last_chance and not seen)) and proc.poll() is None:
            seen |= descendants(proc.pid)  # the workers forked so far
            time.sleep(0.05)
        if proc.poll() is not None:  # it ended before its kill came (nothing left to do): start again
            assert proc.returncode == 0, log.read_text()[-3000:]
            continue
        seen |= descendants(proc.pid)
        tracked += len(seen)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        phases.append(phase(killed, since))
        try:
            orphans += survivors(seen, within_s=5.0)
        finally:
            kill_left(seen)
    final = subprocess.run(command(killed), capture_output=True, text=True, timeout=600)
    starts += 1
    assert final.returncode == 0, final.stderr[-3000:]

    want = contents(reference)
    assert want["transitions"] and want["alerts"] and want["forecast_scores"], "the replay no longer finds the change"
    diff = differences(contents(killed), want)
    print(f"\nreference {wall:.1f} s (start-up {startup:.1f} s); {len(phases)} kills "
          f"({', '.join(phases)}); {tracked} worker processes of killed runs, {len(orphans)} alive 5 s later; "
          f"{starts - 1} resumes; {len(diff)} differences")
    assert orphans == [], f"processes of a killed run still alive 5 s after the kill: {orphans}"
    assert tracked > 0, "no kill came while the evaluation workers were alive"
    assert diff == []
