"""Observation CSV files: a ``time`` column (ISO 8601, UTC when no offset) and one column per series.

Columns are named ``"<station>.<quantity>"`` (``h``, ``h_up``, ``h_down`` in m AD; ``Q`` in m³/s). An empty
cell is a missing observation: it is dropped and counted, never read as zero. Text that is not a
number, an unparsable or repeated time, or times out of order are errors that name the file, the line
and the column.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError
from rivercal.observations import ObservationSet

__all__ = ["read_observations_csv", "write_observations_csv"]


def read_observations_csv(path: str | Path, *, sigma: Mapping[str, float | None] | None = None) -> ObservationSet:
    """Read observations from a CSV file.

    Parameters
    ----------
    path
        The file.
    sigma
        σ per series id or quantity (default :data:`rivercal.observations.DEFAULT_SIGMA`).

    Raises
    ------
    CaseError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    if not path.is_file():
        raise CaseError("file not found", file=str(path))
    try:
        raw = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise CaseError(f"not a readable CSV file ({exc})", file=str(path)) from None
    if raw.shape[1] < 2 or raw.shape[0] < 1:
        raise CaseError("needs a time column, at least one series column and one data line", file=str(path))
    time_col = raw.columns[0]
    times = pd.to_datetime(raw[time_col].str.strip(), utc=True, errors="coerce", format="ISO8601")
    bad = np.flatnonzero(times.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        raise CaseError(f"line {i + 2}: not a time: {raw[time_col].iloc[i]!r} (ISO 8601, e.g. 2010-09-27T00:00:00Z)",
                        file=str(path), field=time_col)
    index = pd.DatetimeIndex(times)
    step = np.diff(index.asi8)
    if (step <= 0).any():
        i = int(np.flatnonzero(step <= 0)[0]) + 1
        raise CaseError(f"line {i + 2}: time {index[i].isoformat()} is not after the previous line",
                        file=str(path), field=time_col)
    data = {}
    for col in raw.columns[1:]:
        text = raw[col].str.strip()
        values = pd.to_numeric(text.replace("", np.nan), errors="coerce")
        wrong = np.flatnonzero(values.isna().to_numpy() & (text != "").to_numpy())
        if wrong.size:
            i = int(wrong[0])
            raise CaseError(f"line {i + 2} ({index[i].isoformat()}): {raw[col].iloc[i]!r} is not a number",
                            file=str(path), field=str(col))
        data[str(col)] = values.to_numpy(dtype=float)
    frame = pd.DataFrame(data, index=index)
    try:
        return ObservationSet.from_frame(frame, sigma=sigma, source=str(path))
    except ValueError as exc:
        raise CaseError(str(exc), file=str(path)) from None


def write_observations_csv(observations: ObservationSet, path: str | Path) -> Path:
    """Write observations in the format :func:`read_observations_csv` reads (missing values empty)."""
    frame = observations.to_frame()
    frame.index = frame.index.strftime("%Y-%m-%dT%H:%M:%SZ")
    frame.index.name = "time"
    path = Path(path)
    frame.to_csv(path, float_format="%.6f")
    return path
