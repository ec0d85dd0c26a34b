"""Dask benchmark: twin scenarios of the thesis on a local Dask cluster of 1 and of 2 workers.

``rivercal bench dask --json`` runs the same scenarios (by default every third of the 36 FaWc scenarios of
thesis §4-4 in their moderate window: 12 two-parameter DuD calibrations, each a task of its own) on a
``local:1`` and a ``local:2`` cluster, ``repeats`` times each, alternating, and reports:

- the median wall time of each and the speed-up (target ≥ 1.8×); the cluster is started and the model
  installed and loaded on its workers (a first, untimed task) before the clock starts;
- the scheduling overhead per task: the wall time of ``tasks`` no-op tasks through the same path as
  the calibrations' batches and the scenarios (:class:`rivercal.evaluate.Tasks`, all submitted at once,
  as one graph) on one worker, divided by their number (target ≤ 5 ms; the median of five such
  batches), the processor time they cost (this process, which holds the scheduler of a local cluster,
  and the worker), and the median round trip of one no-op task submitted alone;
- the expected wall time on 64 workers, from the measured durations of the scenarios on one worker:
  :func:`rivercal.twin.suites.run_scenarios` submits them in the order of its cost rank (the likely longest
  first; for FaWc all rank equal, so in the suite's order), and the time is the makespan of that list
  schedule on 64 workers, after the truths (one model run each, all at once: the 1-worker time not spent in
  calibrations, per truth), plus the scheduling overhead of every task spread over the workers;
- what the schedule allows: ``order_bound_speedup``, the speed-up of the calibrations on two free workers
  in their submission order, and ``longest_first_bound_speedup``, had their durations been known and the
  longest started first (the difference is the tail that the unknown durations cost).

The machine's load average (at the start and the end) and its number of processors are reported with the
numbers: on a shared machine, other processes take cores
from the two workers. So that the speed-up can be read on such a machine, the processor time of the worker
processes is measured over each timed run: ``cores_used_*`` is that time over the wall time (2 workers on
two free cores use nearly 2), and ``expected_s_2_workers`` is the time two free cores would take by the same
list schedule as the 64-worker figure.
"""

from __future__ import annotations

import heapq
import os
import statistics
import time
from dataclasses import asdict, dataclass
from typing import Any

__all__ = ["DaskBenchmark", "bench_dask", "list_schedule"]


@dataclass(frozen=True)
class DaskBenchmark:
    """Result of :func:`bench_dask` (times in s)."""

    suite: str
    scenarios: int
    repeats: int
    wall_s_1_worker: float
    wall_s_2_workers: float
    speedup: float
    speedup_target: float
    overhead_ms_per_task: float
    overhead_target_ms: float
    overhead_cpu_ms_per_task: float
    round_trip_ms: float
    scenario_s_mean: float
    scenario_s_max: float
    expected_s_2_workers: float
    expected_s_64_workers: float
    worker_cpu_s_1_worker: float
    worker_cpu_s_2_workers: float
    cores_used_1_worker: float
    cores_used_2_workers: float
    load_average: float
    load_average_start: float
    cores: int
    order_bound_speedup: float
    longest_first_bound_speedup: float
    runs_1_worker: list[float]
    runs_2_workers: list[float]
    note: str

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form for JSON."""
        return asdict(self)


def list_schedule(durations: list[float], workers: int, *, longest_first: bool = True) -> float:
    """Makespan of starting the jobs (longest first, or in the order given), each on the first worker free, s."""
    free = [0.0] * workers
    for d in (sorted(durations, reverse=True) if longest_first else durations):
        heapq.heappush(free, heapq.heappop(free) + d)
    return max(free)


def _noop(obj: Any, i: int) -> int:
    return i


def _worker_cpu(cluster: Any) -> float:
    """Processor time the cluster's worker processes have used so far, s."""
    return sum(cluster.client.run(time.process_time).values())


def _overhead(cluster: Any, tasks: int, repeats: int = 5) -> tuple[float, float, float]:
    """Per no-op task, submitted ``tasks`` at once: (wall s, processor s), medians of ``repeats`` batches.

    Third: the median round trip of a lone task, s.
    """
    from rivercal.evaluate import Tasks

    with Tasks(None, cluster) as pool:
        pool.map(_noop, list(range(20)))  # warm
        walls, cpus = [], []
        for _ in range(repeats):
            cpu0 = time.process_time() + _worker_cpu(cluster)
            t0 = time.perf_counter()
            pool.map(_noop, list(range(tasks)))
            walls.append((time.perf_counter() - t0) / tasks)
            cpus.append((time.process_time() + _worker_cpu(cluster) - cpu0) / tasks)
        per_task, cpu_per_task = statistics.median(walls), statistics.median(cpus)
        trips = []
        for i in range(30):
            t = time.perf_counter()
            pool.submit(_noop, i).result()
            trips.append(time.perf_counter() - t)
    return per_task, cpu_per_task, statistics.median(trips)


def bench_dask(every: int = 3, repeats: int = 3, tasks: int = 400) -> DaskBenchmark:
    """Time the twin scenarios on ``local:1`` and ``local:2`` Dask clusters.

    Parameters
    ----------
    every
        Take every ``every``-th scenario of the FaWc suite (3: 12 of 36).
    repeats
        Timed runs per cluster size (alternating; medians reported).
    tasks
        No-op tasks of the overhead measurement.
    """
    from rivercal.evaluate import DaskCluster
    from rivercal.model import load_model
    from rivercal.twin.suites import _expected_work, run_scenarios, suite_scenarios

    load_start = os.getloadavg()[0]
    model = load_model("dommel")
    scenarios = suite_scenarios("FaWc")[::every]
    clusters = {n: DaskCluster(f"local:{n}") for n in (1, 2)}
    walls: dict[int, list[float]] = {1: [], 2: []}
    cpus: dict[int, list[float]] = {1: [], 2: []}
    durations: list[float] = []
    try:
        for cluster in clusters.values():  # install the model and load the engine on every worker, untimed
            cluster.share(model)
            run_scenarios(model, scenarios[:2], workers=cluster)
        for _ in range(repeats):
            for n, cluster in clusters.items():
                cpu0 = _worker_cpu(cluster)
                t0 = time.perf_counter()
                results = run_scenarios(model, scenarios, workers=cluster)
                walls[n].append(time.perf_counter() - t0)
                cpus[n].append(_worker_cpu(cluster) - cpu0)
                if n == 1:
                    durations = [r.wall_s for r in results]
        clusters[2].close()  # the overhead of one cluster: the idle one's scheduler would share this process
        per_task, cpu_per_task, trip = _overhead(clusters[1], tasks)
    finally:
        for cluster in clusters.values():
            cluster.close()
    w1, w2 = statistics.median(walls[1]), statistics.median(walls[2])
    truths = len({s.truth_key for s in scenarios})
    per_truth = max(0.0, w1 - sum(durations)) / truths  # one worker: the rest of its wall time is the truths

    # the calibrations in the order run_scenarios submits them (its cost rank, ties in the suite's order)
    submitted = [durations[i] for i in sorted(range(len(scenarios)), key=lambda i: -_expected_work(scenarios[i]))]

    def expected(workers: int) -> float:
        return (list_schedule([per_truth] * truths, workers) + list_schedule(submitted, workers, longest_first=False)
                + per_task * (len(scenarios) + truths) / workers)

    c1, c2 = statistics.median(cpus[1]), statistics.median(cpus[2])
    return DaskBenchmark(
        suite="FaWc", scenarios=len(scenarios), repeats=repeats, wall_s_1_worker=w1, wall_s_2_workers=w2,
        speedup=w1 / w2, speedup_target=1.8, overhead_ms_per_task=per_task * 1e3, overhead_target_ms=5.0,
        overhead_cpu_ms_per_task=cpu_per_task * 1e3, round_trip_ms=trip * 1e3,
        scenario_s_mean=statistics.mean(durations), scenario_s_max=max(durations),
        expected_s_2_workers=expected(2), expected_s_64_workers=expected(64), worker_cpu_s_1_worker=c1,
        worker_cpu_s_2_workers=c2, cores_used_1_worker=c1 / w1, cores_used_2_workers=c2 / w2,
        load_average=os.getloadavg()[0], load_average_start=load_start, cores=os.cpu_count() or 0,
        order_bound_speedup=sum(durations) / list_schedule(submitted, 2, longest_first=False),
        longest_first_bound_speedup=sum(durations) / list_schedule(durations, 2),
        runs_1_worker=walls[1], runs_2_workers=walls[2],
        note=(f"one FaWc scenario in {every} (moderate window), each calibration one task; 2 and 64 workers "
              "expected: the truths (the 1-worker time not spent in calibrations, per truth, scheduled on the "
              "workers), then the list schedule of the calibrations as measured on 1 worker in the order they are "
              "submitted, plus "
              "the per-task overhead spread over the workers; with more workers than scenarios the longest one "
              "bounds the time. cores_used: the workers' processor time over the wall time (less than the "
              "workers when other processes share the cores); order_bound_speedup: the most 2 free workers can "
              "give the calibrations in their submission order (their durations are not known in advance), "
              "longest_first_bound_speedup: the same had they been started longest first; load_average_start and "
              "load_average: the machine's 1-minute load at the start and the end, on cores processors"),
    )
