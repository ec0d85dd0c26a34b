"""Engine benchmark: one simulated week of the synthetic network at Δt = 60 s.

``rivercal bench engine --json`` prints one JSON object with the network size, the median wall
time of the compiled run over several repetitions after warm-up, the time of the first call (a one-hour
run: JIT compilation, or loading the compiled kernels from numba's cache) and whether that call had to
compile anything (``compiled``: false when every kernel came from the cache, as in a second call of
the CLI).
"""

from __future__ import annotations

import importlib
import pkgutil
import statistics
import time
from dataclasses import asdict, dataclass

import pandas as pd
from numba.core.registry import CPUDispatcher

import rivercal.engine.kernels
from rivercal.engine.kernels.codes import LINK_CULVERT, LINK_WEIR
from rivercal.model import load_model

__all__ = ["EngineBenchmark", "bench_engine"]


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

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def bench_engine(case: str = "synthetic", days: float = 7.0, repeats: int = 7) -> EngineBenchmark:
    """Time the compiled run of ``days`` simulated days of ``case``.

    Parameters
    ----------
    case
        Case folder or packaged case name.
    days
        Simulated duration, days.
    repeats
        Number of timed runs after the warm-up run (the median is reported).
    """
    sim = load_model(case)
    start = sim.start
    end = start + pd.Timedelta(days=days)
    state = sim.initial_state(start)
    misses = _kernel_cache_misses()
    t0 = time.perf_counter()
    sim.simulate(start=start, end=min(end, start + pd.Timedelta(hours=1)), state=state)  # JIT compile or cache load
    compile_s = time.perf_counter() - t0
    compiled = _kernel_cache_misses() > misses
    sim.simulate(start=start, end=end, state=state)  # warm-up: caches, page faults
    walls = []
    for _ in range(repeats):
        result, _ = sim.simulate(start=start, end=end, state=state)
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
    )


def _kernel_cache_misses() -> int:
    """Signatures the engine kernels had to compile so far in this process (not found in numba's cache)."""
    count = 0
    for info in pkgutil.iter_modules(rivercal.engine.kernels.__path__, "rivercal.engine.kernels."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if isinstance(obj, CPUDispatcher):
                count += sum(obj.stats.cache_misses.values())
    return count
