"""Hydrology: meteorological forcing and the rainfall-runoff model that makes the lateral inflows.

Layer 3 (next to the engine, never importing it). The lateral inflows of a case are computed once,
before any hydrodynamic run (thesis §3-1-2):

1. :mod:`~rivercal.hydrology.knmi` reads KNMI daily station files in physical units;
2. :mod:`~rivercal.hydrology.disaggregate` turns daily rain and Makkink evaporation into hourly series
   (UTC, each value belongs to the hour ending at its timestamp; daily totals kept exactly);
3. :mod:`~rivercal.hydrology.runoff` runs a WALRUS-type lowland rainfall-runoff model (Wageningen model
   family) to a specific discharge (mm/h), and :func:`~rivercal.hydrology.runoff.lateral_inflow`
   converts it to m³/s for a sub-catchment area;
4. :mod:`~rivercal.hydrology.hupsel` reads the hourly Hupsel Brook data used to test the model, and
   :mod:`~rivercal.hydrology.metrics` scores it (NSE, KGE).
"""

from rivercal.hydrology.disaggregate import disaggregate_evaporation, disaggregate_rain, hourly_forcing
from rivercal.hydrology.hupsel import read_hupsel
from rivercal.hydrology.knmi import MeteoFormatError, read_knmi_daily
from rivercal.hydrology.metrics import kling_gupta, nash_sutcliffe
from rivercal.hydrology.runoff import (
    CALIBRATION_PARAMETERS,
    PARAMETERS,
    RunoffResult,
    WalrusParameters,
    WalrusState,
    lateral_inflow,
    simulate,
    steady_state,
)

__all__ = [
    "CALIBRATION_PARAMETERS",
    "PARAMETERS",
    "MeteoFormatError",
    "RunoffResult",
    "WalrusParameters",
    "WalrusState",
    "disaggregate_evaporation",
    "disaggregate_rain",
    "hourly_forcing",
    "kling_gupta",
    "lateral_inflow",
    "nash_sutcliffe",
    "read_hupsel",
    "read_knmi_daily",
    "simulate",
    "steady_state",
]
