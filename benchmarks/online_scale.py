"""One on-line cycle with 20 parameters on a generated board-size network, Sparse DuD on a Dask cluster.

Usage: ``python benchmarks/online_scale.py --points 40000 --dask local:2`` prints one JSON object: the
network, the cycle's wall time and model runs, and where the time went (a timeline of the service's own
log records, seconds from the start of the cycle), plus the time of one model run over the cycle's
window, from which the time on more workers follows (see ``more_workers``). On a shared machine the
workers' processor time over the cycle's wall time (``cores_used_by_workers``) says how much of the two
cores they got.

The observations are a twin: the generated network run with the friction of region F5 raised from 25 to
32 m^(1/3)/s; the service starts from 25 everywhere (the DSS), 7-day window, 24 h warm-up, 48 h horizon.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import tempfile
import time
from pathlib import Path

import pandas as pd

from rivercal.case.generate import generate_case
from rivercal.evaluate import DaskCluster
from rivercal.model import load_model
from rivercal.observations import ObservationSet
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.store import Store

PARAMS = tuple(f"F{k}" for k in range(1, 21))


class Timeline(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.t0 = time.perf_counter()
        self.events: list[tuple[float, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.events.append((round(time.perf_counter() - self.t0, 2), record.getMessage()[:160]))


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
    args = parser.parse_args()
    out: dict = {"points_asked": args.points, "dask": args.dask, "parameters": len(PARAMS), "algorithm": "sparse_dud",
                 "deadline_s": args.deadline}
    with tempfile.TemporaryDirectory(prefix="rivercal-online-scale-") as folder:
        t = time.perf_counter()
        generate_case(Path(folder) / "case", args.points, args.seed)
        out["generate_s"] = round(time.perf_counter() - t, 2)
        t = time.perf_counter()
        model = load_model(str(Path(folder) / "case"))
        out["load_s"] = round(time.perf_counter() - t, 2)
        out["points"] = model.compiled.n_hpoints
        issue = model.start + pd.Timedelta(days=9)
        config = OnlineConfig(parameters=PARAMS, algorithm="sparse_dud", deadline_s=args.deadline, window="7D",
                              warmup="24h", horizon="48h")
        known = {p.name: p for p in model.case.spec.parameters}
        truth_q = {**known["F5"].quantities(32.0)}
        t = time.perf_counter()
        truth, _ = model.simulate(truth_q, end=issue + pd.Timedelta(hours=48))
        out["truth_run_s"] = round(time.perf_counter() - t, 2)
        out["series"] = truth.series.shape[1]
        observations = ObservationSet.from_frame(truth.series.loc[model.start + pd.Timedelta(days=1):])
        t = time.perf_counter()
        cluster = DaskCluster(args.dask)
        cluster.share(model)
        out["cluster_start_and_model_install_s"] = round(time.perf_counter() - t, 2)
        timeline = Timeline()
        for name in ("rivercal.online", "rivercal.problem", "rivercal.optimise", "rivercal.analysis"):
            logging.getLogger(name).addHandler(timeline)
            logging.getLogger(name).setLevel(logging.INFO)
        try:
            config = OnlineConfig(**{**config.__dict__, "workers": cluster})
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
                out["held"] = sorted(outcomes[-1].held)
        finally:
            cluster.close()
        run_start = issue - pd.Timedelta(days=8)
        _, spun = model.simulate(None, end=run_start)
        t = time.perf_counter()
        model.simulate(None, start=run_start, end=issue, state=spun)
        one_run = time.perf_counter() - t
        out["one_window_run_s"] = round(one_run, 2)
        runs = out["calibration_model_runs"]
        first_batch = min(len(PARAMS) + 1, runs)
        out["more_workers"] = {
            n: round(math.ceil(first_batch / n) * one_run + (runs - first_batch) * one_run, 1)
            for n in (1, 2, 4, 8, 21, 64)}
        out["more_workers_note"] = ("calibration time if it is its runs: the first batch (p + 1 runs with no "
                                    "dependency map) spreads over the workers, every later iteration is one run")
        out["timeline"] = timeline.events[:80]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
