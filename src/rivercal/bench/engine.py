"""Engine benchmark: one simulated week of the synthetic network (or a generated one) at Δt = 60 s.

``rivercal bench engine --json`` prints one JSON object with the network size, the median wall
time of the compiled run over several repetitions after warm-up, the time of the first call (a one-hour
run: JIT compilation, or loading the compiled kernels from numba's cache) and whether that call had to
compile anything (``compiled``: false when every kernel came from the cache, as in a second call of
the CLI).

``--points N`` times a lowland network of about N points generated for the purpose
(:func:`rivercal.case.generate.generate_case`) instead, and reports what grows with the size: the time
to load the case and prepare the network (``load_s``), of that the one-off minimum-degree elimination
order (``ordering_s``) and the solver schedule built from it (``schedule_s``); the memory of the
network's arrays (``model_mb``) and the process' peak resident memory (``peak_rss_mb``); and the cost
per point and time step (``ns_per_point_step``), the number that should not grow with N. On a shared
machine the processor time of the runs (``cpu_s_median``, ``cpu_ns_per_point_step``; the run's own
process time, whole simulate call) is steadier than their wall time; ``load_average`` says how shared.

Each timed run starts from the case's cold state at its start (``start: "cold"``: the initial depth, at rest), or
with ``spun_up`` from the state that the case's own spin-up (``[initial] spinup``, constant forcing) leaves there
(``start: "spun-up"``), where every run of the model without a given state begins: a generated network drains
and fills its ditches in its first day from the cold state, and its step control divides those steps
(``solves_per_step`` says how much).
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import resource
import statistics
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from numba.core.registry import CPUDispatcher

import rivercal.engine.kernels
from rivercal.engine.kernels.codes import LINK_CULVERT, LINK_PUMP, LINK_WEIR
from rivercal.engine.plan import elimination_order, solver_schedule
from rivercal.model import load_model

__all__ = ["EngineBenchmark", "bench_engine", "bench_engine_points"]


@dataclass(frozen=True)
class EngineBenchmark:
    """Result of :func:`bench_engine` (times in s)."""

    case: str
    points: int
    links: int
    weirs: int
    culverts: int
    laterals: int
    dt_s: float
    simulated_days: float
    repeats: int
    wall_s_median: float
    wall_s_min: float
    wall_s_max: float
    compile_s: float
    compiled: bool
    steps_per_s: float
    ns_per_point_step: float
    cpu_s_median: float = float("nan")
    cpu_ns_per_point_step: float = float("nan")
    load_average: float = float("nan")
    load_s: float = float("nan")
    ordering_s: float = float("nan")
    schedule_s: float = float("nan")
    model_mb: float = float("nan")
    peak_rss_mb: float = float("nan")
    solves_per_step: float = float("nan")
    start: str = "cold"

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def bench_engine(case: str = "synthetic", days: float = 7.0, repeats: int = 7,
                 spun_up: bool = False) -> EngineBenchmark:
    """Time the compiled run of ``days`` simulated days of ``case``.

    Parameters
    ----------
    case
        Case folder or packaged case name.
    days
        Simulated duration, days.
    repeats
        Number of timed runs after the warm-up run (the median is reported).
    spun_up
        Start each run from the state the case's spin-up leaves at its start (computed once, not timed) instead of
        its cold state.
    """
    t_load = time.perf_counter()
    sim = load_model(case)
    load_s = time.perf_counter() - t_load
    start = sim.start
    end = start + pd.Timedelta(days=days)
    state = sim.simulate(start=start, end=start)[1] if spun_up else sim.initial_state(start)
    misses = _kernel_cache_misses()
    t0 = time.perf_counter()
    sim.simulate(start=start, end=min(end, start + pd.Timedelta(hours=1)), state=state)  # JIT compile or cache load
    compile_s = time.perf_counter() - t0
    compiled = _kernel_cache_misses() > misses
    sim.simulate(start=start, end=end, state=state)  # warm-up: caches, page faults
    walls, cpus = [], []
    for _ in range(repeats):
        cpu0 = time.process_time()
        result, _ = sim.simulate(start=start, end=end, state=state)
        cpus.append(time.process_time() - cpu0)
        walls.append(result.wall_time)
    c = sim.compiled
    steps = days * 86400.0 / sim.dt
    median = statistics.median(walls)
    return EngineBenchmark(
        case=sim.case.name,
        points=c.n_hpoints,
        links=c.n_links,
        weirs=int((c.arrays.lk_type == LINK_WEIR).sum()),
        culverts=int((c.arrays.lk_type == LINK_CULVERT).sum()),
        laterals=len(c.lateral_ids),
        dt_s=sim.dt,
        simulated_days=days,
        repeats=repeats,
        wall_s_median=median,
        wall_s_min=min(walls),
        wall_s_max=max(walls),
        compile_s=compile_s,
        compiled=compiled,
        steps_per_s=steps / median,
        ns_per_point_step=median / (steps * c.n_hpoints) * 1e9,
        cpu_s_median=statistics.median(cpus),
        cpu_ns_per_point_step=statistics.median(cpus) / (steps * c.n_hpoints) * 1e9,
        load_average=os.getloadavg()[0],
        load_s=load_s,
        **_ordering(sim),
        model_mb=_nbytes(c.arrays, sim._work) / 2**20,
        peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        solves_per_step=sim.last_run_stats["solves"] / max(sim.last_run_stats["steps"], 1),
        start="spun-up" if spun_up else "cold",
    )


def bench_engine_points(points: int, seed: int = 0, days: float = 7.0, repeats: int = 3,
                        spun_up: bool = False) -> EngineBenchmark:
    """:func:`bench_engine` on a lowland network of about ``points`` points generated with ``seed``."""
    from rivercal.case.generate import generate_case

    with tempfile.TemporaryDirectory(prefix="rivercal-bench-") as folder:
        generate_case(Path(folder) / "case", points, seed)
        return bench_engine(str(Path(folder) / "case"), days=days, repeats=repeats, spun_up=spun_up)


def _ordering(sim) -> dict[str, float]:
    """Time the one-off elimination order and solver schedule of the model's network again, s."""
    a = sim.compiled.arrays
    coupling = a.lk_type != LINK_PUMP
    pairs = list(zip(a.lk_k1[coupling].tolist(), a.lk_k2[coupling].tolist(), strict=True))
    t0 = time.perf_counter()
    sym = elimination_order(sim.compiled.n_hpoints, pairs)
    t1 = time.perf_counter()
    solver_schedule(sym)
    return {"ordering_s": t1 - t0, "schedule_s": time.perf_counter() - t1}


def _nbytes(*groups) -> int:
    """Bytes of the numpy arrays in some named tuples."""
    return sum(v.nbytes for g in groups for v in g if isinstance(v, np.ndarray))


def _kernel_cache_misses() -> int:
    """Signatures the engine kernels had to compile so far in this process (not found in numba's cache)."""
    count = 0
    for info in pkgutil.iter_modules(rivercal.engine.kernels.__path__, "rivercal.engine.kernels."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if isinstance(obj, CPUDispatcher):
                count += sum(obj.stats.cache_misses.values())
    return count
