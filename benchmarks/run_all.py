"""Run every benchmark; print one JSON line each and save them under --out.

Usage: ``python benchmarks/run_all.py --out out/bench`` (what ``make bench`` runs). Each benchmark
is a ``rivercal bench <name> --json`` command, so the numbers here are the numbers a user gets (the
dashboard's page load is a script here: it needs the browser of the test environment).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

BENCHMARKS = {
    "engine": ["bench", "engine", "--json"],
    "engine-dommel": ["bench", "engine", "--case", "dommel", "--json"],
    "ensemble": ["bench", "ensemble", "--members", "64", "--json"],
    "calibrate-dud": ["bench", "calibrate", "--algorithms", "dud", "--json"],
    "calibrate-all": ["bench", "calibrate", "--json"],
    "hupsel": ["bench", "hupsel", "--json"],
    "dhydro": ["bench", "dhydro", "--json"],
    "oriege": ["bench", "oriege", "--json"],
    "online": ["bench", "online", "--replay", "--json"],
    "dashboard": ["benchmarks/dashboard_load.py"],
    "engines": ["bench", "engines", "--json"],
    "blackbox": ["bench", "blackbox", "--json"],
    "dask": ["bench", "dask", "--json"],
    # the cost per point and step as the network grows (a week of 400 points takes 0.2 s: more repeats)
    "engine-points-400": ["bench", "engine", "--points", "400", "--repeats", "21", "--json"],
    "engine-points-4000": ["bench", "engine", "--points", "4000", "--json"],
    "engine-points-40000": ["bench", "engine", "--points", "40000", "--repeats", "3", "--json"],
    "engine-points-100000": ["bench", "engine", "--points", "100000", "--repeats", "3", "--json"],
    "sparse-dependency": ["benchmarks/sparse_dependency.py", "--points", "4000"],
    "online-scale": ["benchmarks/online_scale.py", "--points", "40000", "--dask", "local:2", "--dependency-threshold",
                     "0.2", "--catchments-only"],
    "online-scale-dt300": ["benchmarks/online_scale.py", "--points", "40000", "--dask", "local:2",
                           "--dependency-threshold", "0.2", "--catchments-only", "--dt", "300", "--final-jacobian",
                           "secant", "--parallel-line-search", "--stall-ratio", "0.01"],
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    parser.add_argument("names", nargs="*", help="benchmarks to run (default: all)")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for name in args.names or BENCHMARKS:
        args_ = BENCHMARKS[name]
        cmd = [sys.executable, *args_] if args_[0].endswith(".py") else [sys.executable, "-m", "rivercal.cli", *args_]
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            print(json.dumps({"benchmark": name, "error": run.stderr.strip()[-2000:]}))
            failed += 1
            continue
        result = {**json.loads(run.stdout), "benchmark": name}
        print(json.dumps(result))
        (args.out / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
