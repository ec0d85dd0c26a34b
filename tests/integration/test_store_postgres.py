"""The PostgreSQL store's own parts: migrations shared with SQLite, and what its errors show of a URL."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from rivercal.observations import ObservationSet
from rivercal.store import SCHEMA_VERSION, Store, StoreError
from rivercal.store import schema as store_schema

# A later step as the schema's rules ask for it: plain SQL that SQLite and PostgreSQL both run.
PLAIN_STEP = (
    "ALTER TABLE observations ADD COLUMN quality TEXT NOT NULL DEFAULT 'raw' CHECK (quality IN ('raw', 'checked'))",
    """
    CREATE TABLE station_notes (
        series  TEXT NOT NULL CHECK (length(series) > 0),
        time    BIGINT NOT NULL,
        level   DOUBLE PRECISION,
        note    TEXT NOT NULL,
        PRIMARY KEY (series, time)
    )""",
)


@pytest.fixture(params=["sqlite", "postgresql"])
def location(request, tmp_path: Path):
    if request.param == "postgresql":
        return request.getfixturevalue("pg_url")
    return tmp_path / "service.db"


def test_a_plain_sql_step_migrates_a_store_on_either_server(location, monkeypatch) -> None:
    """A new version written once, in plain SQL, brings a store of the current version forward on both servers."""
    frame = pd.DataFrame({"a.h": [1.0, 1.25]}, index=pd.date_range("2010-11-01", periods=2, freq="h", tz="UTC"))
    with Store(location) as store:
        store.create_run("r", "c", {})
        store.ingest(ObservationSet.from_frame(frame), "telemetry")
    new = SCHEMA_VERSION + 1
    step = store_schema.Migration(new, "quality of observations, station notes", store_schema._statements(*PLAIN_STEP))
    monkeypatch.setattr("rivercal.store.base.MIGRATIONS", (*store_schema.MIGRATIONS, step))
    monkeypatch.setattr("rivercal.store.base.SCHEMA_VERSION", new)
    with Store(location) as store:
        assert store.schema_version == new
        conn = store._conn
        rows = conn.execute("SELECT time, value, quality FROM observations ORDER BY time").fetchall()
        assert [tuple(r) for r in rows] == [(1288569600, 1.0, "raw"), (1288573200, 1.25, "raw")]
        conn.execute("INSERT INTO station_notes (series, time, level, note) VALUES (?, ?, ?, ?)",
                     ("a.h", 1288569600, 1.5, "gauge cleaned"))
        assert conn.execute("SELECT level FROM station_notes").fetchone()[0] == 1.5
        described = conn.execute("SELECT description FROM schema_version WHERE version = ?", (new,)).fetchone()[0]
        assert described == "quality of observations, station notes"
        assert store.get_run("r").name == "r" and store.integrity_check() == []


def test_every_step_has_a_postgresql_form_with_the_same_version_and_description() -> None:
    assert [(m.version, m.description) for m in store_schema.PG_MIGRATIONS] == \
        [(m.version, m.description) for m in store_schema.MIGRATIONS]
    later = store_schema.Migration(99, "later", store_schema._statements("SELECT 1"))
    assert store_schema.for_postgresql([later])[0].apply is later.apply  # plain SQL: shared as it stands


def test_an_unreachable_server_is_named_without_the_password() -> None:
    url = "postgresql://alice:s3cret-pw@127.0.0.1:1/rivercal"
    with pytest.raises(StoreError, match=r"postgresql://alice:\*\*\*@127\.0\.0\.1:1/rivercal: cannot connect") as err:
        Store(url, timeout_s=1)
    assert "s3cret-pw" not in str(err.value)
