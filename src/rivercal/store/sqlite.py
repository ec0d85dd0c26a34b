"""The SQLite back-end of the store: one file holds everything a run has stored.

:class:`SqliteStore` implements the connection, transactions, migrations and integrity check of the abstract
:class:`~rivercal.store.base.Store` (whose docstring holds the crash-safety design) over :mod:`sqlite3`:

- **WAL journal, synchronous=FULL.** WAL lets a dashboard read while the service writes. In WAL mode
  ``synchronous=NORMAL`` already survives a killed *process* (committed pages are in the WAL file, in the
  operating system's cache) but may lose the last transactions on power loss or an OS crash; ``FULL``
  syncs the WAL at every commit so a committed cycle also survives those. A cycle commits once a day
  and an fsync costs milliseconds, so FULL is the default; ``synchronous="NORMAL"`` is available for bulk
  work where re-running the last cycles after a power cut is acceptable.
- **One writer at a time**: ``BEGIN IMMEDIATE`` takes the write lock when a transaction starts.
- **Readers on read-only file systems.** ``readonly=True`` opens the file with SQLite's ``mode=ro``; where
  its folder cannot be written (no shared-memory file can be made beside it) and no write-ahead log holds
  changes not yet in the file, the file is read as immutable.
- **Foreign keys on** for every connection; deleting a run deletes its cycles and their rows.

This back-end is the only module of rivercal that imports :mod:`sqlite3`; ``import rivercal`` does not load it.
"""

from __future__ import annotations

import contextlib
import logging
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

from rivercal.store.base import Store
from rivercal.store.records import StoreError
from rivercal.store.schema import (
    APPLICATION_ID,
    SCHEMA_VERSION_DDL,
    current_version,
    user_tables,
)

__all__ = ["MIN_SQLITE", "SqliteStore"]

log = logging.getLogger("rivercal.store")

#: Oldest SQLite library the store works with (window functions: 3.25; INSERT … RETURNING: 3.35).
MIN_SQLITE = (3, 35, 0)


class SqliteStore(Store):
    """The store in an SQLite file (module docstring); open it as ``Store(path)``.

    Parameters
    ----------
    path
        The database file (created with its schema when missing; its folder must exist).
    readonly, synchronous, timeout_s
        As :class:`~rivercal.store.base.Store`.
    """

    backend = "sqlite"

    def __init__(self, path: str | Path, *, readonly: bool = False,
                 synchronous: Literal["FULL", "NORMAL"] = "FULL", timeout_s: float = 30.0):
        if sqlite3.sqlite_version_info < MIN_SQLITE:
            raise StoreError(f"SQLite {sqlite3.sqlite_version} is too old for the store (needs "
                             f"{'.'.join(map(str, MIN_SQLITE))} or newer)")
        if synchronous not in ("FULL", "NORMAL"):
            raise ValueError(f"synchronous must be 'FULL' or 'NORMAL', got {synchronous!r}")
        self.path = Path(path)
        self.readonly = readonly
        if str(path) != ":memory:" and not self.path.parent.is_dir():
            raise StoreError(f"{self.path}: folder {self.path.parent} does not exist")
        if readonly and not self.path.is_file():
            raise StoreError(f"{self.path}: no such store")
        try:
            if readonly:
                self._conn = self._open_readonly(timeout_s)
            else:
                self._conn = sqlite3.connect(str(path), isolation_level=None, timeout=timeout_s)
        except sqlite3.Error as exc:
            raise StoreError(f"{self.path}: cannot open ({exc})") from None
        try:
            self._configure(synchronous)
            self._migrate()
        except sqlite3.OperationalError as exc:
            self._conn.close()
            raise StoreError(f"{self.path}: cannot use the store ({exc})") from None
        except sqlite3.DatabaseError as exc:
            self._conn.close()
            raise StoreError(f"{self.path}: not a usable SQLite database ({exc})") from None
        except BaseException:
            self._conn.close()
            raise

    # -- connection, transactions, migrations ---------------------------------------------------------------

    def _open_readonly(self, timeout_s: float) -> sqlite3.Connection:
        """A read-only connection; on a read-only file system too.

        A WAL-mode file is read through its shared-memory file (``-shm``), which SQLite creates beside the
        store; where the folder cannot be written (a read-only mount) the plain read-only open fails. Then,
        if no write-ahead log holds changes that are not yet in the file, the file is opened as immutable
        (nothing can change it there). A log with changes in it would be skipped by that: refused instead.
        """
        uri = self.path.resolve().as_uri() + "?mode=ro"
        conn = sqlite3.connect(uri, uri=True, isolation_level=None, timeout=timeout_s)
        try:
            conn.execute("PRAGMA schema_version").fetchone()
            return conn
        except sqlite3.OperationalError as exc:
            conn.close()
            if "unable to open" not in str(exc):
                raise
            wal = Path(f"{self.path}-wal")
            if wal.is_file() and wal.stat().st_size > 0:
                raise StoreError(f"{self.path}: cannot be read where it lies ({exc}): its folder cannot be written "
                                 f"(a read-only file system?) and its write-ahead log {wal.name} holds changes not yet "
                                 "in the store; copy the store and that file to a writable folder, or open it once "
                                 "for writing where it can be") from None
        log.info("%s: opened as an immutable file (its folder cannot be written)", self.path)
        return sqlite3.connect(uri + "&immutable=1", uri=True, isolation_level=None, timeout=timeout_s)

    def _configure(self, synchronous: str) -> None:
        conn = self._conn
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        tables = user_tables(conn)
        if app_id not in (0, APPLICATION_ID) or (app_id == 0 and tables and "schema_version" not in tables):
            raise StoreError(f"{self.path}: not a rivercal store (application id {app_id:#x}, tables "
                             f"{', '.join(tables) or 'none'})")
        if not self.readonly:
            mode = conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
            if mode.lower() != "wal" and str(self.path) != ":memory:":
                log.warning("%s: SQLite refused WAL mode (journal mode %s); commits stay atomic, but readers "
                            "block while the service writes", self.path, mode)
        conn.execute(f"PRAGMA synchronous = {synchronous}")
        conn.execute("PRAGMA foreign_keys = ON")

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """``BEGIN IMMEDIATE`` (take the write lock now) … ``COMMIT``; ``ROLLBACK`` on any exception."""
        if self.readonly:
            raise StoreError(f"{self.path}: opened read-only")
        try:
            self._conn.execute("BEGIN IMMEDIATE")
        except sqlite3.OperationalError as exc:  # the write lock was not released within the timeout
            raise StoreError(f"{self.path}: cannot start a write ({exc})") from exc
        try:
            yield self._conn
            self._conn.execute("COMMIT")
        except sqlite3.Error as exc:
            if self._conn.in_transaction:
                self._conn.execute("ROLLBACK")
            raise StoreError(f"{self.path}: write failed and was rolled back ({exc})") from exc
        except BaseException:
            if self._conn.in_transaction:
                self._conn.execute("ROLLBACK")
            raise

    def _version(self, conn: Any) -> int:
        return current_version(conn)

    def _first_step(self, conn: Any) -> None:
        """Before migration step 1: the version table and the file's application id."""
        conn.execute(SCHEMA_VERSION_DDL)
        conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")

    def _steps(self) -> tuple:
        """The schema's migration steps (this dialect's)."""
        return self._migrations()

    def _tables(self, conn: Any) -> list[str]:
        return user_tables(conn)

    def close(self) -> None:
        """Close the connection (uncommitted work, if any, is rolled back)."""
        self._conn.close()

    def integrity_check(self) -> list[str]:
        """Problems found by ``PRAGMA integrity_check`` and ``PRAGMA foreign_key_check`` (empty when sound)."""
        rows = [r[0] for r in self._conn.execute("PRAGMA integrity_check").fetchall()]
        problems = [] if rows == ["ok"] else rows
        for table, rowid, parent, _ in self._conn.execute("PRAGMA foreign_key_check").fetchall():
            problems.append(f"{table} row {rowid}: no parent row in {parent}")
        return problems

