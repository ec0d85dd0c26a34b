"""What the parts of :class:`rivercal.store.Store` share: the connection, the path and a few helpers.

:mod:`rivercal.store.sqlite` implements them; the query modules (:mod:`~rivercal.store._results`,
:mod:`~rivercal.store._observations`) only use them, so that they need not import :mod:`sqlite3`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rivercal.store.records import Run

__all__ = ["StoreBase"]


class StoreBase:
    """The shared state of the store's parts."""

    path: Path
    readonly: bool
    _conn: Any

    def _transaction(self) -> contextlib.AbstractContextManager[Any]:
        raise NotImplementedError

    def _query(self, sql: str, params: Sequence[Any] = ()) -> list[tuple]:
        return self._conn.execute(sql, params).fetchall()

    @staticmethod
    def _run_id(run: int | Run) -> int:
        return run.id if isinstance(run, Run) else int(run)

    def _cycle_row(self, conn: Any, run_id: int, cycle: int) -> tuple | None:
        """(id, window_start, window_end, issue_time, status, attempts, owner, started) of a cycle, or None."""
        return conn.execute("SELECT id, window_start, window_end, issue_time, status, attempts, owner, started "
                            "FROM cycles WHERE run_id = ? AND cycle = ?", (run_id, cycle)).fetchone()

    def _observation_rows(self, series_ids: Sequence[str], start: int | None, end: int | None) -> Any:
        raise NotImplementedError
