"""Compile the time loop ahead of use.

numba compiles a kernel at its first call and keeps the machine code in the user's cache, one folder per
version of the kernels' sources (:mod:`rivercal._kernel_cache`); later processes, of this installation or
of another with the same sources, load it in about a second. The first compile of the time loop takes
over a minute (measured on one core: 44 s for the plain loop, 19 s for the extended loop, 11 s more for
the extended loop with controllers), and a process that pays it looks hung and times everything it does
wrongly. :func:`compile_engine` pays it once, on purpose: ``rivercal compile`` (which ``make`` runs after
a change of the engine, before the demo, the tests, the benchmarks and the documentation; run it once on
each machine of a cluster after installing). With two cores or more and nothing cached yet, the extended
loop compiles in a second process while this one compiles the plain loop (measured on two cores: 73 to
82 s, against 98 s one after the other).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import time
import tomllib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import pandas as pd

from rivercal.case import load_case
from rivercal.case.load import CASE_FILE, Case, case_from_dict, resolve_case_path
from rivercal.engine.kernels import timeloop
from rivercal.engine.simulator import Simulator

__all__ = ["VARIANTS", "Readiness", "compile_engine"]

log = logging.getLogger(__name__)

#: The embedded case that takes each variant of the time loop: without D-HYDRO structures or controllers
#: (:func:`~rivercal.engine.kernels.timeloop.run`); the extended loop
#: (:func:`~rivercal.engine.kernels.timeloop.run_ext`) without controllers, which imported D-HYDRO models
#: with orifices, universal weirs, bridges, culverts with their own barrel or structure setting series take
#: (the synthetic case with one orifice added, :func:`_case`); and the extended loop with controllers.
VARIANTS = {"plain": "synthetic", "structures": "synthetic with an orifice", "controlled": "dommel-controlled"}
_KERNELS = {"plain": timeloop.run, "structures": timeloop.run_ext, "controlled": timeloop.run_ext}


@dataclass(frozen=True)
class Readiness:
    """One variant of the time loop made ready: wall time, s, and whether numba loaded it from its cache."""

    seconds: float
    from_cache: bool


def compile_engine(processes: int | None = None) -> dict[str, Readiness]:
    """Run each variant of the time loop (:data:`VARIANTS`) for one simulated hour.

    Boundaries and laterals that the case leaves to a rainfall-runoff model get a constant 1 m³/s: the
    run is there to compile, its result is dropped.

    Parameters
    ----------
    processes
        1 compiles the variants one after the other in this process. 2 or more, when numba's cache holds no
        extended loop yet: a second process compiles the first variant of the extended loop
        (``structures``) while this one compiles the plain loop; this process then loads it from the cache
        (or compiles it, if the cache does not hold it) before the variants that remain. None: 2 when
        this process may use two cores or more.
    """
    if processes is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        processes = min(2, cores)
    if processes < 1:
        raise ValueError(f"processes must be at least 1, got {processes}")
    if processes == 1 or _in_cache(timeloop.run_ext):  # nothing to compile: a second process would only load
        return {variant: _ready(variant) for variant in VARIANTS}
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        elsewhere = pool.submit(_ready, "structures")
        ready = {"plain": _ready("plain")}
        there = elsewhere.result()
    here = _ready("structures")
    ready["structures"] = there if here.from_cache else here
    ready.update({variant: _ready(variant) for variant in VARIANTS if variant not in ready})
    return {variant: ready[variant] for variant in VARIANTS}


def _in_cache(dispatcher: Any) -> bool:
    """Whether numba's cache holds a compiled version of ``dispatcher`` for its current source.

    Reads the cache's index through numba's internals; where they differ (another numba), False.
    """
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except AttributeError:
        return False


def _ready(variant: str) -> Readiness:
    """One variant of the time loop run for an hour: compiled, or loaded from numba's cache."""
    began = time.perf_counter()
    sim = Simulator(_case(variant))
    index = pd.date_range(sim.start, sim.end, freq="1D")
    for key in sim.compiled.forcing_keys:
        sim.forcing.setdefault(key, pd.Series(1.0, index=index))   # before its first run: nothing cached yet
    if sim.extended != (_KERNELS[variant] is timeloop.run_ext):
        raise RuntimeError(f"internal error: the case of the {variant!r} time loop takes the other loop")
    stats = _KERNELS[variant].stats
    hits, misses = sum(stats.cache_hits.values()), sum(stats.cache_misses.values())
    sim.simulate(end=sim.start + pd.Timedelta("1h"))
    from_cache = sum(stats.cache_hits.values()) > hits and sum(stats.cache_misses.values()) == misses
    ready = Readiness(time.perf_counter() - began, from_cache=from_cache)
    log.info("time loop %s (case %s) %s in %.1f s", variant, VARIANTS[variant],
             "loaded from the cache" if ready.from_cache else "compiled", ready.seconds)
    return ready


def _case(variant: str) -> Case:
    """The embedded case of a variant; for ``structures`` the synthetic case with an orifice on its main stream."""
    if variant != "structures":
        return load_case(VARIANTS[variant])
    root = resolve_case_path("synthetic")
    data = tomllib.loads((root / CASE_FILE).read_text(encoding="utf-8"))
    # 6 km down branch M, where its bed lies at 11.0 m AD: sill 0.4 m above it, gate edge 2 m above the sill
    data["orifices"] = [{"id": "warm-up-orifice", "branch": "M", "chainage": 6000.0, "crest_level": 11.4,
                         "crest_width": 4.0, "gate_lower_edge_level": 13.4}]
    return case_from_dict(data, root)
