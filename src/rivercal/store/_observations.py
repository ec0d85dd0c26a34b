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

from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet, ScreenRule, screen_outliers
from rivercal.store import _frames as fr
from rivercal.store._base import StoreBase
from rivercal.store.records import IngestResult

__all__ = ["ObservationTables"]

log = logging.getLogger("rivercal.store")


class ObservationTables(StoreBase):
    """Queries over the observations table."""

    def ingest(self, observations: ObservationSet, source: str, *,
               on_conflict: Literal["keep", "replace"] = "keep", screen: ScreenRule | None = None,
               plausible: Mapping[str, tuple[Any, ...]] | None = None) -> IngestResult:
        """Store observations from ``source`` in one transaction; values already stored are not duplicated.

        A value whose (series, time, source) is stored already is a duplicate. If its value differs, it is
        a conflict: logged, and the stored value is kept (``on_conflict="keep"``) or replaced
        (``"replace"``, for a source that revises its data).

        Every ingestion records the gaps of the ingested series around the new values (table
        ``observation_gaps``: two consecutive values further apart than 1.5 times the series' usual
        step). With ``screen`` the values are screened for spikes
        (:func:`~rivercal.observations.screen_outliers`) together with the stored values of the same
        series and source within the rule's window of them, and every flag there is set anew: a spike at
        the end of one delivery is judged again when the next delivery brings the values after it.
        With ``plausible`` a value outside its series' plausible range is an outlier too (and the spike
        screening judges the other values without it). Flagged values are stored with flag ``outlier`` and
        left out of :meth:`observations` and :meth:`observation_table` unless asked for.

        Parameters
        ----------
        observations
            Series ``"<station>.<quantity>"`` in m AD or m³/s at whole-second UTC times.
        source
            Where they come from (a feed name, a file name).
        on_conflict
            What to do with a stored value that differs.
        screen
            The spike screening rule; None: no spike screening.
        plausible
            (low, high) per series id, m AD or m³/s, or (low, high, start, end) with the period (UTC) whose values
            the range judges (e.g. :meth:`rivercal.online.screening.PlausibleRange.bounds`); values outside the
            range (in its period) are flagged. Give the same ranges at every ingestion of a source (the flags of
            the values near new ones are set anew).

        Returns
        -------
        IngestResult
            Unpacks as ``(inserted, duplicates)``; ``.conflicts`` counts differing duplicates, ``.outliers``
            and ``.gaps`` what the ingested series hold around the new values.
        """
        if not source:
            raise ValueError("ingest: source must not be empty")
        if on_conflict not in ("keep", "replace"):
            raise ValueError(f"on_conflict must be 'keep' or 'replace', got {on_conflict!r}")
        prepared = [(s.id, fr.index_to_unix(s.times, f"observation series {s.id}"), np.asarray(s.values, float))
                    for s in observations if len(s)]
        inserted = duplicates = conflicts = outliers = gaps = 0
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
                bounds = _bounds((plausible or {}).get(series))
                if screen is not None or bounds is not None:
                    outliers += self._screen(conn, series, source, int(times.min()), int(times.max()), screen,
                                             bounds)
                gaps += self._record_gaps(conn, series, source, int(times.min()), int(times.max()), stamp)
        log.info("%s: ingested from %s: %d values stored, %d duplicates (%d differing), %d outliers flagged, %d gaps",
                 self.path, source, inserted, duplicates, conflicts, outliers, gaps)
        return IngestResult(inserted, duplicates, conflicts, outliers, gaps)

    @staticmethod
    def _screen(conn: Any, series: str, source: str, first: int, last: int, rule: ScreenRule | None,
                bounds: tuple[float, float, int, int] | None = None) -> int:
        """Screen the stored values of a series and source around [first, last]; set their flags anew.

        Values within one window of the new ones are judged (with the values within two windows as their
        context); values outside ``bounds`` (low, high, and the period in Unix seconds whose values they judge)
        are outliers, and the spike screening judges the rest.
        Returns how many of the judged values are outliers.
        """
        half = round(rule.half_window_h * 3600) if rule is not None else 0
        rows = conn.execute("SELECT time, value, flag FROM observations WHERE series = ? AND source = ? AND time "
                            "BETWEEN ? AND ? ORDER BY time",
                            (series, source, first - 2 * half, last + 2 * half)).fetchall()
        if not rows:
            return 0
        times = np.array([r[0] for r in rows], dtype=np.int64)
        values = np.array([r[1] for r in rows], dtype=float)
        was = np.array([r[2] == "outlier" for r in rows], dtype=bool)
        now = np.zeros(values.shape, dtype=bool)
        if bounds is not None:
            now = ((values < bounds[0]) | (values > bounds[1])) & (times >= bounds[2]) & (times <= bounds[3])
        if rule is not None:
            keep = ~now
            now[keep] = screen_outliers(times[keep], values[keep], series.rpartition(".")[2], rule)
        judged = (times >= first - half) & (times <= last + half)
        change = judged & (now != was)
        conn.executemany("UPDATE observations SET flag = ? WHERE series = ? AND source = ? AND time = ?",
                         [("outlier" if now[i] else "ok", series, source, int(times[i]))
                          for i in np.flatnonzero(change)])
        return int((now & judged).sum())

    @staticmethod
    def _record_gaps(conn: Any, series: str, source: str, first: int, last: int, stamp: str) -> int:
        """Store the gaps of a series and source from the value before ``first`` to the one after ``last``."""
        before = conn.execute("SELECT max(time) FROM observations WHERE series = ? AND source = ? AND time < ?",
                              (series, source, first)).fetchone()[0]
        after = conn.execute("SELECT min(time) FROM observations WHERE series = ? AND source = ? AND time > ?",
                             (series, source, last)).fetchone()[0]
        lo = int(before) if before is not None else first
        hi = int(after) if after is not None else last
        times = np.array([r[0] for r in conn.execute(
            "SELECT time FROM observations WHERE series = ? AND source = ? AND time BETWEEN ? AND ? ORDER BY time",
            (series, source, lo, hi)).fetchall()], dtype=np.int64)
        conn.execute("DELETE FROM observation_gaps WHERE series = ? AND source = ? AND gap_start >= ? AND "
                     "gap_start < ?", (series, source, lo, hi))
        if times.size < 3:
            return 0
        steps = np.diff(times)
        usual = float(np.median(steps))
        where = np.flatnonzero(steps > 1.5 * usual)
        conn.executemany("INSERT INTO observation_gaps (series, source, gap_start, gap_end, ingested) "
                         "VALUES (?, ?, ?, ?, ?)",
                         [(series, source, int(times[i]), int(times[i + 1]), stamp) for i in where])
        return int(where.size)

    def _observation_rows(self, series_ids: Sequence[str], start: int | None, end: int | None,
                          flagged: bool = False) -> pd.DataFrame:
        sql = (f"SELECT series, time, source, value, ingested, flag FROM observations WHERE series IN "
               f"({', '.join('?' * len(series_ids))})")
        params: list[Any] = list(series_ids)
        if not flagged:
            sql += " AND flag = 'ok'"
        if start is not None:
            sql += " AND time >= ?"
            params.append(start)
        if end is not None:
            sql += " AND time <= ?"
            params.append(end)
        return fr.frame(self._query(sql, params), ["series", "time", "source", "value", "ingested", "flag"])

    def observation_table(self, series_ids: Iterable[str], start: Any, end: Any, *,
                          sources: Sequence[str] | None = None, flagged: bool = False) -> pd.DataFrame:
        """Stored observations of some series in [start, end] as a long table, one value per series and time.

        Parameters
        ----------
        series_ids
            Series ``"<station>.<quantity>"``.
        start, end
            Window (UTC; naive = UTC), both ends included.
        sources
            Sources to use, in priority order (default all; where sources overlap, the latest ingested wins).
        flagged
            Also the values flagged as outliers (and a column ``flag``); default only the ``ok`` ones.

        Returns
        -------
        DataFrame
            Columns series, time (UTC), value (m AD or m³/s) (and flag).
        """
        raw = self._observation_rows(list(series_ids), fr.to_unix(start, "start"), fr.to_unix(end, "end"), flagged)
        rows = fr.resolve_sources(raw, sources, keep=("flag",) if flagged else ())
        return rows.assign(time=fr.from_unix(rows["time"].to_numpy("int64")))

    def gaps(self, series_ids: Iterable[str] | None = None, start: Any | None = None,
             end: Any | None = None) -> pd.DataFrame:
        """The stored gaps of the ingested series that overlap [start, end].

        Returns
        -------
        DataFrame
            Columns series, source, start, end (UTC: the values either side of the gap), hours (h).
        """
        where, params = [], []
        if series_ids is not None:
            ids = list(series_ids)
            where.append(f"series IN ({', '.join('?' * len(ids))})")
            params.extend(ids)
        if start is not None:
            where.append("gap_end > ?")
            params.append(fr.to_unix(start, "start"))
        if end is not None:
            where.append("gap_start < ?")
            params.append(fr.to_unix(end, "end"))
        sql = ("SELECT series, source, gap_start, gap_end FROM observation_gaps"
               + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY series, source, gap_start")
        out = fr.frame(self._query(sql, params), ["series", "source", "start", "end"])
        hours = (out["end"].astype("int64") - out["start"].astype("int64")) / 3600.0
        out["start"] = fr.from_unix(out["start"].astype("int64"))
        out["end"] = fr.from_unix(out["end"].astype("int64"))
        return out.assign(hours=hours.astype(float))

    def flag_counts(self, series_ids: Iterable[str] | None = None, start: Any | None = None,
                    end: Any | None = None) -> pd.DataFrame:
        """How many stored values of each series in [start, end] carry each flag.

        Returns
        -------
        DataFrame
            Columns series, flag, n.
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
        sql = ("SELECT series, flag, count(*) FROM observations" + (" WHERE " + " AND ".join(where) if where else "")
               + " GROUP BY series, flag ORDER BY series, flag")
        out = fr.frame(self._query(sql, params), ["series", "flag", "n"])
        return out.assign(n=out["n"].astype(int))

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
        parts = dict(tuple(rows.groupby("series", sort=False)))  # one pass, not one scan of all rows per series
        for series_id in ids:
            part = parts.get(series_id, rows.iloc[:0])
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


#: The period of a plausible range given without one: every time (Unix seconds).
_EVER = (-(2**62), 2**62)


def _bounds(given: Any) -> tuple[float, float, int, int] | None:
    """A plausible range as ``_screen`` takes it: (low, high) or (low, high, start, end), the period in Unix s."""
    if given is None:
        return None
    if len(given) == 2:
        return float(given[0]), float(given[1]), *_EVER
    low, high, start, end = given
    return float(low), float(high), int(pd.Timestamp(start).timestamp()), int(pd.Timestamp(end).timestamp())
