"""What the dashboard knows of a run's model besides the store: its map, its parameters in words, the DSS's values.

Read once per model name and process (the model is loaded, never run). A store names a run's model by its
name; a model that cannot be found by it (a case folder of its own, such as an imported model, or an external
program's ``model.toml``) is found through :func:`register_model` (``rivercal dashboard --case``), or leaves
the facts empty and says why; the pages then show what the store holds alone.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from rivercal.dashboard.words import describe_parameter

__all__ = ["ModelFacts", "dss_values", "model_facts", "register_model"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModelFacts:
    """What the pages use of a run's model.

    Attributes
    ----------
    name
        The model (case) name as the run stored it.
    parameters
        The model's calibration parameters by name (:class:`~rivercal.parameters.Parameter`).
    quantities
        The model's own values of its settable quantities (target → value, in the quantity's unit), as far
        as the model tells them (the embedded engine does).
    network
        The river network (:class:`~rivercal.network.Network`), None when the model has none.
    problem
        Why the model could not be loaded ("" when it was).
    """

    name: str
    parameters: Mapping[str, Any] = field(default_factory=dict)
    quantities: Mapping[str, float] = field(default_factory=dict)
    network: Any = None
    problem: str = ""

    def describe(self, parameter: str) -> str:
        """What ``parameter`` sets, in words ("" when unknown)."""
        p = self.parameters.get(parameter)
        return describe_parameter(p) if p is not None else ""


#: Where the model of each name is, for the models a store names by a name that is no case (register_model).
_SOURCES: dict[str, str] = {}


def register_model(source: str) -> str:
    """Load the model at ``source`` (a case folder, a packaged case or a ``model.toml``) for the runs naming it.

    Returns the model's name, by which the store names it. A bad source raises the loader's error
    (:class:`~rivercal.errors.CaseError`).
    """
    from rivercal.model import load_model

    name = str(load_model(source).name)
    _SOURCES[name] = str(source)
    model_facts.cache_clear()
    return name


@functools.lru_cache(maxsize=8)
def model_facts(name: str, source: str | None = None) -> ModelFacts:
    """The facts of the model ``name`` (a packaged case, a case folder, a ``model.toml`` or a registered name).

    ``source``: where a run recorded its model (``model_source``, a case folder or ``model.toml``); used when no
    model is registered under ``name`` and the model there still bears that name.
    """
    from rivercal.model import load_model

    model = None
    if source and name not in _SOURCES:
        try:
            found = load_model(source)
            model = found if str(found.name) == name else None
        except Exception as exc:  # a moved or changed folder: the name is tried instead
            log.info("the dashboard cannot load model %r from %s: %s", name, source, exc)
    try:
        model = model if model is not None else load_model(_SOURCES.get(name, name))
    except Exception as exc:  # any failure only leaves the pages without the model's facts
        log.info("the dashboard cannot load model %r: %s", name, exc)
        return ModelFacts(name, problem=f"the model {name!r} cannot be loaded here ({exc}; give its case folder "
                                        "or model.toml with rivercal dashboard --case)")
    quantities: dict[str, float] = {}
    defaults = getattr(model, "default_parameters", None)
    if callable(defaults):
        try:
            quantities = {k: float(v) for k, v in defaults().items()}
        except (ValueError, TypeError, KeyError) as exc:
            log.info("model %r does not tell its quantities' values: %s", name, exc)
    case = getattr(model, "case", None)
    return ModelFacts(name, parameters={p.name: p for p in model.calibration.parameters}, quantities=quantities,
                      network=getattr(case, "network", None))


def dss_values(facts: ModelFacts, dss: Mapping[str, float], names: list[str]) -> dict[str, float]:
    """The value of each parameter that the DSS's model has, in the parameter's unit.

    The DSS runs the model's own quantities, with the run's ``dss`` settings over them. A parameter sets
    its targets linearly (a value, a shift, a share of a range), so its DSS value is the one whose
    quantities are the DSS's: solved from the parameter's map at its bounds, averaged over its targets.
    Without the model's own values (a model that does not tell them) the parameter's initial value stands
    for the DSS's unless ``dss`` sets its targets.
    """
    out: dict[str, float] = {}
    for name in names:
        p = facts.parameters.get(name)
        if p is None:
            continue
        own = {**facts.quantities, **{k: float(v) for k, v in dss.items()}}
        low, high = p.quantities(p.min), p.quantities(p.max)
        solved = []
        for target, q0 in low.items():
            slope = (high[target] - q0) / (p.max - p.min) if p.max != p.min else 0.0
            if target in own and slope != 0.0 and math.isfinite(own[target]):
                solved.append(p.min + (own[target] - q0) / slope)
        if solved:
            out[name] = sum(solved) / len(solved)
        elif not facts.quantities:
            out[name] = float(p.initial)
    return out
