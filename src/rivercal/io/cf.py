"""CF NetCDF files a water board loads directly: station ids and positions, the CRS and the vertical datum.

rivercal's NetCDF files keep their series on string dimensions (``level_series``, ``discharge_series``:
ids ``"<station>.<quantity>"``). :func:`add_stations` adds, per series, the station id and the station's
map coordinates x and y (from the network: at its structure or its chainage). When the case declares
its coordinate reference system (``[case] crs``, e.g. ``"EPSG:28992"``, RD New) it adds a variable
``crs`` holding it (``crs_wkt``, ``epsg_code``; x and y name it in their ``long_name``) and the WGS 84
latitude and longitude of each station (CF coordinates, computed with pyproj). The two series
dimensions each carry their own x and y, so these are not the CF projection coordinates of one grid
mapping (CF allows one pair per mapping); latitude and longitude are what CF tools place stations by.
Levels say their vertical datum (``[case] vertical_datum``, e.g. ``"NAP"``): the ``long_name`` reads
"m NAP" and the ``vertical_datum`` attribute names it; without one the datum is the case's own (m AD).
:func:`write_netcdf` writes with CF-1.8 encodings (time as double seconds since 1970-01-01 UTC; no
64-bit integers, which CF-1.8 does not allow) and a ``history`` line.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rivercal.network.coordinates import MissingCoordinates, station_coordinates

if TYPE_CHECKING:
    import xarray as xr

__all__ = ["SERIES_DIMS", "add_stations", "write_netcdf"]

#: The dimensions whose coordinate values are series ids ``"<station>.<quantity>"``.
SERIES_DIMS = ("level_series", "discharge_series")
_LEVEL_VARIABLES = ("water_level",)
_TIME_UNITS = "seconds since 1970-01-01 00:00:00"


def _crs(text: str) -> Any:
    from pyproj import CRS

    return CRS.from_user_input(text)


def add_stations(ds: xr.Dataset, case: Any, dims: Sequence[str] = SERIES_DIMS) -> xr.Dataset:
    """The dataset with station ids, positions, CRS and vertical datum of the case (module docstring).

    Parameters
    ----------
    ds
        A dataset whose ``dims`` hold series ids ``"<station>.<quantity>"``.
    case
        The loaded case (:class:`rivercal.case.Case`): its network places the stations, its ``[case]``
        table may declare ``crs`` and ``vertical_datum``.
    dims
        The series dimensions to describe (those absent from ``ds`` are skipped).

    Raises
    ------
    ValueError
        When a series names a station the network does not have. A network without map coordinates (they
        are optional) gets station ids without x and y.
    """
    meta = case.spec.case
    crs_text = getattr(meta, "crs", None)
    datum = getattr(meta, "vertical_datum", None)
    try:
        where: dict[str, tuple[float, float]] | None = station_coordinates(case.network)
    except MissingCoordinates:  # map coordinates are optional in a case: the ids are written without x/y
        where = None
    ds = ds.copy()
    crs = _crs(crs_text) if crs_text else None
    to_wgs84 = None
    if crs is not None:
        from pyproj import Transformer

        to_wgs84 = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
        attrs = {"long_name": f"coordinate reference system of the station x and y: {crs.name}",
                 "crs_wkt": crs.to_wkt(), "spatial_ref": crs.to_wkt()}
        epsg = crs.to_epsg()
        if epsg is not None:
            attrs["epsg_code"] = f"EPSG:{epsg}"
        ds["crs"] = ((), np.int32(0), attrs)
    for dim in dims:
        if dim not in ds.dims:
            continue
        ids = [str(v) for v in ds[dim].values]
        stations = [i.rpartition(".")[0] for i in ids]
        known = {st.id for st in case.network.stations}
        unknown = [s for s in stations if s not in known]
        if unknown:
            raise ValueError(f"series {ids[stations.index(unknown[0])]!r}: no station {unknown[0]!r} in the network")
        prefix = dim.removesuffix("_series")
        names = [f"{prefix}_station_id", f"{prefix}_x", f"{prefix}_y"]
        ds[names[0]] = (dim, np.array(stations, dtype=object), {"long_name": "station id", "cf_role": "timeseries_id"})
        if where is None:
            continue
        x = np.array([where[s][0] for s in stations])
        y = np.array([where[s][1] for s in stations])
        xy_text = f"in {crs.name}" if crs is not None else "of the case (no coordinate reference system declared)"
        ds[names[1]] = (dim, x, {"units": "m", "long_name": f"station x coordinate {xy_text}"})
        ds[names[2]] = (dim, y, {"units": "m", "long_name": f"station y coordinate {xy_text}"})
        if to_wgs84 is not None:
            lon, lat = to_wgs84.transform(x, y)
            ds[f"{prefix}_lat"] = (dim, np.asarray(lat), {"units": "degrees_north", "standard_name": "latitude",
                                                          "long_name": "station latitude (WGS 84)"})
            ds[f"{prefix}_lon"] = (dim, np.asarray(lon), {"units": "degrees_east", "standard_name": "longitude",
                                                          "long_name": "station longitude (WGS 84)"})
            names += [f"{prefix}_lat", f"{prefix}_lon"]
        ds = ds.set_coords(names)
        for var in ds.data_vars.values():
            if dim in var.dims:
                var.attrs["coordinates"] = " ".join(names)
    for name in _LEVEL_VARIABLES:
        if name in ds:
            base = ds[name].attrs.get("long_name", "water level")
            if datum:
                ds[name].attrs.update(long_name=f"{base} (m {datum})", vertical_datum=str(datum))
            else:
                ds[name].attrs.update(long_name=f"{base} (m above the case's datum)",
                                      vertical_datum="the case's own datum (m AD); not declared")
    if datum and "crs" in ds:
        ds["crs"].attrs["geopotential_datum_name"] = str(datum)
    return ds


#: Unit spellings of rivercal's cases that UDUNITS (the CF units) reads otherwise, or not at all (None).
_UNITS = {"m AD": "m", "-": "1", "m^(1/3)/s": None, "m1/3 s-1": None, "m1/3/s": None, "s/m^(1/3)": None}


def _udunits(ds: xr.Dataset) -> xr.Dataset:
    """Units CF tools read: ``m AD`` is m, ``-`` is 1.

    A Strickler or Manning coefficient (m^(1/3)/s, a fractional power UDUNITS cannot express) keeps its
    unit in ``units_text`` and its ``long_name`` instead.
    """
    ds = ds.copy()
    for var in ds.variables.values():
        unit = var.attrs.get("units")
        if isinstance(unit, str) and unit in _UNITS:
            if _UNITS[unit] is None:
                del var.attrs["units"]
                var.attrs["units_text"] = unit
                var.attrs["long_name"] = f"{var.attrs.get('long_name', '')} [{unit}]".strip()
            else:
                var.attrs["units"] = _UNITS[unit]
    return ds


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a dataset as CF-1.8 NetCDF-4: times as double seconds since 1970-01-01 UTC, NaN as fill value."""
    ds = _udunits(ds)
    encoding: dict[str, dict[str, Any]] = {}
    for name, var in ds.variables.items():
        if np.issubdtype(var.dtype, np.datetime64):
            encoding[str(name)] = {"units": _TIME_UNITS, "calendar": "standard", "dtype": "float64",
                                   "_FillValue": None}
        elif var.dtype.kind == "f" and name not in ds.coords:
            encoding[str(name)] = {"_FillValue": np.nan}
        elif var.dtype.kind in "iu" and var.dtype.itemsize == 8:
            encoding[str(name)] = {"dtype": "int32"}
        elif var.dtype.kind == "f":
            encoding[str(name)] = {"_FillValue": None}
    if not ds.attrs.get("history"):
        import datetime as dt

        import rivercal

        stamp = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        ds = ds.assign_attrs(history=f"{stamp} written by rivercal {rivercal.__version__}")
    path = Path(path)
    ds.to_netcdf(path, encoding=encoding, engine="netcdf4")
    return path
