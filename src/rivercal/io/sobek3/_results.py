"""The SOBEK 3 kernel's own results: water levels at the grid points, levels and discharges at observation points."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError

__all__ = ["Sobek3Results", "read_results"]


@dataclass(frozen=True)
class Sobek3Results:
    """What SOBEK 3 wrote to ``output/gridpoints.nc`` and ``output/observations.nc``.

    Attributes
    ----------
    points
        Per grid point: ``id``, ``branch`` (its branch id) and ``chainage`` (m).
    levels
        Water level at every grid point (columns in the order of ``points``), m AD; UTC index.
    observation_levels, observation_discharges
        Water level (m AD) and discharge (m³/s) per observation point id, or None without ``observations.nc``.
    """

    points: pd.DataFrame
    levels: pd.DataFrame
    observation_levels: pd.DataFrame | None
    observation_discharges: pd.DataFrame | None


def _times(ds, path: Path) -> pd.DatetimeIndex:
    unit = str(ds["time"].attrs.get("units", ""))
    match = re.fullmatch(r"\s*(seconds|minutes|hours|days)\s+since\s+(.+?)\s*", unit)
    if not match:
        raise CaseError(f"the time unit {unit!r} is not '<seconds|minutes|hours|days> since <date>'", file=str(path),
                        field="time")
    scale = {"seconds": 1.0, "minutes": 60.0, "hours": 3600.0, "days": 86400.0}[match.group(1)]
    ref = pd.Timestamp(match.group(2))
    ref = ref.tz_localize("UTC") if ref.tzinfo is None else ref.tz_convert("UTC")
    seconds = np.asarray(ds["time"].values, dtype=float) * scale
    return ref + pd.to_timedelta(np.round(seconds * 1000.0).astype(np.int64), unit="ms")


def _text(values) -> list[str]:
    return [v.decode().strip() if isinstance(v, bytes) else str(v).strip() for v in np.asarray(values).ravel()]


def read_results(output: Path | str, branch_ids: list[str] | None = None) -> Sobek3Results:
    """Read a SOBEK 3 output folder (``.../dflow1d/output``).

    Parameters
    ----------
    output
        The folder with ``gridpoints.nc`` (and optionally ``observations.nc``).
    branch_ids
        Branch ids in the order of the model's NetworkDefinition (SOBEK 3 numbers the branches of its output
        1, 2, ...); default: the branch part of the grid point ids (``<branch>_<chainage>``).

    Raises
    ------
    CaseError
        When a file is missing or lacks the variables a SOBEK 3 result file has.
    """
    import xarray as xr

    output = Path(output)
    path = output / "gridpoints.nc"
    if not path.is_file():
        raise CaseError("no such file: SOBEK 3 writes its grid point levels there", file=str(path))
    with xr.open_dataset(path, decode_times=False) as ds:
        for name in ("water_level", "chainage", "time"):
            if name not in ds.variables:
                raise CaseError(f"no variable {name!r}: not a SOBEK 3 grid point result file", file=str(path))
        times = _times(ds, path)
        ids = _text(ds["gridpoint_id"].values) if "gridpoint_id" in ds.variables else [
            str(i) for i in range(ds.sizes["id"])]
        chainage = np.asarray(ds["chainage"].values, dtype=float)
        if branch_ids is not None and "branchid" in ds.variables:
            numbers = np.asarray(ds["branchid"].values, dtype=float).astype(int)
            branches = [branch_ids[n - 1] if 1 <= n <= len(branch_ids) else str(n) for n in numbers]
        else:
            branches = [i.rsplit("_", 1)[0] for i in ids]
        levels = pd.DataFrame(np.asarray(ds["water_level"].values, dtype=float), index=times, columns=ids)
    points = pd.DataFrame({"id": ids, "branch": branches, "chainage": chainage})
    obs_path = output / "observations.nc"
    obs_h = obs_q = None
    if obs_path.is_file():
        with xr.open_dataset(obs_path, decode_times=False) as ds:
            times = _times(ds, obs_path)
            names = _text(ds["observation_id"].values) if "observation_id" in ds.variables else [
                str(i) for i in range(ds.sizes["id"])]
            if "water_level" in ds.variables:
                obs_h = pd.DataFrame(np.asarray(ds["water_level"].values, dtype=float), index=times, columns=names)
            if "water_discharge" in ds.variables:
                obs_q = pd.DataFrame(np.asarray(ds["water_discharge"].values, dtype=float), index=times,
                                     columns=names)
    return Sobek3Results(points=points, levels=levels, observation_levels=obs_h, observation_discharges=obs_q)
