"""Every optimiser on every lower- and average-difficulty NIST StRD problem: a Markdown table.

Usage::

    python benchmarks/optimise_nist_table.py [--out FILE] [--starts 1 2] [--methods dud trf ...] [--jobs N]

With ``--out docs/nist-strd.md`` it writes the whole page (the text below and the tables).

Each cell is "significant digits reached / model runs": digits = min over the parameters of
−log10(|b − certified| / |certified|) (capped at 11; 0 when the fit is off), after mapping permuted
equivalent terms onto NIST's order. **Bold**: at least 4 digits. The settings per method are those of
``tests/optimise/nist.py`` (``settings``): local methods from the NIST start with tight tolerances,
SCE-UA with its initial population in x0 ± |x0| inside wide bounds, grid and GLUE over x0 ± |x0| with
20 000 points, budgets of 20 000-200 000 runs for the global and direct-search methods.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.optimise.nist import AVERAGE, LOWER, problem, solve  # noqa: E402

from rivercal.optimise import OPTIMISERS  # noqa: E402

HEADER = """# NIST StRD nonlinear regression: every optimiser

Produced by `python benchmarks/optimise_nist_table.py --jobs 2 --out docs/nist-strd.md` (settings per method in
`tests/optimise/nist.py`; numpy {numpy}, scipy {scipy}). Each cell: significant digits of the certified
parameters reached / model runs; **bold** = at least 4 digits. Problems and certified values: NIST
Statistical Reference Datasets (public domain), copied into `tests/data/`. `tests/optimise/test_nist.py`
asserts ≥ 4 digits for DuD (both starts), TRF (both starts) and SCE-UA. DDS, grid and GLUE are global
samplers with a fixed budget of 20 000 runs and are not expected to reach 4 digits on these problems.

`trf` is scipy's trust-region reflective method (`scipy.optimize.least_squares(method="trf")`), not
Levenberg-Marquardt (its former name here, `lm`, said otherwise). It runs in units of the initial step
(10 % of |x0|) with its own scaling set so that its first trust region is one initial step: with
scipy's default scaling its first steps grow with the square root of the distance to the (wide) bounds,
and from start 1 it stops in another local minimum on MGH17, Lanczos1, Lanczos2 and Lanczos3.

DuD on MGH17 from start 1 is chaotic in the round-off: its path crosses the valley where the two decay
rates coincide and the amplitudes grow without bound, and whether it leaves the valley depends on the
last bits of the arithmetic. The test asserts a rate over initial perturbations that differ by 1e-9
relative (`test_dud_mgh17_start1`), not the single run below.
"""


def run_one(job: tuple[str, str, int]) -> tuple[str, str, int, float, int, float, str]:
    method, name, start = job
    p = problem(name, start)
    t0 = time.perf_counter()
    res = solve(method, p)
    return method, name, start, p.digits(res.x), res.nfev, time.perf_counter() - t0, res.message


def table(results: dict, methods: list[str], start: int) -> str:
    lines = [f"### NIST start {start}", "",
             "| problem | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for name in LOWER + AVERAGE:
        cells = []
        for method in methods:
            digits, nfev = results[method, name, start][:2]
            text = f"{max(digits, 0.0):.1f} / {nfev}"
            cells.append(f"**{text}**" if digits >= 4 else text)
        level = "lower" if name in LOWER else "average"
        lines.append(f"| {name} ({level}) | " + " | ".join(cells) + " |")
    solved = [sum(results[m, n, start][0] >= 4 for n in LOWER + AVERAGE) for m in methods]
    runs = [sum(results[m, n, start][1] for n in LOWER + AVERAGE) for m in methods]
    lines.append("| **≥ 4 digits** | " + " | ".join(f"{s}/{len(LOWER + AVERAGE)}" for s in solved) + " |")
    lines.append("| **total runs** | " + " | ".join(str(r) for r in runs) + " |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, help="also write the Markdown here")
    parser.add_argument("--starts", type=int, nargs="+", default=[1, 2], choices=[1, 2])
    parser.add_argument("--methods", nargs="+", default=list(OPTIMISERS), choices=list(OPTIMISERS))
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    args = parser.parse_args()
    jobs = [(m, n, s) for s in args.starts for m in args.methods for n in LOWER + AVERAGE]
    t0 = time.perf_counter()
    results = {}
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for m, n, s, d, nfev, sec, msg in pool.map(run_one, jobs):
            results[m, n, s] = (d, nfev, sec, msg)
            print(f"{m:12s} {n:9s} start {s}: {d:5.1f} digits, {nfev:6d} runs, {sec:6.1f} s  {msg}", file=sys.stderr)
    import numpy
    import scipy

    text = HEADER.format(numpy=numpy.__version__, scipy=scipy.__version__) + "\n"
    text += "\n".join(table(results, args.methods, s) for s in args.starts)
    text += f"\n(wall time {time.perf_counter() - t0:.0f} s with {args.jobs} worker(s))\n"
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
