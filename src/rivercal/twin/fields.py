"""A twin's levels at every point: the truth, the DSS and rivercal over a replayed on-line run, for the report.

The stations cannot show what a twin knows: the levels at every calculation point of the truth, of the DSS
and of the model as the on-line service kept it. :func:`twin_fields` runs them once, after a run of the
service on a twin scenario, and :func:`store_twin_fields` keeps them with the run (the store's run
products), so that the report draws its maps and the levels at the weir of thesis Fig. 5-4 from the store
and runs no model. The three continuous runs are

- the **truth**: the scenario's parameters on the model itself (before the change, then after it; the
  identical twin, also when the observations came from a truth with other errors);
- the **DSS**: the run's fixed DSS quantities throughout, from a cold start;
- **rivercal**: each cycle's accepted parameters from its issue time until the next cycle's (a
  piecewise-constant parameter history, one run from one state).

They need a model with snapshots (:class:`~rivercal.models.capabilities.Snapshots`); the levels are m AD, hourly.
"""

from __future__ import annotations

import io
import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.models.capabilities import Snapshots, StateArrays, capability
from rivercal.models.contract import Model, spun_up
from rivercal.parameters import ParameterSet
from rivercal.store import Run, Store
from rivercal.twin.practical import LOCAL_WEIR, SCENARIOS, practical_truth

__all__ = ["FIELDS_FORMAT", "FIELDS_PRODUCT", "TwinFields", "load_twin_fields", "store_twin_fields", "twin_fields"]

#: Name of the run product (:meth:`rivercal.store.Store.product`) and its format tag: an ``.npz`` archive (no
#: pickle) of the times (ns since 1970, UTC), the point and series labels and the float32 values.
FIELDS_PRODUCT = "twin-fields"
FIELDS_FORMAT = "rivercal-twin-fields-npz-1"
_KINDS = ("truth", "dss", "rivercal")


@dataclass(frozen=True)
class TwinFields:
    """The three continuous runs of a twin (module docstring).

    Attributes
    ----------
    levels
        ``truth``, ``dss``, ``rivercal``: levels at every calculation point (m AD), indexed by time (UTC),
        one column per point label.
    series
        The same three runs' station series (m AD, m³/s).
    weir_points
        Labels of the points just up- and downstream of the weir of thesis Fig. 5-4 (``LOCAL_WEIR``), or
        None when the model has no such weir or does not say where its points lie.
    """

    levels: dict[str, pd.DataFrame]
    series: dict[str, pd.DataFrame]
    weir_points: tuple[str, str] | None = None

    def to_bytes(self) -> bytes:
        """The fields as an ``.npz`` archive (float32 values; :data:`FIELDS_FORMAT`)."""
        times = self.levels["truth"].index
        arrays: dict[str, Any] = {"time_ns": times.as_unit("ns").asi8,
                                  "points": np.array(list(self.levels["truth"].columns), dtype=str),
                                  "stations": np.array(list(self.series["truth"].columns), dtype=str),
                                  "weir_points": np.array(list(self.weir_points or ()), dtype=str)}
        for kind in _KINDS:
            arrays[f"levels_{kind}"] = self.levels[kind].to_numpy(dtype=np.float32)
            arrays[f"series_{kind}"] = self.series[kind].to_numpy(dtype=np.float32)
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> TwinFields:
        """Read :meth:`to_bytes`; ValueError for other bytes."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as f:
                times = pd.DatetimeIndex(pd.to_datetime(f["time_ns"], utc=True), name="time")
                points, stations = [str(p) for p in f["points"]], [str(s) for s in f["stations"]]
                levels = {k: pd.DataFrame(f[f"levels_{k}"].astype(float), index=times, columns=points) for k in _KINDS}
                series = {k: pd.DataFrame(f[f"series_{k}"].astype(float), index=times, columns=stations)
                          for k in _KINDS}
                weir = tuple(str(p) for p in f["weir_points"])
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"not a twin-fields archive ({exc})") from None
        return cls(levels=levels, series=series, weir_points=weir if len(weir) == 2 else None)  # type: ignore[arg-type]


def twin_fields(model: Model, store: Store, run: Run, start: Any, end: Any) -> TwinFields:
    """The truth, the DSS and rivercal at every point, hourly, from ``start`` to ``end`` (module docstring).

    Raises
    ------
    MissingCapability
        When the model has no snapshots.
    ValueError
        When the run is not on a twin scenario.
    """
    fields: Snapshots = capability(model, "snapshots", purpose="the twin's levels at every point")
    meta, config = dict(run.config.get("meta") or {}), run.config
    if meta.get("scenario") not in SCENARIOS:
        raise ValueError(f"run {run.name!r} is not on a twin scenario")
    start, end = utc(start), utc(end)
    truth = practical_truth(model, meta["scenario"], start, end, levels=True)
    dss_q = dict(config.get("dss") or {})
    dss, _ = fields.simulate_fields(dss_q, start=start, end=end, state=spun_up(model, dss_q, start),
                                    output_interval=3600)
    known = {p.name: p for p in model.calibration.parameters}
    params = ParameterSet(known[n] for n in config["parameters"])
    est, cycles = store.estimates(run), store.cycles(run)
    accepted: dict[str, float] = {p.name: p.initial for p in params}
    segments: list[tuple[pd.Timestamp, dict[str, float]]] = []
    for c in cycles.itertuples():
        rows = est[(est["cycle"] == c.cycle) & est["accepted"]]
        accepted = {**accepted, **dict(zip(rows["parameter"], rows["value"], strict=True))}
        segments.append((c.issue_time, dict(accepted)))
    first = [q for t, q in segments if t <= start]
    values = first[-1] if first else {p.name: p.initial for p in params}
    state = spun_up(model, {**dss_q, **params.quantities(values)}, start)
    edges = [start, *[t for t, _ in segments if start < t < end], end]
    level_parts, series_parts = [], []
    for a, b in itertools.pairwise(edges):
        later = [q for t, q in segments if t <= a]
        values = later[-1] if later else values
        res, state = fields.simulate_fields({**dss_q, **params.quantities(values)}, start=a, end=b, state=state,
                                            output_interval=3600)
        level_parts.append(res.levels.iloc[:-1])
        series_parts.append(res.series.iloc[:-1])
    levels = pd.concat(level_parts)
    idx = levels.index
    return TwinFields(levels={"truth": truth.levels.loc[idx], "dss": dss.levels.loc[idx], "rivercal": levels},
                      series={"truth": truth.series.loc[idx], "dss": dss.series.loc[idx],
                              "rivercal": pd.concat(series_parts)},
                      weir_points=_weir_points(model))


def _weir_points(model: Model) -> tuple[str, str] | None:
    """The level points either side of ``LOCAL_WEIR`` from the model's state layout (None where it has none)."""
    if not isinstance(model, StateArrays):
        return None
    layout = model.state_layout()
    label = f"weir:{LOCAL_WEIR}"
    if label not in layout.discharges:
        return None
    up, down = (int(k) for k in layout.link_ends[layout.discharges.index(label)])
    return (layout.levels[up], layout.levels[down]) if up >= 0 and down >= 0 else None


def store_twin_fields(store: Store, run: Run, fields: TwinFields) -> None:
    """Keep the fields with the run (the store's run product :data:`FIELDS_PRODUCT`)."""
    store.put_product(run, FIELDS_PRODUCT, FIELDS_FORMAT, fields.to_bytes())


def load_twin_fields(store: Store, run: Run) -> TwinFields | None:
    """The fields stored with the run, or None (none stored, or in a format this rivercal does not read)."""
    stored = store.product(run, FIELDS_PRODUCT)
    if stored is None or stored[0] != FIELDS_FORMAT:
        return None
    return TwinFields.from_bytes(stored[1])
