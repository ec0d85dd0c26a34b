"""The store's file: pragmas, schema versions, forward migrations, and which files it refuses."""

from __future__ import annotations

import ast
import sqlite3
from pathlib import Path

import pandas as pd
import pytest

from rivercal.store import SCHEMA_VERSION, Store, StoreError, StoreVersionError
from rivercal.store import schema as store_schema
from rivercal.store.schema import APPLICATION_ID, MIGRATIONS

SRC = Path(__file__).resolve().parents[2] / "src" / "rivercal"

# The version-1 schema exactly as released (a frozen copy: a migration test must not follow later edits).
V1_SQL = """
CREATE TABLE schema_version (version INTEGER PRIMARY KEY, applied TEXT NOT NULL, description TEXT NOT NULL,
    rivercal_version TEXT NOT NULL);
CREATE TABLE runs (
    id INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE CHECK (length(name) > 0), case_name TEXT NOT NULL,
    created TEXT NOT NULL, config TEXT NOT NULL CHECK (json_valid(config) AND json_type(config) = 'object'),
    status TEXT NOT NULL DEFAULT 'active' CHECK (status IN ('active', 'stopped', 'finished', 'failed')));
CREATE TABLE cycles (
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
    cycle INTEGER NOT NULL CHECK (cycle >= 0), window_start INTEGER NOT NULL, window_end INTEGER NOT NULL,
    issue_time INTEGER NOT NULL,
    status TEXT NOT NULL DEFAULT 'pending' CHECK (status IN ('pending', 'running', 'done', 'failed', 'aborted')),
    attempts INTEGER NOT NULL DEFAULT 0 CHECK (attempts >= 0), owner TEXT, algorithm TEXT,
    model_runs INTEGER CHECK (model_runs IS NULL OR model_runs >= 0),
    wall_time_s REAL CHECK (wall_time_s IS NULL OR wall_time_s >= 0), cost_before REAL, cost_after REAL,
    message TEXT, started TEXT, finished TEXT, UNIQUE (run_id, cycle), CHECK (window_end > window_start),
    CHECK ((status IN ('done', 'failed', 'aborted')) = (finished IS NOT NULL)));
CREATE TABLE estimates (
    cycle_id INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
    parameter TEXT NOT NULL CHECK (length(parameter) > 0), value REAL NOT NULL,
    std REAL CHECK (std IS NULL OR std >= 0), unit TEXT NOT NULL, accepted INTEGER NOT NULL CHECK (accepted IN (0, 1)),
    reason TEXT, PRIMARY KEY (cycle_id, parameter), CHECK (accepted = 1 OR reason IS NOT NULL));
CREATE TABLE alerts (
    id INTEGER PRIMARY KEY, cycle_id INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE, parameter TEXT,
    kind TEXT NOT NULL CHECK (length(kind) > 0), message TEXT NOT NULL, magnitude REAL);
CREATE INDEX alerts_cycle ON alerts(cycle_id);
INSERT INTO schema_version VALUES (1, '2026-01-05T10:00:00.000Z', 'runs, cycles, estimates, alerts', '0.1.0');
PRAGMA application_id = 1381385036;
INSERT INTO runs VALUES (1, 'dommel-2010', 'dommel', '2026-01-05T10:00:01.000Z', '{"window_days": 7}', 'active');
INSERT INTO cycles VALUES (1, 1, 0, 1288000800, 1288605600, 1288605600, 'done', 1, '1@host', 'dud', 9, 2.5, 3.1,
    0.4, 'converged', '2026-01-05T10:00:02.000Z', '2026-01-05T10:00:04.500Z');
INSERT INTO cycles VALUES (2, 1, 1, 1288087200, 1288692000, 1288692000, 'running', 1, '1@host', NULL, NULL, NULL,
    NULL, NULL, NULL, '2026-01-05T10:00:05.000Z', NULL);
INSERT INTO estimates VALUES (1, 'friction:global', 16.2, 0.3, 'm1/3 s-1', 1, NULL);
INSERT INTO alerts VALUES (1, 1, 'friction:global', 'jump', 'friction jumped', 4.5);
"""


def _v1_file(path: Path) -> Path:
    conn = sqlite3.connect(path)
    conn.executescript(V1_SQL)
    conn.close()
    return path


def test_a_new_store_has_wal_foreign_keys_full_sync_and_the_current_schema(tmp_path: Path) -> None:
    with Store(tmp_path / "s.db") as store:
        pragma = {p: store._conn.execute(f"PRAGMA {p}").fetchone()[0]
                  for p in ("journal_mode", "foreign_keys", "synchronous", "application_id")}
        assert pragma == {"journal_mode": "wal", "foreign_keys": 1, "synchronous": 2, "application_id": APPLICATION_ID}
        assert store.schema_version == SCHEMA_VERSION == MIGRATIONS[-1].version
        rows = store._conn.execute("SELECT version, description FROM schema_version ORDER BY version").fetchall()
        assert [r[0] for r in rows] == list(range(1, SCHEMA_VERSION + 1))
        assert store_schema.user_tables(store._conn) == ["alerts", "cycles", "ensembles", "estimates",
                                                         "forecast_bands", "forecast_scores", "forecasts",
                                                         "model_states", "observation_gaps", "observations",
                                                         "run_products", "runs", "schema_version", "transitions"]
    with Store(tmp_path / "s.db", synchronous="NORMAL") as store:
        assert store._conn.execute("PRAGMA synchronous").fetchone()[0] == 1


def test_a_version_1_file_migrates_forward_and_keeps_its_data(tmp_path: Path) -> None:
    path = _v1_file(tmp_path / "old.db")
    with Store(path) as store:
        assert store.schema_version == SCHEMA_VERSION
        history = store._conn.execute("SELECT version, applied FROM schema_version ORDER BY version").fetchall()
        assert [v for v, _ in history] == [1, 2, 3, 4, 5, 6, 7]
        assert history[0][1] == "2026-01-05T10:00:00.000Z"  # the old row stays
        run = store.get_run("dommel-2010")
        assert run.config == {"window_days": 7}
        cycles = store.cycles(run.id)
        assert cycles["status"].tolist() == ["done", "running"]
        assert cycles["issue_time"][0] == pd.Timestamp("2010-11-01T10:00:00Z")
        assert store.estimates(run.id)["value"].tolist() == [16.2]
        assert store.alerts(run.id)["magnitude"].tolist() == [4.5]
        assert store.first_unfinished(run.id).cycle == 1
        assert store.forecasts(run.id).empty and store.availability().empty  # the tables of versions 2 and 3
        # version 5: the old cycles issued nothing recorded, and there are no transitions, flags or gaps yet
        assert cycles["issued_forecast"].isna().all() and store.transitions(run.id).empty
        assert store.gaps().empty and store.flag_counts().empty
        assert store.ensemble(run.id) is None and store.forecast_bands(run.id).empty  # version 6
        assert store.metrics(run.id) is None and store.product(run.id, "twin-fields") is None  # version 7
        assert store.integrity_check() == []
    with Store(path) as store:  # opening again changes nothing
        assert len(store._conn.execute("SELECT * FROM schema_version").fetchall()) == SCHEMA_VERSION


def test_a_failing_migration_leaves_the_file_at_its_last_whole_version(tmp_path: Path, monkeypatch) -> None:
    path = _v1_file(tmp_path / "old.db")

    def broken(conn) -> None:
        conn.execute("CREATE TABLE observations (x INTEGER)")
        raise RuntimeError("disk on fire")

    steps = list(MIGRATIONS)
    steps[1] = store_schema.Migration(2, "broken", broken)
    monkeypatch.setattr("rivercal.store.base.MIGRATIONS", tuple(steps))
    with pytest.raises(RuntimeError, match="disk on fire"):
        Store(path)
    conn = sqlite3.connect(path)
    assert conn.execute("SELECT max(version) FROM schema_version").fetchone()[0] == 1
    assert "observations" not in store_schema.user_tables(conn)  # the step's DDL rolled back with it
    conn.close()
    monkeypatch.undo()
    with Store(path) as store:
        assert store.schema_version == SCHEMA_VERSION


def test_a_newer_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "s.db"
    Store(path).close()
    conn = sqlite3.connect(path)
    conn.execute("INSERT INTO schema_version VALUES (?, 'x', 'from the future', '9.0')", (SCHEMA_VERSION + 1,))
    conn.commit()
    conn.close()
    with pytest.raises(StoreVersionError, match=f"schema version {SCHEMA_VERSION + 1} was written by a newer"):
        Store(path)


def test_read_only_opens_current_files_and_refuses_old_ones(tmp_path: Path) -> None:
    path = tmp_path / "s.db"
    with Store(path) as store:
        store.create_run("r", "c", {})
    with Store(path, readonly=True) as store:
        assert store.get_run("r").name == "r"
        with pytest.raises(StoreError, match="read-only"):
            store.create_run("q", "c", {})
    with pytest.raises(StoreVersionError, match="older than"):
        Store(_v1_file(tmp_path / "old.db"), readonly=True)
    with pytest.raises(StoreError, match="no such store"):
        Store(tmp_path / "missing.db", readonly=True)


def test_files_that_are_not_stores_are_refused(tmp_path: Path) -> None:
    text = tmp_path / "notes.db"
    text.write_text("this is not a database, just some text that is long enough " * 20)
    with pytest.raises(StoreError, match="not a usable SQLite database"):
        Store(text)
    other = tmp_path / "other.db"
    conn = sqlite3.connect(other)
    conn.execute("CREATE TABLE t (x)")
    conn.commit()
    conn.close()
    with pytest.raises(StoreError, match="not a rivercal store"):
        Store(other)
    with pytest.raises(StoreError, match="does not exist"):
        Store(tmp_path / "no" / "such" / "folder.db")


def test_only_store_sqlite_imports_sqlite3() -> None:
    """STYLE.md: only store/sqlite.py imports sqlite3."""
    importers = []
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n.split(".")[0] in ("sqlite3", "_sqlite3") for n in names):
                importers.append(path.relative_to(SRC).as_posix())
    assert importers == ["store/sqlite.py"]
