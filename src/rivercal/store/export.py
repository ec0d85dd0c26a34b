"""Exports of a stored run: estimates and forecasts as CSV, and both as CF-1.8 NetCDF.

CSV files are long tables with ISO 8601 UTC times (``2010-11-01T06:00:00Z``):

- estimates: ``cycle, issue_time, window_start, window_end, status, parameter, value, std, unit, accepted,
  reason`` (value and std in ``unit``);
- forecasts: ``cycle, issue_time, kind, series, lead_h, time, value`` (lead in h; value in m AD for
  levels, m³/s for discharges).

The NetCDF file (:func:`to_xarray` builds it) follows CF-1.8:

- estimates on dimension ``time`` (the end of each cycle's calibration window, which is its forecast issue
  time) with cell bounds ``time_bnds`` (the window): one variable per parameter, named after the parameter
  with characters other than letters, digits and ``_`` replaced by ``_``, with ``units`` and the original
  name in ``rivercal_parameter``; its standard deviation in ``<name>_std`` and the accepted flag in
  ``<name>_accepted`` (``flag_values`` 0, 1). Per cycle also ``cycle``, ``status``, ``cost_before``,
  ``cost_after``, ``model_runs`` and ``wall_time_s``.
- forecasts on dimensions ``kind`` (``updated``, ``dss``), ``reference_time`` (standard name
  ``forecast_reference_time``) and ``lead_time`` (``forecast_period``, hours), with the valid time
  ``valid_time`` = reference_time + lead_time as an auxiliary coordinate: water levels in ``water_level``
  (m, standard name ``water_surface_height_above_reference_datum``, series on ``level_series``) and
  discharges in ``discharge`` (m3 s-1, ``water_volume_transport_in_river_channel``, on ``discharge_series``).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

import rivercal
from rivercal._time import utc_index
from rivercal.observations import CF_VARIABLES
from rivercal.store._frames import now_stamp
from rivercal.store.records import Run, StoreError

if TYPE_CHECKING:
    import xarray as xr

    from rivercal.store.sqlite import Store

__all__ = ["export_estimates_csv", "export_forecasts_csv", "to_netcdf", "to_xarray"]

_TIME_UNITS = "seconds since 1970-01-01"  # CF: no time zone means UTC


def _iso(times: pd.Series) -> pd.Series:
    return times.dt.strftime("%Y-%m-%dT%H:%M:%SZ")


def export_estimates_csv(store: Store, run: int | Run, path: str | Path) -> Path:
    """Write a run's estimates as a long CSV table (see the module docstring for the columns)."""
    table = store.estimates(run)
    for col in ("issue_time", "window_start", "window_end"):
        table[col] = _iso(table[col])
    path = Path(path)
    table.to_csv(path, index=False)
    return path


def export_forecasts_csv(store: Store, run: int | Run, path: str | Path, *, cycle: int | None = None,
                         kind: str | None = None) -> Path:
    """Write a run's forecasts (optionally of one cycle or kind) as a long CSV table."""
    table = store.forecasts(run, cycle=cycle, kind=kind)
    for col in ("issue_time", "time"):
        table[col] = _iso(table[col])
    path = Path(path)
    table.to_csv(path, index=False)
    return path


def _var_name(parameter: str, taken: set[str]) -> str:
    name = re.sub(r"[^A-Za-z0-9_]", "_", parameter)
    if not name or not name[0].isalpha():
        name = "p_" + name
    base, k = name, 2
    while name in taken or name + "_std" in taken:
        name, k = f"{base}_{k}", k + 1
    taken.add(name)
    return name


def _naive(times: Any) -> np.ndarray:
    """UTC times as naive datetime64[ns] (CF time coordinates are UTC by convention)."""
    return utc_index(times).tz_localize(None).as_unit("ns").to_numpy()


def _estimates_dataset(store: Store, run: int | Run) -> xr.Dataset:
    import xarray as xr

    cycles = store.cycles(run)
    cycles = cycles[cycles["status"].isin(["done", "failed", "aborted"])].reset_index(drop=True)
    est = store.estimates(run)
    time = _naive(cycles["window_end"])
    ds = xr.Dataset(coords={"time": ("time", time, {"standard_name": "time", "axis": "T", "bounds": "time_bnds",
                                                   "long_name": "end of the calibration window (forecast issue "
                                                                "time)"})})
    ds["time_bnds"] = (("time", "nv"), np.stack([_naive(cycles["window_start"]), time], axis=1),
                       {"long_name": "calibration window"})
    ds["cycle"] = ("time", cycles["cycle"].to_numpy("int64"), {"long_name": "cycle index"})
    ds["status"] = ("time", cycles["status"].to_numpy(str).astype(object), {"long_name": "cycle status"})
    for col, unit, text in (("cost_before", "1", "cost S at the warm start (thesis Eq. 2-3)"),
                            ("cost_after", "1", "cost S at the estimate (thesis Eq. 2-3)"),
                            ("wall_time_s", "s", "wall time of the cycle")):
        ds[col] = ("time", cycles[col].to_numpy(float), {"units": unit, "long_name": text})
    ds["model_runs"] = ("time", cycles["model_runs"].fillna(-1).to_numpy("int64"),
                        {"long_name": "number of model runs (-1: not recorded)"})
    taken: set[str] = set(ds.variables)
    position = {int(c): i for i, c in enumerate(cycles["cycle"])}
    for parameter, rows in est.groupby("parameter", sort=True):
        units = sorted(rows["unit"].unique())
        if len(units) != 1:
            raise StoreError(f"parameter {parameter!r} is stored in several units ({', '.join(units)})")
        rows = rows[rows["cycle"].isin(position)]
        idx = rows["cycle"].map(position).to_numpy("int64")
        value, std = np.full(time.size, np.nan), np.full(time.size, np.nan)
        accepted = np.full(time.size, -1, dtype="int8")
        value[idx], std[idx] = rows["value"].to_numpy(float), rows["std"].to_numpy(float)
        accepted[idx] = rows["accepted"].to_numpy(bool).astype("int8")
        name = _var_name(str(parameter), taken)
        ds[name] = ("time", value, {"long_name": f"estimate of parameter {parameter}", "units": units[0],
                                    "rivercal_parameter": str(parameter),
                                    "ancillary_variables": f"{name}_std {name}_accepted"})
        ds[f"{name}_std"] = ("time", std, {"long_name": f"standard deviation of the estimate of {parameter}",
                                           "units": units[0]})
        ds[f"{name}_accepted"] = ("time", accepted, {"long_name": f"estimate of {parameter} accepted",
                                                     "flag_values": np.array([0, 1], dtype="int8"),
                                                     "flag_meanings": "held_or_rejected accepted"})
        taken |= {f"{name}_std", f"{name}_accepted"}
    return ds


def _forecast_dataset(store: Store, run: int | Run) -> xr.Dataset:
    import xarray as xr

    fc = store.forecasts(run)
    if fc.empty:
        return xr.Dataset()
    fc = fc.assign(reference_time=_naive(fc["issue_time"]))
    ref = np.unique(fc["reference_time"].to_numpy())
    lead = np.unique(fc["lead_h"].to_numpy(float))
    ds = xr.Dataset(coords={
        "kind": ("kind", np.array(["updated", "dss"], dtype=object), {"long_name": "forecast kind: with the cycle's "
                                                                     "updated parameters, or the fixed DSS ones"}),
        "reference_time": ("reference_time", ref, {"standard_name": "forecast_reference_time",
                                                   "long_name": "forecast issue time"}),
        "lead_time": ("lead_time", lead, {"standard_name": "forecast_period", "units": "hours",
                                          "long_name": "lead time"}),
    })
    valid = ref[:, None] + (lead[None, :] * 3600e9).astype("timedelta64[ns]")
    ds.coords["valid_time"] = (("reference_time", "lead_time"), valid, {"standard_name": "time",
                                                                         "long_name": "forecast valid time"})
    quantity = fc["series"].str.rpartition(".")[2]
    for var, text in zip(CF_VARIABLES, ("forecast water level", "forecast discharge"), strict=True):
        part = fc[quantity.isin(var.quantities)]
        if part.empty:
            continue
        dim = var.dimension
        cube = (part.set_index(["kind", "reference_time", "lead_h", "series"])["value"].to_xarray()
                .rename({"lead_h": "lead_time", "series": dim})
                .reindex(kind=ds["kind"].values, reference_time=ref, lead_time=lead))
        ds.coords[dim] = (dim, cube[dim].values.astype(object), {"long_name": "series id <station>.<quantity>"})
        ds[var.name] = (("kind", "reference_time", "lead_time", dim), cube.values, var.attrs(text))
    return ds


def to_xarray(store: Store, run: int | Run) -> xr.Dataset:
    """A run's estimates and forecasts as one CF-1.8 dataset (layout in the module docstring)."""
    import xarray as xr

    info = run if isinstance(run, Run) else store.run_by_id(int(run))
    ds = xr.merge([_estimates_dataset(store, info), _forecast_dataset(store, info)], combine_attrs="drop_conflicts")
    ds.attrs = {"Conventions": "CF-1.8",
                "title": f"rivercal on-line parameter estimates and forecasts, run {info.name}",
                "source": f"rivercal {rivercal.__version__}",
                "history": f"{now_stamp()} exported from {store.path}",
                "run": info.name, "case": info.case}
    return ds


def to_netcdf(store: Store, run: int | Run, path: str | Path) -> Path:
    """Write :func:`to_xarray` to a NetCDF-4 file; times in s since 1970-01-01 UTC."""
    ds = to_xarray(store, run)
    encoding: dict[str, dict[str, Any]] = {}
    for name in ("time", "time_bnds", "reference_time", "valid_time"):
        if name in ds.variables:
            encoding[name] = {"units": _TIME_UNITS, "calendar": "proleptic_gregorian", "dtype": "int64"}
    for name, var in ds.data_vars.items():
        if var.dtype.kind == "f":
            encoding[str(name)] = {"_FillValue": np.nan}
        elif str(name).endswith("_accepted") or name == "model_runs":
            encoding[str(name)] = {"_FillValue": -1}
    path = Path(path)
    ds.to_netcdf(path, encoding=encoding, engine="netcdf4")
    return path
