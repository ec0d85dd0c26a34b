"""Engine state (hot start) and simulation results."""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.engine.kernels.codes import CONTROL_STATS
from rivercal.observations import CF_VARIABLES

__all__ = ["EngineState", "Shortfall", "SimulationResult", "VolumeBalance"]


@dataclass
class EngineState:
    """Everything needed to continue a run exactly where it stopped.

    Attributes
    ----------
    time
        Simulated time of the state (UTC).
    z
        Levels at the h-points, m AD.
    dz
        Level change over the last step at the h-points, m (the engine extrapolates with it).
    vol
        Volumes at the h-points, m³.
    u
        Velocities at the links, m/s.
    q
        Discharges at the links, m³/s.
    pump_on
        Pump switches (0 off, 1 on).
    signature
        Grid signature (h-points, links) of the network that produced the state.
    ctl
        The controllers' state, one row per controller (:mod:`rivercal.engine.kernels.control`: integral in
        m·s, last error in m, crest in m AD, time since the last action in s, target crest in m AD, started);
        no rows for a network without controllers.
    control
        The step control's state (:data:`rivercal.engine.kernels.codes.CONTROL_STATS`: sub-step levels and their
        counters), so that a run continued from the state divides its steps as the whole run would; zeros for a
        cold start.
    flicker, swing
        Per h-point, the flicker detector's count and the level's change since it last turned, m.
    dikes
        Per summer dike whose storage changes curve (:class:`~rivercal.engine.compile.DikeArrays`), 1 while it
        drains by its falling curve, else 0; None for a network without such dikes or a cold start (all rising).
    """

    time: pd.Timestamp
    z: np.ndarray
    dz: np.ndarray
    vol: np.ndarray
    u: np.ndarray
    q: np.ndarray
    pump_on: np.ndarray
    signature: tuple[int, int]
    ctl: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    control: np.ndarray = field(default_factory=lambda: np.zeros(len(CONTROL_STATS), dtype=np.int64))
    flicker: np.ndarray | None = None
    swing: np.ndarray | None = None
    dikes: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.flicker is None:
            self.flicker = np.zeros(np.shape(self.z), dtype=np.int32)
        if self.swing is None:
            self.swing = np.zeros(np.shape(self.z))

    def dike_curves(self, n: int) -> np.ndarray:
        """A copy of :attr:`dikes` for a network with ``n`` such dikes (all rising where the state holds none)."""
        if self.dikes is None or np.size(self.dikes) != n:
            return np.zeros(n, dtype=np.int8)
        return np.asarray(self.dikes, dtype=np.int8).copy()

    def copy(self) -> EngineState:
        """A deep copy (the engine updates states in place)."""
        return EngineState(
            time=self.time,
            z=self.z.copy(),
            dz=self.dz.copy(),
            vol=self.vol.copy(),
            u=self.u.copy(),
            q=self.q.copy(),
            pump_on=self.pump_on.copy(),
            signature=self.signature,
            ctl=self.ctl.copy(),
            control=self.control.copy(),
            flicker=self.flicker.copy(),
            swing=self.swing.copy(),
            dikes=None if self.dikes is None else self.dikes.copy(),
        )

    #: Format tag of :meth:`to_bytes` (stored with the bytes so a later rivercal can tell what it reads).
    BYTES_FORMAT = "rivercal-engine-state-npz-1"

    def to_bytes(self) -> bytes:
        """The state as bytes (an ``.npz`` archive of plain arrays; no pickle), for the on-line store."""
        buffer = io.BytesIO()
        np.savez(buffer, time_ns=np.int64(self.time.value), z=self.z, dz=self.dz, vol=self.vol, u=self.u, q=self.q,
                 pump_on=self.pump_on, signature=np.asarray(self.signature, dtype=np.int64), ctl=self.ctl,
                 control=self.control, flicker=self.flicker, swing=self.swing,
                 **({} if self.dikes is None else {"dikes": self.dikes}))
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, fmt: str = BYTES_FORMAT) -> EngineState:
        """Read a state written by :meth:`to_bytes`.

        Raises
        ------
        ValueError
            For another format tag or bytes that are not such an archive.
        """
        if fmt != cls.BYTES_FORMAT:
            raise ValueError(f"engine state format {fmt!r} is not {cls.BYTES_FORMAT!r}")
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as f:
                return cls(time=pd.Timestamp(int(f["time_ns"]), tz="UTC"), z=f["z"], dz=f["dz"], vol=f["vol"],
                           u=f["u"], q=f["q"], pump_on=f["pump_on"],
                           signature=tuple(int(v) for v in f["signature"]),  # type: ignore[arg-type]
                           ctl=f["ctl"] if "ctl" in f.files else np.zeros((0, 6)),
                           control=f["control"] if "control" in f.files else np.zeros(len(CONTROL_STATS),
                                                                                        dtype=np.int64),
                           flicker=f["flicker"] if "flicker" in f.files else None,
                           swing=f["swing"] if "swing" in f.files else None,
                           dikes=f["dikes"] if "dikes" in f.files else None)
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"not an engine state archive ({exc})") from None


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
        Volume balance of the run.
    levels, discharges
        Full fields at the output times (columns: h-point and link labels) when snapshots were
        requested, else ``None``.
    wall_time
        Wall-clock time of the compiled run, s.
    shortfalls
        The withdrawals that ran short of water, by forcing key (``"boundary:<id>"``, ``"lateral:<id>"``);
        empty when every withdrawal was delivered in full.
    """

    series: pd.DataFrame
    balance: VolumeBalance
    levels: pd.DataFrame | None = None
    discharges: pd.DataFrame | None = None
    wall_time: float = field(default=0.0, compare=False)
    shortfalls: dict[str, Shortfall] = field(default_factory=dict)

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
            source="rivercal embedded 1D De Saint-Venant engine (staggered Delft scheme)",
        )
        ds["time"].encoding.update(units="seconds since 1970-01-01 00:00:00", calendar="standard")
        return ds

    def to_netcdf(self, path: str | Path) -> None:
        """Write the station series as CF-1.8 NetCDF (see :meth:`to_dataset`)."""
        self.to_dataset().to_netcdf(path)
