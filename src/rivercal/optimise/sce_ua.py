"""SCE-UA: Shuffled Complex Evolution (Duan, Sorooshian & Gupta 1992, 1994).

A population of s = p·m points (p complexes of m points, x0 among them, the rest drawn uniformly in the
box) is sorted and dealt into complexes (complex k gets ranks k, k + p, k + 2p, ...). Each complex
evolves by β competitive complex evolution (CCE) steps (Duan et al. 1994, step iv): q points are chosen,
the best one and q − 1 others with the trapezoidal probability 2(m + 1 − i)/(m(m + 1)) of their rank i;
the worst of them, u, is reflected through the centroid g of the others, r = 2g − u (a reflection that
leaves the box is replaced by a random point in the smallest box containing the complex); if r is not
better than u, the contraction (g + u)/2 is tried, and if that is not better either, a random point in
that smallest box replaces u ("mutation"). Then the complexes are shuffled and the process repeats.

The complexes are independent between two shuffles, so rivercal evolves them side by side: each CCE
generation's reflection points of *all* complexes go out as one ``batch``, then their contraction
points, then their mutation points. Random numbers are drawn in a fixed order from one seeded generator,
so a run is reproducible whatever ``batch`` does (OpenDA's SCE cannot be seeded, reference note §3).

Stopping (Duan et al. 1994): ``max_nfev``; the best cost improving by less than ``pcento`` percent over
the last ``kstop`` shuffling loops; the population converging in parameter space (normalised geometric
range < ``peps``); ``max_loops``.

Status codes (``TERMINATION_MESSAGES``): 1 ``pcento`` over ``kstop`` loops; 2 ``peps``; −3 ``max_loops``;
0 / −1 / −2 budget, callback, deadline.

References
----------
Duan, Q., Sorooshian, S. & Gupta, V. (1992). Effective and efficient global optimization for conceptual
rainfall-runoff models. Water Resources Research 28(4), 1015-1031.
Duan, Q., Sorooshian, S. & Gupta, V. K. (1994). Optimal use of the SCE-UA global optimization method for
calibrating watershed models. Journal of Hydrology 158, 265-284.
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
    option_vector,
    optional_array,
    require_finite_bounds,
    validate_controls,
    validate_problem,
)
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "SceOptions", "sce_ua"]

STATUS_NO_IMPROVEMENT = 1
STATUS_CONVERGED_SPACE = 2

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_MAX_ITER: "The maximum number of shuffling loops (max_loops) is reached.",
    STATUS_NO_IMPROVEMENT: "The best cost improved by less than pcento percent over the last kstop shuffling loops.",
    STATUS_CONVERGED_SPACE: "The population converged in parameter space (normalised geometric range < peps).",
}


@dataclass(frozen=True, slots=True)
class SceOptions:
    """Options of :func:`sce_ua` (p is the number of parameters).

    Attributes
    ----------
    n_complexes
        Number of complexes (default max(2, p)).
    points_per_complex
        m (default 2p + 1).
    points_per_subcomplex
        q (default p + 1).
    evolution_steps
        β, CCE steps per complex between shuffles (default 2p + 1).
    max_loops
        Maximum number of shuffling loops (default: no limit).
    kstop, pcento
        Stop when the best cost improved by less than ``pcento`` percent over ``kstop`` loops (10, 0.1).
    peps
        Stop when the normalised geometric range of the population is below this (1e-3).
    seed
        Seed of the random generator; None draws one from the OS (reported in ``extra["seed"]``).
    init_lb, init_ub
        Draw the initial population in this box (inside [lb, ub]) instead of the whole box, e.g. around
        x0 when the bounds are far wider than the region of interest. The search itself still ranges
        over [lb, ub]: reflections may leave the initial box.
    """

    n_complexes: int | None = None
    points_per_complex: int | None = None
    points_per_subcomplex: int | None = None
    evolution_steps: int | None = None
    max_loops: int | None = None
    kstop: int = 10
    pcento: float = 0.1
    peps: float = 1e-3
    seed: int | None = None
    init_lb: Any = None
    init_ub: Any = None

    def __post_init__(self) -> None:
        optional_array(self, "init_lb")
        optional_array(self, "init_ub")
        if (self.init_lb is None) != (self.init_ub is None):
            raise ValueError("init_lb and init_ub must be given together")
        for name, minimum in (("n_complexes", 1), ("points_per_complex", 2), ("points_per_subcomplex", 2),
                              ("evolution_steps", 1), ("max_loops", 1), ("seed", 0)):
            if getattr(self, name) is not None:
                check_int(name, getattr(self, name), minimum)
        check_int("kstop", self.kstop, 1)
        check_real("pcento", self.pcento)
        check_real("peps", self.peps)


class _Complexes:
    """The population dealt into p complexes of m points (arrays (p, m, n) and (p, m)), evolved together."""

    def __init__(self, run: Run, rng: np.random.Generator, p: int, m: int, q: int):
        self.run, self.rng, self.p, self.m, self.q = run, rng, p, m, q
        rank = np.arange(1, m + 1)
        self.weight = 2.0 * (m + 1 - rank) / (m * (m + 1))
        self.rows = np.arange(p)

    def deal(self, x: np.ndarray, f: np.ndarray) -> None:
        """Sort the population and deal it into complexes: complex k gets ranks k, k + p, ..."""
        order = np.argsort(f, kind="stable").reshape(self.m, self.p).T
        self.x, self.f = x[order], f[order]

    def gather(self) -> tuple[np.ndarray, np.ndarray]:
        """The population again, (p·m, n) and (p·m,)."""
        return self.x.reshape(-1, self.x.shape[2]).copy(), self.f.reshape(-1).copy()

    def select(self) -> np.ndarray:
        """Choose q distinct ranks per complex: the best, and q − 1 drawn with the trapezoidal probabilities.

        Drawing with replacement and rejecting duplicates (Duan's code) is sequential weighted sampling
        without replacement; the Efraimidis-Spirakis keys u^(1/w) give the same distribution in one go.
        """
        keys = self.rng.random((self.p, self.m - 1)) ** (1.0 / self.weight[1:])
        others = np.argsort(-keys, axis=1, kind="stable")[:, : self.q - 1] + 1
        return np.sort(np.hstack([np.zeros((self.p, 1), dtype=int), others]), axis=1)

    def _costs(self, points: np.ndarray) -> np.ndarray:
        return np.array([self.run.cost_of(r) for r in self.run.evaluate_many(list(points))])

    def _random_in_hull(self, which: np.ndarray) -> np.ndarray:
        """Uniform points in the smallest box around each complex in ``which``."""
        return self.rng.uniform(self.x[which].min(axis=1), self.x[which].max(axis=1))

    def cce_step(self) -> None:
        """One CCE generation of every complex: reflections, contractions, mutations, each one batch."""
        lb, ub, rows = self.run.lb, self.run.ub, self.rows
        sel = self.select()
        worst = sel[:, -1]
        x_worst, f_worst = self.x[rows, worst], self.f[rows, worst]
        centroid = self.x[rows[:, None], sel[:, :-1]].mean(axis=1)
        trial = 2.0 * centroid - x_worst
        outside = np.any((trial < lb) | (trial > ub), axis=1)
        if outside.any():
            trial[outside] = self._random_in_hull(rows[outside])
        cost = self._costs(trial)
        done = cost < f_worst
        new_x, new_f = trial, cost
        todo = rows[~done]
        if todo.size:
            contracted = 0.5 * (centroid[todo] + x_worst[todo])
            c_cost = self._costs(contracted)
            ok = c_cost < f_worst[todo]
            new_x[todo[ok]], new_f[todo[ok]] = contracted[ok], c_cost[ok]
            todo = todo[~ok]
            if todo.size:
                mutated = self._random_in_hull(todo)
                new_x[todo], new_f[todo] = mutated, self._costs(mutated)
        self.x[rows, worst], self.f[rows, worst] = new_x, new_f
        order = np.argsort(self.f, axis=1, kind="stable")
        self.x = np.take_along_axis(self.x, order[:, :, None], axis=1)
        self.f = np.take_along_axis(self.f, order, axis=1)


def _geometric_range(x: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> float:
    """exp(mean(log(range_j / (ub_j − lb_j)))) of the population (0 if a parameter collapsed)."""
    spread = (x.max(axis=0) - x.min(axis=0)) / (ub - lb)
    if np.any(spread <= 0):
        return 0.0
    return float(math.exp(np.mean(np.log(spread))))


def _no_improvement(best: list[float], kstop: int, pcento: float) -> bool:
    """Duan's criterion: change of the best cost over the last kstop loops, in percent of their mean."""
    if len(best) <= kstop:
        return False
    window = np.abs(best[-kstop - 1:])
    change = abs(best[-kstop - 1] - best[-1])
    mean = float(np.mean(window))
    return change == 0.0 or (mean > 0 and change * 100.0 / mean < pcento)


def sce_ua(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: SceOptions | dict | None = None,
           callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
           deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² globally with SCE-UA.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`; the bounds must be finite. The callback is called after
        every shuffling loop.
    options
        :class:`SceOptions` or a dict.

    Returns
    -------
    OptimiseResult
        Without Jacobian. ``extra`` holds ``seed``, ``n_complexes``, ``population`` and
        ``population_costs`` (the final population).
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    require_finite_bounds("sce_ua", lb, ub)
    opts = coerce_options(options, SceOptions)
    n = x0.shape[0]
    p = opts.n_complexes or max(2, n)
    m = opts.points_per_complex or 2 * n + 1
    q = opts.points_per_subcomplex or n + 1
    beta = opts.evolution_steps or 2 * n + 1
    if q > m:
        raise ValueError(f"points_per_subcomplex ({q}) must not exceed points_per_complex ({m})")
    seed = opts.seed if opts.seed is not None else int(np.random.SeedSequence().entropy % 2**63)
    rng = np.random.default_rng(seed)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    complexes = _Complexes(run, rng, p, m, q)
    lo, hi = _initial_box(opts, lb, ub)
    population = np.vstack([x0, rng.uniform(lo, hi, size=(p * m - 1, n))])
    extra: dict[str, Any] = {"seed": seed, "n_complexes": p}
    try:
        costs = np.array([run.cost_of(r) for r in run.evaluate_many(list(population))])
        status = _shuffle_loops(run, complexes, population, costs, opts, beta, extra)
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "sce_ua", extra=extra)


def _initial_box(opts: SceOptions, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box of the initial population: ``init_lb``/``init_ub`` (checked) or the bounds."""
    if opts.init_lb is None:
        return lb, ub
    lo = option_vector("init_lb", opts.init_lb, lb.shape[0])
    hi = option_vector("init_ub", opts.init_ub, lb.shape[0])
    if np.any(lo < lb) or np.any(hi > ub) or np.any(lo >= hi):
        raise ValueError("options.init_lb/init_ub must satisfy lb <= init_lb < init_ub <= ub")
    return lo, hi


def _shuffle_loops(run: Run, complexes: _Complexes, x: np.ndarray, f: np.ndarray, opts: SceOptions, beta: int,
                   extra: dict[str, Any]) -> int:
    """Evolve and shuffle until a stopping rule fires (the population is kept in ``extra``)."""
    best: list[float] = [float(f.min())]
    while True:
        complexes.deal(x, f)
        extra["population"], extra["population_costs"] = x, f
        for _ in range(beta):
            complexes.cce_step()
            extra["population"], extra["population_costs"] = complexes.gather()
        x, f = extra["population"], extra["population_costs"]
        best.append(float(f.min()))
        run.iteration(x[int(np.argmin(f))], best[-1])
        if _no_improvement(best, opts.kstop, opts.pcento):
            return STATUS_NO_IMPROVEMENT
        if _geometric_range(x, run.lb, run.ub) < opts.peps:
            return STATUS_CONVERGED_SPACE
        if opts.max_loops is not None and run.nit >= opts.max_loops:
            return STATUS_MAX_ITER
