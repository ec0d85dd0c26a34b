"""The gauge advice on dommel: its cost, the twin proof, and its effect on the on-line service.

``rivercal bench advise --json`` runs, on the packaged dommel case with the nine crests estimated one by
one and the global friction (W1…W9 and FA, thesis Table 4-4):

1. **the advice** for every calculation point (gauges measuring levels) in the moderate window: its wall
   time and model runs (one Jacobian of every candidate's series), the verdict per parameter with the five
   stations and with the advised gauges, and K, the number of gauges the advice says is enough;
2. **the twin proof**: the truth is the case's own values (Table 4-4, row AVG); a twin calibration with DuD
   and the thesis' stopping criteria (Table 4-3) starts from the thesis' perturbed values, every crest
   0.15 m low and FA 14 (Table 4-4's scenarios 2 and FA4; FA 14 is also the low start of Tables 4-5 and
   4-7), and again from every crest 0.15 m high and FA 18 (scenarios 4 and FA2; the high start). It
   succeeds when every crest ends within 1 cm of its truth and FA within 0.5 m^(1/3)/s, from both starts.
   It runs with the five stations, with the advised gauges, and with K candidates of the same kind drawn
   at random (``seeds`` draws): the counts of successes are the result;
3. **the on-line effect**: scenario PI-Wl (weir ZL1-5930, W4, lowered by 0.15 m on 2010-11-01, thesis
   §5-2-2) replayed with daily cycles by the on-line service estimating ``online_parameters`` (by default
   all ten parameters, so that it is not told which crest changes), once with
   the five stations and once with the advised gauges added: the jump alerts after the change, the cycles
   until W4's estimated change is within 1 cm of the true change (time to correct, as the service's run
   figures define it for a crest shift), W4's last estimate and the forecast error ratio (DSS over
   rivercal, level forecasts up to 24 h ahead after the change; :func:`rivercal.online.metrics.run_figures`).

Wall times are of the machine it runs on.
"""

from __future__ import annotations

import logging
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.analysis.advise import advise, model_candidates
from rivercal.model import load_model
from rivercal.observations import ScreenRule, measurable
from rivercal.online.metrics import run_figures
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.store import Store
from rivercal.twin import twin_truth
from rivercal.twin.practical import CHANGE_TIME, practical_truth
from rivercal.twin.suites import SENSITIVITY_PARAMETERS

__all__ = ["CREST_TOLERANCE_M", "FRICTION_TOLERANCE", "bench_advise", "twin_proof"]

log = logging.getLogger(__name__)

#: A twin calibration succeeds when every crest ends this close to its truth (m) …
CREST_TOLERANCE_M = 0.01
#: … and FA this close (m^(1/3)/s).
FRICTION_TOLERANCE = 0.5
#: The thesis' start values relative to the truth: every crest ∓0.15 m (Table 4-4, scenarios 2 and 4) with
#: FA 14 and 18 (FA4 and FA2; the starts 1 and 2 of Tables 4-5 and 4-7).
STARTS = {"low": (-0.15, 14.0), "high": (0.15, 18.0)}


def _starts(params: ParameterSet, truth: dict[str, float]) -> dict[str, dict[str, float]]:
    out = {}
    for key, (shift, fa) in STARTS.items():
        values = {}
        for p in params:
            value = fa if p.name == "FA" else truth[p.name] + shift
            values[p.name] = min(max(value, p.min), p.max)
        out[key] = values
    return out


def twin_proof(model: Any, params: ParameterSet, window: tuple[pd.Timestamp, pd.Timestamp], places: Sequence[Any],
               *, workers: int | None = None, starts: Sequence[str] = tuple(STARTS)) -> dict[str, Any]:
    """Twin calibrations from the thesis starts (``low``, ``high``) observing the model's stations plus ``places``.

    Returns per start the estimates' errors (parameter units), the runs and whether every parameter ended
    within tolerance, and ``success`` (from every start).
    """
    extended = model.with_stations([c.location for c in places]) if places else model
    series = measurable(model.observables) + [s for c in places for s in c.series]
    truth = {p.name: p.initial for p in params}
    tt = twin_truth(extended, params.quantities(truth), window, series=series)
    out: dict[str, Any] = {"gauges": [c.id for c in places]}
    ok = True
    for key, start in _starts(params, truth).items():
        if key not in starts:
            continue
        problem = CalibrationProblem(extended, params.with_initial(start), tt.observations, window, state=tt.state)
        t0 = time.perf_counter()
        cal = calibrate(problem, "dud", dict(model.calibration.options), workers=workers)
        errors = {n: cal.estimates[n] - truth[n] for n in truth}
        within = all(abs(e) <= (FRICTION_TOLERANCE if n == "FA" else CREST_TOLERANCE_M) for n, e in errors.items())
        ok &= within
        out[key] = {"within_tolerance": within, "model_runs": cal.result.nfev, "wall_s": round(time.perf_counter() - t0,
                                                                                                  1),
                    "errors": {n: round(e, 4) + 0.0 for n, e in errors.items()},
                    "worst_crest_error_m": round(max(abs(e) for n, e in errors.items() if n != "FA"), 4)}
    out["success"] = ok
    return out


def _online(model: Any, parameters: Sequence[str], first: str, last: str, folder: Path, name: str,
            workers: int | None) -> dict[str, Any]:
    """One PI-Wl replay; the run's figures, with W4's time to correct and its alerts."""
    config = OnlineConfig(parameters=tuple(parameters), workers=workers)
    db = folder / f"{name}.sqlite"
    t0 = time.perf_counter()
    with Store(db) as store:
        service = OnlineService(model, store, f"PI-Wl-{name}", config, pd.Timestamp(first, tz="UTC"),
                                meta={"scenario": "PI-Wl", "noise": "none", "seed": 0})
        end = pd.Timestamp(last, tz="UTC")
        truth = practical_truth(model, "PI-Wl", *service.data_period(end), series=service.series)
        store.ingest(truth.observations, source="twin:PI-Wl", screen=ScreenRule())
        outcomes = service.replay(end)
        figures = run_figures(store, service.run)
        cycles = store.cycles(service.run)
        est = store.estimates(service.run)
        alerts = store.alerts(service.run)
    change = CHANGE_TIME
    table = est.pivot_table(index="cycle", columns="parameter", values="value", aggfunc="first")
    accepted = est.pivot_table(index="cycle", columns="parameter", values="accepted", aggfunc="first").astype(bool)
    # the accepted value after each cycle; a parameter the gate never let move keeps its start (the case's value)
    start = {p.name: p.initial for p in model.calibration.parameters}
    table = table.where(accepted).ffill()
    table = table.fillna({n: start[n] for n in table.columns if n in start})
    before_cycles = cycles[cycles["issue_time"] <= change]["cycle"]
    after_cycles = cycles[cycles["issue_time"] > change].sort_values("cycle")["cycle"]
    dss = model.default_parameters()["weir:ZL1-5930.crest_level"]
    w4 = table["W4"] if "W4" in table else None
    w4_before = float(w4.reindex(before_cycles).ffill().iloc[-1]) if w4 is not None and len(before_cycles) else dss
    correct = None
    if w4 is not None:
        after = w4.reindex(after_cycles).to_numpy()
        hits = np.flatnonzero(np.abs(after - (w4_before - 0.15)) <= CREST_TOLERANCE_M)
        correct = int(hits[0]) + 1 if hits.size else None
    after_alerts = alerts[alerts["issue_time"] > change] if len(alerts) else alerts
    jumps = after_alerts[after_alerts["kind"] == "jump"] if len(after_alerts) else after_alerts
    return {"stations": sorted({s.rpartition(".")[0] for s in service.series}), "cycles": len(outcomes),
            "jump_alerts_after_change": len(jumps),
            "alerted_parameters": sorted(set(jumps["parameter"])) if len(jumps) else [],
            "w4_before_change": round(w4_before, 4), "w4_last": round(float(w4.iloc[-1]), 4) if w4 is not None
            else None, "w4_true_after": round(dss - 0.15, 4), "time_to_correct_cycles": correct,
            "forecast_mae_ratio": figures.get("forecast_mae_ratio"), "rivercal_mae_m": figures.get("rivercal_mae_m"),
            "dss_mae_m": figures.get("dss_mae_m"), "fallbacks": figures.get("fallbacks"),
            "final_estimates": {k: round(v, 4) + 0.0 for k, v in outcomes[-1].accepted.items()} if outcomes else {},
            "wall_s": round(time.perf_counter() - t0, 1)}


def bench_advise(case: str = "dommel", *, parameters: Sequence[str] = SENSITIVITY_PARAMETERS,
                 window: str = "moderate", candidates: str = "points", kind: str = "level", seeds: int = 20,
                 workers: int | None = None, twin: bool = True, online: bool = True,
                 online_parameters: Sequence[str] | None = None, online_from: str = "2010-10-27",
                 online_to: str = "2010-11-08", progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The advice, its twin proof and its on-line effect (module docstring), as one JSON-friendly dict.

    Parameters
    ----------
    case, parameters, window, candidates, kind
        What is advised: the case, its parameters, the window (a name of the case or START/END), the
        candidates (``points`` or ``structures``) and what a gauge measures.
    seeds
        Random draws of K candidates of the same kind for the twin proof (0: none).
    workers
        Worker processes (threads of batched engine calls) per Jacobian and calibration (None: all cores).
    twin, online
        Run the twin proof; run the on-line replays.
    online_parameters, online_from, online_to
        What the on-line service estimates (default: ``parameters``, so that it is not told which crest
        changes), and the first and last issue times of its daily cycles.
    progress
        Called with a line per stage.
    """
    say = progress or (lambda _line: None)
    model = load_model(case)
    defined = {p.name: p for p in model.calibration.parameters}
    params = ParameterSet(defined[n] for n in parameters)
    named = dict(model.calibration.windows)
    if window in named:
        win = named[window]
    else:
        a, _, b = window.partition("/")
        win = (pd.Timestamp(a, tz="UTC"), pd.Timestamp(b, tz="UTC"))
    places = model_candidates(model, candidates, kind)
    say(f"advice over {len(places)} candidates")
    t0 = time.perf_counter()
    result = advise(model, params, win, places, workers=workers)
    wall = time.perf_counter() - t0
    by_id = {c.id: c for c in places}
    chosen = [by_id[g] for g in result.chosen]
    out: dict[str, Any] = {
        "case": model.name, "parameters": list(parameters), "window": [win[0].isoformat(), win[1].isoformat()],
        "candidates": candidates, "kind": kind, "workers": workers,
        "advice": {"candidates": len(places), "wall_s": round(wall, 1), "jacobian_runs": result.jacobian_runs,
                   "chosen": [{"id": c.id, "name": c.name, "series": list(c.series)} for c in chosen],
                   "enough": result.enough,
                   "before": {"identifiable": result.before.identifiable, "verdict": result.before.verdicts,
                              "smallest_singular_value": result.before.smallest_singular_value},
                   "after": {"identifiable": result.after.identifiable, "verdict": result.after.verdicts,
                             "smallest_singular_value": result.after.smallest_singular_value},
                   "steps": [{"step": s.number, "gauge": s.candidate, "worth": round(s.worth, 4),
                              "identifiable": s.assessment.identifiable} for s in result.steps]},
    }
    if twin:
        truth = {p.name: p.initial for p in params}
        proof: dict[str, Any] = {"truth": truth, "starts": _starts(params, truth),
                                 "tolerance": {"crest_m": CREST_TOLERANCE_M, "FA": FRICTION_TOLERANCE}}
        say("twin calibration with the five stations")
        proof["present_stations"] = twin_proof(model, params, win, [], workers=workers)
        say("twin calibration with the advised gauges")
        proof["advised"] = twin_proof(model, params, win, chosen, workers=workers)
        draws = []
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            pick = [places[i] for i in sorted(rng.choice(len(places), size=len(chosen), replace=False))]
            say(f"twin calibration with {len(pick)} random candidates (seed {seed})")
            verdict = result.analysis.assess([c.id for c in pick])
            row = twin_proof(model, params, win, pick, workers=workers)
            row.update(seed=seed, identifiable=verdict.identifiable)
            draws.append(row)
        proof["random"] = {"draws": len(draws), "successes": sum(d["success"] for d in draws),
                           "all_identifiable": sum(d["identifiable"] == len(params) for d in draws),
                           "runs": draws}
        out["twin"] = proof
    if online:
        online_parameters = list(online_parameters or parameters)
        with tempfile.TemporaryDirectory(prefix="rivercal-advise-") as tmp:
            say("on-line replay of PI-Wl with the five stations")
            before = _online(model, online_parameters, online_from, online_to, Path(tmp), "present", workers)
            say("on-line replay of PI-Wl with the advised gauges")
            extended = model.with_stations([c.location for c in chosen])
            after = _online(extended, online_parameters, online_from, online_to, Path(tmp), "advised", workers)
        out["online"] = {"scenario": "PI-Wl", "change_time": CHANGE_TIME.isoformat(),
                         "parameters": list(online_parameters), "from": online_from, "to": online_to,
                         "present_stations": before, "advised": after}
    return _finite(out)


def _finite(value: Any) -> Any:
    """NaN and infinities as None, numpy scalars as Python numbers (for JSON)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
