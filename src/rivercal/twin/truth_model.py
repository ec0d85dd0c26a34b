"""The truth of a twin experiment under a realism level: rainfall, runoff-parameter and structural errors.

:func:`truth_model` returns the model itself for a level that leaves the truth alone (``ideal``,
``noisy``), and otherwise a :class:`PerturbedTruth`: a variant of the model (its ``variants`` capability,
:class:`~rivercal.models.capabilities.Variants`; the embedded engine builds it from its case) with

- the lateral inflows of the rainfall-runoff model fed with the measured rain times one factor per rain
  event (:func:`~rivercal.twin.realism.event_factors`) and with rainfall-runoff parameters times a
  factor per catchment and parameter;
- a finer grid (every branch's ``dx`` times ``grid_factor``) and an own friction per branch: the
  global value (or the branch's own) times a lognormal factor f_b, normalised so that the
  length-weighted mean of f_b is 1.

A model without rainfall-runoff catchments whose inflows are given series (SWMM ``[INFLOWS]``, a BMI
component) takes the rain and runoff errors on those series (:func:`~rivercal.twin.realism.inflow_factors`,
through ``variant(forcing_factors=…)``: it needs the capability *perturbable forcing*). A structural error
needs branches to vary: a level with one is refused on a model without them (``realistic-forcing`` is
``realistic`` without it), never applied in part.

The truth takes the model's quantities: ``friction:global = v`` sets every branch that inherits the
global friction in the model to v · f_b, ``friction:branch:<id> = v`` sets that branch to v · f_b, crests
pass unchanged. So a scenario written against the model (``friction:global`` 16 → 25) changes the
truth alike, and the truth's mean friction is the value the scenario sets.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from rivercal.models.capabilities import MissingCapability, VariantInputs, Variants, has_capability, require
from rivercal.models.contract import Model, ModelState
from rivercal.results import SimulationResult
from rivercal.twin.realism import Realism, event_factors, generator, get_realism, inflow_factors

__all__ = ["PerturbedTruth", "truth_model"]

log = logging.getLogger(__name__)


def truth_model(model: Model, realism: str | Realism, seed: int = 0) -> Model:
    """The truth of a twin of ``model`` under ``realism`` (the model itself when the level leaves the truth alone).

    Raises
    ------
    MissingCapability
        When the level changes the truth but the model cannot make variants of itself, or cannot take one of
        the level's errors (:class:`PerturbedTruth`).
    """
    realism = get_realism(realism)
    if not realism.changes_truth:
        return model
    require(model, "variants", purpose=f"realism {realism.name!r} (it changes the truth's rain, runoff or structure)")
    return PerturbedTruth(model, realism, seed)


class PerturbedTruth:
    """The model's case with the rainfall, runoff and structural errors of a realism level (module docstring).

    Parameters
    ----------
    model
        A model that makes variants of itself (:class:`~rivercal.models.capabilities.Variants`).
    realism
        The realism level (its ``rain``, ``runoff`` and ``structure`` tables).
    seed
        Seed of the errors.

    Attributes
    ----------
    truth
        The model's variant with the errors.
    branch_factors
        f_b per branch id (-): the truth's friction of a branch over the model's (1 without structural error).
    rain_factor
        The factor on the measured rain per hour (-), or None.
    runoff_factors
        Per catchment, the factors on its rainfall-runoff parameters (-).
    forcing_factors
        A model without catchments: per inflow (forcing key), the factor series (-, hourly UTC index) of its
        rain and runoff errors (:func:`~rivercal.twin.realism.inflow_factors`); else empty.

    Raises
    ------
    MissingCapability
        For a structural error on a model without branches, and for rain or runoff errors on a model without
        catchments that has no perturbable forcing (or, for the rain, does not give its inflow series).
    """

    def __init__(self, model: Variants, realism: Realism, seed: int = 0):
        self.model = model
        self.realism = realism
        self.seed = int(seed)
        inputs = model.variant_inputs()
        if realism.structure is not None and not inputs.branches:
            raise MissingCapability(
                f"realism {realism.name!r} gives the truth a friction error per branch and a finer grid; model "
                f"{model.name!r} ({type(model).__name__}) has no branches to vary (its variants scale its inflows "
                "only): use --realism realistic-forcing (the same errors without the structural one) or a realism "
                "file without [structure]")
        self.branch_factors = dict.fromkeys(inputs.branches, 1.0)
        grid_factor = 1.0
        if realism.structure is not None:
            s = realism.structure
            rng = generator(seed, "friction")
            raw = np.exp(s.friction_sigma_ln * rng.standard_normal(len(inputs.branches)))
            lengths = np.array(list(inputs.branches.values()), dtype=float)
            raw /= float(np.sum(raw * lengths) / np.sum(lengths))
            self.branch_factors = {b: float(f) for b, f in zip(inputs.branches, raw, strict=True)}
            grid_factor = s.grid_factor
        self.rain_factor = None
        self.runoff_factors: dict[str, dict[str, float]] = {}
        self.forcing_factors: dict[str, pd.Series] = {}
        if realism.rain is not None and inputs.catchments and inputs.rain is not None:
            self.rain_factor = event_factors(inputs.rain, realism.rain, seed)
        if realism.runoff is not None and inputs.catchments:
            r = realism.runoff
            for c in inputs.catchments:
                rng = generator(seed, "runoff", c)
                self.runoff_factors[c] = {p: float(np.exp(r.sigma_ln * rng.standard_normal())) for p in r.parameters}
        if (realism.rain is not None or realism.runoff is not None) and not inputs.catchments:
            self.forcing_factors = self._inflow_errors(model, inputs, realism, self.seed)
        self.truth = model.variant(branch_factors=self.branch_factors if realism.structure is not None else None,
                                   grid_factor=grid_factor, rain_factor=self.rain_factor,
                                   runoff_factors=self.runoff_factors or None,
                                   forcing_factors=self.forcing_factors or None)
        self._inherit = list(inputs.inherit)
        log.info("perturbed truth of %s (%s, seed %d)", model.name, realism.name, seed)

    @staticmethod
    def _inflow_errors(model: Variants, inputs: VariantInputs, realism: Realism, seed: int) -> dict[str, pd.Series]:
        """The rain and runoff errors of a model without catchments, as factor series on its inflows."""
        what = " and ".join(k for k in ("rain", "runoff") if getattr(realism, k) is not None)
        if not has_capability(model, "perturbable forcing") or not model.perturbable_forcing():  # type: ignore[attr-defined]
            raise MissingCapability(
                f"realism {realism.name!r} puts {what} errors on the truth; model {model.name!r} "
                f"({type(model).__name__}) has no rainfall-runoff catchments and no inflows to scale (capability "
                "'perturbable forcing'): use a level without [rain] and [runoff] (e.g. 'noisy')")
        keys = tuple(model.perturbable_forcing())  # type: ignore[attr-defined]
        forcing = dict(inputs.forcing or {})
        missing = [k for k in keys if k not in forcing]
        if missing and realism.rain is not None:
            raise MissingCapability(
                f"realism {realism.name!r} puts a rain error on the inflows of model {model.name!r}, but the model "
                f"does not give the series of {missing[0]!r} to find its events in: use a level without [rain]")
        if missing:  # the runoff error alone needs no values: a constant factor on each inflow
            span = pd.DatetimeIndex([model.start, model.end])
            forcing = {k: pd.Series(1.0, index=span) for k in keys}
        factors = inflow_factors({k: forcing[k] for k in keys}, seed, rain=realism.rain, runoff=realism.runoff,
                                 measured_rain=inputs.rain)
        log.info("realism %r: model %s has no rainfall-runoff catchments; its truth takes the %s errors on its "
                 "%d inflow series (docs/realism.md)", realism.name, model.name, what, len(keys))
        return factors

    # -- what the twin machinery asks of a model --------------------------------------------------------

    @property
    def name(self) -> str:
        """The model's name with the realism level."""
        return f"{self.model.name} (truth, {self.realism.name})"

    @property
    def start(self) -> pd.Timestamp:
        """Start of the period (UTC)."""
        return self.truth.start

    @property
    def end(self) -> pd.Timestamp:
        """End of the period (UTC)."""
        return self.truth.end

    @property
    def dt(self) -> float:
        """Time step, s."""
        return float(self.truth.dt)

    @property
    def output_interval(self) -> float:
        """Default output interval, s."""
        return float(self.truth.output_interval)

    @property
    def observables(self) -> list[str]:
        """The simulated series (the model's stations)."""
        return list(self.truth.observables)

    def default_parameters(self) -> dict[str, float]:
        """The *model's* defaults: scenarios are written against the model's quantities."""
        return self.model.default_parameters()

    def quantities_of(self, parameters: Mapping[str, float]) -> dict[str, float]:
        """The truth's own quantities for the model's (module docstring); the model's own without structural error."""
        if self.realism.structure is None:
            return {k: float(v) for k, v in parameters.items()}
        out: dict[str, float] = {}
        branch = {}
        for key, value in parameters.items():
            if key == "friction:global":
                for b in self._inherit:
                    out[f"friction:branch:{b}"] = float(value) * self.branch_factors[b]
            elif key.startswith("friction:branch:"):
                branch[key] = float(value) * self.branch_factors[key.removeprefix("friction:branch:")]
            else:
                out[key] = float(value)
        return {**out, **branch}

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: ModelState | None = None, *,
                 output_interval: float | None = None) -> tuple[SimulationResult, ModelState]:
        """Run the truth with the model's quantities (see :meth:`quantities_of`)."""
        return self.truth.simulate(self.quantities_of(parameters or {}), start, end, state,
                                   output_interval=output_interval)

    def simulate_fields(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                        state: ModelState | None = None, *,
                        output_interval: float | None = None) -> tuple[SimulationResult, ModelState]:
        """:meth:`simulate` with the levels and discharges at every point of the truth's (finer) grid."""
        return self.truth.simulate_fields(self.quantities_of(parameters or {}), start, end, state,
                                          output_interval=output_interval)
