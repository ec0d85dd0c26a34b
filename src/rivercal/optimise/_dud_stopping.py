"""DuD's stopping rules after an accepted step: rivercal's (invariant to the weights' scale) and OpenDA's.

See :class:`~rivercal.optimise._dud_options.DudOptions` for what each rule means; this module only
decides. Costs are S = Σ r² of the (augmented) weighted residuals.
"""

from __future__ import annotations

from dataclasses import dataclass

from rivercal.optimise._dud_options import (
    STATUS_ABS,
    STATUS_LINEAR,
    STATUS_NEGLIGIBLE,
    STATUS_REL,
    STATUS_ZERO_COST,
    DudOptions,
)

__all__ = ["AcceptedStep", "negligible", "openda_rules", "rivercal_rules"]

#: OpenDA's ε_lin is 0 when its denominator |J₀ − J_lin| is at most this (OpenDA cost units, ½ S).
_OPENDA_TINY = 1e-14


@dataclass(frozen=True)
class AcceptedStep:
    """What the rules see of one outer iteration whose line search found a lower cost.

    Attributes
    ----------
    s_old, s_new
        Best cost before and after the step.
    linear
        Linearised cost of the full step (the secant model's prediction).
    predicted
        Linearised cost of the accepted step (equal to ``linear`` unless the step was shortened).
    first_trial
        Cost at the full step (t = 1), the first trial of the line search.
    shortened
        The line search had to shorten (or reverse) the step.
    second_best
        The second lowest cost of the interpolation set after the step replaced the worst point.
    dof
        Residual rows minus parameters (at least 1).
    """

    s_old: float
    s_new: float
    linear: float
    first_trial: float
    shortened: bool
    second_best: float
    dof: int
    predicted: float


def negligible(opts: DudOptions, cost: float, step_cost: float | None) -> bool:
    """The ``negligible_cost`` rule: S ≤ negligible_cost · S_h (never when S_h is unknown or zero)."""
    return step_cost is not None and step_cost > 0 and cost <= opts.negligible_cost * step_cost


def rivercal_rules(opts: DudOptions, step: AcceptedStep, step_cost: float | None) -> tuple[int | None, bool]:
    """Zero or negligible cost, T1 (drop ≤ abs_tol · s²), T2, T3; and whether the secant model needs refreshing.

    After a shortened step T1 and T2 do not fire: the cost dropped little because the step was cut
    short, not because the minimum is near. The second value is then True when they would have fired,
    or (with ``stall_ratio`` > 0) when the cost fell by at most ``stall_ratio`` times what the secant
    model predicted for the shortened step, or the model predicted no decrease for it (a reversed step):
    the model predicted a step the cost did not follow, so it should be re-initialised.
    """
    if step.s_new == 0.0:
        return STATUS_ZERO_COST, False
    if negligible(opts, step.s_new, step_cost):
        return STATUS_NEGLIGIBLE, False
    drop = step.s_old - step.s_new
    small = drop <= opts.abs_tol * step.s_new / step.dof or drop <= opts.rel_tol * step.s_new
    if small and not step.shortened:
        return (STATUS_ABS if drop <= opts.abs_tol * step.s_new / step.dof else STATUS_REL), False
    if step.s_old - step.linear <= opts.rel_tol_linear * step.s_old:
        return STATUS_LINEAR, False
    gain = step.s_old - step.predicted  # the decrease the secant model predicted for the step taken
    stalled = step.shortened and opts.stall_ratio > 0 and (gain <= 0 or drop <= opts.stall_ratio * gain)
    return None, small or stalled


def openda_rules(opts: DudOptions, step: AcceptedStep) -> int | None:
    """OpenDA's rules (reference note §1, step 8) in OpenDA's cost J = ½ S; None after any backtracking."""
    if step.shortened:
        return None
    j0, j1 = 0.5 * step.s_new, 0.5 * step.second_best
    d = j1 - j0
    if d <= opts.abs_tol:
        return STATUS_ABS
    if d <= opts.rel_tol * abs(j0):
        return STATUS_REL
    j_old, j_lin, j_try = 0.5 * step.s_old, 0.5 * step.linear, 0.5 * step.first_trial
    denominator = abs(j_old - j_lin)
    eps_lin = abs(j_try - j_lin) / denominator if denominator > _OPENDA_TINY else 0.0
    if eps_lin <= opts.rel_tol_linear:
        return STATUS_LINEAR
    return None
