"""Instructions the engine executes for a simulated period, counted by callgrind (deterministic, unlike times).

Usage: ``python benchmarks/engine_instructions.py --case synthetic --days 1`` prints one JSON object: the case,
the simulated days and the instructions of one run of :meth:`Simulator.simulate` over them, from the case
start, after a first (warm-up) run of the same period that loads or compiles the engine. Only the second run
is instrumented (callgrind's ``--instr-atstart=no``, switched on and off with ``callgrind_control``), so the
count compares versions of the engine on this machine to the instruction; a wall time on a shared machine
does not. Callgrind counts each byte of a string store (``rep stosb``, which ``memset`` uses for larger
arrays) as one instruction; ``memset_instructions`` says how much of the total that is.

Needs valgrind (Debian: ``apt-get install valgrind``); about ten minutes for a day of the synthetic case.
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


def _inner(case: str, days: float) -> None:
    """Inside valgrind: a warm-up run, then the instrumented run of the same period."""
    import pandas as pd

    from rivercal.model import load_model

    sim = load_model(case)
    end = sim.start + pd.Timedelta(days=days)
    sim.simulate(None, end=end)
    control = ["callgrind_control", "-i"]
    subprocess.run([*control, "on", str(os.getpid())], check=True, capture_output=True)
    sim.simulate(None, end=end)
    subprocess.run([*control, "off", str(os.getpid())], check=True, capture_output=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="synthetic")
    parser.add_argument("--days", type=float, default=1.0)
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.inner:
        _inner(args.case, args.days)
        return
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        sys.exit("engine_instructions needs valgrind (Debian: apt-get install valgrind)")
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "callgrind.out"
        subprocess.run([valgrind, "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}",
                        sys.executable, __file__, "--inner", "--case", args.case, "--days", str(args.days)],
                       check=True, capture_output=True)
        total = next(int(line.split()[1]) for line in out.read_text().splitlines() if line.startswith("totals:"))
        report = subprocess.run(["callgrind_annotate", str(out)], check=True, capture_output=True, text=True).stdout
        memset = sum(int(line.split()[0].replace(",", "")) for line in report.splitlines()
                     if "memset" in line and line.strip()[:1].isdigit())
    print(json.dumps({"case": args.case, "days": args.days, "instructions": total, "memset_instructions": memset}))


if __name__ == "__main__":
    main()
