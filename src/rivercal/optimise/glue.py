"""GLUE: Generalised Likelihood Uncertainty Estimation (Beven & Binley 1992).

1. Draw ``n_samples`` parameter sets by Latin-hypercube sampling of the box [lb, ub]
   (:class:`scipy.stats.qmc.LatinHypercube`, seeded) and evaluate them in chunks of ``batch``.
2. Give each a likelihood L from its cost S = Σ r² (m residuals, S_min the smallest sampled cost):

   ============== ============================================================================
   ``"exp"``      L = exp(−shape · S / S_min)   (Beven & Binley's exponential form, default)
   ``"gaussian"`` L = exp(−(S − S_min)/2)       (the formal likelihood for r = (y − ŷ)/σ)
   ``"inverse"``  L = (S/m)^(−shape)            (inverse error variance, Beven & Binley 1992)
   ``"nse"``      L = 1 − S / reference_cost    (Nash-Sutcliffe efficiency; reference_cost is
                                                 Σ w(y − ȳ)², the cost of the mean-observation model)
   callable       L = likelihood(r), called with each residual vector
   ============== ============================================================================

3. Keep the *behavioural* sets: L ≥ ``threshold`` when given, else the best ``behavioural_fraction``
   of the samples. Normalise their likelihoods to weights.
4. Report likelihood-weighted parameter quantiles (5/50/95 % by default) and, when ``predictions``
   (x ↦ prediction vector) is given, likelihood-weighted prediction bounds from the behavioural sets.

x0 is evaluated first (it validates the problem and may be the best point) but is not one of the
samples. OpenDA's GLUE only writes the prior draws to a CSV (reference note §4); this is the complete
method. Status codes (``TERMINATION_MESSAGES``): 1 every sample evaluated; 0 / −1 / −2 budget, callback,
deadline (the statistics then use the samples evaluated so far).

References
----------
Beven, K. & Binley, A. (1992). The future of distributed models: model calibration and uncertainty
prediction. Hydrological Processes 6(3), 279-298.
McKay, M. D., Beckman, R. J. & Conover, W. J. (1979). A comparison of three methods for selecting values
of input variables in the analysis of output from a computer code. Technometrics 21(2), 239-245.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    Stop,
    check_choice,
    check_int,
    check_real,
    coerce_options,
    require_finite_bounds,
    validate_controls,
    validate_problem,
)
from rivercal.optimise.result import COMMON_MESSAGES, OptimiseResult

__all__ = ["LIKELIHOODS", "TERMINATION_MESSAGES", "GlueOptions", "glue", "weighted_quantiles"]

LIKELIHOODS = ("exp", "gaussian", "inverse", "nse")

STATUS_DONE = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_DONE: "Every sample was evaluated.",
}


@dataclass(frozen=True, slots=True)
class GlueOptions:
    """Options of :func:`glue` (see the module docstring for the likelihoods).

    Attributes
    ----------
    n_samples
        Number of Latin-hypercube samples (1000).
    seed
        Seed of the sampler; None draws one (reported in ``extra["seed"]``).
    likelihood
        ``"exp"``, ``"gaussian"``, ``"inverse"``, ``"nse"`` or a callable r ↦ L ≥ 0.
    shape
        Shape factor N of ``"exp"`` and ``"inverse"`` (1).
    reference_cost
        Cost of the no-skill model for ``"nse"`` (required there).
    threshold
        Behavioural threshold on L; None: keep the best ``behavioural_fraction``.
    behavioural_fraction
        Fraction of samples kept when ``threshold`` is None (0.1).
    quantiles
        Probabilities of the reported quantiles ((0.05, 0.5, 0.95)).
    chunk_size
        Samples per batch (1000).
    """

    n_samples: int = 1000
    seed: int | None = None
    likelihood: str | Callable[[np.ndarray], float] = "exp"
    shape: float = 1.0
    reference_cost: float | None = None
    threshold: float | None = None
    behavioural_fraction: float = 0.1
    quantiles: tuple[float, ...] = (0.05, 0.5, 0.95)
    chunk_size: int = 1000

    def __post_init__(self) -> None:
        check_int("n_samples", self.n_samples, 1)
        check_int("chunk_size", self.chunk_size, 1)
        if self.seed is not None:
            check_int("seed", self.seed)
        if not callable(self.likelihood):
            check_choice("likelihood", self.likelihood, LIKELIHOODS)
        check_real("shape", self.shape, strict=True)
        if self.likelihood == "nse":
            if self.reference_cost is None:
                raise ValueError("likelihood 'nse' needs reference_cost (the cost of the mean-observation model)")
            check_real("reference_cost", self.reference_cost, strict=True)
        if self.threshold is not None:
            check_real("threshold", self.threshold, -np.inf)
        check_real("behavioural_fraction", self.behavioural_fraction, strict=True, maximum=1.0)
        quantiles = tuple(float(q) for q in self.quantiles)
        if not quantiles or any(not 0.0 <= q <= 1.0 for q in quantiles):
            raise ValueError(f"quantiles must be probabilities in [0, 1], got {self.quantiles!r}")
        object.__setattr__(self, "quantiles", quantiles)


def weighted_quantiles(values: np.ndarray, weights: np.ndarray, probabilities: tuple[float, ...]) -> np.ndarray:
    """Quantiles of ``values`` (k, ...) along axis 0 under ``weights`` (k,), one row per probability.

    The weighted empirical distribution puts the i-th sorted value at cumulative probability
    (W_i − w_i/2)/W (midpoint rule); quantiles interpolate linearly between those points. Values with
    zero weight are ignored.
    """
    values = np.asarray(values, dtype=float)
    keep = np.asarray(weights) > 0
    flat = values.reshape(values.shape[0], -1)[keep]
    weights = np.asarray(weights, dtype=float)[keep]
    out = np.empty((len(probabilities), flat.shape[1]))
    for j in range(flat.shape[1]):
        order = np.argsort(flat[:, j], kind="stable")
        w = weights[order]
        cdf = (np.cumsum(w) - 0.5 * w) / np.sum(w)
        out[:, j] = np.interp(probabilities, cdf, flat[order, j])
    return out.reshape((len(probabilities), *values.shape[1:]))


def _likelihood(opts: GlueOptions, costs: np.ndarray, custom: np.ndarray, m: int) -> np.ndarray:
    """L per sample (NaN where not evaluated)."""
    if callable(opts.likelihood):
        return custom
    s_min = np.nanmin(costs)
    if opts.likelihood == "exp":
        return np.exp(-opts.shape * costs / s_min) if s_min > 0 else (costs == 0).astype(float)
    if opts.likelihood == "gaussian":
        return np.exp(-(costs - s_min) / 2.0)
    if opts.likelihood == "inverse":
        with np.errstate(divide="ignore"):
            return (costs / m) ** (-opts.shape)
    return 1.0 - costs / opts.reference_cost


def _behavioural(opts: GlueOptions, like: np.ndarray) -> np.ndarray:
    """Mask of the behavioural samples (finite, positive likelihood above the threshold or in the top fraction)."""
    valid = np.isfinite(like) & (like > 0)
    if opts.threshold is not None:
        return valid & (like >= opts.threshold)
    keep = max(1, round(opts.behavioural_fraction * np.count_nonzero(np.isfinite(like))))
    order = np.argsort(np.where(valid, -like, np.inf), kind="stable")[:keep]
    mask = np.zeros(like.shape, dtype=bool)
    mask[order] = True
    return mask & valid


def _statistics(opts: GlueOptions, samples: np.ndarray, costs: np.ndarray, custom: np.ndarray, m: int,
                predictions: Callable[[np.ndarray], Any] | None) -> dict[str, Any]:
    """Likelihoods, behavioural mask, weights, parameter and prediction quantiles."""
    like = _likelihood(opts, costs, custom, m)
    mask = _behavioural(opts, like)
    weights = np.where(mask, like, 0.0)
    stats: dict[str, Any] = {"likelihood": like, "behavioural": mask}
    if not mask.any():
        stats["weights"] = weights
        return stats
    weights = weights / weights.sum()
    stats["weights"] = weights
    rows = weighted_quantiles(samples[mask], weights[mask], opts.quantiles)
    stats["quantiles"] = dict(zip(opts.quantiles, rows, strict=True))
    if predictions is not None:
        simulated = np.array([np.asarray(predictions(x), dtype=float) for x in samples[mask]])
        rows = weighted_quantiles(simulated, weights[mask], opts.quantiles)
        stats["prediction_quantiles"] = dict(zip(opts.quantiles, rows, strict=True))
    return stats


def _score(opts: GlueOptions, run: Run, costs: np.ndarray, custom: np.ndarray, start: int,
           residuals: list[np.ndarray | None]) -> None:
    """Store cost (and a callable likelihood) of each evaluated sample of a chunk."""
    for i, r in enumerate(residuals):
        if r is not None:
            costs[start + i] = run.cost_of(r)
            if callable(opts.likelihood):
                custom[start + i] = float(opts.likelihood(r))


def glue(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: GlueOptions | dict | None = None,
         callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
         deadline: float | None = None, predictions: Callable[[np.ndarray], Any] | None = None) -> OptimiseResult:
    """GLUE: sample, weigh by likelihood, and report the best set and the uncertainty bounds.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`; the bounds must be finite. The callback is called after
        every chunk.
    options
        :class:`GlueOptions` or a dict.
    predictions
        Optional ``x -> prediction vector`` (e.g. simulated levels for a forecast period), called once
        per behavioural sample after the sampling (serially, not counted in ``nfev``).

    Returns
    -------
    OptimiseResult
        ``x`` is the best evaluated point. ``extra``: ``samples`` (N, p), ``costs``, ``likelihood``,
        ``behavioural`` (mask), ``weights`` (sum 1 over the behavioural sets), ``quantiles``
        ({probability: parameter vector}), ``prediction_quantiles`` ({probability: vector}, with
        ``predictions``), ``seed``.
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    require_finite_bounds("glue", lb, ub)
    opts = coerce_options(options, GlueOptions)
    if predictions is not None and not callable(predictions):
        raise TypeError("predictions must be callable or None")
    seed = opts.seed if opts.seed is not None else int(np.random.SeedSequence().entropy % 2**63)
    # imported here: scipy.stats adds ~0.7 s to every process that imports rivercal.optimise
    from scipy.stats import qmc

    sampler = qmc.LatinHypercube(d=x0.shape[0], rng=np.random.default_rng(seed))
    samples = qmc.scale(sampler.random(opts.n_samples), lb, ub)
    costs = np.full(opts.n_samples, np.nan)
    custom = np.full(opts.n_samples, np.nan)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    try:
        for start in range(0, opts.n_samples, opts.chunk_size):
            chunk = list(samples[start:start + opts.chunk_size])
            lead = [x0] if start == 0 else []
            try:
                residuals = run.evaluate_many(lead + chunk)[len(lead):]
            except Stop as stop:
                _score(opts, run, costs, custom, start, (stop.partial or [])[len(lead):])
                raise
            _score(opts, run, costs, custom, start, residuals)
            run.iteration(run.best_x, run.best_cost)
        status = STATUS_DONE
    except Stop as stop:
        status = stop.status
    extra: dict[str, Any] = {"samples": samples, "costs": costs, "seed": seed}
    if np.any(np.isfinite(costs)):
        extra.update(_statistics(opts, samples, costs, custom, run.m or 1, predictions))
    return run.result(status, TERMINATION_MESSAGES, "glue", extra=extra)
