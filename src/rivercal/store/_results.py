"""Results of the on-line service's cycles: estimates, alerts, forecasts, scores, run metrics and products.

The scores and the run metrics are computed by :mod:`rivercal.online.metrics`; the store only keeps them.

Part of :class:`rivercal.store.Store` (this module holds the queries; the cycle bookkeeping is in
:mod:`rivercal.store.base`, the connections and transactions in the back-ends beside it).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Mapping
from typing import Any

import pandas as pd

from rivercal.store import _frames as fr
from rivercal.store._base import StoreBase
from rivercal.store.records import FORECAST_KINDS, CycleStateError, Run

__all__ = ["ResultTables"]

log = logging.getLogger("rivercal.store")


class ResultTables(StoreBase):
    """Queries over the estimates, alerts, forecasts, scores, bands, ensembles, metrics and products tables."""

    # -- run metrics (rivercal.online.metrics) and products of a run -------------------------------------------

    def put_metrics(self, run: int | Run, cycle: int, metrics: Mapping[str, Any]) -> None:
        """Store the run metrics as of a finished cycle (a JSON object; replaces what the cycle held).

        Raises
        ------
        CycleStateError
            When the run has no such finished cycle.
        """
        text = fr.config_json(metrics)
        with self._transaction() as conn:
            done = conn.execute("UPDATE cycles SET metrics = ? WHERE run_id = ? AND cycle = ? AND finished IS NOT "
                                "NULL", (text, self._run_id(run), int(cycle))).rowcount
            if done != 1:
                raise CycleStateError(f"{self.path}: run {self._run_id(run)} has no finished cycle {cycle}")

    def metrics(self, run: int | Run, cycle: int | None = None) -> dict[str, Any] | None:
        """The run metrics stored with ``cycle`` (None: the latest cycle that has them), or None."""
        if cycle is None:
            rows = self._query("SELECT metrics FROM cycles WHERE run_id = ? AND metrics IS NOT NULL ORDER BY cycle "
                               "DESC LIMIT 1", (self._run_id(run),))
        else:
            rows = self._query("SELECT metrics FROM cycles WHERE run_id = ? AND cycle = ? AND metrics IS NOT NULL",
                               (self._run_id(run), int(cycle)))
        return json.loads(rows[0][0]) if rows else None

    def put_product(self, run: int | Run, name: str, fmt: str, data: bytes) -> None:
        """Store a product of a run as a whole (bytes in format ``fmt``), replacing one of the same name."""
        if not name or not fmt:
            raise ValueError("a run product needs a name and a format")
        with self._transaction() as conn:
            conn.execute("INSERT INTO run_products (run_id, name, format, data, created) VALUES (?, ?, ?, ?, ?) "
                         "ON CONFLICT (run_id, name) DO UPDATE SET format = excluded.format, data = excluded.data, "
                         "created = excluded.created", (self._run_id(run), name, fmt, bytes(data), fr.now_stamp()))

    def product(self, run: int | Run, name: str) -> tuple[str, bytes] | None:
        """A stored product of a run: (format, data), or None."""
        rows = self._query("SELECT format, data FROM run_products WHERE run_id = ? AND name = ?",
                           (self._run_id(run), name))
        return (str(rows[0][0]), bytes(rows[0][1])) if rows else None

    def estimates(self, run: int | Run, *, accepted_only: bool = False) -> pd.DataFrame:
        """Every stored estimate of a run (long format), in cycle and parameter order.

        Returns
        -------
        DataFrame
            Columns cycle, issue_time, window_start, window_end (UTC), status, parameter, value, std (in
            ``unit``), unit, accepted (bool), reason.
        """
        rows = self._query("SELECT c.cycle, c.issue_time, c.window_start, c.window_end, c.status, e.parameter, "
                           "e.value, e.std, e.unit, e.accepted, e.reason FROM estimates e JOIN cycles c ON "
                           "c.id = e.cycle_id WHERE c.run_id = ? AND (e.accepted = 1 OR ? = 0) "
                           "ORDER BY c.cycle, e.parameter", (self._run_id(run), int(accepted_only)))
        out = fr.frame(rows, ["cycle", "issue_time", "window_start", "window_end", "status", "parameter", "value",
                              "std", "unit", "accepted", "reason"])
        for col in ("issue_time", "window_start", "window_end"):
            out[col] = fr.from_unix(out[col].astype("int64"))
        out["std"] = out["std"].astype(float)
        out["accepted"] = out["accepted"].astype(bool)
        return out

    def last_accepted(self, run: int | Run) -> dict[str, float]:
        """Per parameter, the value of its latest accepted estimate (the warm start of the next cycle)."""
        rows = self._query(
            "SELECT e.parameter, e.value FROM estimates e JOIN cycles c ON c.id = e.cycle_id "
            "WHERE c.run_id = ? AND e.accepted = 1 AND c.cycle = (SELECT max(c2.cycle) FROM estimates e2 "
            "JOIN cycles c2 ON c2.id = e2.cycle_id WHERE c2.run_id = c.run_id AND e2.parameter = e.parameter "
            "AND e2.accepted = 1) ORDER BY e.parameter", (self._run_id(run),))
        return {p: float(v) for p, v in rows}

    def model_state(self, run: int | Run, name: str, *,
                    cycle: int | None = None) -> tuple[pd.Timestamp, str, bytes] | None:
        """The model state ``name`` handed over by a cycle: (time (UTC), format, data), or None.

        Without ``cycle``, the state of the latest final cycle that stored one (the hot start of the next).
        """
        sql = ("SELECT s.time, s.format, s.data FROM model_states s JOIN cycles c ON c.id = s.cycle_id "
               "WHERE c.run_id = ? AND s.name = ? AND c.status IN ('done', 'failed', 'aborted')")
        params: list[Any] = [self._run_id(run), name]
        if cycle is not None:
            sql += " AND c.cycle = ?"
            params.append(int(cycle))
        row = self._conn.execute(sql + " ORDER BY c.cycle DESC LIMIT 1", params).fetchone()
        return None if row is None else (fr.from_unix(int(row[0])), str(row[1]), bytes(row[2]))

    def ensemble(self, run: int | Run) -> tuple[pd.Timestamp, int, int, str, bytes] | None:
        """The run's stored ensemble (the latest cycle's): (time (UTC), cycle, members, format, data), or None."""
        rows = self._query("SELECT e.time, c.cycle, e.members, e.format, e.data FROM ensembles e JOIN cycles c ON "
                           "c.id = e.cycle_id WHERE e.run_id = ?", (self._run_id(run),))
        if not rows:
            return None
        time, cycle, members, fmt, data = rows[0]
        return fr.from_unix(int(time)), int(cycle), int(members), str(fmt), bytes(data)

    def forecast_bands(self, run: int | Run, *, cycle: int | None = None) -> pd.DataFrame:
        """Stored forecast bands (long format), optionally of one cycle.

        Returns
        -------
        DataFrame
            Columns cycle, issue_time (UTC), series, lead_h (h), time (UTC), probability, low, high (m AD or
            m³/s).
        """
        sql = ("SELECT c.cycle, c.issue_time, b.series, b.lead_h, b.time, b.probability, b.low, b.high FROM "
               "forecast_bands b JOIN cycles c ON c.id = b.cycle_id WHERE c.run_id = ?")
        params: list[Any] = [self._run_id(run)]
        if cycle is not None:
            sql += " AND c.cycle = ?"
            params.append(int(cycle))
        rows = self._query(sql + " ORDER BY c.cycle, b.series, b.time", params)
        out = fr.frame(rows, ["cycle", "issue_time", "series", "lead_h", "time", "probability", "low", "high"])
        out["issue_time"] = fr.from_unix(out["issue_time"].astype("int64"))
        out["time"] = fr.from_unix(out["time"].astype("int64"))
        for col in ("lead_h", "probability", "low", "high"):
            out[col] = out[col].astype(float)
        return out

    def alerts(self, run: int | Run) -> pd.DataFrame:
        """The run's alerts: cycle, issue_time (UTC), parameter, kind, message, magnitude (|Δθ|/σ)."""
        rows = self._query("SELECT c.cycle, c.issue_time, a.parameter, a.kind, a.message, a.magnitude FROM alerts a "
                           "JOIN cycles c ON c.id = a.cycle_id WHERE c.run_id = ? ORDER BY c.cycle, a.id",
                           (self._run_id(run),))
        out = fr.frame(rows, ["cycle", "issue_time", "parameter", "kind", "message", "magnitude"])
        out["issue_time"] = fr.from_unix(out["issue_time"].astype("int64"))
        out["magnitude"] = out["magnitude"].astype(float)
        return out

    def transitions(self, run: int | Run) -> pd.DataFrame:
        """The transitions the run's cycles estimated or carried on (thesis §6-3), in cycle order.

        Returns
        -------
        DataFrame
            Columns cycle, issue_time (UTC), parameter, time (UTC, of the change), before, after (in
            ``unit``), unit, found_cycle (the cycle that found the change), cost_single, cost_transition
            (dimensionless), p_value.
        """
        rows = self._query("SELECT c.cycle, c.issue_time, t.parameter, t.time, t.value_before, t.value_after, t.unit, "
                           "t.found_cycle, t.cost_single, t.cost_transition, t.p_value FROM transitions t JOIN cycles "
                           "c ON c.id = t.cycle_id WHERE c.run_id = ? ORDER BY c.cycle, t.parameter",
                           (self._run_id(run),))
        out = fr.frame(rows, ["cycle", "issue_time", "parameter", "time", "before", "after", "unit", "found_cycle",
                              "cost_single", "cost_transition", "p_value"])
        out["issue_time"] = fr.from_unix(out["issue_time"].astype("int64"))
        out["time"] = fr.from_unix(out["time"].astype("int64"))
        for col in ("before", "after", "cost_single", "cost_transition", "p_value"):
            out[col] = out[col].astype(float)
        return out

    def _forecast_rows(self, run_id: int, cycle: int | None, kind: str | None,
                       series: Iterable[str] | None) -> list[tuple]:
        sql = ("SELECT c.cycle, c.id, c.issue_time, f.kind, f.series, f.lead_h, f.time, f.value FROM forecasts f "
               "JOIN cycles c ON c.id = f.cycle_id WHERE c.run_id = ?")
        params: list[Any] = [run_id]
        if cycle is not None:
            sql += " AND c.cycle = ?"
            params.append(int(cycle))
        if kind is not None:
            if kind not in FORECAST_KINDS:
                raise ValueError(f"forecast kind must be one of {FORECAST_KINDS}, got {kind!r}")
            sql += " AND f.kind = ?"
            params.append(kind)
        if series is not None:
            ids = list(series)
            sql += f" AND f.series IN ({', '.join('?' * len(ids))})"
            params.extend(ids)
        return self._query(sql + " ORDER BY c.cycle, f.kind, f.series, f.time", params)

    def forecasts(self, run: int | Run, *, cycle: int | None = None, kind: str | None = None,
                  series: Iterable[str] | None = None) -> pd.DataFrame:
        """Stored forecasts (long format), optionally of one cycle, kind or some series.

        Returns
        -------
        DataFrame
            Columns cycle, issue_time (UTC), kind, series, lead_h (h), time (UTC), value (m AD or m³/s).
        """
        rows = self._forecast_rows(self._run_id(run), cycle, kind, series)
        out = fr.frame(rows, ["cycle", "cycle_id", "issue_time", "kind", "series", "lead_h", "time", "value"])
        out = out.drop(columns="cycle_id")
        out["issue_time"] = fr.from_unix(out["issue_time"].astype("int64"))
        out["time"] = fr.from_unix(out["time"].astype("int64"))
        out["lead_h"] = out["lead_h"].astype(float)
        out["value"] = out["value"].astype(float)
        return out

    def put_scores(self, run: int | Run, scores: pd.DataFrame) -> None:
        """Store forecast scores in one transaction; each cycle in ``scores`` has its earlier scores replaced.

        Parameters
        ----------
        run
            Run id.
        scores
            Columns cycle, kind, series, lead_from_h, lead_to_h (h), rmse, bias (m or m³/s), n, as
            :func:`rivercal.online.metrics.score_forecasts` computes them. Cycles not in the table keep
            their scores.
        """
        run_id = self._run_id(run)
        with self._transaction() as conn:
            self._write_scores(conn, run_id, scores, fr.now_stamp())

    def _write_scores(self, conn: Any, run_id: int, scores: pd.DataFrame, stamp: str) -> None:
        for cycle, table in scores.groupby("cycle", sort=True):
            row = self._cycle_row(conn, run_id, int(cycle))
            if row is None:
                raise CycleStateError(f"{self.path}: run {run_id} has no cycle {cycle}")
            conn.execute("DELETE FROM forecast_scores WHERE cycle_id = ?", (row[0],))
            conn.executemany(
                "INSERT INTO forecast_scores (cycle_id, kind, series, lead_from_h, lead_to_h, rmse, bias, n, "
                "scored) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [(row[0], r.kind, r.series, float(r.lead_from_h), float(r.lead_to_h), float(r.rmse),
                  float(r.bias), int(r.n), stamp) for r in table.itertuples(index=False)])
        log.info("%s: run %d: scores of %d cycles written (%d rows)", self.path, run_id, scores["cycle"].nunique(),
                 len(scores))

    def scores(self, run: int | Run) -> pd.DataFrame:
        """Stored scores: cycle, issue_time, kind, series, lead_from_h, lead_to_h (h), rmse, bias, n, scored."""
        rows = self._query("SELECT c.cycle, c.issue_time, s.kind, s.series, s.lead_from_h, s.lead_to_h, s.rmse, "
                           "s.bias, s.n, s.scored FROM forecast_scores s JOIN cycles c ON c.id = s.cycle_id "
                           "WHERE c.run_id = ? ORDER BY c.cycle, s.kind, s.series, s.lead_from_h",
                           (self._run_id(run),))
        out = fr.frame(rows, ["cycle", "issue_time", "kind", "series", "lead_from_h", "lead_to_h", "rmse", "bias",
                              "n", "scored"])
        out["issue_time"] = fr.from_unix(out["issue_time"].astype("int64"))
        out["scored"] = fr.stamp_to_time(out["scored"])
        return out
