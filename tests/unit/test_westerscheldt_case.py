"""The packaged Western Scheldt: written by its generator, laid out along the data's own course, run stably.

The independent references: the WGS 84 ellipsoid's geodesics (pyproj) for the distances between the gauges'
positions, and Rijkswaterstaat's predicted tide at the four gauges for the model driven by the predicted tide
at the mouth.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.bench.westerscheldt import GAUGES, _tide, case_folder, chainages, write_case
from rivercal.models import load_model


def test_the_packaged_case_is_what_its_generator_writes(tmp_path: Path) -> None:
    write_case(tmp_path)
    for name in ("case.toml", "forcing.csv"):
        assert (tmp_path / name).read_text() == (case_folder() / name).read_text(), name


def test_the_gauges_lie_at_the_distances_between_their_positions() -> None:
    from pyproj import Geod

    x = chainages()
    positions = {"vlissingen": (3.597577, 51.443861), "terneuzen": (3.820107, 51.337192),
                 "hansweert": (3.997696, 51.446618), "bath": (4.210261, 51.400048)}  # the files' headers
    geod = Geod(ellps="WGS84")
    for a, b in itertools.pairwise(GAUGES):
        _, _, metres = geod.inv(*positions[a], *positions[b])
        assert x[b] - x[a] == pytest.approx(metres, rel=0.005), (a, b)
    assert x["gent"] - x["vlissingen"] == 160_000.0   # the tide's limit above the mouth


def test_driven_by_the_predicted_tide_the_model_reproduces_it_at_the_gauges_on_a_converged_grid(tmp_path) -> None:
    model = load_model(case_folder())
    fine = load_model(write_case(tmp_path, dx=250.0, dt=30.0))
    result, _ = model.simulate({}, start=model.start, end=model.end)
    finer, _ = fine.simulate({}, start=fine.start, end=fine.end)
    window = slice("2013-12-05T03:00Z", "2013-12-05T15:00Z")
    for g in GAUGES:
        tide = _tide(case_folder() / f"tide_{g}.txt")[window]
        err = result.series[f"{g}.h"].reindex(tide.index) - tide
        assert np.isfinite(result.series[f"{g}.h"]).all()
        assert float(np.sqrt(np.mean(err**2))) < 0.17, g          # measured: 0.08 … 0.16 m
        grid = (result.series[f"{g}.h"] - finer.series[f"{g}.h"])[window]
        assert float(np.sqrt(np.mean(grid**2))) < 0.02, g         # halving dx and dt: 0.4 … 1.4 cm
    # the spin-up day before the data is the harmonic extension, continuous with the data at midnight
    forcing = pd.read_csv(case_folder() / "forcing.csv", index_col="time")["tide_cadzand"]
    assert len(forcing) == 433 and forcing.index[144] == "2013-12-05T00:00:00Z"
    steps = np.diff(forcing.to_numpy())
    assert abs(steps[143]) <= np.abs(steps[140:148]).max() and np.abs(steps).max() < 0.35  # no jump at midnight
