"""Compile the time loop ahead of use.

numba compiles a kernel at its first call and keeps the machine code beside the package's sources
(``cache=True``); later processes load it in about a second. The first compile of the time loop takes
over a minute (measured on one core: 44 s for the plain loop, 19 s for the extended loop, 11 s more for
the extended loop with controllers), and a process that pays it looks hung and times everything it does
wrongly. :func:`compile_engine` pays it once, on purpose: ``rivercal compile`` (which ``make`` runs after
a change of the engine, before the demo, the tests, the benchmarks and the documentation; run it once on
each machine of a cluster after installing).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import pandas as pd

from rivercal.case import load_case
from rivercal.engine.kernels import timeloop
from rivercal.engine.simulator import Simulator

__all__ = ["VARIANTS", "Readiness", "compile_engine"]

log = logging.getLogger(__name__)

#: The embedded case that takes each variant of the time loop: without D-HYDRO structures or controllers
#: (:func:`~rivercal.engine.kernels.timeloop.run`); the extended loop
#: (:func:`~rivercal.engine.kernels.timeloop.run_ext`) without controllers, which every imported D-HYDRO
#: model with orifices, culverts or bridges takes (run here on the plain case: the same argument types, its
#: structure arrays empty); and the extended loop with controllers.
VARIANTS = {"plain": "synthetic", "structures": "synthetic", "controlled": "dommel-controlled"}
_KERNELS = {"plain": timeloop.run, "structures": timeloop.run_ext, "controlled": timeloop.run_ext}


@dataclass(frozen=True)
class Readiness:
    """One variant of the time loop made ready: wall time, s, and whether numba loaded it from its cache."""

    seconds: float
    from_cache: bool


def compile_engine() -> dict[str, Readiness]:
    """Run each variant of the time loop (:data:`VARIANTS`) for one simulated hour.

    Boundaries and laterals that the case leaves to a rainfall-runoff model get a constant 1 m³/s: the
    run is there to compile, its result is dropped.
    """
    ready = {}
    for variant, name in VARIANTS.items():
        began = time.perf_counter()
        case = load_case(name)
        sim = Simulator(case)
        missing = [key for key in sim.compiled.forcing_keys if key not in sim.forcing]
        if missing:
            index = pd.date_range(sim.start, sim.end, freq="1D")
            sim = Simulator(case, forcing={key: pd.Series(1.0, index=index) for key in missing})
        if variant == "structures":
            sim.extended = True
        stats = _KERNELS[variant].stats
        hits, misses = sum(stats.cache_hits.values()), sum(stats.cache_misses.values())
        sim.simulate(end=sim.start + pd.Timedelta("1h"))
        from_cache = sum(stats.cache_hits.values()) > hits and sum(stats.cache_misses.values()) == misses
        ready[variant] = Readiness(time.perf_counter() - began, from_cache=from_cache)
        log.info("time loop %s (case %s) %s in %.1f s", variant, name,
                 "loaded from the cache" if ready[variant].from_cache else "compiled", ready[variant].seconds)
    return ready
