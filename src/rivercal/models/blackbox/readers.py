"""Output readers of a black box: files in its run folder → series named ``<station>.<quantity>``.

- ``csv``: a column of ISO 8601 times (``time_column``; times without offset are UTC) and one column per
  variable;
- ``netcdf``: a CF NetCDF file read with xarray; a variable over ``time`` (``name``) or one series of a CF
  timeSeries variable (``name@id``, the id in the coordinate whose ``cf_role`` is ``timeseries_id``), as
  :meth:`rivercal.engine.SimulationResult.to_netcdf` writes them;
- ``pixml``: a Delft-FEWS PI-XML time-series file (:func:`rivercal.io.read_pixml_series`), a variable
  being ``locationId/parameterId``;
- ``swmm``: EPA SWMM's binary output (:func:`rivercal.models.swmm.output.read_swmm_output`), a variable
  being ``node:<id>`` (head, m) or ``link:<id>`` (flow, m³/s).

Every reader raises ValueError naming the file and what is wrong (missing, unreadable, truncated, a
variable it does not hold); the black box turns that into a failed run.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["READERS", "read_output"]


def _utc_index(values, label: str) -> pd.DatetimeIndex:
    try:
        index = pd.DatetimeIndex(pd.to_datetime(values, utc=True))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{label}: times that are not ISO 8601 ({exc})") from None
    return index


def _csv(path: Path, series: Mapping[str, str], time_column: str) -> pd.DataFrame:
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a readable CSV file ({' '.join(str(exc).split())})") from None
    if time_column not in frame.columns:
        raise ValueError(f"{path}: no time column {time_column!r} (columns: {', '.join(map(str, frame.columns))})")
    index = _utc_index(frame[time_column], str(path))
    out = {}
    for name, column in series.items():
        if column not in frame.columns:
            raise ValueError(f"{path}: no column {column!r} for {name}")
        out[name] = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
    return pd.DataFrame(out, index=index)


def _netcdf(path: Path, series: Mapping[str, str], time_column: str) -> pd.DataFrame:
    import xarray as xr

    try:
        ds = xr.open_dataset(path)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable NetCDF file ({' '.join(str(exc).split())})") from None
    with ds:
        if "time" not in ds.coords:
            raise ValueError(f"{path}: no time coordinate")
        index = _utc_index(ds["time"].values, str(path))
        out = {}
        for name, spec in series.items():
            var, _, ident = spec.partition("@")
            if var not in ds.data_vars:
                raise ValueError(f"{path}: no variable {var!r} for {name}")
            da = ds[var]
            if ident:
                dims = [d for d in da.dims if d != "time"]
                coord = next((ds[d] for d in dims if ds[d].attrs.get("cf_role") == "timeseries_id"), None)
                if coord is None:
                    raise ValueError(f"{path}: variable {var!r} has no timeseries_id coordinate for {spec!r}")
                ids = [str(v) for v in coord.values]
                if ident not in ids:
                    raise ValueError(f"{path}: {var!r} has no series {ident!r} (has {', '.join(ids)})")
                da = da.isel({coord.name: ids.index(ident)})
            if da.dims != ("time",):
                raise ValueError(f"{path}: {spec!r} is not one series over time (dimensions {da.dims})")
            out[name] = np.asarray(da.values, dtype=float)
    return pd.DataFrame(out, index=index)


def _pixml(path: Path, series: Mapping[str, str], time_column: str) -> pd.DataFrame:
    from rivercal.io import read_pixml_series

    try:
        found = {f"{s.location_id}/{s.parameter_id}": s for s in read_pixml_series(path)}
    except ValueError as exc:
        raise ValueError(f"{path}: not a readable PI-XML file ({' '.join(str(exc).split())})") from None
    parts = []
    for name, key in series.items():
        s = found.get(key)
        if s is None:
            raise ValueError(f"{path}: no series {key!r} (locationId/parameterId) for {name}; has "
                             f"{', '.join(found) or 'none'}")
        values = np.where(s.values == s.miss_val, np.nan, s.values.astype(float))
        parts.append(pd.Series(values, index=s.times, name=name))
    return pd.concat(parts, axis=1)


def _swmm(path: Path, series: Mapping[str, str], time_column: str) -> pd.DataFrame:
    from rivercal.models.swmm.output import read_swmm_output

    return read_swmm_output(path, series)


#: Reader name → function(path, series, time_column) → DataFrame.
READERS: dict[str, Callable[[Path, Mapping[str, str], str], pd.DataFrame]] = {
    "csv": _csv, "netcdf": _netcdf, "pixml": _pixml, "swmm": _swmm}


def read_output(reader: str, path: str | Path, series: Mapping[str, str], time_column: str = "time") -> pd.DataFrame:
    """The series of one output file, columns named as the keys of ``series``, indexed by UTC time.

    Raises
    ------
    ValueError
        For a missing, empty or unreadable file, or a variable the file does not hold (naming the file).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"the program wrote no {path.name} ({path} does not exist)")
    if path.stat().st_size == 0:
        raise ValueError(f"{path} is empty")
    frame = READERS[reader](path, series, time_column)
    if frame.index.has_duplicates:
        frame = frame[~frame.index.duplicated(keep="last")]
    return frame.sort_index()
