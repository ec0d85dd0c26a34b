"""How sparse is the Jacobian of a generated board-size network: what a dependency map could save Sparse DuD.

Usage: ``python benchmarks/sparse_dependency.py --points 4000`` prints one JSON object. The network of
``rivercal case generate --points N`` is run for ``--days`` days, once as generated and once per region
friction F1 … F20 raised by its perturbation (25 → 27 m^(1/3)/s). For each series the largest change
after the first day (the spin-up) is taken in units of its σ (:data:`rivercal.observations.DEFAULT_SIGMA`:
2.5 cm for levels, 0.1 m³/s for discharges): a series "sees" a region when the change exceeds a
threshold of 0.02 … 0.2 σ.

Sparse DuD needs n_dir = min(p, k + 1) perturbed runs to start and 2 n_dir for its final Jacobian, k the
most regions one residual row sees; the dense map has k = p = 20. Reported per threshold: k, the series
that sees the most, the histogram of regions per series, and the same without the trunk canal's
stations (``ST…``), whose discharge sums the outflow of every catchment upstream.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case.generate import generate_case
from rivercal.model import load_model
from rivercal.observations import DEFAULT_SIGMA

THRESHOLDS = (0.02, 0.05, 0.1, 0.2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--points", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--days", type=float, default=8.0, help="simulated days (the first is spin-up)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="rivercal-sparse-") as folder:
        generate_case(Path(folder) / "case", args.points, args.seed)
        model = load_model(str(Path(folder) / "case"))
    regions = [p for p in model.case.spec.parameters if p.name != "FA"]
    series = list(model.observables)
    sigma = np.array([DEFAULT_SIGMA[s.rpartition(".")[2]] for s in series])
    end = model.start + pd.Timedelta(days=args.days)
    after = model.start + pd.Timedelta(days=1)
    t = time.perf_counter()
    base, _ = model.simulate(None, end=end)
    run_s = time.perf_counter() - t
    effect = np.empty((len(series), len(regions)))
    for j, p in enumerate(regions):
        run, _ = model.simulate(p.quantities(p.initial + p.perturbation), end=end)
        effect[:, j] = (run.series.loc[after:, series] - base.series.loc[after:, series]).abs().max().to_numpy()
    seen_sigma = effect / sigma[:, None]
    catchment = np.array([not s.startswith("ST") for s in series])
    out: dict = {"points": model.compiled.n_hpoints, "series": len(series), "parameters": len(regions),
                 "days": args.days, "one_run_s": round(run_s, 2), "thresholds": {}}
    for thr in THRESHOLDS:
        seen = seen_sigma > thr
        counts = seen.sum(axis=1)
        k, k_catchment = int(counts.max()), int(counts[catchment].max())
        out["thresholds"][f"{thr:g} sigma"] = {
            "k": k, "most_seen_by": series[int(np.argmax(counts))],
            "regions_per_series": np.bincount(counts, minlength=len(regions) + 1).tolist(),
            "regions_seen_by_no_series": int((~seen.any(axis=0)).sum()),
            "n_directions": min(len(regions), k + 1), "final_jacobian_runs": 2 * min(len(regions), k + 1),
            "k_without_trunk": k_catchment,
            "n_directions_without_trunk": min(len(regions), k_catchment + 1)}
    out["note"] = ("k: the most regions whose perturbation moves one series by more than the threshold; a dense map "
                   "has k = p; regions_per_series[i]: how many series see i regions")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
