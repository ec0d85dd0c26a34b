"""Variants of an embedded model for a twin's truth: other rain, runoff, grid, friction per branch, forcing.

A twin experiment's truth differs from the model the service runs (:mod:`rivercal.twin.truth_model`,
:mod:`rivercal.twin.forcing_error`). The twin draws the errors; this module builds the truth from the
model's case with them (:meth:`EmbeddedModel.variant <rivercal.models.EmbeddedModel.variant>`), so that the
twin needs nothing of the case or the engine:

- ``branch_factors``: each branch's friction is the case's value for it (its own, else the case's global
  friction) times its factor, written into the case (so no branch of the variant inherits a global value);
- ``grid_factor``: every branch's ``dx`` times the factor (a branch given by its points keeps them);
- ``rain_factor``, ``runoff_factors``: the rainfall-runoff inflows of the catchments computed with the measured
  rain times a factor per hour and with the catchments' parameters times a factor each
  (:func:`rivercal.hydrology.catchments.catchment_forcing`);
- ``forcing_factors``: per forcing key (``boundary:<id>``, ``lateral:<id>``) a factor series (UTC index,
  interpolated in time) on the model's own forcing of that key.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from rivercal.case.load import case_from_dict

if TYPE_CHECKING:
    from rivercal.models.embedded import EmbeddedModel

__all__ = ["variant_of"]


def variant_of(model: EmbeddedModel, *, branch_factors: Mapping[str, float] | None = None, grid_factor: float = 1.0,
               rain_factor: pd.Series | None = None, runoff_factors: Mapping[str, Mapping[str, float]] | None = None,
               forcing_factors: Mapping[str, pd.Series] | None = None) -> EmbeddedModel:
    """The embedded model of a variant of ``model``'s case (module docstring).

    Raises
    ------
    ValueError
        For a branch, a forcing key or a grid factor the case does not have (or one that is not positive).
    """
    from rivercal.hydrology.catchments import catchment_forcing
    from rivercal.models.embedded import EmbeddedModel

    case = model.case
    spec = case.spec
    if not grid_factor > 0:
        raise ValueError(f"the grid factor must be positive, got {grid_factor}")
    factors = dict(branch_factors or {})
    unknown = sorted(set(factors) - {b.id for b in spec.branches})
    if unknown:
        raise ValueError(f"case {case.name!r} has no branch {unknown[0]!r}")
    perturbed = case
    if factors or grid_factor != 1.0:
        data = spec.model_dump(mode="json", exclude_unset=True, by_alias=True)
        for b, item in zip(spec.branches, data["branches"], strict=True):
            if grid_factor != 1.0 and b.points is None:
                item["dx"] = float(b.dx) * grid_factor
            if factors:
                base = b.friction if b.friction is not None else spec.friction
                item["friction"] = {"type": base.type, "value": float(base.value) * factors.get(b.id, 1.0)}
        perturbed = case_from_dict(data, case.root)
    forcing = dict(model.forcing)
    if rain_factor is not None or runoff_factors:
        forcing.update(catchment_forcing(perturbed, rain_factor=rain_factor, parameter_factors=runoff_factors))
    keys = set(model.compiled.forcing_keys)
    for key, factor in (forcing_factors or {}).items():
        if key not in keys:
            raise ValueError(f"case {case.name!r} has no forcing {key!r}")
        series = forcing[key]
        at = (series.index - factor.index[0]).total_seconds()
        forcing[key] = series * np.interp(at, (factor.index - factor.index[0]).total_seconds(),
                                          factor.to_numpy(dtype=float))
    return EmbeddedModel(perturbed, forcing={k: v for k, v in forcing.items() if k in keys})
