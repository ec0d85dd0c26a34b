"""Batches of a calibration as batched engine calls, beside worker processes and a serial loop, interleaved.

Usage: ``python benchmarks/batched_calibration.py [--rounds 3] [--workers 2] [--algorithms dud,sce_ua]``.
The thesis twin of ``rivercal bench calibrate`` (dommel, FA and Wc, the moderate window, noise-free
observations; truth FA = 20, Wc = 0.8 from FA = 14, Wc = 0.1) is calibrated with each algorithm in three
ways, one after the other in each round:

- ``batched``: every batch one batched engine call on ``workers`` numba threads (the default of
  :func:`rivercal.problem.calibrate` on the embedded engine);
- ``processes``: every batch on a pool of ``workers`` worker processes (``batched=False``);
- ``serial``: every run in this process, one after the other (``workers=1``).

Prints one JSON object: per algorithm and way the median wall time and processor time (this process and
its worker processes) of the calibration, its model runs and estimates, the ratios against ``processes``
and ``serial``, and the load average before and after (the machine may be shared: compare the ratios of one
run, not figures across runs).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import time

from rivercal.bench.calibrate import START, TRUTH, algorithm_arguments
from rivercal.model import load_model
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth

WAYS = {"batched": {"batched": True}, "processes": {"batched": False}, "serial": {"workers": 1}}


def _cpu() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--algorithms", default="dud,sce_ua")
    args = parser.parse_args()
    load_before = os.getloadavg()
    sim = load_model("dommel")
    params = ParameterSet(p for p in sim.case.spec.parameters if p.name in ("FA", "Wc"))
    window = next((w.start, w.end) for w in sim.case.spec.windows if w.name == "moderate")
    truth = twin_truth(sim, params.quantities(TRUTH), window)
    algorithms = args.algorithms.split(",")
    out: dict[str, dict] = {a: {w: {"wall_s": [], "cpu_s": []} for w in WAYS} for a in algorithms}

    def once(name: str, way: str) -> None:
        problem = CalibrationProblem(sim, params.with_initial(START), truth.observations, window, state=truth.state)
        options, kwargs = algorithm_arguments(name, sim.case.spec.calibration.options)
        kwargs = {"workers": args.workers, **kwargs, **WAYS[way]}
        c0, w0 = _cpu(), time.perf_counter()
        cal = calibrate(problem, name, options, **kwargs)
        row = out[name][way]
        row["wall_s"].append(time.perf_counter() - w0)
        row["cpu_s"].append(_cpu() - c0)
        row["model_runs"], row["estimates"] = cal.result.nfev, cal.estimates

    for name in algorithms:  # warm-up: kernels compiled or loaded from numba's cache
        once(name, "batched")
        out[name]["batched"] = {"wall_s": [], "cpu_s": []}
    for _ in range(args.rounds):
        for name in algorithms:
            for way in WAYS:
                once(name, way)
    summary = {}
    for name, ways in out.items():
        med = {w: {"wall_s": statistics.median(r["wall_s"]), "cpu_s": statistics.median(r["cpu_s"]),
                   "model_runs": r["model_runs"], "estimates": r["estimates"]} for w, r in ways.items()}
        b = med["batched"]["wall_s"]
        summary[name] = {**med, "wall_speedup_vs_processes": med["processes"]["wall_s"] / b,
                         "wall_speedup_vs_serial": med["serial"]["wall_s"] / b}
    print(json.dumps({"case": "dommel", "parameters": ["FA", "Wc"], "workers": args.workers, "rounds": args.rounds,
                      "load_average_before": load_before, "load_average_after": os.getloadavg(), **summary}))


if __name__ == "__main__":
    main()
