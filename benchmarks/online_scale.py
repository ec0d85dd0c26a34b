"""One on-line cycle with 20 parameters on a generated board-size network, Sparse DuD on a Dask cluster.

Usage: ``python benchmarks/online_scale.py --points 40000 --dask local:2`` prints one JSON object: the
network, the cycle's wall time and model runs, and where the time went (a timeline of the service's own
log records, seconds from the start of the cycle), plus the time of one model run over the cycle's
window, from which the time on more workers follows (see ``more_workers``). On a shared machine the
workers' processor time over the cycle's wall time (``cores_used_by_workers``) says how much of the two
cores they got.

The observations are a twin: the generated network run with the friction of region F5 raised from 25 to
32 m^(1/3)/s; the service starts from 25 everywhere (the DSS), 7-day window, 24 h warm-up, 48 h horizon.

``--dependency-threshold T`` first measures Sparse DuD's dependency map over the cycle's window (p + 1 runs
on the cluster, timed apart: ``dependency_map_s``; a service measures it once, not every cycle) and gives
it to the cycle; ``--catchments-only`` leaves the trunk canal's stations out of the calibration (their
discharge sums every catchment upstream, so it sees every region). ``--dt 300`` generates the network with
a five-minute time step (the generator's default is 60 s); ``--final-jacobian secant`` keeps the Jacobian
of Sparse DuD's last secant model for the cycle's uncertainty instead of taking a fresh one at the end;
``--parallel-line-search`` evaluates a failed full step's shorter trials as one batch, and ``--stall-ratio 0.01``
re-initialises the interpolation set after a shortened step that gained little of what the secant model
predicted (both DuD options).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.analysis.dependency import dependency_map
from rivercal.case.generate import generate_case
from rivercal.evaluate import DaskCluster
from rivercal.model import load_model
from rivercal.observations import ObservationSet, measurable
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.optimise._core import Run
from rivercal.optimise._dud_engine import DudEngine
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem
from rivercal.store import Store

PARAMS = tuple(f"F{k}" for k in range(1, 21))


class Timeline(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.t0 = time.perf_counter()
        self.events: list[tuple[float, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        event = (round(time.perf_counter() - self.t0, 2), record.getMessage()[:160])
        self.events.append(event)
        print(f"{event[0]:8.1f} s  {event[1]}", file=sys.stderr, flush=True)  # progress while it runs


class Phases:
    """Wall and processor time (this process) of the cycle's phases, and the model runs of each batch.

    Wraps methods of the service, the DuD engine and the optimiser's evaluation (a benchmark's probe, not a
    change of what they do); a phase inside another is counted in both.
    """

    def __init__(self) -> None:
        self.stack: list[str] = []
        self.totals: dict[str, list[float]] = {}
        self.batches: list[tuple[str, int, float]] = []  # innermost phase, runs, wall s

    def wrap(self, owner: type, name: str, label: str) -> None:
        original = getattr(owner, name)

        def timed(*args, **kwargs):
            self.stack.append(label)
            t, c = time.perf_counter(), time.process_time()
            try:
                return original(*args, **kwargs)
            finally:
                self.stack.pop()
                total = self.totals.setdefault(label, [0, 0.0, 0.0])
                total[0] += 1
                total[1] += time.perf_counter() - t
                total[2] += time.process_time() - c

        setattr(owner, name, timed)

    def wrap_runs(self) -> None:
        original = Run._run

        def counted(run, xs, raw, todo):
            t = time.perf_counter()
            try:
                return original(run, xs, raw, todo)
            finally:
                self.batches.append((self.stack[-1] if self.stack else "other", len(todo), time.perf_counter() - t))

        Run._run = counted

    def report(self, workers: int) -> dict:
        by_phase: dict[str, dict] = {}
        for phase, runs, wall in self.batches:
            b = by_phase.setdefault(phase, {"batches": 0, "runs": 0, "wall_s": 0.0, "run_slots": 0})
            b["batches"] += 1
            b["runs"] += runs
            b["wall_s"] = round(b["wall_s"] + wall, 2)
            b["run_slots"] += math.ceil(runs / workers)
        return {"phases": {k: {"calls": n, "wall_s": round(w, 2), "service_cpu_s": round(c, 2)}
                           for k, (n, w, c) in self.totals.items()},
                "model_run_batches": by_phase,
                "run_slots": sum(math.ceil(r / workers) for _, r, _ in self.batches)}


def _worker_cpu(cluster: DaskCluster) -> float:
    """Processor time of the cluster's worker processes so far, s."""
    return sum(cluster.client.run(time.process_time).values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--points", type=int, default=40000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--dask", default="local:2")
    parser.add_argument("--deadline", type=float, default=None,
                        help="wall-clock limit of the calibration, s (the service's guardrail; default none)")
    parser.add_argument("--dependency-threshold", type=float, default=None,
                        help="measure a dependency map first and use it, with this threshold (σ; default: no map)")
    parser.add_argument("--catchments-only", action="store_true", help="leave the trunk canal's stations out")
    parser.add_argument("--dt", type=float, default=60.0, help="the generated network's time step, s (default 60)")
    parser.add_argument("--final-jacobian", choices=("auto", "fresh", "secant"), default="auto",
                        help="Sparse DuD's final Jacobian (default auto: a fresh one)")
    parser.add_argument("--parallel-line-search", action="store_true",
                        help="evaluate the shorter trials of a failed step as one batch")
    parser.add_argument("--stall-ratio", type=float, default=0.0,
                        help="re-initialise after a shortened step that gains at most this fraction of its "
                             "predicted decrease (DuD's stall_ratio; default 0: off)")
    args = parser.parse_args()
    out: dict = {"points_asked": args.points, "dask": args.dask, "parameters": len(PARAMS), "algorithm": "sparse_dud",
                 "deadline_s": args.deadline, "dependency_threshold": args.dependency_threshold,
                 "catchments_only": args.catchments_only, "dt_s": args.dt, "final_jacobian": args.final_jacobian,
                 "parallel_line_search": args.parallel_line_search, "stall_ratio": args.stall_ratio}
    with tempfile.TemporaryDirectory(prefix="rivercal-online-scale-") as folder:
        t = time.perf_counter()
        generate_case(Path(folder) / "case", args.points, args.seed, dt=args.dt)
        out["generate_s"] = round(time.perf_counter() - t, 2)
        t = time.perf_counter()
        model = load_model(str(Path(folder) / "case"))
        out["load_s"] = round(time.perf_counter() - t, 2)
        out["points"] = model.compiled.n_hpoints
        issue = model.start + pd.Timedelta(days=9)
        options = {"final_jacobian": args.final_jacobian, "parallel_line_search": args.parallel_line_search,
                   "stall_ratio": args.stall_ratio}
        config = OnlineConfig(parameters=PARAMS, algorithm="sparse_dud", deadline_s=args.deadline, window="7D",
                              warmup="24h", horizon="48h", options=options)
        known = {p.name: p for p in model.case.spec.parameters}
        truth_q = {**known["F5"].quantities(32.0)}
        t = time.perf_counter()
        truth, _ = model.simulate(truth_q, end=issue + pd.Timedelta(hours=48))
        out["truth_run_s"] = round(time.perf_counter() - t, 2)
        out["series"] = truth.series.shape[1]
        columns = [c for c in measurable(truth.series.columns) if not (args.catchments_only and c.startswith("ST"))]
        observations = ObservationSet.from_frame(truth.series.loc[model.start + pd.Timedelta(days=1):, columns])
        config = replace(config, series=tuple(columns))
        t = time.perf_counter()
        cluster = DaskCluster(args.dask)
        workers = cluster.n_workers
        cluster.share(model)
        out["cluster_start_and_model_install_s"] = round(time.perf_counter() - t, 2)
        if args.dependency_threshold is not None:
            window = (issue - pd.Timedelta(config.window), issue)
            problem = CalibrationProblem(model, ParameterSet(known[n] for n in PARAMS), observations, window,
                                         warmup=config.warmup, loss=config.loss)
            t = time.perf_counter()
            measured = dependency_map(problem, threshold=args.dependency_threshold, workers=cluster)
            out["dependency_map_s"] = round(time.perf_counter() - t, 2)
            out["dependency_map_runs"] = len(PARAMS) + 1
            out["dependency_k"] = measured.k
            counts = measured.seen.sum(axis=1)
            out["dependency_parameters_per_series"] = np.bincount(counts, minlength=len(PARAMS) + 1).tolist()
            out["dependency_most_seen_by"] = counts.sort_values(ascending=False).head(8).to_dict()
            path = measured.to_csv(Path(folder) / "dependency.csv")
            config = replace(config, dependency=str(path), dependency_threshold=args.dependency_threshold)
        timeline = Timeline()
        phases = Phases()
        for owner, name, label in ((OnlineService, "_state", "cold start (spin-up)"),
                                   (OnlineService, "_calibrate", "calibration"),
                                   (OnlineService, "_search", "transition search"),
                                   (OnlineService, "_gate", "gate"),
                                   (OnlineService, "_forecasts", "forecasts"),
                                   (Store, "commit_cycle", "store commit"),
                                   (DudEngine, "iterate", "DuD iterations"),
                                   (DudEngine, "reinit", "DuD re-initialisation"),
                                   (DudEngine, "final_jacobian", "DuD final Jacobian")):
            if hasattr(owner, name):
                phases.wrap(owner, name, label)
        phases.wrap_runs()
        for name in ("rivercal.online", "rivercal.problem", "rivercal.optimise", "rivercal.analysis"):
            logging.getLogger(name).addHandler(timeline)
            logging.getLogger(name).setLevel(logging.DEBUG if name == "rivercal.optimise" else logging.INFO)
        try:
            config = replace(config, workers=cluster)
            with Store(Path(folder) / "online.sqlite") as store:
                store.ingest(observations, source="twin")
                service = OnlineService(model, store, "scale", config, issue)
                cpu0 = time.process_time(), _worker_cpu(cluster)
                timeline.t0 = time.perf_counter()
                outcomes = service.replay(issue)
                out["cycle_wall_s"] = round(time.perf_counter() - timeline.t0, 2)
                out["cycle_cpu_s_service"] = round(time.process_time() - cpu0[0], 2)
                out["cycle_cpu_s_workers"] = round(_worker_cpu(cluster) - cpu0[1], 2)
                out["cores_used_by_workers"] = round(out["cycle_cpu_s_workers"] / out["cycle_wall_s"], 2)
                out["load_average"] = round(os.getloadavg()[0], 2)
                cycle = store.cycles(service.run).iloc[0]
                out["cycle_status"] = str(cycle["status"])
                out["calibration_model_runs"] = int(cycle["model_runs"])
                out["estimates"] = {k: round(v, 3) for k, v in outcomes[-1].accepted.items()}
                out["held"] = {k: v for k, v in sorted(outcomes[-1].held.items())}
                out["calibrated"] = {k: round(v, 3) for k, v in outcomes[-1].estimates.items()}
                out["cost_before_after"] = [outcomes[-1].cost_before, outcomes[-1].cost_after]
        finally:
            cluster.close()
        run_start = issue - pd.Timedelta(days=8)
        _, spun = model.simulate(None, end=run_start)
        t, c = time.perf_counter(), time.process_time()
        model.simulate(None, start=run_start, end=issue, state=spun)
        one_run, one_cpu = time.perf_counter() - t, time.process_time() - c
        out["one_window_run_s"] = round(one_run, 2)
        out["one_window_run_cpu_s"] = round(one_cpu, 2)
        batches = [r for _, r, _ in phases.batches]
        per_run = out["cycle_cpu_s_workers"] / max(sum(batches), 1)
        out["worker_cpu_per_run_s"] = round(per_run, 2)
        service = out["cycle_cpu_s_service"]
        out["floor_s"] = round(sum(batches) * per_run / workers, 1)
        out["more_workers"] = {n: round(sum(math.ceil(r / n) for r in batches) * per_run + service, 1)
                               for n in (1, 2, 4, 8, 21, 64)}
        out["more_workers_note"] = ("the cycle on n free cores: each evaluation batch of the calibration in rounds of "
                                    "one run per worker (worker_cpu_per_run_s: the workers' processor time per run, "
                                    "residuals included; one_window_run_cpu_s: the bare run), plus the service's own "
                                    "processor time (spin-up, forecasts, optimiser, store, the local scheduler), which "
                                    "does not spread; floor_s: the runs' processor time over the workers")
        out["timeline"] = timeline.events[:80]
        out["breakdown"] = phases.report(workers)
        out["breakdown_note"] = ("phases: wall and this process' processor time (nested phases count in each); "
                                 "model_run_batches: per innermost phase the evaluation batches, their runs and "
                                 "wall time; run_slots: the batches' runs in rounds of one run per worker, so "
                                 "run_slots x one_window_run_s is the calibration's time on free cores")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
