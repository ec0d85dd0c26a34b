"""Cache behaviour of the engine per point and time step, from valgrind's cache simulation (callgrind).

Usage: ``python benchmarks/engine_cache.py --points 4000 100000`` prints one JSON object: per generated
network (:func:`rivercal.case.generate.generate_case`, seed 0) the instructions, data references, first-level
data-cache misses and last-level-cache misses per point and time step of one simulated hour (60 steps, after
a two-hour spin-up and a warm-up hour), counted by callgrind with ``--cache-sim=yes`` and a last-level cache
of ``--llc-mb`` MB (32: this machine's L3, simulated as the process' own). Instruction and miss counts do not
depend on what else the machine runs, unlike times; a point-step whose data stay in the cache costs ~0.2
last-level misses, one that streams its arrays from memory several.

Needs valgrind (Debian: ``apt-get install valgrind``). Only the timed hour is instrumented (callgrind's
``--instr-atstart=no``, switched on and off with ``callgrind_control``); loading runs at about a fifth of its
usual speed, the instrumented hour at about a hundredth: about 10 minutes for 100,000 points.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def _inner(case: str) -> None:
    """Inside valgrind: load, spin up, warm up, then run the instrumented hour."""
    import pandas as pd

    from rivercal.model import load_model

    sim = load_model(case)
    start = sim.start + pd.Timedelta(hours=2)
    _, state = sim.simulate(None, end=start)
    sim.simulate(None, start=start, end=start + pd.Timedelta(hours=1), state=state)
    toggle = ["callgrind_control", "-i"]
    subprocess.run([*toggle, "on", str(os.getpid())], check=True, capture_output=True)
    sim.simulate(None, start=start, end=start + pd.Timedelta(hours=1), state=state)
    subprocess.run([*toggle, "off", str(os.getpid())], check=True, capture_output=True)
    stats = sim.last_run_stats
    print(json.dumps({"points": sim.compiled.n_hpoints, "steps": stats["steps"], "solves": stats["solves"]}))


def _measure(points: int, llc_mb: int, folder: Path) -> dict:
    from rivercal.case.generate import generate_case

    case = folder / f"case{points}"
    generate_case(case, points, 0)
    out = folder / f"callgrind{points}.out"
    run = subprocess.run(["valgrind", "--tool=callgrind", "--instr-atstart=no", "--cache-sim=yes",
                          f"--LL={llc_mb * 2**20},16,64", f"--callgrind-out-file={out}", sys.executable, __file__,
                          "--inner", str(case)], capture_output=True, text=True, check=False)
    if run.returncode != 0:
        raise SystemExit(f"valgrind failed on {points} points:\n{run.stderr[-2000:]}")
    info = json.loads(run.stdout.strip().splitlines()[-1])
    text = out.read_text()
    events = next(line for line in text.splitlines() if line.startswith("events:")).split()[1:]
    totals = next(line for line in text.splitlines() if line.startswith("totals:")).split()[1:]
    count = dict(zip(events, map(int, totals), strict=True))
    per = info["points"] * info["steps"]
    return {
        "points": info["points"], "steps": info["steps"], "solves_per_step": info["solves"] / info["steps"],
        "instructions": round(count["Ir"] / per, 1),
        "data_refs": round((count["Dr"] + count["Dw"]) / per, 1),
        "l1d_misses": round((count["D1mr"] + count["D1mw"]) / per, 2),
        "llc_misses": round((count["DLmr"] + count["DLmw"]) / per, 3),
    }


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--inner":
        _inner(sys.argv[2])
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, nargs="+", default=[4000, 100000])
    parser.add_argument("--llc-mb", type=int, default=32, help="simulated last-level cache, MB")
    args = parser.parse_args()
    if shutil.which("valgrind") is None:
        raise SystemExit("valgrind is not installed (Debian: apt-get install valgrind)")
    with tempfile.TemporaryDirectory(prefix="rivercal-cache-") as folder:
        rows = [_measure(n, args.llc_mb, Path(folder)) for n in args.points]
    print(json.dumps({"llc_mb": args.llc_mb, "per_point_step": rows,
                      "note": "counts per calculation point and time step of one simulated hour (callgrind)"}))


if __name__ == "__main__":
    main()
