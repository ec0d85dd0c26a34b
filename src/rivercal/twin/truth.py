"""Twin observations: the model run with the true parameters, sampled at the stations, plus noise.

A twin experiment differs from its truth only in the parameters (thesis §4-2-3: the observations are
made "with the original input like parameter values and initial conditions"), so the truth run also
provides the model state at the start of every calibration run.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.models.contract import Model, ModelState, spun_up
from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet, measurable
from rivercal.twin.noise import add_noise

__all__ = ["TwinTruth", "twin_truth"]


@dataclass(frozen=True)
class TwinTruth:
    """The truth of a twin experiment.

    Attributes
    ----------
    observations
        Observed series in the window (with noise when asked).
    state
        Model state of the truth at the start of each calibration run (window start − warm-up).
    run_start
        That time (UTC).
    truth
        The true model quantities.
    series
        The noise-free truth series from ``run_start`` to the window end.
    """

    observations: ObservationSet
    state: ModelState | None
    run_start: pd.Timestamp
    truth: dict[str, float]
    series: pd.DataFrame


def twin_truth(model: Model, truth: Mapping[str, float], window: tuple[Any, Any], *,
               warmup: pd.Timedelta | str = "24h", series: Sequence[str] | None = None, noise: str = "none",
               seed: int = 0, sigma: Mapping[str, float | None] | None = None) -> TwinTruth:
    """Run the truth and make the observations of a twin experiment.

    Parameters
    ----------
    model
        A model following the model protocol; the truth runs from the model's own start (cold start,
        spin-up) so that it has a realistic state.
    truth
        True model quantities (target → value), e.g. from ``ParameterSet.quantities``.
    window
        (start, end) of the calibration window (UTC); observations are kept inside it.
    warmup
        Time before the window at which calibration runs start (the state handed over).
    series
        Series ids to observe (default: all the model's stations measure).
    noise, seed
        Noise model of :mod:`rivercal.twin.noise` and its seed.
    sigma
        σ per quantity or series id for the weights (default :data:`~rivercal.observations.DEFAULT_SIGMA`).
    """
    start, end = utc(window[0]), utc(window[1])
    run_start = start - pd.Timedelta(warmup)
    truth = dict(truth)
    state = spun_up(model, truth, run_start)
    result, _ = model.simulate(truth, start=run_start, end=end, state=state)
    frame = result.series
    inside = frame.loc[start:end]
    ids = list(series) if series is not None else measurable(frame.columns)
    sigma = dict(sigma if sigma is not None else DEFAULT_SIGMA)
    rng = np.random.default_rng(seed)
    out = []
    for sid in ids:
        quantity = sid.rpartition(".")[2]
        values = add_noise(inside[sid].to_numpy(), quantity, noise, rng)
        out.append(ObservationSeries.from_series(pd.Series(values, index=inside.index), id=sid,
                                                 sigma=sigma.get(sid, sigma.get(quantity)),
                                                 source=f"twin truth, noise {noise} (seed {seed})"))
    return TwinTruth(observations=ObservationSet(tuple(out)), state=state, run_start=run_start, truth=truth,
                     series=frame)
