"""Readers and writers of observations and results: CSV, Delft-FEWS PI-XML, and gauge files described by sidecars."""

from rivercal.io.observations import read_observations, read_observations_csv, write_observations_csv
from rivercal.io.pixml import (
    STANDARD_CONVERSIONS,
    PiSeries,
    PiXmlError,
    read_pixml,
    read_pixml_series,
    write_pixml,
    write_pixml_series,
)
from rivercal.io.sensors import SIDECAR_SCHEMA, parse_time_zone, read_sidecar

__all__ = [
    "SIDECAR_SCHEMA",
    "STANDARD_CONVERSIONS",
    "PiSeries",
    "PiXmlError",
    "parse_time_zone",
    "read_observations",
    "read_observations_csv",
    "read_pixml",
    "read_pixml_series",
    "read_sidecar",
    "write_observations_csv",
    "write_pixml",
    "write_pixml_series",
]
