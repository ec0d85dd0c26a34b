"""Readers and writers of observations and results (layer 6): CSV and Delft-FEWS PI-XML."""

from rivercal.io.observations import read_observations_csv, write_observations_csv
from rivercal.io.pixml import (
    STANDARD_CONVERSIONS,
    PiSeries,
    PiXmlError,
    read_pixml,
    read_pixml_series,
    write_pixml,
    write_pixml_series,
)

__all__ = [
    "STANDARD_CONVERSIONS",
    "PiSeries",
    "PiXmlError",
    "read_observations_csv",
    "read_pixml",
    "read_pixml_series",
    "write_observations_csv",
    "write_pixml",
    "write_pixml_series",
]
