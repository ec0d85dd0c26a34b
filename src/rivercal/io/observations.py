"""Observation CSV files: a ``time`` column (ISO 8601, UTC when no offset) and one column per series.

Columns are named ``"<station>.<quantity>"`` (``h``, ``h_up``, ``h_down`` in m AD; ``Q`` in m³/s). An empty
cell is a missing observation: it is dropped and counted, never read as zero. Text that is not a
number, an unparsable or repeated time, or times out of order are errors that name the file, the line
and the column (the checks of the case's series files, :mod:`rivercal.case.series`, without the gap
rule: observations may have gaps).

:func:`read_observations` reads any observation file rivercal knows by its suffix: such a CSV file, a
Delft-FEWS PI-XML file (:func:`rivercal.io.read_pixml`), or a sidecar TOML that describes gauge files as
they were delivered (:func:`rivercal.io.read_sidecar`: MATROOS/NOOS exports, loggers' CSV with local time,
depths, units and quality flags).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from rivercal.case.series import read_series_table, series_column
from rivercal.errors import CaseError
from rivercal.observations import ObservationSet

__all__ = ["OBSERVATION_SUFFIXES", "read_observations", "read_observations_csv", "write_observations_csv"]

#: The suffixes of the observation files :func:`read_observations` reads.
OBSERVATION_SUFFIXES = (".csv", ".xml", ".toml")


def read_observations_csv(path: str | Path, *, sigma: Mapping[str, float | None] | None = None) -> ObservationSet:
    """Read observations from a CSV file.

    Parameters
    ----------
    path
        The file.
    sigma
        σ per series id or quantity (default :data:`rivercal.observations.DEFAULT_SIGMA`).

    Raises
    ------
    CaseError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    table = read_series_table(path, label=str(path), allow_gaps=True)
    data = {c: series_column(table, c, allow_missing=True) for c in table.columns}
    frame = pd.DataFrame(data, index=table.times)
    try:
        return ObservationSet.from_frame(frame, sigma=sigma, source=str(path))
    except ValueError as exc:
        raise CaseError(str(exc), file=str(path)) from None


def read_observations(path: str | Path) -> ObservationSet:
    """Observations from a file, by its suffix.

    ``.csv`` (:func:`read_observations_csv`), ``.xml`` (Delft-FEWS PI-XML, :func:`rivercal.io.read_pixml`) or
    ``.toml`` (a sidecar describing gauge files, :func:`rivercal.io.read_sidecar`).

    Raises
    ------
    CaseError
        For a file of another kind, or naming the file (and line) of the first problem.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return read_observations_csv(path)
    if suffix == ".xml":
        from rivercal.io.pixml import read_pixml

        return read_pixml(path)
    if suffix == ".toml":
        from rivercal.io.sensors import read_sidecar

        return read_sidecar(path)
    raise CaseError(f"expected an observation file ending in {', '.join(OBSERVATION_SUFFIXES)} (CSV, PI-XML, or a "
                    "sidecar TOML describing gauge files)", file=str(path))


def write_observations_csv(observations: ObservationSet, path: str | Path) -> Path:
    """Write observations in the format :func:`read_observations_csv` reads (missing values empty)."""
    frame = observations.to_frame()
    frame.index = frame.index.strftime("%Y-%m-%dT%H:%M:%SZ")
    frame.index.name = "time"
    path = Path(path)
    frame.to_csv(path, float_format="%.6f")
    return path
