"""Ingested observations: storing them once, and reading them back for a window.

Part of :class:`rivercal.store.Store` (the connection and transactions are in :mod:`rivercal.store.sqlite`,
the only module that imports :mod:`sqlite3`).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet
from rivercal.store import _frames as fr
from rivercal.store._base import StoreBase
from rivercal.store.records import IngestResult

__all__ = ["ObservationTables"]

log = logging.getLogger("rivercal.store")


class ObservationTables(StoreBase):
    """Queries over the observations table."""

    def ingest(self, observations: ObservationSet, source: str, *,
               on_conflict: Literal["keep", "replace"] = "keep") -> IngestResult:
        """Store observations from ``source`` in one transaction; values already stored are not duplicated.

        A value whose (series, time, source) is stored already is a duplicate. If its value differs, it is
        a conflict: logged, and the stored value is kept (``on_conflict="keep"``) or replaced
        (``"replace"``, for a source that revises its data).

        Parameters
        ----------
        observations
            Series ``"<station>.<quantity>"`` in m AD or m³/s at whole-second UTC times.
        source
            Where they come from (a feed name, a file name).

        Returns
        -------
        IngestResult
            Unpacks as ``(inserted, duplicates)``; ``.conflicts`` counts differing duplicates.
        """
        if not source:
            raise ValueError("ingest: source must not be empty")
        if on_conflict not in ("keep", "replace"):
            raise ValueError(f"on_conflict must be 'keep' or 'replace', got {on_conflict!r}")
        prepared = [(s.id, fr.index_to_unix(s.times, f"observation series {s.id}"), np.asarray(s.values, float))
                    for s in observations if len(s)]
        inserted = duplicates = conflicts = 0
        stamp = fr.now_stamp()
        with self._transaction() as conn:
            for series, times, values in prepared:
                old = dict(conn.execute("SELECT time, value FROM observations WHERE series = ? AND source = ? AND "
                                        "time BETWEEN ? AND ?", (series, source, int(times.min()),
                                                                 int(times.max()))).fetchall())
                stored = np.array([t in old for t in times.tolist()], dtype=bool)
                new = [(series, t, source, v, stamp) for t, v in zip(times[~stored].tolist(),
                                                                      values[~stored].tolist(), strict=True)]
                conn.executemany("INSERT INTO observations (series, time, source, value, ingested) "
                                 "VALUES (?, ?, ?, ?, ?)", new)
                log.debug("ingest %s from %s: %d new values written", series, source, len(new))
                old_values = np.array([old[t] for t in times[stored].tolist()], dtype=float)
                differ = ~np.isclose(values[stored], old_values, rtol=1e-9, atol=0.0)
                if differ.any():
                    first = int(np.flatnonzero(differ)[0])
                    t_first = int(times[stored][first])
                    log.warning("ingest %s from %s: %d values differ from the stored ones (first at %s: stored %r, "
                                "new %r); %s", series, source, int(differ.sum()), fr.from_unix(t_first).isoformat(),
                                old[t_first], float(values[stored][first]),
                                "kept the stored values" if on_conflict == "keep" else "replaced them")
                    if on_conflict == "replace":
                        conn.executemany("UPDATE observations SET value = ?, ingested = ? WHERE series = ? AND "
                                         "time = ? AND source = ?",
                                         [(v, stamp, series, t, source) for t, v in
                                          zip(times[stored][differ].tolist(), values[stored][differ].tolist(),
                                              strict=True)])
                inserted += len(new)
                duplicates += int(stored.sum())
                conflicts += int(differ.sum())
        log.info("%s: ingested from %s: %d values stored, %d duplicates (%d differing)", self.path, source,
                 inserted, duplicates, conflicts)
        return IngestResult(inserted, duplicates, conflicts)

    def _observation_rows(self, series_ids: Sequence[str], start: int | None, end: int | None) -> pd.DataFrame:
        sql = (f"SELECT series, time, source, value, ingested FROM observations WHERE series IN "
               f"({', '.join('?' * len(series_ids))})")
        params: list[Any] = list(series_ids)
        if start is not None:
            sql += " AND time >= ?"
            params.append(start)
        if end is not None:
            sql += " AND time <= ?"
            params.append(end)
        return fr.frame(self._query(sql, params), ["series", "time", "source", "value", "ingested"])

    def observation_table(self, series_ids: Iterable[str], start: Any, end: Any, *,
                          sources: Sequence[str] | None = None) -> pd.DataFrame:
        """Stored observations of some series in [start, end] as a long table, one value per series and time.

        Parameters
        ----------
        series_ids
            Series ``"<station>.<quantity>"``.
        start, end
            Window (UTC; naive = UTC), both ends included.
        sources
            Sources to use, in priority order (default all; where sources overlap, the latest ingested wins).

        Returns
        -------
        DataFrame
            Columns series, time (UTC), value (m AD or m³/s).
        """
        rows = fr.resolve_sources(
            self._observation_rows(list(series_ids), fr.to_unix(start, "start"), fr.to_unix(end, "end")), sources)
        return rows.assign(time=fr.from_unix(rows["time"].to_numpy("int64")))

    def observations(self, series_ids: Iterable[str], start: Any, end: Any, *, sources: Sequence[str] | None = None,
                     sigma: Mapping[str, float | None] | None = None) -> ObservationSet:
        """Stored observations of some series in [start, end], as the calibration problem takes them.

        Parameters
        ----------
        series_ids
            Series ``"<station>.<quantity>"``, in the order wanted (a series with no stored values is
            returned empty).
        start, end
            Window (UTC; naive = UTC), both ends included.
        sources
            Sources to use, in priority order (default all; where sources overlap, the latest ingested wins).
        sigma
            σ per series id or quantity (default :data:`rivercal.observations.DEFAULT_SIGMA`).
        """
        ids = list(series_ids)
        rows = self.observation_table(ids, start, end, sources=sources)
        sigma = dict(DEFAULT_SIGMA if sigma is None else sigma)
        out = []
        for series_id in ids:
            part = rows[rows["series"] == series_id]
            values = pd.Series(part["value"].to_numpy(float), index=pd.DatetimeIndex(part["time"]))
            s = sigma.get(series_id, sigma.get(series_id.rpartition(".")[2]))
            out.append(ObservationSeries.from_series(values, id=series_id, sigma=s, source=f"store:{self.path}"))
        return ObservationSet(tuple(out))

    def availability(self, series_ids: Iterable[str] | None = None, start: Any | None = None,
                     end: Any | None = None) -> pd.DataFrame:
        """What is stored for a window: per series and source, the count, first and last time and largest gap.

        Returns
        -------
        DataFrame
            Columns series, source, n, first, last (UTC), max_gap_h (h; NaN for a single value).
        """
        where, params = [], []
        if series_ids is not None:
            ids = list(series_ids)
            where.append(f"series IN ({', '.join('?' * len(ids))})")
            params.extend(ids)
        if start is not None:
            where.append("time >= ?")
            params.append(fr.to_unix(start, "start"))
        if end is not None:
            where.append("time <= ?")
            params.append(fr.to_unix(end, "end"))
        sql = ("SELECT series, source, count(*), min(time), max(time), CAST(max(gap) AS DOUBLE PRECISION) / 3600 "
               "FROM (SELECT series, source, time, time - lag(time) OVER (PARTITION BY series, source ORDER BY "
               "time) AS gap FROM observations" + (" WHERE " + " AND ".join(where) if where else "")
               + ") AS gaps GROUP BY series, source ORDER BY series, source")
        out = fr.frame(self._query(sql, params), ["series", "source", "n", "first", "last", "max_gap_h"])
        out["first"] = fr.from_unix(out["first"].astype("int64"))
        out["last"] = fr.from_unix(out["last"].astype("int64"))
        out["max_gap_h"] = out["max_gap_h"].astype(float)
        return out
