"""Cost of controllers: an engine week of dommel-controlled beside one of dommel, interleaved in one process.

Usage: ``python benchmarks/controlled_engine.py [--pairs 15]``. Both cases are loaded, warmed up (kernels
compiled or loaded from numba's cache), then their week (Δt = 60 s, hot start from the initial state, as
``rivercal bench engine``) runs alternately ``pairs`` times. Prints one JSON object: the median processor
time and wall time of each and their ratios (controlled / uncontrolled), and the level solves per step of
each (moving crests make the Picard iteration work more). Processor time is the figure to compare on a
shared machine: it does not count the time the process waited for a core.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import pandas as pd

from rivercal.model import load_model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=15)
    args = parser.parse_args()
    sims = {c: load_model(c) for c in ("dommel", "dommel-controlled")}
    runs = {}
    for case, sim in sims.items():
        start = sim.start
        end = start + pd.Timedelta(days=7)
        state = sim.initial_state(start)
        sim.simulate(start=start, end=end, state=state)  # warm-up
        runs[case] = (start, end, state)
    cpu: dict[str, list[float]] = {c: [] for c in sims}
    wall: dict[str, list[float]] = {c: [] for c in sims}
    for _ in range(args.pairs):
        for case, sim in sims.items():
            start, end, state = runs[case]
            c0, w0 = time.process_time(), time.perf_counter()
            sim.simulate(start=start, end=end, state=state)
            cpu[case].append(time.process_time() - c0)
            wall[case].append(time.perf_counter() - w0)
    mc = {c: statistics.median(v) for c, v in cpu.items()}
    mw = {c: statistics.median(v) for c, v in wall.items()}
    print(json.dumps({
        "cpu_s_median": mc, "wall_s_median": mw,
        "cpu_ratio": mc["dommel-controlled"] / mc["dommel"], "wall_ratio": mw["dommel-controlled"] / mw["dommel"],
        "solves_per_step": {c: s.last_run_stats["solves"] / s.last_run_stats["steps"] for c, s in sims.items()},
        "pairs": args.pairs,
    }))


if __name__ == "__main__":
    main()
