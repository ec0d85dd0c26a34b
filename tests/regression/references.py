"""The engine regression references: which runs, and the script that (re)writes their CSV files.

Each reference is the hourly station series of one run of a packaged case with its own parameters,
cold-started (after the case's spin-up). They pin the engine's results: a change that moves a level or
a discharge by more than the tolerance of ``test_engine_regression.py`` fails that test. When a
change is meant to alter the results (new physics, a corrected bug), regenerate the files with

    python -m tests.regression.references

and say in the commit why the references moved and by how much.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from rivercal.model import load_model

DATA = Path(__file__).parent / "data"

#: name → (case, start, end): the synthetic benchmark network's first week and the dommel flood week
#: of 8–15 November 2010 (Fig. 4-3's second window), when every weir of the default case carries flow.
RUNS = {
    "synthetic_week": ("synthetic", "2020-01-01T00:00:00Z", "2020-01-08T00:00:00Z"),
    "dommel_flood_week": ("dommel", "2010-11-08T00:00:00Z", "2010-11-15T00:00:00Z"),
}


def simulate(name: str) -> pd.DataFrame:
    """The station series (m AD, m³/s) of reference run ``name``, hourly."""
    case, start, end = RUNS[name]
    result, _ = load_model(case).simulate(start=start, end=end)
    return result.series


def path(name: str) -> Path:
    """The CSV file of reference run ``name``."""
    return DATA / f"{name}.csv"


def main() -> None:
    """Rewrite every reference file."""
    DATA.mkdir(exist_ok=True)
    for name in RUNS:
        simulate(name).to_csv(path(name), float_format="%.9f")
        print(f"wrote {path(name)}")


if __name__ == "__main__":
    main()
