"""The store of the on-line service (layer 7): runs, cycles, estimates, alerts, forecasts, observations.

One abstract store (:mod:`rivercal.store.base`) with two back-ends beside it: an SQLite file by default
(:mod:`rivercal.store.sqlite`); ``Store("postgresql://…")`` keeps the same records in a PostgreSQL database that
several services and readers share (:mod:`rivercal.store.postgres`).

``import rivercal`` does not import this package (it loads :mod:`sqlite3`); import it where needed::

    from rivercal.store import Store, Schedule, CycleRecord, EstimateRecord, AlertRecord, TransitionRecord

See :mod:`rivercal.store.base` for the crash-safety design, :mod:`rivercal.store.schema` for the tables
and their units, and :mod:`rivercal.store.export` for the CSV and NetCDF exports (functions over a store).
The run metrics (forecast scores and the rest) are computed by :mod:`rivercal.online.metrics` and kept here.
"""

from rivercal.store.base import Store, is_url
from rivercal.store.export import export_estimates_csv, export_forecasts_csv, to_netcdf, to_xarray
from rivercal.store.records import (
    CYCLE_STATUSES,
    FINAL_STATUSES,
    FORECAST_KINDS,
    OBSERVATION_FLAGS,
    RUN_STATUSES,
    AlertRecord,
    BandRecord,
    CycleRecord,
    CycleSpec,
    CycleStateError,
    EstimateRecord,
    IngestResult,
    Run,
    RunMismatchError,
    Schedule,
    StoreError,
    StoreVersionError,
    TransitionRecord,
)
from rivercal.store.schema import SCHEMA_VERSION

__all__ = [
    "CYCLE_STATUSES",
    "FINAL_STATUSES",
    "FORECAST_KINDS",
    "OBSERVATION_FLAGS",
    "RUN_STATUSES",
    "SCHEMA_VERSION",
    "AlertRecord",
    "BandRecord",
    "CycleRecord",
    "CycleSpec",
    "CycleStateError",
    "EstimateRecord",
    "IngestResult",
    "Run",
    "RunMismatchError",
    "Schedule",
    "Store",
    "StoreError",
    "StoreVersionError",
    "TransitionRecord",
    "export_estimates_csv",
    "export_forecasts_csv",
    "is_url",
    "to_netcdf",
    "to_xarray",
]
