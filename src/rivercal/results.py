"""What a run of any model gives: :class:`SimulationResult`, with an optional water balance.

Every adapter of the model contract (:mod:`rivercal.models.contract`) returns a :class:`SimulationResult`:
the embedded engine with its :class:`VolumeBalance` and the withdrawals that ran short (:class:`Shortfall`),
an external program, SWMM or a BMI component without a balance (``balance`` is None: those models report
their own continuity, or none). This module sits below the engine and the adapters, so that all of them use
it without importing one another.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.observations import CF_VARIABLES

__all__ = ["ENGINE_SOURCE", "Shortfall", "SimulationResult", "VolumeBalance"]

#: The ``source`` of the embedded engine's results.
ENGINE_SOURCE = "rivercal embedded 1D De Saint-Venant engine (staggered Delft scheme)"


@dataclass(frozen=True)
class VolumeBalance:
    """Water balance of one run over the model domain (level-boundary points excluded).

    Attributes
    ----------
    initial, final
        Stored volume at the start and the end, m³.
    boundaries
        Net volume that entered through each boundary, m³ (negative: left).
    laterals
        Net volume of all laterals, m³.
    """

    initial: float
    final: float
    boundaries: dict[str, float]
    laterals: float

    @property
    def inflow(self) -> float:
        """Net volume that entered the domain, m³."""
        return sum(self.boundaries.values()) + self.laterals

    @property
    def residual(self) -> float:
        """Final - initial - inflow, m³ (zero up to round-off)."""
        return self.final - self.initial - self.inflow

    @property
    def throughput(self) -> float:
        """Gross exchange with the outside: Σ |boundary volume| + |lateral volume|, m³."""
        return sum(abs(v) for v in self.boundaries.values()) + abs(self.laterals)

    @property
    def relative_error(self) -> float:
        """|residual| / throughput (0 when nothing flowed)."""
        return abs(self.residual) / self.throughput if self.throughput > 0 else abs(self.residual)


@dataclass(frozen=True)
class Shortfall:
    """A withdrawal (a boundary or lateral with a negative discharge) that ran short of water in a run.

    A withdrawal takes at most half of the water at its point per time step; what it asks beyond that is
    not delivered (the run goes on, and warns).

    Attributes
    ----------
    requested
        Volume the withdrawal asked for over the run, m³.
    delivered
        Volume it took, m³.
    """

    requested: float
    delivered: float

    @property
    def missing(self) -> float:
        """Volume asked for and not delivered, m³."""
        return self.requested - self.delivered


@dataclass(frozen=True)
class SimulationResult:
    """Output of one run.

    Attributes
    ----------
    series
        One column per observable ``"<station>.<quantity>"`` (m for levels, m³/s for
        discharges), indexed by UTC time at the output interval, first row = initial state.
    balance
        Volume balance of the run; None for a model that does not report one (SWMM, BMI, a black box).
    levels, discharges
        Full fields at the output times (columns: h-point and link labels) when snapshots were
        requested, else ``None``.
    wall_time
        Wall-clock time of the compiled run, s.
    shortfalls
        The withdrawals that ran short of water, by forcing key (``"boundary:<id>"``, ``"lateral:<id>"``);
        empty when every withdrawal was delivered in full.
    source
        What computed the series, for the NetCDF ``source`` attribute (default: the embedded engine).
    """

    series: pd.DataFrame
    balance: VolumeBalance | None = None
    levels: pd.DataFrame | None = None
    discharges: pd.DataFrame | None = None
    wall_time: float = field(default=0.0, compare=False)
    shortfalls: dict[str, Shortfall] = field(default_factory=dict)
    source: str = field(default=ENGINE_SOURCE, compare=False)

    def to_csv(self, path: str | Path) -> None:
        """Write the station series as CSV (ISO 8601 UTC times)."""
        frame = self.series.copy()
        frame.index = frame.index.strftime("%Y-%m-%dT%H:%M:%SZ")
        frame.index.name = "time"
        frame.to_csv(path, float_format="%.6f")

    def to_dataset(self):
        """The station series as a CF-1.8 ``xarray.Dataset`` (discrete sampling geometry: timeSeries).

        Levels (``h``, ``h_up``, ``h_down``) go into ``water_level(level_series, time)`` in m,
        discharges into ``discharge(discharge_series, time)`` in m³/s, the crests of controlled weirs
        (``<weir>.crest``) into ``crest_level(crest_series, time)`` in m; the series names are
        ``timeseries_id`` coordinates.
        """
        import xarray as xr

        cols = list(self.series.columns)
        time = self.series.index.tz_convert("UTC").tz_localize(None)
        data_vars = {}
        coords = {"time": ("time", time.values, {"standard_name": "time", "axis": "T"})}
        for var, text in zip(CF_VARIABLES, ("simulated water level", "simulated discharge"), strict=True):
            columns = var.columns(cols)
            if columns:
                coords[var.dimension] = (var.dimension, np.array(columns, dtype=object),
                                         {"cf_role": "timeseries_id", "long_name": "station.quantity"})
                data_vars[var.name] = ((var.dimension, "time"), self.series[columns].to_numpy().T,
                                       var.attrs(text))
        crests = [c for c in cols if c.endswith(".crest")]
        if crests:  # controlled weirs: no CF standard name for a crest level, so a long name only
            coords["crest_series"] = ("crest_series", np.array(crests, dtype=object),
                                      {"cf_role": "timeseries_id", "long_name": "weir.crest"})
            data_vars["crest_level"] = (("crest_series", "time"), self.series[crests].to_numpy().T,
                                        {"units": "m", "long_name": "simulated crest level of a controlled weir"})
        ds = xr.Dataset(data_vars=data_vars, coords=coords)
        ds.attrs.update(
            Conventions="CF-1.8",
            featureType="timeSeries",
            title="rivercal simulation",
            source=self.source,
        )
        ds["time"].encoding.update(units="seconds since 1970-01-01 00:00:00", calendar="standard")
        return ds

    def to_netcdf(self, path: str | Path) -> None:
        """Write the station series as CF-1.8 NetCDF (see :meth:`to_dataset`)."""
        self.to_dataset().to_netcdf(path)
