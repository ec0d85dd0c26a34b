"""The store in a PostgreSQL database: the same contract as the SQLite file, for several services and readers.

``Store("postgresql://user@host/dbname")`` returns a :class:`PostgresStore` (psycopg 3; install rivercal's
``postgresql`` extra). Everything :class:`rivercal.store.Store` promises holds here too, by these means:

- **One transaction per cycle**, as in SQLite; PostgreSQL rolls back the open transaction of a client
  that is killed or loses its connection, so a killed service leaves its cycle ``running`` without results.
- **One writer at a time.** Every write transaction first takes a transaction-level advisory lock
  (``pg_advisory_xact_lock``), the counterpart of SQLite's ``BEGIN IMMEDIATE``: the checks of a cycle
  (next index, no gap, owner) and its writes see no other writer in between. Services writing different
  runs therefore take turns for the milliseconds of a commit and never block readers (MVCC).
- **Readers** (a report, the dashboard) read committed data while services write; ``readonly=True``
  makes the session read-only.
- **Durability**: ``synchronous="FULL"`` keeps PostgreSQL's ``synchronous_commit = on`` (a commit is on
  disk when it returns); ``"NORMAL"`` sets it ``off`` (a crash of the server may lose the last commits;
  a killed client never loses a committed one).
- **Migrations**: :data:`~rivercal.store.schema.PG_MIGRATIONS`, the same versions as the SQLite file (a step
  written in plain SQL is shared by both);
  the version table carries the comment ``rivercal store`` (SQLite's application id) so that a database
  holding other tables is not taken for a store.

Tables live in the connection's current schema (``options=-csearch_path=NAME`` in the URL puts a store in
a schema of its own). The password of the URL never appears in messages or logs.
"""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Iterator, Sequence
from typing import Any, Literal

from rivercal.store.base import Store
from rivercal.store.records import StoreError
from rivercal.store.schema import APPLICATION_ID, PG_SCHEMA_VERSION_DDL, for_postgresql

__all__ = ["PostgresStore"]

log = logging.getLogger("rivercal.store")

_MARK = "rivercal store"
#: Child tables and their parent, for the integrity check.
_PARENTS = {"cycles": ("run_id", "runs"), "estimates": ("cycle_id", "cycles"), "alerts": ("cycle_id", "cycles"),
            "forecasts": ("cycle_id", "cycles"), "forecast_scores": ("cycle_id", "cycles"),
            "model_states": ("cycle_id", "cycles"), "forecast_bands": ("cycle_id", "cycles"),
            "ensembles": ("cycle_id", "cycles")}


def _masked(url: str) -> str:
    """The URL without its password."""
    return re.sub(r"(://[^:/@]+):[^@/]*@", r"\1:***@", url)


class _Connection:
    """The store's queries (``?`` placeholders, as sqlite3) on a psycopg connection in autocommit mode."""

    def __init__(self, raw: Any):
        self.raw = raw

    @staticmethod
    def _sql(sql: str) -> str:
        return sql.replace("%", "%%").replace("?", "%s")

    def execute(self, sql: str, params: Sequence[Any] = ()) -> Any:
        if params:
            return self.raw.execute(self._sql(sql), tuple(params))
        return self.raw.execute(sql)

    def executemany(self, sql: str, rows: Any) -> None:
        rows = list(rows)
        if rows:
            with self.raw.cursor() as cursor:
                cursor.executemany(self._sql(sql), rows)

    @property
    def in_transaction(self) -> bool:
        from psycopg.pq import TransactionStatus

        return self.raw.info.transaction_status != TransactionStatus.IDLE


class PostgresStore(Store):
    """The on-line service's store in a PostgreSQL database (see the module docstring); ``Store(url)`` opens it.

    Parameters
    ----------
    path
        ``postgresql://[user[:password]@][host][:port]/dbname[?options]`` (libpq's URL form).
    readonly, synchronous, timeout_s
        As :class:`rivercal.store.Store`; ``timeout_s`` is also the connection timeout.

    Raises
    ------
    StoreError
        If psycopg is missing, the server cannot be reached, or the database holds other tables.
    StoreVersionError
        As :class:`rivercal.store.Store`.
    """

    backend = "postgresql"

    def __init__(self, path: str, *, readonly: bool = False, synchronous: Literal["FULL", "NORMAL"] = "FULL",
                 timeout_s: float = 30.0):
        if synchronous not in ("FULL", "NORMAL"):
            raise ValueError(f"synchronous must be 'FULL' or 'NORMAL', got {synchronous!r}")
        try:
            import psycopg
        except ImportError:
            raise StoreError("a PostgreSQL store needs psycopg: install rivercal with the 'postgresql' extra "
                             "(pip install 'rivercal[postgresql]')") from None
        self._psycopg = psycopg
        self.url = str(path)
        self.path = _masked(self.url)  # type: ignore[assignment] - a URL, shown in messages
        self.readonly = readonly
        try:
            raw = psycopg.connect(self.url, autocommit=True, connect_timeout=max(1, round(timeout_s)))
        except psycopg.Error as exc:
            raise StoreError(f"{self.path}: cannot connect ({_first_line(exc)})") from None
        self._conn = _Connection(raw)
        try:
            raw.execute(f"SET lock_timeout = {int(timeout_s * 1000)}")
            raw.execute(f"SET synchronous_commit = {'on' if synchronous == 'FULL' else 'off'}")
            if readonly:
                raw.execute("SET default_transaction_read_only = on")
            self._check_database()
            if readonly and self._version(self._conn) == 0:
                raise StoreError(f"{self.path}: no such store (the database holds no rivercal tables)")
            self._migrate()
        except psycopg.Error as exc:
            raw.close()
            raise StoreError(f"{self.path}: cannot use the store ({_first_line(exc)})") from None
        except BaseException:
            raw.close()
            raise

    # -- connection, transactions, migrations ------------------------------------------------------------

    def _tables(self, conn: Any) -> list[str]:
        rows = conn.execute("SELECT table_name FROM information_schema.tables WHERE table_schema = current_schema() "
                            "AND table_type = 'BASE TABLE' ORDER BY table_name").fetchall()
        return [r[0] for r in rows]

    def _check_database(self) -> None:
        tables = self._tables(self._conn)
        mark = None
        if "schema_version" in tables:
            mark = self._conn.execute("SELECT obj_description(to_regclass('schema_version'), 'pg_class')").fetchone()[0]
        if (tables and "schema_version" not in tables) or ("schema_version" in tables and mark != _MARK):
            raise StoreError(f"{self.path}: not a rivercal store (its schema holds the tables "
                             f"{', '.join(tables)}); use another database or schema")

    def _version(self, conn: Any) -> int:
        if conn.execute("SELECT to_regclass('schema_version')").fetchone()[0] is None:
            return 0
        row = conn.execute("SELECT max(version) FROM schema_version").fetchone()
        return int(row[0]) if row and row[0] is not None else 0

    def _steps(self) -> tuple:
        return for_postgresql(self._migrations())

    def _first_step(self, conn: Any) -> None:
        conn.execute(PG_SCHEMA_VERSION_DDL)
        conn.execute(f"COMMENT ON TABLE schema_version IS '{_MARK}'")

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[Any]:
        """``BEGIN``, the store's write lock (an advisory lock) … ``COMMIT``; ``ROLLBACK`` on any exception."""
        if self.readonly:
            raise StoreError(f"{self.path}: opened read-only")
        psycopg = self._psycopg
        conn = self._conn
        try:
            conn.execute("BEGIN")
            conn.execute("SELECT pg_advisory_xact_lock(?)", (APPLICATION_ID,))
        except psycopg.Error as exc:  # the lock was not released within the timeout, or the server went away
            self._rollback()
            raise StoreError(f"{self.path}: cannot start a write ({_first_line(exc)})") from exc
        try:
            yield conn
            conn.execute("COMMIT")
        except psycopg.Error as exc:
            self._rollback()
            raise StoreError(f"{self.path}: write failed and was rolled back ({_first_line(exc)})") from exc
        except BaseException:
            self._rollback()
            raise

    def _rollback(self) -> None:
        if not self._conn.raw.closed and self._conn.in_transaction:
            self._conn.execute("ROLLBACK")

    def close(self) -> None:
        """Close the connection (uncommitted work, if any, is rolled back by the server)."""
        self._conn.raw.close()

    def integrity_check(self) -> list[str]:
        """Rows whose parent row is missing (PostgreSQL enforces the keys; this checks them all the same)."""
        problems = []
        for table, (column, parent) in _PARENTS.items():
            n = self._conn.execute(f"SELECT count(*) FROM {table} t LEFT JOIN {parent} p ON p.id = t.{column} "
                                   "WHERE p.id IS NULL").fetchone()[0]
            if n:
                problems.append(f"{table}: {n} rows without a parent row in {parent}")
        return problems


def _first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
