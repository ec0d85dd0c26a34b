"""Helpers shared by the analyses: one batch evaluator per analysis, and words for parameters and stations."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rivercal.problem import problem_evaluator

Batch = Callable[[list[np.ndarray]], Sequence[np.ndarray]]


@contextmanager
def batch_for(problem: Any, batch: Batch | None, workers: int | None) -> Iterator[Batch]:
    """The caller's batch, or an :class:`~rivercal.evaluate.Evaluator` over ``problem.residuals``.

    The start state and the weights are computed here, before the workers fork, so that every worker
    inherits them instead of recomputing them (as :func:`rivercal.problem.calibrate` does).
    """
    if batch is not None:
        yield batch
        return
    problem.state  # noqa: B018 - computed before the workers fork
    problem.sqrt_weights  # noqa: B018
    with problem_evaluator(problem, workers) as evaluator:
        yield evaluator


def station_of(series_id: str) -> str:
    """Station id of a series id ``"<station>.<quantity>"``."""
    return series_id.rpartition(".")[0] or series_id


@dataclass(frozen=True)
class Context:
    """Words for the plain-language verdicts.

    Attributes
    ----------
    descriptions
        What each parameter sets, by name (``"crest level of weir ZL1-3014"``).
    units
        Unit of each parameter, by name (``"m AD"``).
    stations
        What each station measures, by station id (``"levels either side of weir ZL1-3014"``).
    at
        Per parameter, the stations that measure right at the structure it sets.
    """

    descriptions: Mapping[str, str] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    stations: Mapping[str, str] = field(default_factory=dict)
    at: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


def _measures(quantities: list[str], where: str, at_structure: bool) -> str:
    """``the levels up- and downstream of weir X and the discharge over it`` and the like."""
    levels = [q for q in quantities if q != "Q"]
    parts = []
    if at_structure:
        if {"h_up", "h_down"} <= set(levels):
            parts.append(f"the levels up- and downstream of {where}")
        elif levels:
            parts.append(f"the level {'upstream' if levels[0] == 'h_up' else 'downstream'} of {where}")
        if "Q" in quantities:
            over = "over" if where.startswith("weir ") else "through"  # a weir spills; a culvert or pump passes
            parts.append(f"the discharge {over} it" if parts else f"the discharge {over} {where}")
    else:
        if levels:
            parts.append(f"the level {where}")
        if "Q" in quantities:
            parts.append("the discharge there" if parts else f"the discharge {where}")
    return " and ".join(parts)


#: A structure's kind in words, by its class in the network (rivercal.network.topology).
_KINDS = {"Weir": "weir", "UniversalWeir": "weir", "Orifice": "orifice", "Culvert": "culvert", "Pump": "pump",
          "Bridge": "bridge"}


def _structure_kind(network: Any, structure_id: str) -> str:
    """``weir``, ``pump``, ``culvert`` … for a structure of the network (``structure`` when it cannot tell)."""
    try:
        return _KINDS.get(type(network.structure(structure_id)).__name__, "structure")
    except (AttributeError, KeyError, ValueError):  # a duck-typed network without its structures
        return "structure"


def context_from_problem(problem: Any) -> Context:
    """Describe the problem's parameters and, when the model exposes its network, its stations.

    The model is only duck-typed (``model.case.network.stations``), so any model of the model protocol
    works; without a network the verdicts name stations by id only.
    """
    descriptions, units, weirs_of = {}, {}, {}
    for p in problem.parameters:
        units[p.name] = p.unit
        if p.cluster:
            descriptions[p.name] = f"the crests of {len(p.cluster)} weirs, each at this fraction of its range"
            weirs_of[p.name] = {c.target[5:-12] for c in p.cluster}
            continue
        weirs = [t[5:-12] for t in p.targets if t.startswith("weir:")]
        parts = []
        if weirs:
            parts.append(("crest level of weir " if len(weirs) == 1 else "crest levels of weirs ") + ", ".join(weirs))
        if "friction:global" in p.targets:
            parts.append("bed friction of the whole network")
        branches = [t.split(":", 2)[2] for t in p.targets if t.startswith("friction:branch:")]
        if branches:
            parts.append("bed friction of branch " + ", ".join(branches))
        descriptions[p.name] = "; ".join(parts)
        weirs_of[p.name] = set(weirs)
    stations, structure_of = {}, {}
    network = getattr(getattr(getattr(problem, "model", None), "case", None), "network", None)
    for st in getattr(network, "stations", None) or []:
        quantities = list(st.quantities or (["h_up", "h_down"] if st.structure else ["h"]))
        if st.structure:
            stations[st.id] = _measures(quantities, f"{_structure_kind(network, st.structure)} {st.structure}", True)
            structure_of[st.id] = st.structure
        else:
            stations[st.id] = _measures(quantities, f"on branch {st.branch} at {st.chainage:g} m", False)
    at = {name: tuple(s for s, w in structure_of.items() if w in weirs) for name, weirs in weirs_of.items()}
    return Context(descriptions=descriptions, units=units, stations=stations, at={k: v for k, v in at.items() if v})
