"""The on-line parameter estimation service (layer 7): rolling windows, warm starts, guardrails.

:mod:`rivercal.online.service` runs the cycles (replay or follow) against a :class:`rivercal.store.Store`;
:mod:`rivercal.online.transition` holds the transition discretisation of thesis §6-3.
"""

from rivercal.online.service import CycleOutcome, OnlineConfig, OnlineService
from rivercal.online.transition import (
    AFTER,
    BEFORE,
    TIME,
    TransitionEstimate,
    TransitionModel,
    TransitionTest,
    estimate_transition,
    transition_start,
    transition_test,
)

__all__ = [
    "AFTER",
    "BEFORE",
    "TIME",
    "CycleOutcome",
    "OnlineConfig",
    "OnlineService",
    "TransitionEstimate",
    "TransitionModel",
    "TransitionTest",
    "estimate_transition",
    "transition_start",
    "transition_test",
]
