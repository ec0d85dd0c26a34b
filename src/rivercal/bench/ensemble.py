"""Ensemble benchmark: N members of the default case through one simulated week in one batched call.

``rivercal bench ensemble --members 64 --json`` hot-starts every member from the state after the case's
spin-up, gives each its own global friction (evenly over 12 … 24 m^(1/3)/s) and its own laterals (AR(1)
multiplicative errors of 30 %, correlation time 6 h: the model error of an ensemble Kalman filter), and
advances them all in one compiled call. Beside it, in the same process and interleaved with it, one
member's single run (:meth:`Simulator.simulate`) is timed; ``speedup`` is members × single-run wall time
/ ensemble wall time. Medians over the repeats.

The processor time of the batched call (all threads of the process) and of the single run, and the load
average of the machine, are reported too: on a shared machine the wall time says as much about the neighbours as about
the code.
"""

from __future__ import annotations

import os
import statistics
import time
from dataclasses import asdict, dataclass

import numba
import numpy as np
import pandas as pd

from rivercal.assimilate.perturb import ar1_series, multiplicative_factors
from rivercal.engine.ensemble import run_ensemble
from rivercal.model import load_model

__all__ = ["EnsembleBenchmark", "bench_ensemble"]


@dataclass(frozen=True)
class EnsembleBenchmark:
    """Result of :func:`bench_ensemble` (times in s).

    ``first_call_s`` is the first ensemble call of the process, two members over one hour, after the single run
    that made the hot-start state: what an ensemble adds once per process to the engine's time loop.
    """

    members: int
    wall_s: float
    single_run_wall_s: float
    speedup: float
    case: str
    simulated_days: float
    threads: int
    repeats: int
    cpu_s: float
    single_run_cpu_s: float
    wall_s_runs: list[float]
    single_run_wall_s_runs: list[float]
    load_average_1min: list[float]
    cpu_count: int
    first_call_s: float

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def bench_ensemble(case: str = "dommel", members: int = 64, days: float = 7.0, repeats: int = 3,
                   threads: int | None = None, seed: int = 1) -> EnsembleBenchmark:
    """Time ``members`` members of ``case`` over ``days`` simulated days in one batched call.

    Parameters
    ----------
    case
        Case folder or packaged case name.
    members
        Ensemble size.
    days
        Simulated days.
    repeats
        Timed repetitions of the ensemble call and of the single run, interleaved (medians reported).
    threads
        Threads that run members at the same time (None: ``NUMBA_NUM_THREADS``, by default the cores).
    seed
        Seed of the forcing perturbations.
    """
    sim = load_model(case)
    start = sim.start
    _, state = sim.simulate(end=start)   # the state after the case's spin-up
    end = start + pd.Timedelta(days=days)
    n_steps = round((end - start).total_seconds() / sim.dt)
    base = sim.forcing_matrix(start, n_steps)
    lateral = np.array([k.startswith("lateral:") for k in sim.compiled.forcing_keys])
    rng = np.random.default_rng(seed)
    hourly = multiplicative_factors(ar1_series(rng, int(np.ceil(n_steps * sim.dt / 3600)), (members,), 0.3, 6.0), 0.3)
    factors = np.repeat(hourly, round(3600 / sim.dt), axis=0)[:n_steps].T          # (members, steps)
    forcing = np.repeat(base[None], members, axis=0)
    forcing[:, :, lateral] *= factors[:, :, None]
    params = [{"friction:global": float(v)} for v in np.linspace(12.0, 24.0, members)]
    states = [state] * members
    t0 = time.perf_counter()
    run_ensemble(sim, params[:2], start, start + pd.Timedelta("1h"), states[:2], n_threads=threads)  # JIT / cache
    first = time.perf_counter() - t0
    sim.simulate(params[0], start, start + pd.Timedelta("1h"), state)
    walls, cpus, singles, single_cpus, loads = [], [], [], [], []
    used = numba.config.NUMBA_NUM_THREADS if threads is None else threads
    for _ in range(repeats):
        loads.append(os.getloadavg()[0])
        t0, c0 = time.perf_counter(), time.process_time()
        result = run_ensemble(sim, params, start, end, states, forcing=forcing, n_threads=threads)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        if result.failures:
            raise RuntimeError(f"benchmark members failed: {result.failures}")
        t0, c0 = time.perf_counter(), time.process_time()
        sim.simulate(params[members // 2], start, end, state)
        singles.append(time.perf_counter() - t0)
        single_cpus.append(time.process_time() - c0)
    wall = statistics.median(walls)
    single = statistics.median(singles)
    return EnsembleBenchmark(
        members=members, wall_s=wall, single_run_wall_s=single, speedup=members * single / wall, case=case,
        simulated_days=days, threads=used, repeats=repeats, cpu_s=statistics.median(cpus),
        single_run_cpu_s=statistics.median(single_cpus), wall_s_runs=walls,
        single_run_wall_s_runs=singles, load_average_1min=loads, cpu_count=os.cpu_count() or 1, first_call_s=first,
    )
