"""Readers and writers of observations and results (layer 6)."""

from rivercal.io.observations import read_observations_csv, write_observations_csv

__all__ = ["read_observations_csv", "write_observations_csv"]
