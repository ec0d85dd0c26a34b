"""The search of the transition estimator (thesis §6-3): where to start the three-value fit, and the verdict.

- :func:`transition_start` reads a start (before, after, τ) for the three-value fit from the residuals of
  the one-value fit (a CUSUM), so that the fit begins between the right pair of observations (see
  :mod:`rivercal.models.transition` for why a fit started far from τ can stall);
- :func:`transition_test` decides from the costs of the one-value and the three-value fit whether a
  window holds a transition worth estimating.

The estimator that runs both fits is :func:`rivercal.online.transition.estimate_transition`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rivercal.problem import Calibration, CalibrationProblem

__all__ = ["TransitionTest", "effective_size", "transition_start", "transition_test"]


@dataclass(frozen=True)
class TransitionTest:
    """Outcome of :func:`transition_test`.

    Attributes
    ----------
    transition
        True when the window holds a transition worth estimating.
    cost_single, cost_transition
        Cost S (thesis Eq. 2-3, dimensionless) of the one-value and of the three-value fit.
    n_residuals
        Number of observations in the window.
    n_effective
        The number of independent residuals they are worth (:func:`effective_size`; ``n_residuals`` when
        the residuals are taken as independent).
    f_statistic, p_value
        F = ((S₁ − S₃)/2) / (S₃/(n − 3)) · n_eff/n and its upper-tail probability under F(2, n_eff − 3).
    reduction
        Relative cost reduction (S₁ − S₃)/S₁.
    reason
        The rule's verdict in words.
    """

    transition: bool
    cost_single: float
    cost_transition: float
    n_residuals: int
    n_effective: float
    f_statistic: float
    p_value: float
    reduction: float
    reason: str


def effective_size(residuals: np.ndarray, lengths: list[int] | tuple[int, ...]) -> float:
    """How many independent residuals a window's residuals are worth, from their lag-1 autocorrelation.

    Hourly residuals of a model that differs from the river are strongly autocorrelated: an inflow that
    the model underestimates for a day leaves a day of residuals of one sign. For a stationary AR(1)
    sequence with lag-1 autocorrelation ρ the variance of a mean is that of n_eff = n (1 − ρ)/(1 + ρ)
    independent values (Bretherton et al. 1999, *J. Climate* 12, 1990–2009, Eq. 31). ρ is pooled over
    the series, ρ = Σ r_t r_{t+1} / Σ r_t² over the consecutive pairs of each series, and clipped to
    [0, 0.999].

    Parameters
    ----------
    residuals
        The residuals (any scale), series after series.
    lengths
        The number of values of each series, in the same order; they sum to the size of ``residuals``.

    Returns
    -------
    float
        n_eff, between 4 and n.

    Examples
    --------
    >>> round(effective_size(np.array([1.0, -1.0] * 50), [100]))
    100
    """
    r = np.asarray(residuals, dtype=float)
    if sum(lengths) != r.size:
        raise ValueError(f"the series lengths {list(lengths)} do not add up to the {r.size} residuals")
    lag, total, start = 0.0, 0.0, 0
    for n in lengths:
        x = r[start:start + n]
        start += n
        total += float(x @ x)
        if n > 1:
            lag += float(x[:-1] @ x[1:])
    if not total > 0:
        return float(r.size)
    rho = min(max(lag / total, 0.0), 0.999)
    return float(max(min(r.size * (1.0 - rho) / (1.0 + rho), r.size), 4.0))


def transition_test(cost_single: float, cost_transition: float, n_residuals: int, *, alpha: float = 1e-3,
                    min_reduction: float = 0.25, min_gain: float = 1.0,
                    n_effective: float | None = None) -> TransitionTest:
    """Does a window hold a transition? Compare the one-value fit (S₁) with the three-value fit (S₃).

    The three-value model nests the one-value model (before = after), so S₃ ≤ S₁ up to the optimiser's
    tolerance. The rule accepts a transition when both hold:

    - the F-test of nested least-squares models rejects "no transition" at level ``alpha`` (p < alpha).
      With n independent residuals F = ((S₁ − S₃)/2) / (S₃/(n − 3)) follows F(2, n − 3); it is free of
      the scale of the weights (σ need not be right). Correlated residuals carry less information than
      their number: with ``n_effective`` (:func:`effective_size`) F is scaled by n_eff/n and compared
      with F(2, n_eff − 3). Without it, hourly residuals of a model that differs from the river make
      any event that the model misses "significant" (p = 1e-133 for a flood whose rain the model
      underestimated). τ means nothing when there is no change, so the optimiser picks the τ that
      fits the noise best and p still comes out somewhat small: hence the small default ``alpha``;
    - the relative cost reduction (S₁ − S₃)/S₁ is at least ``min_reduction``: a change that explains
      less than this share of the misfit is not worth three parameters in an operational cycle, however
      significant (with thousands of residuals the F-test alone flags tiny, irrelevant drifts); and
    - the cost drops by at least ``min_gain`` in absolute terms, so that round-off is not read as a
      transition when both fits are already (nearly) perfect (noise-free twin data without a change,
      where S₁ and S₃ are both ~1e-10 and their ratio means nothing).

    Parameters
    ----------
    cost_single, cost_transition
        S₁ and S₃ (dimensionless, the same weights).
    n_residuals
        Number of observations (residuals) in the window; more than 3.
    alpha
        Significance level of the F-test, in (0, 1).
    min_reduction
        Smallest relative cost reduction, in [0, 1).
    min_gain
        Smallest absolute cost reduction S₁ − S₃ (dimensionless; with 1/σ² weights, 1 is the variance of
        one observation), >= 0.
    n_effective
        The number of independent residuals they are worth, in (3, n_residuals]; None: n_residuals.

    Raises
    ------
    ValueError
        For a negative or non-finite cost, n ≤ 3, or an option out of its range.

    Examples
    --------
    >>> transition_test(10.0, 1.0, 500).transition
    True
    >>> transition_test(10.0, 9.9, 500).transition
    False
    >>> transition_test(10.0, 6.0, 500).transition, transition_test(10.0, 6.0, 500, n_effective=10).transition
    (True, False)
    """
    for label, value in (("cost_single", cost_single), ("cost_transition", cost_transition)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"{label} must be a finite cost >= 0, got {value!r}")
    if n_residuals <= 3:
        raise ValueError(f"n_residuals must exceed the 3 parameters of the transition fit, got {n_residuals}")
    n_eff = float(n_residuals if n_effective is None else n_effective)
    if not 3.0 < n_eff <= n_residuals:
        raise ValueError(f"n_effective must lie in (3, n_residuals = {n_residuals}], got {n_effective!r}")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}")
    if not 0.0 <= min_reduction < 1.0:
        raise ValueError(f"min_reduction must lie in [0, 1), got {min_reduction!r}")
    if not (math.isfinite(min_gain) and min_gain >= 0.0):
        raise ValueError(f"min_gain must be a finite number >= 0, got {min_gain!r}")
    gain = cost_single - cost_transition
    reduction = gain / cost_single if cost_single > 0 else 0.0
    if gain <= 0.0:
        f_stat, p = 0.0, 1.0
    elif cost_transition == 0.0:
        f_stat, p = math.inf, 0.0
    else:
        from scipy import stats  # imported here: scipy.stats takes a noticeable time to import

        f_stat = (gain / 2.0) / (cost_transition / (n_residuals - 3)) * (n_eff / n_residuals)
        p = float(stats.f.sf(f_stat, 2, n_eff - 3.0))
    significant, relevant = p < alpha, reduction >= min_reduction and gain >= min_gain
    worth = "" if n_effective is None else f", {n_eff:.0f} independent of {n_residuals} residuals"
    if significant and relevant:
        reason = (f"transition: the three-value fit lowers the cost by {reduction:.0%} ({gain:.4g}; "
                  f"F = {f_stat:.3g}, p = {p:.2g}{worth})")
    elif gain < min_gain:
        reason = f"no transition: the cost drops by only {gain:.3g} < min_gain = {min_gain:g}"
    elif not significant:
        reason = (f"no transition: the cost reduction of {reduction:.1%} is not significant (p = {p:.2g} >= "
                  f"{alpha:g}{worth})")
    else:
        reason = (f"no transition worth estimating: significant (p = {p:.2g}) but the cost drops by only "
                  f"{reduction:.1%} < {min_reduction:.0%}")
    return TransitionTest(transition=significant and relevant, cost_single=float(cost_single),
                          cost_transition=float(cost_transition), n_residuals=int(n_residuals),
                          n_effective=n_eff, f_statistic=float(f_stat), p_value=p, reduction=float(reduction),
                          reason=reason)


# -- a start for the three-value fit -------------------------------------------------------------------


def transition_start(problem: CalibrationProblem, single: Calibration) -> dict[str, float]:
    """Initial before, after and τ from the residuals of a one-value fit (one extra model run).

    At the one-value estimate s the weighted residuals r = √W (y − ŷ) are, to first order,
    r_i ≈ −J_i (θ(t_i) − s), with J_i = ∂r_i/∂θ taken by one forward difference (the parameter's first
    DuD step). If θ jumps from θ_b to θ_a at τ, g_i = J_i r_i ≈ −J_i² (θ_b − s) before τ and
    −J_i² (θ_a − s) after: opposite signs, since s lies between them. Their running sum over time,
    C(t) = Σ_{t_i ≤ t} g_i, starts and ends at 0 (the normal equation of the one-value fit) and is
    extreme at the transition (a CUSUM). The start τ is the middle between the observation time where
    |C| peaks and the next one, and before/after are the Gauss-Newton values of each side,
    s − Σ g / Σ J² (clipped to the bounds). A response that lags the change makes τ late by about the
    response time; the fit corrects it.

    Parameters
    ----------
    problem
        The one-value problem (one parameter).
    single
        Its calibration.

    Returns
    -------
    dict
        ``before``, ``after`` (the parameter's unit) and ``time`` (h since ``problem.start``).

    Raises
    ------
    ValueError
        For a problem with more than one parameter.
    """
    if len(problem.parameters) != 1:
        raise ValueError(f"transition_start needs a one-parameter problem, got {problem.parameters.names}")
    p = next(iter(problem.parameters))
    x_s = float(single.result.x[0])
    lb, ub = (float(b[0]) for b in problem.bounds)
    step = p.initial_step(p.from_x(x_s))
    step = step if x_s + step <= ub else -step
    n = problem.observations.n_values
    r0 = single.result.extra.get("residuals")
    r0 = np.asarray(r0 if r0 is not None else problem.residuals(np.array([x_s])))[:n]
    jac = (problem.residuals(np.array([x_s + step])) - r0) / step
    times = np.concatenate([o.times.as_unit("ns").asi8 for o in problem.observations])
    order = np.argsort(times, kind="stable")
    unique, where = np.unique(times[order], return_inverse=True)
    g = np.bincount(where, weights=(jac * r0)[order])
    jj = np.bincount(where, weights=(jac * jac)[order])
    middle = 0.5 * (problem.end - problem.start).total_seconds() / 3600.0
    if unique.size < 2 or not np.any(jj > 0):
        return {"before": p.from_x(x_s), "after": p.from_x(x_s), "time": middle}
    cusum = np.cumsum(g)[:-1]
    k = int(np.argmax(np.abs(cusum)))
    t_switch = 0.5 * (unique[k] + unique[k + 1])
    tau = float(t_switch - problem.start.value) / 3.6e12

    def side(sl: slice) -> float:
        den = jj[sl].sum()
        x = x_s - g[sl].sum() / den if den > 0 else x_s  # r ≈ r0 + J Δx → Δx = −Σ J r0 / Σ J²
        return p.from_x(min(max(x, lb), ub))

    return {"before": side(slice(0, k + 1)), "after": side(slice(k + 1, None)), "time": tau}
