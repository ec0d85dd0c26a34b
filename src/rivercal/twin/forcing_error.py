"""A twin whose rain is wrong: the truth's inflows and laterals carry a multiplicative AR(1) error.

The model that the on-line service and the DSS run keeps the case's forcing; the truth that makes the
observations runs the same case with its inflows and laterals multiplied by log-normal factors
exp(e − σ²/2), e an AR(1) process in time (:mod:`rivercal.assimilate.perturb`). So the model carries the
error of the rain and the runoff, which state updating is there to correct.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rivercal.assimilate.perturb import ar1_series, multiplicative_factors
from rivercal.models.capabilities import require
from rivercal.models.contract import Model

__all__ = ["rain_error_model"]


def rain_error_model(model: Model, sigma: float, seed: int, tau: str = "24h") -> Model:
    """A twin's truth whose inflows and laterals are the model's times log-normal AR(1) factors.

    The model that the service and the DSS run keeps the case's forcing, so it carries the error of the
    rain and the runoff: σ of the log of the factors (0.3: about 30 %), correlation time ``tau``, hourly
    values, one series per inflow and lateral (the model's perturbable forcing). The truth is a variant of
    the model (:class:`~rivercal.models.capabilities.Variants`).

    Raises
    ------
    MissingCapability
        For a model without perturbable forcing or variants.
    """
    require(model, "perturbable forcing", "variants", purpose="a twin with a rain error")
    rng = np.random.default_rng([seed, 20])
    keys = list(model.perturbable_forcing())
    hours = pd.date_range(model.start - pd.Timedelta("7D"), model.end + pd.Timedelta("1D"), freq="1h")
    errors = ar1_series(rng, hours.size, (len(keys),), sigma, pd.Timedelta(tau) / pd.Timedelta("1h"))
    factors = multiplicative_factors(errors, sigma)
    return model.variant(forcing_factors={key: pd.Series(factors[:, j], index=hours) for j, key in enumerate(keys)})
