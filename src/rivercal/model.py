"""The embedded model of a case: its engine with the rainfall-runoff inflows computed once.

Layer 4: above the engine and the hydrology, which do not know each other. Everything that runs a
case (command line, calibration problem, twin experiments, the on-line service) builds it here, so
that a bad ``[runoff]`` table or meteo file fails when the model is loaded, before any run.
"""

from __future__ import annotations

from pathlib import Path

from rivercal.case.load import Case, load_case
from rivercal.engine.simulator import Simulator
from rivercal.hydrology.catchments import catchment_forcing

__all__ = ["build_model", "load_model"]


def build_model(case: Case) -> Simulator:
    """A simulator of ``case`` whose catchment-fed laterals carry the rainfall-runoff inflow."""
    return Simulator(case, forcing=catchment_forcing(case))


def load_model(source: str | Path) -> Simulator:
    """Load a case (folder or packaged name) and build its model.

    Examples
    --------
    >>> from rivercal.model import load_model
    >>> sim = load_model("dommel")
    >>> sim.observables[:2]
    ['0028.h_up', '0028.h_down']
    """
    return build_model(load_case(source))
