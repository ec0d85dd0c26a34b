"""Which check of the step control divides a run's steps: a census of its decisions, counted inside the time loop.

Usage: ``python benchmarks/step_control_census.py [--case synthetic | --points 40000] [--days 1] [--chunk-hours 1]``.
Prints one JSON object: for the whole run, the sub-steps computed (and committed), the solves, how many sub-steps
were computed at a finer level and which control's level that was (``stability``, ``accuracy``, ``courant``: the
finest of the three is taken, :func:`rivercal.engine.kernels.timeloop._level`), how often each check raised a
level (the explicit depth's forecast, a flicker) or refused a solved sub-step (a dry point, a velocity, the Courant
limit, the accuracy estimate above ``ERR_REDO``), the sub-steps per level, and the points whose accuracy estimate
was the largest when a committed sub-step asked the next step to be divided (the ten most frequent, with their
links' kinds); then per chunk of ``chunk-hours`` the solves, sub-steps and divided steps per step
(``Simulator.last_run_stats``; a run continued from a state divides its steps as the whole run does).

Like ``benchmarks/engine_cycles.py`` it runs a copy of ``timeloop.py`` with counters added (compiled each time, never
cached; the counters change no arithmetic). ``--points N`` generates the lowland network of
``rivercal bench engine --points N`` (seed 0). Networks with D-HYDRO's structures (the extended time loop) are not
instrumented.
"""

from __future__ import annotations

import argparse
import collections
import inspect
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from engine_cycles import _before, _load_plain, _replace

import rivercal.engine.simulator as simulator
from rivercal.engine.kernels import timeloop
from rivercal.engine.kernels.codes import LINK_CHANNEL, LINK_CULVERT, LINK_PUMP, LINK_WEIR
from rivercal.model import load_model

#: Counter slots; the sub-steps per level follow from ``LEVELS``, the points from ``POINTS``.
COUNTS = {0: "substeps_computed", 11: "substeps_committed", 16: "solves", 1: "computed_at_a_finer_level",
          2: "level_of_stability", 3: "level_of_accuracy", 4: "level_of_courant",
          5: "raised_by_the_explicit_depth_forecast", 10: "raised_by_a_flicker", 6: "refused_dry_point",
          7: "refused_velocity", 8: "refused_courant", 9: "refused_accuracy_above_err_redo",
          14: "committed_asking_the_next_step_divided"}
LEVELS = 20
POINTS = 64
KINDS = {LINK_CHANNEL: "channel", LINK_WEIR: "weir", LINK_CULVERT: "culvert", LINK_PUMP: "pump"}


def _instrumented(folder: Path):
    """The copy of the time loop with the counters, imported from ``folder``."""
    s = Path(inspect.getsourcefile(timeloop)).read_text()
    s = _replace(s, "    STAT_REDONE,\n", "    STAT_REDONE,\n    STAT_SOLVES,\n")
    s = _replace(s, "q_out, balance):\n    \"\"\"Advance the state over ``forcing.shape[0]``",
                 "q_out, balance, clk):\n    \"\"\"Advance the state over ``forcing.shape[0]``")
    s = _replace(s, "courant, balance)\n        if swap:", "courant, balance, clk)\n        if swap:")
    s = _replace(s, "min_depth, vmax, courant, balance):\n    \"\"\"Advance the state over step ``n``",
                 "min_depth, vmax, courant, balance, clk):\n    \"\"\"Advance the state over step ``n``")
    s = _replace(s, "        level = _level(stats)\n", """        level = _level(stats)
        clk[0] += 1
        clk[1] += level > 0
        clk[2] += (stats[STAT_LEVEL] == level) & (level > 0)
        clk[3] += (stats[STAT_ACC] == level) & (level > 0)
        clk[4] += (stats[STAT_COURANT] == level) & (level > 0)
        clk[20 + level] += 1
        s0 = stats[STAT_SOLVES]
""")
    s = _replace(s, "            continue\n        switched = switch_pumps(",
                 "            clk[5] += 1\n            continue\n        switched = switch_pumps(")
    s = _before(s, " = _screen(net, work, z, dz, u1,", "        clk[16] += stats[STAT_SOLVES] - s0\n")
    s = _replace(s, "courant * FULL / (span * dt))\n", "courant * FULL / (span * dt), clk)\n")
    s = _replace(s, "            swapped = not swapped\n",
                 "            swapped = not swapped\n            clk[11] += 1\n")
    s = _replace(s, "            if status == STATUS_FLICKER and level < MAX_HALVINGS:\n",
                 "            if status == STATUS_FLICKER and level < MAX_HALVINGS:\n                clk[10] += 1\n")
    s = _replace(s, "def _screen(net, work, z, dz, un, vmax, level, first, fastest):",
                 "def _screen(net, work, z, dz, un, vmax, level, first, fastest, clk):")
    s = _replace(s, "        _rise(stats, level)\n        return SCREEN_REDO, -1\n    if level >= MAX_HALVINGS:",
                 "        _rise(stats, level)\n        clk[6] += 1\n        return SCREEN_REDO, -1\n"
                 "    if level >= MAX_HALVINGS:")
    s = _replace(s, "    if too_fast(un, vmax):\n", "    if too_fast(un, vmax):\n        clk[7] += 1\n")
    s = _replace(s, "        stats[STAT_COURANT] = level + 1\n",
                 "        stats[STAT_COURANT] = level + 1\n        clk[8] += 1\n")
    s = _replace(s, "    if error > ERR_REDO:\n", "    if error > ERR_REDO:\n        clk[9] += 1\n")
    s = _replace(s, "    stats[STAT_ACC_NEXT] = max(stats[STAT_ACC_NEXT], wanted)\n", """    if wanted > 0:
        clk[14] += 1
        back = 1.0 / shorter
        best = -1
        largest = 0.0
        for i in range(z.size):
            e = math.fabs(work.zk[i] - z[i] - dz[i] * back)
            if not work.fixed[i] and e > largest:
                largest = e
                best = i
        if best >= 0:
            clk[64 + best] += 1
    stats[STAT_ACC_NEXT] = max(stats[STAT_ACC_NEXT], wanted)
""")
    return _load_plain(s, folder, "timeloop_census")


def _census(case: str, days: float, chunk_hours: float) -> dict:
    sim = load_model(case)
    if sim.extended:
        raise SystemExit("step_control_census: the case needs the extended time loop, which is not instrumented")
    a, n_h = sim.compiled.arrays, sim.compiled.n_hpoints
    clk = np.zeros(POINTS + n_h, dtype=np.int64)
    with tempfile.TemporaryDirectory(prefix="rivercal-census-") as folder:
        module = _instrumented(Path(folder))
        simulator.run = lambda *args: module.run(*args, clk)  # the copy in place of the time loop, in this process
        state = sim.initial_state(sim.start)
        t, end = sim.start, sim.start + pd.Timedelta(days=days)
        chunks = []
        while t < end:
            t1 = min(t + pd.Timedelta(hours=chunk_hours), end)
            _, state = sim.simulate(start=t, end=t1, state=state, output_interval=sim.dt)
            s = sim.last_run_stats
            taken = s["steps"] - s["divided_steps"] + s["substeps"]
            chunks.append({"from_h": round((t - sim.start).total_seconds() / 3600, 2),
                           "solves_per_step": round(s["solves"] / s["steps"], 2),
                           "substeps_per_step": round(taken / s["steps"], 2),
                           "divided_steps": s["divided_steps"], "max_division": s["max_division"],
                           "geometry_fallbacks": s["geometry_fallbacks"]})
            t = t1
    out = {name: int(clk[k]) for k, name in COUNTS.items()}
    out["substeps_per_level"] = {str(k): int(clk[LEVELS + k]) for k in range(POINTS - LEVELS) if clk[LEVELS + k]}
    asked = clk[POINTS:]
    overfall = set(a.dl_link.tolist())
    points = []
    for i in np.argsort(asked)[::-1][:10]:
        if asked[i] == 0:
            break
        links = [int(a.nl_link[c]) for c in range(a.nl_ptr[i], a.nl_ptr[i + 1])]
        points.append({"point": sim.compiled.hp_label[i], "times": int(asked[i]), "bed_m": round(float(a.hp_bed[i]), 3),
                       "links": dict(collections.Counter(
                           "free overfall" if link in overfall else KINDS.get(int(a.lk_type[link]), "other")
                           for link in links))})
    out["largest_accuracy_estimate_at"] = points
    out["chunks"] = chunks
    return {"case": sim.case.name, "points": n_h, "days": days, **out}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="synthetic")
    parser.add_argument("--points", type=int, default=0, help="a generated network of about this many points")
    parser.add_argument("--days", type=float, default=1.0)
    parser.add_argument("--chunk-hours", type=float, default=1.0)
    args = parser.parse_args()
    if args.points:
        from rivercal.case.generate import generate_case

        with tempfile.TemporaryDirectory(prefix="rivercal-census-case-") as folder:
            generate_case(Path(folder) / "case", args.points, 0)
            result = _census(str(Path(folder) / "case"), args.days, args.chunk_hours)
    else:
        result = _census(args.case, args.days, args.chunk_hours)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
