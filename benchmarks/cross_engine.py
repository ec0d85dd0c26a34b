"""Cross-engine refinement: the flood wave on the weir chain, embedded engine and EPA SWMM at halved Δx and Δt.

Usage: ``python benchmarks/cross_engine.py`` prints one JSON line per resolution (Δx, both time steps, the
largest level difference between the engines at the stations, each engine's change to its own finest run,
wall times); see :func:`rivercal.bench.engines.refinement`.
"""

from __future__ import annotations

import json
import tempfile

from rivercal.bench.engines import refinement


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for row in refinement(tmp):
            print(json.dumps(row))


if __name__ == "__main__":
    main()
