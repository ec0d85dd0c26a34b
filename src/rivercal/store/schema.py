"""The store's schema: versioned DDL and the forward migrations between versions.

Units and conventions of every column
-------------------------------------
- **Data times** (window start/end, issue time, observation and forecast times) are INTEGER Unix
  seconds, s since 1970-01-01T00:00:00Z (UTC). ``datetime(time, 'unixepoch')`` shows them in the
  ``sqlite3`` shell.
- **Wall-clock stamps** (``created``, ``started``, ``finished``, ``ingested``, ``scored``, ``applied``) are
  TEXT, ISO 8601 UTC with milliseconds (``2010-11-01T06:00:03.125Z``); the fixed format sorts in time order.
- **Values** of series ``"<station>.<quantity>"``: m AD for levels (``h``, ``h_up``, ``h_down``), m³/s for
  discharges (``Q``). Parameter values carry their own ``unit`` column.
- **Costs** are S(θ) of thesis Eq. 2-3: dimensionless weighted sums of squared residuals.

Tables (current version)
------------------------

- ``schema_version(version, applied, description, rivercal_version)``:
  One row per applied migration; the schema version is ``max(version)``.
- ``runs(id, name UNIQUE, case_name, created, config JSON object, status)``:
  A run of the on-line service; ``status`` in active/stopped/finished/failed.
- ``cycles(id, run_id → runs, cycle, window_start, window_end, issue_time, status, attempts, owner,
  algorithm, model_runs, wall_time_s [s], cost_before, cost_after, message, started, finished)``:
  One row per cycle, UNIQUE (run_id, cycle). ``status`` pending/running (unfinished) or
  done/failed/aborted (final; ``finished`` is set if and only if the status is final). ``attempts``
  counts how often the cycle was begun; ``owner`` is ``pid@host/start`` of the process that began it last
  (``start``: its start time, Unix s; stores written before kept ``pid@host``).
- ``estimates(cycle_id → cycles, parameter, value [unit], std [unit], unit, accepted 0/1, reason)``:
  PRIMARY KEY (cycle_id, parameter); a held or rejected estimate (accepted = 0) has a reason.
- ``alerts(id, cycle_id → cycles, parameter or NULL, kind, message, magnitude [|Δθ|/σ, dimensionless])``
- ``observations(series, time, source, value [m AD or m³/s], ingested)``:
  PRIMARY KEY (series, time, source): one value per series, time and source.
- ``forecasts(cycle_id → cycles, kind 'updated'|'dss', series, time, lead_h [h], value [m AD or m³/s])``:
  PRIMARY KEY (cycle_id, kind, series, time); ``lead_h`` = (time − issue time) / 3600 ≥ 0.
- ``forecast_scores(cycle_id → cycles, kind, series, lead_from_h [h], lead_to_h [h], rmse, bias
  [m or m³/s], n, scored)``:
  Forecast minus observation over the lead-time bucket (lead_from_h, lead_to_h] (the first bucket
  includes lead 0); PRIMARY KEY (cycle_id, kind, series, lead_from_h).
- ``model_states(cycle_id → cycles, name, time, format, data BLOB)``:
  Model states a cycle hands to the next one (hot start), by name (e.g. ``updated``, ``dss``), at
  ``time``; ``data`` is opaque to the store (``format`` says how it was written). PRIMARY KEY
  (cycle_id, name).
- ``observations.flag``:
  ``ok`` or ``outlier`` (a spike found by the screening at ingestion); flagged values stay stored and
  are left out of calibrations and scores.
- ``observation_gaps(series, source, gap_start, gap_end, ingested)``:
  A gap in an ingested series: no value between the times ``gap_start`` and ``gap_end`` (the values
  either side), longer than the series' usual step. PRIMARY KEY (series, source, gap_start).
- ``cycles.issued_forecast, issued_reason, skill_updated, skill_dss``:
  Which forecast the cycle issued (``updated``: the updated parameters; ``dss``: the fixed DSS's, a
  fallback), why, and the rolling forecast skill the choice rests on (RMSE of recent level
  forecasts, m, of each kind; NULL when none were scored).
- ``transitions(cycle_id → cycles, parameter, time, value_before, value_after [unit], unit, found_cycle,
  cost_single, cost_transition, p_value)``:
  A change of a parameter at ``time`` inside the cycle's window (thesis §6-3), as that cycle knows it;
  ``found_cycle`` is the cycle that found it (one intervention keeps its ``found_cycle`` while the
  window slides over it). PRIMARY KEY (cycle_id, parameter).
- ``ensembles(run_id → runs, cycle_id → cycles, time, members, format, data BLOB)``:
  The ensemble of state updating that the latest cycle of a run handed to the next (hot start of every
  member), at ``time``; one row per run (PRIMARY KEY run_id), replaced by the cycle's commit, so the store
  does not grow with the cycles. ``data`` is opaque to the store (``format`` says how it was written).
- ``forecast_bands(cycle_id → cycles, series, time, lead_h [h], probability, low, high [m AD or m³/s])``:
  The uncertainty band of the cycle's ``updated`` forecast (an ensemble's): the observation at ``time`` is
  expected between ``low`` and ``high`` with the given ``probability`` (0.9: the 5 % and 95 % quantiles).
  PRIMARY KEY (cycle_id, series, time).
- ``cycles.metrics``:
  The run metrics as of the cycle (a JSON object: forecast errors, the headline figures, the error by lead
  time, the band coverage; :mod:`rivercal.online.metrics`), written after the cycle's commit; NULL for a cycle
  stored before they were (readers then compute them from the other tables).
- ``run_products(run_id → runs, name, format, data BLOB, created)``:
  What was computed for a run as a whole, for its readers (e.g. ``twin-fields``: a twin's levels at every
  point of the truth, the DSS and rivercal, for the report's maps); ``data`` is opaque to the store
  (``format`` says how it was written). PRIMARY KEY (run_id, name); a new product replaces the old.

Every child row is deleted with its cycle and every cycle with its run (ON DELETE CASCADE; the store
turns foreign keys on for each connection).

Migrations
----------
:data:`MIGRATIONS` lists the steps 0→1→2→…; step *n* brings a version *n − 1* file to version *n* and
records itself in ``schema_version`` in the same transaction, so a file is always at one whole version.
A released step is never edited: a change to the schema is a new step appended to the list (with a test
that opens a file of the version before). Versions 1–3 were laid down together in the first release,
in the order the service needs them: cycles and estimates, then observation ingestion, then forecasts
and their scores. Version 4 adds the model states that a cycle hands to the next (hot start), so that a
restarted service continues from the stored state instead of spinning the model up again. Version 5
adds what the service needs under realistic data: observation flags and gaps, the transitions it
estimated, and the forecast it issued with the skill comparison behind that choice. Its statements are
plain SQL that PostgreSQL runs as well (DOUBLE PRECISION, BIGINT). Version 6 adds state updating: the latest
ensemble per run (one row, replaced in each cycle's commit; before it the members would have been stored per
cycle, about 1 MB a cycle at 64 members) and the forecasts' uncertainty bands (the ``forecasts`` table keeps
its kinds).

The PostgreSQL store (:mod:`rivercal.store.postgres`) applies :data:`PG_MIGRATIONS`: the same versions,
tables and checks in PostgreSQL's types.

This module does not import ``sqlite3``: the steps take any DB-API connection.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

__all__ = ["APPLICATION_ID", "MIGRATIONS", "PG_MIGRATIONS", "SCHEMA_VERSION", "Migration", "current_version",
           "for_postgresql", "user_tables"]

#: ``PRAGMA application_id`` of a rivercal store ("RVCL"), so that other SQLite files are recognised.
APPLICATION_ID = 0x5256434C


class _Connection(Protocol):
    def execute(self, sql: str, parameters: Sequence[Any] = ..., /) -> Any: ...


@dataclass(frozen=True)
class Migration:
    """One forward step of the schema.

    Attributes
    ----------
    version
        The version the step produces.
    description
        What the step adds or changes (stored in ``schema_version``).
    apply
        Function that executes the step's statements on a connection inside an open transaction.
    """

    version: int
    description: str
    apply: Callable[[_Connection], None]


def _statements(*sql: str) -> Callable[[_Connection], None]:
    def apply(conn: _Connection) -> None:
        for statement in sql:
            conn.execute(statement)

    return apply


SCHEMA_VERSION_DDL = """
CREATE TABLE IF NOT EXISTS schema_version (
    version          INTEGER PRIMARY KEY,
    applied          TEXT NOT NULL,
    description      TEXT NOT NULL,
    rivercal_version TEXT NOT NULL
)"""

# --- version 1: runs, cycles, estimates, alerts ------------------------------------------------------------
_V1 = _statements(
    """
    CREATE TABLE runs (
        id        INTEGER PRIMARY KEY,
        name      TEXT NOT NULL UNIQUE CHECK (length(name) > 0),
        case_name TEXT NOT NULL,
        created   TEXT NOT NULL,
        config    TEXT NOT NULL CHECK (json_valid(config) AND json_type(config) = 'object'),
        status    TEXT NOT NULL DEFAULT 'active' CHECK (status IN ('active', 'stopped', 'finished', 'failed'))
    )""",
    """
    CREATE TABLE cycles (
        id           INTEGER PRIMARY KEY,
        run_id       INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
        cycle        INTEGER NOT NULL CHECK (cycle >= 0),
        window_start INTEGER NOT NULL,
        window_end   INTEGER NOT NULL,
        issue_time   INTEGER NOT NULL,
        status       TEXT NOT NULL DEFAULT 'pending'
                     CHECK (status IN ('pending', 'running', 'done', 'failed', 'aborted')),
        attempts     INTEGER NOT NULL DEFAULT 0 CHECK (attempts >= 0),
        owner        TEXT,
        algorithm    TEXT,
        model_runs   INTEGER CHECK (model_runs IS NULL OR model_runs >= 0),
        wall_time_s  REAL CHECK (wall_time_s IS NULL OR wall_time_s >= 0),
        cost_before  REAL,
        cost_after   REAL,
        message      TEXT,
        started      TEXT,
        finished     TEXT,
        UNIQUE (run_id, cycle),
        CHECK (window_end > window_start),
        CHECK ((status IN ('done', 'failed', 'aborted')) = (finished IS NOT NULL))
    )""",
    """
    CREATE TABLE estimates (
        cycle_id  INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        parameter TEXT NOT NULL CHECK (length(parameter) > 0),
        value     REAL NOT NULL,
        std       REAL CHECK (std IS NULL OR std >= 0),
        unit      TEXT NOT NULL,
        accepted  INTEGER NOT NULL CHECK (accepted IN (0, 1)),
        reason    TEXT,
        PRIMARY KEY (cycle_id, parameter),
        CHECK (accepted = 1 OR reason IS NOT NULL)
    )""",
    """
    CREATE TABLE alerts (
        id        INTEGER PRIMARY KEY,
        cycle_id  INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        parameter TEXT,
        kind      TEXT NOT NULL CHECK (length(kind) > 0),
        message   TEXT NOT NULL,
        magnitude REAL
    )""",
    "CREATE INDEX alerts_cycle ON alerts(cycle_id)",
)

# --- version 2: ingested observations ------------------------------------------------------------------
_V2 = _statements(
    """
    CREATE TABLE observations (
        series   TEXT NOT NULL CHECK (length(series) > 0),
        time     INTEGER NOT NULL,
        source   TEXT NOT NULL CHECK (length(source) > 0),
        value    REAL NOT NULL,
        ingested TEXT NOT NULL,
        PRIMARY KEY (series, time, source)
    ) WITHOUT ROWID""",
)

# --- version 3: forecasts and their scores -------------------------------------------------------------
_V3 = _statements(
    """
    CREATE TABLE forecasts (
        cycle_id INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        kind     TEXT NOT NULL CHECK (kind IN ('updated', 'dss')),
        series   TEXT NOT NULL,
        time     INTEGER NOT NULL,
        lead_h   REAL NOT NULL CHECK (lead_h >= 0),
        value    REAL NOT NULL,
        PRIMARY KEY (cycle_id, kind, series, time)
    ) WITHOUT ROWID""",
    """
    CREATE TABLE forecast_scores (
        cycle_id    INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        kind        TEXT NOT NULL CHECK (kind IN ('updated', 'dss')),
        series      TEXT NOT NULL,
        lead_from_h REAL NOT NULL,
        lead_to_h   REAL NOT NULL,
        rmse        REAL NOT NULL CHECK (rmse >= 0),
        bias        REAL NOT NULL,
        n           INTEGER NOT NULL CHECK (n > 0),
        scored      TEXT NOT NULL,
        PRIMARY KEY (cycle_id, kind, series, lead_from_h),
        CHECK (lead_to_h > lead_from_h)
    )""",
)

# --- version 4: model states for the hot start of the next cycle ----------------------------------------
_V4 = _statements(
    """
    CREATE TABLE model_states (
        cycle_id INTEGER NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        name     TEXT NOT NULL CHECK (length(name) > 0),
        time     INTEGER NOT NULL,
        format   TEXT NOT NULL,
        data     BLOB NOT NULL,
        PRIMARY KEY (cycle_id, name)
    )""",
)

# --- version 5: observation flags and gaps, transitions, the issued forecast ------------------------------
_V5_STATEMENTS = (
    "ALTER TABLE observations ADD COLUMN flag TEXT NOT NULL DEFAULT 'ok' CHECK (flag IN ('ok', 'outlier'))",
    """
    CREATE TABLE observation_gaps (
        series    TEXT NOT NULL CHECK (length(series) > 0),
        source    TEXT NOT NULL CHECK (length(source) > 0),
        gap_start BIGINT NOT NULL,
        gap_end   BIGINT NOT NULL,
        ingested  TEXT NOT NULL,
        PRIMARY KEY (series, source, gap_start),
        CHECK (gap_end > gap_start)
    )""",
    "ALTER TABLE cycles ADD COLUMN issued_forecast TEXT CHECK (issued_forecast IN ('updated', 'dss'))",
    "ALTER TABLE cycles ADD COLUMN issued_reason TEXT",
    "ALTER TABLE cycles ADD COLUMN skill_updated DOUBLE PRECISION CHECK (skill_updated >= 0)",
    "ALTER TABLE cycles ADD COLUMN skill_dss DOUBLE PRECISION CHECK (skill_dss >= 0)",
    """
    CREATE TABLE transitions (
        cycle_id        BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        parameter       TEXT NOT NULL CHECK (length(parameter) > 0),
        time            BIGINT NOT NULL,
        value_before    DOUBLE PRECISION NOT NULL,
        value_after     DOUBLE PRECISION NOT NULL,
        unit            TEXT NOT NULL,
        found_cycle     INTEGER NOT NULL CHECK (found_cycle >= 0),
        cost_single     DOUBLE PRECISION,
        cost_transition DOUBLE PRECISION,
        p_value         DOUBLE PRECISION,
        PRIMARY KEY (cycle_id, parameter)
    )""",
)
_V5 = _statements(*_V5_STATEMENTS)


# --- version 6: state updating: the latest ensemble per run, forecast bands ----------------------------------
def _v6_statements(blob: str) -> tuple[str, ...]:
    """The statements of version 6 with the dialect's binary type (the only word that differs)."""
    return (
        f"""
        CREATE TABLE ensembles (
            run_id   BIGINT NOT NULL PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
            cycle_id BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
            time     BIGINT NOT NULL,
            members  INTEGER NOT NULL CHECK (members > 0),
            format   TEXT NOT NULL CHECK (length(format) > 0),
            data     {blob} NOT NULL
        )""",
        "CREATE INDEX ensembles_cycle ON ensembles(cycle_id)",
        """
        CREATE TABLE forecast_bands (
            cycle_id    BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
            series      TEXT NOT NULL CHECK (length(series) > 0),
            time        BIGINT NOT NULL,
            lead_h      DOUBLE PRECISION NOT NULL CHECK (lead_h >= 0),
            probability DOUBLE PRECISION NOT NULL CHECK (probability > 0 AND probability < 1),
            low         DOUBLE PRECISION NOT NULL,
            high        DOUBLE PRECISION NOT NULL,
            PRIMARY KEY (cycle_id, series, time),
            CHECK (high >= low)
        )""",
    )


_V6 = _statements(*_v6_statements("BLOB"))

# --- version 7: the run metrics with each cycle, products of a run ---------------------------------------------
def _v7_statements(blob: str) -> tuple[str, ...]:
    """The statements of version 7 with the dialect's binary type."""
    return (
        "ALTER TABLE cycles ADD COLUMN metrics TEXT",
        f"""
        CREATE TABLE run_products (
            run_id  BIGINT NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
            name    TEXT NOT NULL CHECK (length(name) > 0),
            format  TEXT NOT NULL CHECK (length(format) > 0),
            data    {blob} NOT NULL,
            created TEXT NOT NULL,
            PRIMARY KEY (run_id, name)
        )""",
    )


_V7 = _statements(*_v7_statements("BLOB"))

#: The forward steps, in order. Append only; never edit a released step.
MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "runs, cycles, estimates, alerts", _V1),
    Migration(2, "ingested observations", _V2),
    Migration(3, "forecasts and forecast scores", _V3),
    Migration(4, "model states for hot starts", _V4),
    Migration(5, "observation flags and gaps, transitions, the issued forecast and its skill", _V5),
    Migration(6, "the latest ensemble per run, forecast uncertainty bands", _V6),
    Migration(7, "the run metrics with each cycle, products of a run", _V7),
)
#: The version this rivercal writes.
SCHEMA_VERSION = MIGRATIONS[-1].version

# --- the same versions in PostgreSQL ----------------------------------------------------------------------
# The tables, columns, keys and checks of the SQLite steps above in PostgreSQL's types: BIGINT for data times
# (Unix seconds) and ids (an identity column where SQLite has INTEGER PRIMARY KEY), DOUBLE PRECISION for REAL
# (PostgreSQL's REAL is 4 bytes), BYTEA for BLOB, the JSON check through PostgreSQL's json type. A step here
# always matches the step of the same version above. Steps after version 4 are written once, in plain SQL that
# both servers run; versions 6 and 7 differ only in their binary type and are written once with it as a parameter.

PG_SCHEMA_VERSION_DDL = """
CREATE TABLE IF NOT EXISTS schema_version (
    version          INTEGER PRIMARY KEY,
    applied          TEXT NOT NULL,
    description      TEXT NOT NULL,
    rivercal_version TEXT NOT NULL
)"""

_PG_V1 = _statements(
    """
    CREATE TABLE runs (
        id        BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
        name      TEXT NOT NULL UNIQUE CHECK (length(name) > 0),
        case_name TEXT NOT NULL,
        created   TEXT NOT NULL,
        config    TEXT NOT NULL CHECK (json_typeof(config::json) = 'object'),
        status    TEXT NOT NULL DEFAULT 'active' CHECK (status IN ('active', 'stopped', 'finished', 'failed'))
    )""",
    """
    CREATE TABLE cycles (
        id           BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
        run_id       BIGINT NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
        cycle        INTEGER NOT NULL CHECK (cycle >= 0),
        window_start BIGINT NOT NULL,
        window_end   BIGINT NOT NULL,
        issue_time   BIGINT NOT NULL,
        status       TEXT NOT NULL DEFAULT 'pending'
                     CHECK (status IN ('pending', 'running', 'done', 'failed', 'aborted')),
        attempts     INTEGER NOT NULL DEFAULT 0 CHECK (attempts >= 0),
        owner        TEXT,
        algorithm    TEXT,
        model_runs   INTEGER CHECK (model_runs IS NULL OR model_runs >= 0),
        wall_time_s  DOUBLE PRECISION CHECK (wall_time_s IS NULL OR wall_time_s >= 0),
        cost_before  DOUBLE PRECISION,
        cost_after   DOUBLE PRECISION,
        message      TEXT,
        started      TEXT,
        finished     TEXT,
        UNIQUE (run_id, cycle),
        CHECK (window_end > window_start),
        CHECK ((status IN ('done', 'failed', 'aborted')) = (finished IS NOT NULL))
    )""",
    """
    CREATE TABLE estimates (
        cycle_id  BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        parameter TEXT NOT NULL CHECK (length(parameter) > 0),
        value     DOUBLE PRECISION NOT NULL,
        std       DOUBLE PRECISION CHECK (std IS NULL OR std >= 0),
        unit      TEXT NOT NULL,
        accepted  INTEGER NOT NULL CHECK (accepted IN (0, 1)),
        reason    TEXT,
        PRIMARY KEY (cycle_id, parameter),
        CHECK (accepted = 1 OR reason IS NOT NULL)
    )""",
    """
    CREATE TABLE alerts (
        id        BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
        cycle_id  BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        parameter TEXT,
        kind      TEXT NOT NULL CHECK (length(kind) > 0),
        message   TEXT NOT NULL,
        magnitude DOUBLE PRECISION
    )""",
    "CREATE INDEX alerts_cycle ON alerts(cycle_id)",
)

_PG_V2 = _statements(
    """
    CREATE TABLE observations (
        series   TEXT NOT NULL CHECK (length(series) > 0),
        time     BIGINT NOT NULL,
        source   TEXT NOT NULL CHECK (length(source) > 0),
        value    DOUBLE PRECISION NOT NULL,
        ingested TEXT NOT NULL,
        PRIMARY KEY (series, time, source)
    )""",
)

_PG_V3 = _statements(
    """
    CREATE TABLE forecasts (
        cycle_id BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        kind     TEXT NOT NULL CHECK (kind IN ('updated', 'dss')),
        series   TEXT NOT NULL,
        time     BIGINT NOT NULL,
        lead_h   DOUBLE PRECISION NOT NULL CHECK (lead_h >= 0),
        value    DOUBLE PRECISION NOT NULL,
        PRIMARY KEY (cycle_id, kind, series, time)
    )""",
    """
    CREATE TABLE forecast_scores (
        cycle_id    BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        kind        TEXT NOT NULL CHECK (kind IN ('updated', 'dss')),
        series      TEXT NOT NULL,
        lead_from_h DOUBLE PRECISION NOT NULL,
        lead_to_h   DOUBLE PRECISION NOT NULL,
        rmse        DOUBLE PRECISION NOT NULL CHECK (rmse >= 0),
        bias        DOUBLE PRECISION NOT NULL,
        n           INTEGER NOT NULL CHECK (n > 0),
        scored      TEXT NOT NULL,
        PRIMARY KEY (cycle_id, kind, series, lead_from_h),
        CHECK (lead_to_h > lead_from_h)
    )""",
)

_PG_V4 = _statements(
    """
    CREATE TABLE model_states (
        cycle_id BIGINT NOT NULL REFERENCES cycles(id) ON DELETE CASCADE,
        name     TEXT NOT NULL CHECK (length(name) > 0),
        time     BIGINT NOT NULL,
        format   TEXT NOT NULL,
        data     BYTEA NOT NULL,
        PRIMARY KEY (cycle_id, name)
    )""",
)

#: PostgreSQL's own form of the steps written in SQLite's dialect (INTEGER PRIMARY KEY, REAL, BLOB, WITHOUT
#: ROWID, json_valid). Every later step is plain SQL both servers run (BIGINT, DOUBLE PRECISION, TEXT, CHECK,
#: ALTER TABLE … ADD COLUMN) and is used as it stands; a step that cannot be written so adds its form here.
_PG_STEPS: dict[int, Callable[[_Connection], None]] = {1: _PG_V1, 2: _PG_V2, 3: _PG_V3, 4: _PG_V4,
                                                       6: _statements(*_v6_statements("BYTEA")),
                                                       7: _statements(*_v7_statements("BYTEA"))}



def for_postgresql(steps: Sequence[Migration]) -> tuple[Migration, ...]:
    """The steps as PostgreSQL runs them: the same versions and descriptions, PostgreSQL's form where one exists."""
    return tuple(Migration(m.version, m.description, _PG_STEPS.get(m.version, m.apply)) for m in steps)


#: The PostgreSQL steps: the same versions and descriptions as :data:`MIGRATIONS`.
PG_MIGRATIONS: tuple[Migration, ...] = for_postgresql(MIGRATIONS)


def user_tables(conn: _Connection) -> list[str]:
    """Names of the file's tables, without SQLite's own."""
    rows = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%' "
                        "ORDER BY name").fetchall()
    return [r[0] for r in rows]


def current_version(conn: _Connection) -> int:
    """The file's schema version (0 for a file without a ``schema_version`` table)."""
    if "schema_version" not in user_tables(conn):
        return 0
    row = conn.execute("SELECT max(version) FROM schema_version").fetchone()
    return int(row[0]) if row and row[0] is not None else 0
