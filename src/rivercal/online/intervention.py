"""Automatic transition estimation in the on-line service: one intervention, found once, followed while in view.

A daily cycle over a week-long window averages a sudden change (mowing, a lowered weir) with the week
before it (thesis §6-3), so the per-cycle estimate creeps towards the new value over a window's length
of cycles. The service therefore, when a cycle's estimate jumps (the jump test of
:mod:`rivercal.online.guardrails`),

1. runs the transition estimator (:func:`~rivercal.online.transition.estimate_transition`) on the
   parameter that jumped most, over the cycle's run (its warm-up and window: the state at the run's
   start comes from the values before, and a change just before a short window's start has no
   observation before it inside the window), with the other parameters at their last accepted values;
2. if the window holds a transition (:func:`~rivercal.online.transition_search.transition_test`: a
   cost reduction that is significant — counting the residuals as the independent values they are
   worth, :func:`~rivercal.online.transition_search.effective_size` — and relevant) whose values
   differ by more than the parameter's resolution and that at least ``transition_min_after_h`` hours
   of the window follow (default 36 h: in a realistic twin, a flood whose rain the model
   underestimated made the friction look changed for the day it passed, 42 % cost reduction, and an
   intervention lasts), it *carries* the transition: a
   :class:`~rivercal.store.TransitionRecord` (the value before, the value after and the estimated time
   of the change) stored with the cycle, and the cycle's calibration is run again on the
   :class:`~rivercal.models.transition.TransitionModel`, with the value before and the time fixed and
   the value after estimated together with the other parameters; the after-value is accepted;
3. every later cycle whose run (warm-up and window) still holds the time of the change calibrates the
   same way and stores the transition again with the same ``found_cycle`` and its updated after-value;
   once the change has left the run, the after-value is simply the parameter's warm start.

So an intervention raises one ``jump`` alert, in the cycle that found it, and later cycles refine it
instead of raising new alerts.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import replace

import pandas as pd

from rivercal.models.contract import Model
from rivercal.models.transition import AFTER, BEFORE, TIME, TransitionModel
from rivercal.parameters import Parameter, ParameterSet
from rivercal.store import Run, Store, TransitionRecord

__all__ = ["active_transition", "after_parameters", "carried", "fixed_transition", "transition_model",
           "transition_quantities"]

log = logging.getLogger(__name__)


def active_transition(store: Store, run: Run, run_start: pd.Timestamp,
                      window_end: pd.Timestamp) -> TransitionRecord | None:
    """The transition the previous cycle carried, if its time still lies in (run_start, window_end]."""
    table = store.transitions(run)
    if table.empty:
        return None
    last = table[table["cycle"] == table["cycle"].max()]
    inside = last[(last["time"] > run_start) & (last["time"] <= window_end)]
    if inside.empty:
        return None
    r = inside.iloc[0]
    return TransitionRecord(parameter=str(r["parameter"]), time=r["time"], before=float(r["before"]),
                            after=float(r["after"]), unit=str(r["unit"]), found_cycle=int(r["found_cycle"]))


def transition_model(model: Model, parameter: Parameter, run_start: pd.Timestamp) -> TransitionModel:
    """The model whose ``parameter`` switches from before to after; τ in h since ``run_start``."""
    return TransitionModel(model, parameter, reference=run_start)


def after_parameters(box: ParameterSet, name: str) -> ParameterSet:
    """``box`` with parameter ``name`` setting the transition's value after (its bounds and steps kept)."""
    out = []
    for p in box:
        if p.name == name:
            data = p.model_dump()
            data.update(targets=[AFTER], cluster=[], cluster_mode="fraction")
            p = Parameter.model_validate(data)
        out.append(p)
    return ParameterSet(out)


def transition_quantities(tm: TransitionModel, quantities: Mapping[str, float], record: TransitionRecord,
                          after: float) -> dict[str, float]:
    """Model quantities for ``tm``: ``quantities`` without the changing parameter's targets, plus the transition.

    ``after`` is the value after the change; before and time come from ``record``.
    """
    own = set(tm.targets_of(record.before))
    rest = {k: v for k, v in quantities.items() if k not in own}
    tau = (record.time - tm.reference).total_seconds() / 3600.0
    return {**rest, BEFORE: record.before, AFTER: float(after), TIME: tau}


def fixed_transition(tm: TransitionModel, record: TransitionRecord) -> dict[str, float]:
    """The fixed quantities of a calibration on ``tm``: the value before and the time of the change."""
    return {BEFORE: record.before, TIME: (record.time - tm.reference).total_seconds() / 3600.0}


def carried(record: TransitionRecord, after: float) -> TransitionRecord:
    """The record as a later cycle stores it: the same change with its updated after-value, no test figures."""
    return replace(record, after=float(after), cost_single=None, cost_transition=None, p_value=None)
