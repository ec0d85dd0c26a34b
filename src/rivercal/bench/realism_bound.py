"""The best any parameter estimator can do under a realism level: forecasts with fixed, known parameters.

``forecast_mae_ratio`` (:mod:`rivercal.bench.realism`) compares the DSS's level forecasts with rivercal's
over the cycles after a scenario's change. Under rainfall, runoff and structural errors part of both
forecasts' error is not a parameter's: no value of the estimated parameters removes it. This bound runs
the model with parameters that no estimator has to find:

- ``true``: the truth's own parameter values (the scenario's model quantities before and, from the exact
  time of the change, after it) — perfect, instantaneous knowledge of the intervention;
- for each value of ``values``: the DSS's parameters before the change and the value after it, for the
  one parameter that the scenario changes (FA, Wd or FL) — the best *constant* value after the change.

Each run is continuous from the model's start (the service's updated model also runs on from its own
state with its own parameters; a cycle's forecast from t₀ is this run's continuation when the
parameters do not change). The errors are taken, like the service's, against the twin's stored
observations that ingestion did not flag, over the hours that the lead 1–24 h forecasts of the daily
cycles issued after the change cover (the first cycle issued after the change + 1 h up to the last
cycle + 24 h); each hour is then counted once, as in the ratio of daily cycles with 24 h leads.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from rivercal._time import utc
from rivercal.model import load_model
from rivercal.observations import ScreenRule, measurable
from rivercal.parameters import ParameterSet
from rivercal.store import Store
from rivercal.twin.practical import SCENARIOS, practical_truth
from rivercal.twin.realism import get_realism

__all__ = ["realism_bound"]

_LEVELS = ("h", "h_up", "h_down")


def realism_bound(scenario: str, level: str = "realistic", *, case: str = "dommel", seed: int = 0,
                  values: Sequence[float] | None = None, first: str = "2010-10-18",
                  last: str = "2010-11-15", flood: tuple[str, str] | None = None) -> dict[str, Any]:
    """MAE (m) of the DSS and of runs with known parameters after the change, and their ratios (module docstring).

    Parameters
    ----------
    scenario, level, case, seed
        The practical scenario, realism level, case and seed of the errors (as ``rivercal bench realism``).
    values
        Values after the change of the parameter the scenario changes (FA or FL in m^(1/3)/s, Wd in m);
        default none (only the truth's own parameters).
    first, last
        The first and the last daily cycle's issue date (as ``rivercal bench realism``).
    flood
        Optionally a period (start, end; UTC) whose hours are also left out in a second set of figures.
    """
    sc = SCENARIOS[scenario]
    model = load_model(case)
    change = utc(sc.change_time)
    issues = pd.date_range(utc(first), utc(last), freq="1D")
    after = issues[issues > change]
    if after.empty:
        raise ValueError(f"no cycle from {first} to {last} is issued after the change at {change}")
    lo, hi = after[0] + pd.Timedelta("1h"), after[-1] + pd.Timedelta("24h")
    series = [s for s in measurable(model.observables) if s.rpartition(".")[2] in _LEVELS]
    truth = practical_truth(model, sc, lo - pd.Timedelta("1D"), min(hi, model.end), seed=seed, series=series,
                            realism=get_realism(level))
    with tempfile.TemporaryDirectory(prefix="rivercal-bound-") as tmp, Store(Path(tmp) / "bound.sqlite") as store:
        store.ingest(truth.observations, source=f"twin:{scenario}", screen=ScreenRule())
        observed = {s.id: pd.Series(s.values, index=s.times) for s in store.observations(series, lo, hi) if len(s)}

    def mae(before: dict[str, float], after_q: dict[str, float], skip: tuple[str, str] | None = None) -> float:
        _, state = model.simulate(before, end=change)
        run, _ = model.simulate(after_q, start=change, end=min(hi, model.end), state=state)
        errors = [(run.series[k].reindex(v.index) - v).abs() for k, v in observed.items()]
        e = pd.concat(errors)
        e = e[(e.index >= lo) & (e.index <= hi)]
        if skip is not None:
            e = e[(e.index < utc(skip[0])) | (e.index >= utc(skip[1]))]
        return float(e.mean())

    runs: dict[str, tuple[dict[str, float], dict[str, float]]] = {"dss": ({}, {}),
                                                                    "true": (dict(truth.before), dict(truth.after))}
    changed = [n for n, v in sc.true_after.items() if v is not None and v != sc.true_before.get(n)]
    if values:
        if len(changed) != 1:
            raise ValueError(f"scenario {scenario} changes {len(changed)} parameters; values can be tried for one")
        params = ParameterSet(p for p in model.calibration.parameters if p.name == changed[0])
        for v in values:
            runs[f"{changed[0]}={v:g}"] = ({}, params.quantities({changed[0]: float(v)}))
    out: dict[str, Any] = {"case": case, "scenario": scenario, "realism": level, "seed": seed,
                           "scored_from": lo.isoformat(), "scored_to": hi.isoformat(), "mae_m": {}, "ratio": {}}
    for name, (b, a) in runs.items():
        out["mae_m"][name] = mae(b, a)
        if flood is not None:
            out.setdefault("mae_without_flood_m", {})[name] = mae(b, a, flood)
    for key in ("mae_m", "mae_without_flood_m"):
        if key in out:
            ratios = {n: out[key]["dss"] / m for n, m in out[key].items() if n != "dss" and m > 0}
            out["ratio" if key == "mae_m" else "ratio_without_flood"] = ratios
    if flood is not None:
        out["flood"] = [utc(t).isoformat() for t in flood]
    return out
