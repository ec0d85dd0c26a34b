"""DDS: Dynamically Dimensioned Search (Tolson & Shoemaker 2007).

A greedy global search for a fixed evaluation budget m: around the best point so far, each parameter
is perturbed with probability P(i) = 1 − ln(i)/ln(m) after i evaluations (at least one always), by
r·(ub − lb)·N(0, 1), reflected at the bounds; the candidate replaces the best point if it is no worse.
Early on the search is global (all parameters move), late it is local (one or two move).

``candidates`` > 1 is a parallel variant: that many candidates are drawn around the same best point and
evaluated as one ``batch``; the best of them competes with the best point. With 1 (default) it is the
original sequential DDS.

Status codes (``TERMINATION_MESSAGES``): 1 the budget ``max_evaluations`` is used; 0 / −1 / −2
``max_nfev`` (if smaller), callback, deadline.

References
----------
Tolson, B. A. & Shoemaker, C. A. (2007). Dynamically dimensioned search algorithm for computationally
efficient watershed model calibration. Water Resources Research 43, W01413. doi:10.1029/2005WR004723.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    Stop,
    check_int,
    check_real,
    coerce_options,
    require_finite_bounds,
    validate_controls,
    validate_problem,
)
from rivercal.optimise.result import COMMON_MESSAGES, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "DdsOptions", "dds"]

STATUS_BUDGET = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_BUDGET: "The evaluation budget (max_evaluations) is used.",
}


@dataclass(frozen=True, slots=True)
class DdsOptions:
    """Options of :func:`dds`.

    Attributes
    ----------
    max_evaluations
        The budget m that shapes the neighbourhood schedule (1000). ``max_nfev``, if smaller, cuts the
        run short (``aborted``) without changing the schedule.
    r
        Perturbation size as a fraction of the bound range (0.2, Tolson & Shoemaker's value).
    candidates
        Candidates per iteration, evaluated as one batch (1: the original DDS).
    seed
        Seed of the random generator; None draws one (reported in ``extra["seed"]``).
    """

    max_evaluations: int = 1000
    r: float = 0.2
    candidates: int = 1
    seed: int | None = None

    def __post_init__(self) -> None:
        check_int("max_evaluations", self.max_evaluations, 2)
        check_real("r", self.r, strict=True, maximum=1.0)
        check_int("candidates", self.candidates, 1)
        if self.seed is not None:
            check_int("seed", self.seed)


def _perturb(rng: np.random.Generator, x: np.ndarray, lb: np.ndarray, ub: np.ndarray, r: float,
             probability: float) -> np.ndarray:
    """One DDS candidate: perturb a random subset of parameters, reflecting at the bounds.

    A reflection that overshoots the opposite bound lands on the bound that was violated (Tolson &
    Shoemaker 2007, step 4).
    """
    n = x.shape[0]
    chosen = rng.random(n) < probability
    if not chosen.any():
        chosen[rng.integers(n)] = True
    width = ub - lb
    new = x.copy()
    new[chosen] = x[chosen] + r * width[chosen] * rng.standard_normal(int(chosen.sum()))
    low = new < lb
    new[low] = lb[low] + (lb[low] - new[low])
    back = low & (new > ub)
    new[back] = lb[back]
    high = ~low & (new > ub)
    new[high] = ub[high] - (new[high] - ub[high])
    back = high & (new < lb)
    new[back] = ub[back]
    return np.minimum(np.maximum(new, lb), ub)


def dds(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: DdsOptions | dict | None = None,
        callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
        deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with Dynamically Dimensioned Search.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`; the bounds must be finite. The callback is called after
        every iteration (each ``candidates`` evaluations).
    options
        :class:`DdsOptions` or a dict.

    Returns
    -------
    OptimiseResult
        Without Jacobian; ``extra["seed"]`` is the seed used.
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    require_finite_bounds("dds", lb, ub)
    opts = coerce_options(options, DdsOptions)
    seed = opts.seed if opts.seed is not None else int(np.random.SeedSequence().entropy % 2**63)
    rng = np.random.default_rng(seed)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    budget = opts.max_evaluations
    try:
        best_x, best_f = x0, run.cost_of(run.evaluate(x0))
        while run.nfev < budget:
            probability = 1.0 - math.log(run.nfev) / math.log(budget)
            count = min(opts.candidates, budget - run.nfev)
            trials = [_perturb(rng, best_x, lb, ub, opts.r, probability) for _ in range(count)]
            costs = [run.cost_of(res) for res in run.evaluate_many(trials)]
            i = int(np.argmin(costs))
            if costs[i] <= best_f:
                best_x, best_f = trials[i], costs[i]
            run.iteration(best_x, best_f)
        status = STATUS_BUDGET
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "dds", extra={"seed": seed})
