"""One-at-a-time sensitivity (thesis §2-3-1-1 and §4-5-1: Table 4-4, Fig. 4-5, Figs. C-1 … C-5).

Each scenario changes one parameter from the base point (the initial values) and keeps the others there;
its cost (thesis Eq. 2-3) is split per station and per series, from the weighted residuals of the run.
All scenarios go out as ONE batch to an :class:`~rivercal.evaluate.Evaluator`, so that they run in
parallel; scenarios that repeat the base point (the middle value of each parameter in Table 4-4) are run
once.

:func:`thesis_scenarios` builds thesis Table 4-4 from a case's parameters: five values per parameter,
the base value ("AVG") ± 0.15 and ± 0.30 m for every weir crest and ± 2 and ± 4 m^(1/3)/s for a friction
parameter (k_s = 16: FA1 … FA5 = 20, 18, 16, 14, 12, in the thesis' order). A cluster parameter (Wc, not in
the table) gets the base ± 0.1 and ± 0.2. Any parameter can be given its own list instead.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from rivercal.analysis._common import Batch, batch_for, station_of
from rivercal.parameters import Parameter, ParameterSet

__all__ = [
    "CLUSTER_STEPS",
    "FRICTION_STEPS",
    "WEIR_STEPS",
    "SensitivityResult",
    "scenario_table",
    "sensitivity",
    "thesis_scenarios",
]

log = logging.getLogger(__name__)

#: Thesis Table 4-4: crest scenarios W·-1 … W·-5 relative to the base ("AVG") crest, m.
WEIR_STEPS = (-0.30, -0.15, 0.0, 0.15, 0.30)
#: Thesis Table 4-4: FA1 … FA5 relative to the base Strickler coefficient, m^(1/3)/s (20, 18, 16, 14, 12).
FRICTION_STEPS = (4.0, 2.0, 0.0, -2.0, -4.0)
#: The unit of a Strickler coefficient, for which FRICTION_STEPS are meant (a Manning n or a Chézy C is not).
STRICKLER_UNIT = "m^(1/3)/s"
#: Our choice for a cluster parameter in [0, 1] (Wc is not in Table 4-4), dimensionless.
CLUSTER_STEPS = (-0.2, -0.1, 0.0, 0.1, 0.2)
#: Our choice for any other quantity (a Manning or Chézy coefficient, a roughness factor, a quantity of an external
#: model): these multiples of the parameter's first DuD step, kept inside its bounds.
OTHER_STEPS = (-2.0, -1.0, 0.0, 1.0, 2.0)


def _kind(p: Parameter) -> str:
    if p.cluster:
        return "cluster"
    if all(t.startswith("weir:") for t in p.targets):
        return "weir"
    if all(t.startswith("friction:") for t in p.targets) and p.unit in ("", STRICKLER_UNIT):
        return "friction"  # Table 4-4's steps are Strickler coefficients; another law's value takes OTHER_STEPS
    return "mixed"


def thesis_scenarios(parameters: ParameterSet, names: Sequence[str] | None = None, *,
                     custom: Mapping[str, Sequence[float]] | None = None) -> dict[str, list[float]]:
    """The values per parameter of thesis Table 4-4 (five per parameter), with optional custom lists.

    Parameters
    ----------
    parameters
        The parameters; their initial values are the base ("AVG").
    names
        Parameters to include (default: all, in set order).
    custom
        Value lists (physical units) that replace the thesis' for some parameters.

    A parameter for which the table's steps would leave its bounds (or a friction parameter whose unit is not
    the Strickler coefficient's) gets five values at multiples -2 … 2 of its first DuD step instead, kept inside
    its bounds.

    Returns
    -------
    dict
        Name → list of values in physical units (m AD for crests, m^(1/3)/s for Strickler friction).

    Raises
    ------
    ValueError
        For a custom list of a parameter that is not analysed.
    """
    custom = dict(custom or {})
    names = list(names) if names is not None else parameters.names
    out: dict[str, list[float]] = {}
    for name in names:
        p = parameters[name]
        if name in custom:
            out[name] = [float(v) for v in custom[name]]
            continue
        steps = {"weir": WEIR_STEPS, "friction": FRICTION_STEPS, "cluster": CLUSTER_STEPS}.get(_kind(p))
        if steps is not None and not all(p.min <= p.initial + s <= p.max for s in steps):
            steps = None  # the table's steps leave this parameter's range: its own steps instead
        if steps is None:
            step = p.initial_step(p.initial)
            values = [p.from_x(p.to_x(p.initial) + k * step) for k in OTHER_STEPS]
            out[name] = [round(min(max(v, p.min), p.max), 10) for v in values]
            continue
        out[name] = [round(p.initial + s, 10) for s in steps]
    for name in custom:
        if name not in out:
            raise ValueError(f"custom scenario values for {name!r}, which is not among the parameters analysed")
    return out


def scenario_table(parameters: ParameterSet, values: Mapping[str, Sequence[float]]) -> pd.DataFrame:
    """Thesis Table 4-4: one row per scenario (``AVG`` first, then ``<name>-<i>``), one column per parameter.

    Columns: ``parameter`` (the one changed; empty for AVG), ``step`` (i, 1-based; 0 for AVG), then the
    value of every parameter of the set in physical units.
    """
    base = {p.name: p.initial for p in parameters}
    if {"parameter", "step"} & set(base):
        raise ValueError("a parameter named 'parameter' or 'step' clashes with the scenario table's columns")
    rows = [{"scenario": "AVG", "parameter": "", "step": 0, **base}]
    for name, vals in values.items():
        p = parameters[name]  # KeyError naming the known parameters
        if len(vals) == 0:
            raise ValueError(f"no scenario values for {name!r}")
        for i, value in enumerate(vals, start=1):
            if not np.isfinite(value):
                raise ValueError(f"scenario {name}-{i}: value {value!r} is not finite")
            if not p.min <= value <= p.max:
                log.warning("scenario %s-%d: %s = %g lies outside its bounds [%g, %g]", name, i, name, value,
                            p.min, p.max)
            rows.append({"scenario": f"{name}-{i}", "parameter": name, "step": i, **base, name: float(value)})
    return pd.DataFrame(rows).set_index("scenario")


@dataclass(frozen=True)
class SensitivityResult:
    """Costs of one-at-a-time scenarios.

    Attributes
    ----------
    table
        The scenarios (thesis Table 4-4): index scenario; columns ``parameter``, ``step`` and the value of
        every parameter (physical units).
    frame
        Tidy costs: one row per scenario and scope with columns ``scenario``, ``parameter``, ``step``,
        ``value`` (of the changed parameter), ``scope`` (``total``, ``station`` or ``series``), ``name``
        (``total``, a station id or a series id) and ``cost`` (thesis Eq. 2-3, dimensionless).
    nfev
        Model runs used (distinct scenario points).
    """

    table: pd.DataFrame
    frame: pd.DataFrame
    nfev: int

    def costs(self, scope: str = "station") -> pd.DataFrame:
        """Wide costs: index scenario; columns ``parameter``, ``value``, ``total`` and one per station (or series)."""
        if scope not in ("station", "series"):
            raise ValueError(f"scope must be 'station' or 'series', got {scope!r}")
        part = self.frame[self.frame["scope"].isin(["total", scope])]
        wide = part.pivot(index="scenario", columns="name", values="cost")
        order = list(dict.fromkeys(part["name"]))
        wide = wide[order].reindex(self.table.index)
        wide.insert(0, "value", [self._value(s) for s in wide.index])
        wide.insert(0, "parameter", self.table["parameter"])
        return wide

    def _value(self, scenario: str) -> float:
        name = self.table.loc[scenario, "parameter"]
        return float(self.table.loc[scenario, name]) if name else float("nan")

    @property
    def base_cost(self) -> float:
        """Total cost at the base point (AVG)."""
        f = self.frame
        return float(f[(f["scenario"] == "AVG") & (f["scope"] == "total")]["cost"].iloc[0])

    def ranking(self) -> pd.DataFrame:
        """Parameters by their largest total cost over their scenarios (most influential first).

        Columns ``max_cost``, ``scenario`` (where it occurs), ``min_cost``; ties broken by name.
        """
        tot = self.frame[(self.frame["scope"] == "total") & (self.frame["parameter"] != "")]
        rows = []
        for name, part in tot.groupby("parameter", sort=False):
            i = int(np.argmax(part["cost"].to_numpy()))
            rows.append({"parameter": name, "max_cost": float(part["cost"].max()),
                         "scenario": part["scenario"].iloc[i], "min_cost": float(part["cost"].min())})
        out = pd.DataFrame(rows)
        return out.sort_values(["max_cost", "parameter"], ascending=[False, True]).set_index("parameter")

    def summary(self) -> dict[str, Any]:
        """JSON-friendly summary: ranking and costs per scenario (total and per station)."""
        wide = self.costs("station")
        return {
            "model_runs": self.nfev,
            "base_cost": self.base_cost,
            "ranking": [{"parameter": n, **{k: (v if isinstance(v, str) else float(v)) for k, v in r.items()}}
                        for n, r in self.ranking().iterrows()],
            "costs": {s: {k: (v if isinstance(v, str) else float(v)) for k, v in row.items()}
                      for s, row in wide.iterrows()},
        }


def sensitivity(problem: Any, values: Mapping[str, Sequence[float]] | None = None, *, batch: Batch | None = None,
                workers: int | None = None) -> SensitivityResult:
    """Run one-at-a-time scenarios as one parallel batch and split their costs per station and series.

    Parameters
    ----------
    problem
        A :class:`~rivercal.problem.CalibrationProblem`; its parameters' initial values are the base.
    values
        Per parameter name the values to try (physical units); default :func:`thesis_scenarios` of all the
        problem's parameters (thesis Table 4-4).
    batch
        A batch evaluator over ``problem.residuals`` (e.g. a shared :class:`~rivercal.evaluate.Evaluator`);
        default: a new one with ``workers`` processes.
    workers
        Worker processes when no ``batch`` is given (None: all cores).

    Returns
    -------
    SensitivityResult
    """
    pset: ParameterSet = problem.parameters
    values = thesis_scenarios(pset) if values is None else values
    table = scenario_table(pset, values)
    points, slot, keys = [], [], {}
    for _, row in table.iterrows():
        x = pset.to_x({n: float(row[n]) for n in pset.names})
        key = x.tobytes()
        if key not in keys:
            keys[key] = len(points)
            points.append(x)
        slot.append(keys[key])
    log.info("sensitivity: %d scenarios, %d distinct runs", len(table), len(points))
    with batch_for(problem, batch, workers) as run:
        results = [np.asarray(r, dtype=float) for r in run(points)]
    series = [(s.id, len(s)) for s in problem.observations]
    records = []
    for (scenario, row), k in zip(table.iterrows(), slot, strict=True):
        r = results[k]
        name = row["parameter"]
        base = {"scenario": scenario, "parameter": name, "step": int(row["step"]),
                "value": float(row[name]) if name else float("nan")}
        by_series, i = {}, 0
        for sid, n in series:
            by_series[sid] = float(r[i:i + n] @ r[i:i + n])
            i += n
        by_station: dict[str, float] = {}
        for sid, c in by_series.items():
            by_station[station_of(sid)] = by_station.get(station_of(sid), 0.0) + c
        records.append({**base, "scope": "total", "name": "total", "cost": float(r @ r)})
        records += [{**base, "scope": "station", "name": st, "cost": c} for st, c in by_station.items()]
        records += [{**base, "scope": "series", "name": sid, "cost": c} for sid, c in by_series.items()]
    return SensitivityResult(table=table, frame=pd.DataFrame(records), nfev=len(points))
