"""Reader for the hourly Hupsel Brook forcing and discharge (``PEQ_Hupsel.dat``).

The file comes with the WALRUS demo (Brauer et al. 2014b; GitHub ``ClaudiaBrauer/WALRUS``) and is
GPL-3: rivercal never copies it; it reads it from where it lies. The path is taken from the
environment variable :data:`ENV_VAR` (``RIVERCAL_HUPSEL_FILE``) or defaults to
``<repository>/../shared/data/walrus-hupsel-hourly/PEQ_Hupsel.dat``.

Format: one header line ``"date" "P" "ETpot" "Q"``, then whitespace-separated rows. ``date`` is
``YYYYMMDDHH``, the **end** of the hour; ``P`` (precipitation), ``ETpot`` (Makkink potential
evapotranspiration) and ``Q`` (specific discharge of the 6.5 km² catchment) are mm/h; ``NA`` is
a missing value (NaN, counted in ``attrs["missing"]``). The file does not state a time zone;
the index is labelled UTC.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.hydrology.knmi import MeteoFormatError

__all__ = ["AREA_KM2", "ENV_VAR", "hupsel_path", "read_hupsel"]

logger = logging.getLogger(__name__)

#: Environment variable that points at ``PEQ_Hupsel.dat``.
ENV_VAR = "RIVERCAL_HUPSEL_FILE"

#: Area of the Hupsel Brook catchment (km²) as given by Brauer et al. (2014b).
AREA_KM2 = 6.5

_COLUMNS = ("date", "P", "ETpot", "Q")


def hupsel_path() -> Path:
    """The path of ``PEQ_Hupsel.dat``: ``$RIVERCAL_HUPSEL_FILE`` or the default next to the repository.

    Raises
    ------
    FileNotFoundError
        When the file does not exist (the message names the path and the environment variable).
    """
    env = os.environ.get(ENV_VAR)
    if env:
        path = Path(env).expanduser()
        origin = f"${ENV_VAR}"
    else:
        repository = Path(__file__).resolve().parents[3]
        path = (repository / ".." / "shared" / "data" / "walrus-hupsel-hourly" / "PEQ_Hupsel.dat").resolve()
        origin = "default location"
    if not path.is_file():
        raise FileNotFoundError(f"Hupsel data not found at {path} ({origin}); set {ENV_VAR} to the path of "
                                f"PEQ_Hupsel.dat (WALRUS demo data, GPL-3; not shipped with rivercal)")
    return path


def read_hupsel(path: str | Path | None = None) -> pd.DataFrame:
    """Read the hourly Hupsel series.

    Parameters
    ----------
    path
        The file; default :func:`hupsel_path`.

    Returns
    -------
    pandas.DataFrame
        Columns ``P``, ``ETpot``, ``Q`` (mm/h, float, NaN where the file says ``NA``), indexed by
        the end of each hour (``DatetimeIndex`` named ``time``, UTC). ``attrs``: ``source``,
        ``units``, ``missing`` (column → count), ``area_km2``.

    Raises
    ------
    FileNotFoundError
        When the file is absent.
    MeteoFormatError
        When the header, a date or a value is malformed, or times are not strictly increasing.
    """
    path = hupsel_path() if path is None else Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"Hupsel data not found at {path}; set {ENV_VAR}")
    name = str(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines:
        raise MeteoFormatError("empty file", file=name)
    header = [c.strip('"') for c in lines[0].split()]
    if tuple(header) != _COLUMNS:
        raise MeteoFormatError(f"header {header} is not {list(_COLUMNS)}", file=name, line=1)
    dates: list[str] = []
    values: list[list[float]] = []
    for no, text in enumerate(lines[1:], 2):
        if not text.strip():
            continue
        fields = text.split()
        if len(fields) != 4:
            raise MeteoFormatError(f"expected 4 fields, found {len(fields)}", file=name, line=no)
        dates.append(fields[0])
        row = []
        for col, field in zip(_COLUMNS[1:], fields[1:], strict=True):
            if field == "NA":
                row.append(np.nan)
                continue
            try:
                row.append(float(field))
            except ValueError:
                raise MeteoFormatError(f"{field!r} is not a number", file=name, line=no, column=col) from None
        values.append(row)
    times = pd.to_datetime(pd.Series(dates), format="%Y%m%d%H", errors="coerce", utc=True)
    bad = np.flatnonzero(times.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        raise MeteoFormatError(f"{dates[i]!r} is not a time YYYYMMDDHH", file=name, line=i + 2, column="date")
    index = pd.DatetimeIndex(times, name="time")
    back = np.flatnonzero(np.diff(index.asi8) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise MeteoFormatError(f"time {dates[i]} repeats or runs backwards", file=name, line=i + 2, column="date")
    frame = pd.DataFrame(np.array(values, dtype=float), index=index, columns=list(_COLUMNS[1:]))
    missing = {c: int(n) for c, n in frame.isna().sum().items() if n}
    if missing:
        logger.info("%s: missing values (NaN): %s", name, missing)
    irregular = int((index[1:] - index[:-1] != pd.Timedelta(hours=1)).sum())
    if irregular:
        logger.warning("%s: the series is not regularly hourly (%d irregular steps)", name, irregular)
    frame.attrs.update(source=name, units={"P": "mm/h", "ETpot": "mm/h", "Q": "mm/h"}, missing=missing,
                       area_km2=AREA_KM2)
    return frame
