"""The store of the on-line service, whatever holds it: runs, cycles, estimates, alerts, forecasts, observations.

:class:`Store` is the abstract store: everything the service and its readers ask of it, written once over
the connection of a back-end beside it — :class:`~rivercal.store.sqlite.SqliteStore` (one file, the default)
and :class:`~rivercal.store.postgres.PostgresStore` (a PostgreSQL database that several services and
readers share). ``Store(location)`` opens the back-end the location names (a ``postgresql://`` URL or a
file); this module imports neither (:data:`BACKENDS` names them; schema and units: :mod:`rivercal.store.schema`).

The store is built so that **nothing that was stored is lost when a process is killed**, and no cycle is
stored twice or skipped:

- **One transaction per cycle.** :meth:`Store.commit_cycle` writes a cycle's final status, estimates,
  alerts and forecasts in one transaction that holds the store's write lock: a cycle is stored whole or
  not at all.
- **Resume where it stopped.** :meth:`Store.begin_cycle` marks a cycle ``running`` before its computation;
  a process killed in between leaves it ``running`` with no results, and :meth:`Store.next_cycle` returns
  that cycle again on restart (then the next index). Cycle indices are contiguous and unique
  (UNIQUE (run_id, cycle); a gap or a second commit of a final cycle is refused).
- **One process per cycle.** The process that begins a cycle is recorded by its process id and start time
  (``pid@host/start``); while that process runs, another is refused the cycle. A process that merely has
  the dead owner's id (after a reboot or a container restart) is told apart by its start time;
  ``begin_cycle(..., take_over=True)`` (``rivercal online --take-over``) overrides the check.
- **Foreign keys** everywhere; deleting a run deletes its cycles and their rows.

Durability, readers and locking are the back-ends' (:mod:`rivercal.store.sqlite`, :mod:`rivercal.store.postgres`).

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> from rivercal.store import Store, Schedule, CycleRecord, EstimateRecord
>>> with tempfile.TemporaryDirectory() as folder, Store(Path(folder) / "service.db") as store:
...     run = store.ensure_run("dommel", "dommel", {"window_days": 7})
...     spec = store.begin_cycle(run.id, store.next_cycle(run.id, Schedule("2010-11-01T06:00Z")))
...     store.commit_cycle(run.id, CycleRecord(spec.cycle, spec.window_start, spec.window_end, spec.issue_time,
...                                            estimates=[EstimateRecord("FA", 25.2, "m^(1/3)/s", std=0.4)]))
...     store.estimates(run)[["cycle", "parameter", "value", "std", "accepted"]]
   cycle parameter  value  std  accepted
0      0        FA   25.2  0.4      True
"""

from __future__ import annotations

import contextlib
import importlib
import json
import logging
import os
import socket
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import pandas as pd

import rivercal
from rivercal.store import _frames as fr
from rivercal.store._observations import ObservationTables
from rivercal.store._results import ResultTables
from rivercal.store.records import (
    CYCLE_STATUSES,
    FINAL_STATUSES,
    RUN_STATUSES,
    CycleRecord,
    CycleSpec,
    CycleStateError,
    Run,
    RunMismatchError,
    Schedule,
    StoreError,
    StoreVersionError,
    utc,
)
from rivercal.store.schema import MIGRATIONS, SCHEMA_VERSION

__all__ = ["BACKENDS", "Store", "is_url"]

log = logging.getLogger("rivercal.store")

#: The back-ends by the kind of location: module and class (imported on first use; each subclasses :class:`Store`).
BACKENDS = {"sqlite": ("rivercal.store.sqlite", "SqliteStore"), "postgresql": ("rivercal.store.postgres",
                                                                                "PostgresStore")}

_CYCLE_COLUMNS = ("cycle", "window_start", "window_end", "issue_time", "status", "attempts", "owner", "algorithm",
                  "model_runs", "wall_time_s", "cost_before", "cost_after", "message", "started", "finished",
                  "issued_forecast", "issued_reason", "skill_updated", "skill_dss")
_UNFINISHED = tuple(s for s in CYCLE_STATUSES if s not in FINAL_STATUSES)
#: Tables whose rows belong to one cycle's results (replaced together when a cycle is committed or re-opened).
_CYCLE_CHILDREN = ("estimates", "alerts", "forecasts", "forecast_scores", "model_states", "transitions",
                   "forecast_bands", "ensembles")


def is_url(location: Any) -> bool:
    """Whether a store location is a PostgreSQL URL (``postgresql://…`` or ``postgres://…``) and not a file."""
    return isinstance(location, str) and location.startswith(("postgresql://", "postgres://"))


def _owner() -> str:
    """The owner this process writes into a cycle: ``pid@host/start``, start being its start time (Unix s)."""
    pid = os.getpid()
    start = _process_start(pid)
    return f"{pid}@{socket.gethostname()}" + (f"/{start:.2f}" if start is not None else "")


def _process_start(pid: int) -> float | None:
    """When process ``pid`` started (Unix seconds, to 0.01 s), or None when it does not run or cannot be seen."""
    import psutil

    try:
        return float(psutil.Process(pid).create_time())
    except (psutil.Error, OSError, ValueError):
        return None


def _parse_owner(owner: str) -> tuple[str, str, float | None]:
    """``pid@host/start`` (or ``pid@host``, as stores written before start times kept it) → (pid, host, start)."""
    who, _, start = owner.partition("/")
    pid_text, _, host = who.partition("@")
    try:
        return pid_text, host, float(start) if start else None
    except ValueError:
        return pid_text, host, None


def _owner_alive(owner: str | None, started: str | None = None) -> bool:
    """Whether ``owner`` is another process of this host that still runs: the same process id AND start time.

    A process id alone is not enough: after a reboot or a container restart another program (often the
    container's process 1) has the dead service's id. A record with its owner's start time matches only the
    process that started then (within 1 s); a record without one (written before start times were kept)
    cannot be owned by a process that started after the cycle was begun (``started``, the stored stamp).
    """
    if not owner:
        return False
    pid_text, host, start = _parse_owner(owner)
    if host != socket.gethostname() or not pid_text.isdigit():
        return False  # another host: no way to know; the caller's lock is the authority there
    if int(pid_text) == os.getpid():
        return False  # this process: a cycle it began itself (or its id's dead earlier holder)
    try:
        os.kill(int(pid_text), 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # alive, another user's
    except OSError:
        return False
    running_since = _process_start(int(pid_text))
    if running_since is None:
        return True  # alive, but its start cannot be read: take it for the owner (the override is there for this)
    if start is not None:
        return abs(running_since - start) < 1.0
    if started is not None:
        begun = fr.stamp_to_time(started)
        if not pd.isna(begun) and running_since > begun.timestamp() + 1.0:
            return False
    return True


def _describe_owner(owner: str) -> str:
    """``process 1234@vm (started 2026-11-25 10:00:01 UTC)`` for messages."""
    pid_text, host, start = _parse_owner(owner)
    when = f" (started {pd.Timestamp(start, unit='s', tz='UTC'):%Y-%m-%d %H:%M:%S} UTC)" if start else ""
    return f"process {pid_text}@{host}{when}"


class Store(ResultTables, ObservationTables):
    """The on-line service's store (module docstring); ``Store(location)`` opens the back-end of ``location``.

    Parameters
    ----------
    path
        An SQLite file (created with its schema when missing; its folder must exist) or a
        ``postgresql://`` URL.
    readonly
        Open for reading only (a dashboard); an older schema is then an error instead of being migrated.
    synchronous
        ``"FULL"`` (default: a commit survives power loss) or ``"NORMAL"`` (survives a killed process).
    timeout_s
        How long to wait for another connection's write lock, s.

    Raises
    ------
    StoreError
        If the location is not a rivercal store or cannot be opened.
    StoreVersionError
        If its schema is newer than this rivercal's (or older, when ``readonly``).
    """

    #: The kind of location a back-end serves (a key of :data:`BACKENDS`).
    backend: ClassVar[str] = ""

    def __new__(cls, path: str | Path = ":memory:", **kwargs: Any) -> Store:
        """The back-end of the location: PostgreSQL for a ``postgresql://`` URL, else SQLite."""
        if cls is Store:
            module, name = BACKENDS["postgresql" if is_url(path) else "sqlite"]
            cls = getattr(importlib.import_module(module), name)
        return super().__new__(cls)

    # -- what each back-end provides ---------------------------------------------------------------------------

    def _transaction(self) -> contextlib.AbstractContextManager[Any]:
        """A write transaction that holds the store's write lock; rolled back on any exception."""
        raise NotImplementedError

    def _version(self, conn: Any) -> int:
        """The schema version of the store (0 when it has none yet)."""
        raise NotImplementedError

    def _tables(self, conn: Any) -> list[str]:
        """Names of the store's own tables."""
        raise NotImplementedError

    def _first_step(self, conn: Any) -> None:
        """Before migration step 1: the version table and the store's mark."""
        raise NotImplementedError

    def _steps(self) -> tuple:
        """The schema's migration steps in the back-end's dialect (:data:`~rivercal.store.schema.MIGRATIONS`)."""
        raise NotImplementedError

    @staticmethod
    def _migrations() -> tuple:
        """The schema's migration steps as written (in SQLite's dialect)."""
        return MIGRATIONS

    def close(self) -> None:
        """Close the connection (uncommitted work, if any, is rolled back)."""
        raise NotImplementedError

    def integrity_check(self) -> list[str]:
        """Problems of the stored rows (empty when sound)."""
        raise NotImplementedError

    def _migrate(self, target: int | None = None) -> None:
        target = SCHEMA_VERSION if target is None else target
        version = self._version(self._conn)
        if version > SCHEMA_VERSION:
            raise StoreVersionError(f"{self.path}: schema version {version} was written by a newer rivercal (this "
                                    f"one knows up to {SCHEMA_VERSION}); upgrade rivercal to use it")
        if version >= target:
            return
        if self.readonly and version == 0 and not self._tables(self._conn):
            raise StoreError(f"{self.path}: not a rivercal store: an empty database (no run was ever written to it)")
        if self.readonly:
            raise StoreVersionError(f"{self.path}: schema version {version} is older than {SCHEMA_VERSION}; open it "
                                    "once for writing to migrate it")
        for step in self._steps():
            if step.version > target:
                break
            with self._transaction() as conn:
                # Re-read under the write lock: another process may have migrated meanwhile.
                if self._version(conn) >= step.version:
                    continue
                if step.version == 1:
                    self._first_step(conn)
                step.apply(conn)
                conn.execute("INSERT INTO schema_version (version, applied, description, rivercal_version) "
                             "VALUES (?, ?, ?, ?)", (step.version, fr.now_stamp(), step.description,
                                                     rivercal.__version__))
            log.info("%s: schema migrated to version %d (%s)", self.path, step.version, step.description)

    @property
    def schema_version(self) -> int:
        """The file's schema version."""
        return self._version(self._conn)

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- runs -----------------------------------------------------------------------------------------------

    def create_run(self, name: str, case: str, config: Mapping[str, Any] | None = None) -> int:
        """Create a run; returns its id.

        Parameters
        ----------
        name
            Unique run name.
        case
            Case name or path the run serves.
        config
            The run's configuration (JSON-serialisable mapping; numpy numbers, times and paths are converted).

        Raises
        ------
        StoreError
            If a run of that name exists.
        """
        text = fr.config_json(config or {})
        with self._transaction() as conn:
            if conn.execute("SELECT 1 FROM runs WHERE name = ?", (name,)).fetchone():
                raise StoreError(f"{self.path}: a run named {name!r} exists already")
            run_id = int(conn.execute("INSERT INTO runs (name, case_name, created, config) VALUES (?, ?, ?, ?) "
                                      "RETURNING id", (name, str(case), fr.now_stamp(), text)).fetchone()[0])
        log.info("%s: run %r created (id %d, case %s)", self.path, name, run_id, case)
        return run_id

    def get_run(self, name: str) -> Run | None:
        """The run named ``name``, or None."""
        row = self._conn.execute("SELECT id, name, case_name, created, config, status FROM runs WHERE name = ?",
                                 (name,)).fetchone()
        if row is None:
            return None
        return Run(id=row[0], name=row[1], case=row[2], created=fr.stamp_to_time(row[3]),
                   config=json.loads(row[4]), status=row[5])

    def ensure_run(self, name: str, case: str, config: Mapping[str, Any] | None = None) -> Run:
        """The run named ``name``, created if missing; a restarted service calls this.

        Raises
        ------
        RunMismatchError
            If the run exists with another case or configuration (resuming would mix two set-ups); the
            message names the differing keys.
        """
        run = self.get_run(name)
        if run is None:
            self.create_run(name, case, config)
            run = self.get_run(name)
            assert run is not None
            return run
        if run.case != str(case):
            raise RunMismatchError(f"{self.path}: run {name!r} serves case {run.case!r}, not {case!r}")
        differ = fr.config_differences(run.config, config or {})
        if differ:
            raise RunMismatchError(f"{self.path}: run {name!r} was created with another configuration (keys differ: "
                             f"{', '.join(differ)}); use a new run name")
        return run

    def runs(self) -> pd.DataFrame:
        """All runs: id, name, case, created (UTC), status, cycles (count) and done (count)."""
        rows = self._query("SELECT r.id, r.name, r.case_name, r.created, r.status, count(c.id), "
                           "coalesce(sum(CASE WHEN c.status = 'done' THEN 1 ELSE 0 END), 0) FROM runs r LEFT JOIN "
                           "cycles c ON c.run_id = r.id GROUP BY r.id, r.name, r.case_name, r.created, r.status "
                           "ORDER BY r.id")
        out = fr.frame(rows, ["id", "name", "case", "created", "status", "cycles", "done"])
        out["created"] = fr.stamp_to_time(out["created"])
        return out

    def set_run_status(self, run: int | Run, status: str) -> None:
        """Set a run's status (one of :data:`~rivercal.store.records.RUN_STATUSES`)."""
        if status not in RUN_STATUSES:
            raise ValueError(f"run status must be one of {', '.join(RUN_STATUSES)}, got {status!r}")
        with self._transaction() as conn:
            if conn.execute("UPDATE runs SET status = ? WHERE id = ?", (status, self._run_id(run))).rowcount != 1:
                raise StoreError(f"{self.path}: no run with id {self._run_id(run)}")

    # -- cycles ---------------------------------------------------------------------------------------------

    def cycles(self, run: int | Run) -> pd.DataFrame:
        """The run's cycles in order.

        Returns
        -------
        DataFrame
            Columns cycle, window_start, window_end, issue_time (UTC), status, attempts, owner, algorithm,
            model_runs, wall_time_s (s), cost_before, cost_after (dimensionless), message, started, finished
            (UTC wall clock), issued_forecast (``updated``, ``dss`` or None), issued_reason, skill_updated,
            skill_dss (RMSE of recent level forecasts, m).
        """
        rows = self._query(f"SELECT {', '.join(_CYCLE_COLUMNS)} FROM cycles WHERE run_id = ? ORDER BY cycle",
                           (self._run_id(run),))
        out = fr.frame(rows, _CYCLE_COLUMNS)
        for col in ("window_start", "window_end", "issue_time"):
            out[col] = fr.from_unix(out[col].astype("int64"))
        for col in ("started", "finished"):
            out[col] = fr.stamp_to_time(out[col])
        for col in ("skill_updated", "skill_dss"):
            out[col] = out[col].astype(float)
        return out

    @staticmethod
    def _spec(row: Sequence[Any]) -> CycleSpec:
        """CycleSpec from (cycle, window_start, window_end, issue_time, status, attempts)."""
        return CycleSpec(int(row[0]), fr.from_unix(row[1]), fr.from_unix(row[2]), fr.from_unix(row[3]),
                         status=row[4], attempts=int(row[5]))

    def first_unfinished(self, run: int | Run) -> CycleSpec | None:
        """The lowest-index cycle that is pending or running (left by a killed process), or None."""
        row = self._conn.execute(
            "SELECT cycle, window_start, window_end, issue_time, status, attempts FROM cycles WHERE run_id = ? "
            f"AND status IN ({', '.join('?' * len(_UNFINISHED))}) ORDER BY cycle LIMIT 1",
            (self._run_id(run), *_UNFINISHED)).fetchone()
        return None if row is None else self._spec(row)

    def next_cycle(self, run: int | Run, schedule: Schedule, now: Any | None = None) -> CycleSpec | None:
        """The cycle to compute next: the first unfinished one, else the one after the last stored.

        Cycle 0 is issued at ``schedule.first_issue``; a new cycle ``schedule.period`` after the last stored
        cycle's issue time, with window [t₀ − ``schedule.window``, t₀]. A stored unfinished cycle keeps its
        stored window.

        Parameters
        ----------
        run
            Run id.
        schedule
            The cycle schedule.
        now
            If given, a new cycle whose issue time is after ``now`` is not due yet: None is returned.
        """
        resume = self.first_unfinished(run)
        if resume is not None:
            return resume
        last = self._conn.execute("SELECT cycle, issue_time FROM cycles WHERE run_id = ? ORDER BY cycle DESC "
                                  "LIMIT 1", (self._run_id(run),)).fetchone()
        if last is None:
            spec = schedule.spec(0)
        else:
            spec = schedule.spec(int(last[0]) + 1, fr.from_unix(last[1]) + schedule.period)
        if now is not None and spec.issue_time > utc(now):
            return None
        return spec

    def _check_new_cycle(self, conn: Any, run_id: int, cycle: int) -> None:
        if conn.execute("SELECT 1 FROM runs WHERE id = ?", (run_id,)).fetchone() is None:
            raise StoreError(f"{self.path}: no run with id {run_id}")
        last = conn.execute("SELECT max(cycle) FROM cycles WHERE run_id = ?", (run_id,)).fetchone()[0]
        expected = 0 if last is None else int(last) + 1
        if cycle != expected:
            raise CycleStateError(f"{self.path}: run {run_id}: cycle {cycle} would leave a gap (next index is "
                                  f"{expected})")
        unfinished = conn.execute(f"SELECT min(cycle) FROM cycles WHERE run_id = ? AND status IN "
                                  f"({', '.join('?' * len(_UNFINISHED))})", (run_id, *_UNFINISHED)).fetchone()[0]
        if unfinished is not None:
            raise CycleStateError(f"{self.path}: run {run_id}: cycle {unfinished} is unfinished; finish it before "
                                  f"cycle {cycle}")

    def _check_existing_cycle(self, row: tuple, run_id: int, spec: CycleSpec, take_over: bool = False) -> None:
        _, w0, w1, t0, status, _, owner, started = row
        if status in FINAL_STATUSES:
            raise CycleStateError(f"{self.path}: run {run_id}: cycle {spec.cycle} is already {status}; it is not "
                                  "stored twice (retry_cycle() re-opens it)")
        stored = (w0, w1, t0)
        given = tuple(fr.to_unix(t) for t in (spec.window_start, spec.window_end, spec.issue_time))
        if stored != given:
            raise CycleStateError(
                f"{self.path}: run {run_id}: cycle {spec.cycle} is stored with window "
                f"{fr.from_unix(w0).isoformat()}/{fr.from_unix(w1).isoformat()}, issue {fr.from_unix(t0).isoformat()}; "
                f"got {spec.window_start.isoformat()}/{spec.window_end.isoformat()}, "
                f"issue {spec.issue_time.isoformat()}")
        if _owner_alive(owner, started):
            if take_over:
                log.warning("%s: run %d: cycle %d: taking it over from %s, which still runs (take-over asked for)",
                            self.path, run_id, spec.cycle, _describe_owner(owner))
                return
            raise CycleStateError(f"{self.path}: run {run_id}: cycle {spec.cycle} is being computed by "
                                  f"{_describe_owner(owner)}, which is still alive. If that process is not a rivercal "
                                  "service of this run (after a reboot or a container restart another program can "
                                  "have its process id), take the cycle over: rivercal online --take-over (in "
                                  "Python: begin_cycle(..., take_over=True))")

    def begin_cycle(self, run: int | Run, spec: CycleSpec, *, take_over: bool = False) -> CycleSpec:
        """Mark a cycle running (inserting it if new) before computing it; returns it as stored.

        A new cycle must be the next index and every earlier cycle final. A cycle left ``running`` by a dead
        process is taken over (``attempts`` grows); one owned by a live process on this host is refused.
        The owner is known by its process id and its start time (``pid@host/start``), so a process that
        merely has the dead owner's id (after a reboot or a container restart) is not taken for it.

        Parameters
        ----------
        run, spec
            The run and the cycle.
        take_over
            Take the cycle over even when its owner looks alive (logged): for the case the start time cannot
            tell, e.g. a store written before start times were kept whose owner's id was reused. Only when no
            other service computes this run.

        Raises
        ------
        CycleStateError
            For a gap, an unfinished earlier cycle, a final cycle, a different window, or a live owner.
        """
        run_id = self._run_id(run)
        values = [fr.to_unix(t) for t in (spec.window_start, spec.window_end, spec.issue_time)]
        with self._transaction() as conn:
            row = self._cycle_row(conn, run_id, spec.cycle)
            if row is None:
                self._check_new_cycle(conn, run_id, spec.cycle)
                conn.execute("INSERT INTO cycles (run_id, cycle, window_start, window_end, issue_time, status, "
                             "attempts, owner, started) VALUES (?, ?, ?, ?, ?, 'running', 1, ?, ?)",
                             (run_id, spec.cycle, *values, _owner(), fr.now_stamp()))
                attempts = 1
            else:
                self._check_existing_cycle(row, run_id, spec, take_over)
                if row[4] == "running":
                    log.warning("%s: run %d: cycle %d was left running by %s (attempt %d); computing it again",
                                self.path, run_id, spec.cycle, row[6], row[5])
                attempts = int(row[5]) + 1
                conn.execute("UPDATE cycles SET status = 'running', attempts = ?, owner = ?, started = ? WHERE id = ?",
                             (attempts, _owner(), fr.now_stamp(), row[0]))
        return CycleSpec(spec.cycle, spec.window_start, spec.window_end, spec.issue_time, "running", attempts)

    def commit_cycle(self, run: int | Run, record: CycleRecord) -> None:
        """Store a cycle's final status, estimates, alerts, forecasts, states and scores in ONE transaction.

        Either all of it is stored or none (a kill during the commit leaves the cycle as it was: running,
        without results). A cycle that was not begun is inserted (it must be the next index).

        Raises
        ------
        CycleStateError
            If the cycle is final already, would leave a gap, has another window, or a live process owns it.
        ValueError
            For forecasts with bad times or series ids (checked before anything is written).
        """
        run_id = self._run_id(run)
        rows = fr.forecast_rows(record.forecasts, record.cycle, record.issue_time)  # checked before writing
        bands = fr.band_rows(record.bands, record.cycle, record.issue_time)
        started = None
        with self._transaction() as conn:
            row = self._cycle_row(conn, run_id, record.cycle)
            if row is None:
                self._check_new_cycle(conn, run_id, record.cycle)
                values = [fr.to_unix(t) for t in (record.window_start, record.window_end, record.issue_time)]
                cycle_id = int(conn.execute("INSERT INTO cycles (run_id, cycle, window_start, window_end, "
                                            "issue_time, status, attempts, owner) VALUES (?, ?, ?, ?, ?, 'running', "
                                            "1, ?) RETURNING id", (run_id, record.cycle, *values, _owner()))
                                .fetchone()[0])
            else:
                self._check_existing_cycle(row, run_id, record.spec)
                cycle_id, started = int(row[0]), row[7]
            finished = fr.now_stamp()
            wall = record.wall_time_s
            if wall is None and started is not None:
                wall = max(0.0, (fr.stamp_to_time(finished) - fr.stamp_to_time(started)).total_seconds())
            for table in _CYCLE_CHILDREN:
                conn.execute(f"DELETE FROM {table} WHERE cycle_id = ?", (cycle_id,))
            conn.execute("UPDATE cycles SET status = ?, algorithm = ?, model_runs = ?, wall_time_s = ?, "
                         "cost_before = ?, cost_after = ?, message = ?, finished = ?, issued_forecast = ?, "
                         "issued_reason = ?, skill_updated = ?, skill_dss = ?, metrics = NULL WHERE id = ?",
                         (record.status, record.algorithm, record.model_runs, wall, record.cost_before,
                          record.cost_after, record.message, finished, record.issued, record.issued_reason,
                          record.skill_updated, record.skill_dss, cycle_id))
            conn.executemany("INSERT INTO estimates (cycle_id, parameter, value, std, unit, accepted, reason) "
                             "VALUES (?, ?, ?, ?, ?, ?, ?)",
                             [(cycle_id, e.parameter, float(e.value), e.std, e.unit, int(e.accepted), e.reason)
                              for e in record.estimates])
            log.debug("commit cycle %d of run %d: cycle row and %d estimates written; writing %d alerts and %d "
                      "forecast values", record.cycle, run_id, len(record.estimates), len(record.alerts), len(rows))
            conn.executemany("INSERT INTO alerts (cycle_id, parameter, kind, message, magnitude) "
                             "VALUES (?, ?, ?, ?, ?)",
                             [(cycle_id, a.parameter, a.kind, a.message, a.magnitude) for a in record.alerts])
            conn.executemany("INSERT INTO forecasts (cycle_id, kind, series, time, lead_h, value) "
                             "VALUES (?, ?, ?, ?, ?, ?)", [(cycle_id, *r) for r in rows])
            conn.executemany("INSERT INTO model_states (cycle_id, name, time, format, data) VALUES (?, ?, ?, ?, ?)",
                             [(cycle_id, name, fr.to_unix(t, f"state {name} time"), fmt, bytes(data))
                              for name, (t, fmt, data) in record.states.items()])
            conn.executemany("INSERT INTO transitions (cycle_id, parameter, time, value_before, value_after, unit, "
                             "found_cycle, cost_single, cost_transition, p_value) "
                             "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                             [(cycle_id, t.parameter, fr.to_unix(t.time.floor("s"), "transition time"),
                               float(t.before), float(t.after), t.unit, int(t.found_cycle), t.cost_single,
                               t.cost_transition, t.p_value) for t in record.transitions])
            conn.executemany("INSERT INTO forecast_bands (cycle_id, series, time, lead_h, probability, low, high) "
                             "VALUES (?, ?, ?, ?, ?, ?, ?)", [(cycle_id, *r) for r in bands])
            if record.ensemble is not None:
                self._replace_ensemble(conn, run_id, cycle_id, record)
            if record.scores is not None:
                self._write_scores(conn, run_id, record.scores, finished)
        log.info("%s: run %d: cycle %d committed (%s; %d estimates, %d alerts, %d forecast values)", self.path,
                 run_id, record.cycle, record.status, len(record.estimates), len(record.alerts), len(rows))

    @staticmethod
    def _replace_ensemble(conn: Any, run_id: int, cycle_id: int, record: CycleRecord) -> None:
        """The run's one stored ensemble becomes this cycle's, unless a later cycle's is stored (a re-run cycle)."""
        time, members, fmt, data = record.ensemble
        row = conn.execute("SELECT c.cycle FROM ensembles e JOIN cycles c ON c.id = e.cycle_id WHERE e.run_id = ?",
                           (run_id,)).fetchone()
        if row is not None and int(row[0]) > record.cycle:
            log.info("run %d: cycle %d's ensemble not stored, cycle %d's is later", run_id, record.cycle, row[0])
            return
        conn.execute("DELETE FROM ensembles WHERE run_id = ?", (run_id,))
        conn.execute("INSERT INTO ensembles (run_id, cycle_id, time, members, format, data) VALUES (?, ?, ?, ?, ?, ?)",
                     (run_id, cycle_id, fr.to_unix(time, "ensemble time"), int(members), fmt, bytes(data)))

    def retry_cycle(self, run: int | Run, cycle: int) -> None:
        """Re-open a final cycle: delete its results and set it pending, in one transaction.

        Later cycles are left as they are (their warm starts came from this cycle's old estimate).
        """
        run_id = self._run_id(run)
        with self._transaction() as conn:
            row = self._cycle_row(conn, run_id, cycle)
            if row is None:
                raise CycleStateError(f"{self.path}: run {run_id} has no cycle {cycle}")
            for table in _CYCLE_CHILDREN:
                conn.execute(f"DELETE FROM {table} WHERE cycle_id = ?", (row[0],))
            conn.execute("UPDATE cycles SET status = 'pending', owner = NULL, algorithm = NULL, model_runs = NULL, "
                         "wall_time_s = NULL, cost_before = NULL, cost_after = NULL, message = NULL, started = NULL, "
                         "finished = NULL, issued_forecast = NULL, issued_reason = NULL, skill_updated = NULL, "
                         "skill_dss = NULL, metrics = NULL WHERE id = ?", (row[0],))
        log.info("%s: run %d: cycle %d re-opened", self.path, run_id, cycle)

    def run_by_id(self, run_id: int) -> Run:
        """The run with this id."""
        row = self._conn.execute("SELECT name FROM runs WHERE id = ?", (int(run_id),)).fetchone()
        run = None if row is None else self.get_run(row[0])
        if run is None:
            raise StoreError(f"{self.path}: no run with id {run_id}")
        return run
