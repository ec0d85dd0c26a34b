"""The DuD iteration shared by :func:`~rivercal.optimise.dud.dud` and :func:`~rivercal.optimise.sparse_dud.sparse_dud`.

DuD ("doesn't use derivatives", Ralston & Jennrich 1978) keeps a set of k + 1 evaluated points and
linearises the residual vector through them: r(x_b + δ) ≈ r_b + J δ, with J the secant Jacobian that
interpolates (DuD) or fits by least squares (Sparse DuD) the stored residual vectors. Each outer
iteration solves the bounded linear least-squares problem min ‖r_b + J δ‖², lb ≤ x_b + δ ≤ ub, caps
the step, and backtracks along it until the cost decreases; the new point replaces the worst stored
point. How this differs from OpenDA's implementation (reference note §1) is listed in :mod:`rivercal.optimise.dud`.

A *secant model* supplies what differs between the two methods: the perturbed points of a (re-)
initialisation, the Jacobian of a set of points (None when the set is degenerate) and the size of a
step in units of the set's spread (for ``max_rel_step``).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from scipy.optimize import lsq_linear

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    Stop,
    check_int,
    check_real,
    default_initial_step,
    option_vector,
    optional_array,
    project,
)
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, IterationRecord, OptimiseResult

log = logging.getLogger(__name__)

STATUS_ABS = 1
STATUS_REL = 2
STATUS_LINEAR = 3
STATUS_NO_DECREASE = 4
STATUS_LINE_SEARCH = 5
STATUS_ZERO_COST = 6
STATUS_ABS_FLOOR = 7
STATUS_DEGENERATE = -4

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_MAX_ITER: "The maximum number of outer iterations (max_outer) is reached.",
    STATUS_ABS: "T1: the cost decreased by no more than abs_tol in the last iteration.",
    STATUS_REL: "T2: the relative decrease of the cost in the last iteration is at most rel_tol.",
    STATUS_LINEAR: "T3: the relative decrease predicted by the linearised cost is at most rel_tol_linear.",
    STATUS_NO_DECREASE: "The secant model of a freshly re-initialised interpolation set predicts no decrease: "
                        "the (projected) gradient vanishes at the best point.",
    STATUS_LINE_SEARCH: "The line search found no lower cost along the step of a freshly re-initialised "
                        "interpolation set: the best point is a local minimum to the resolution of the secant model.",
    STATUS_ZERO_COST: "The cost is zero: the residuals vanish at the best point.",
    STATUS_ABS_FLOOR: "T1: the cost is at most abs_tol, so no further iteration can lower it by more than abs_tol.",
    STATUS_DEGENERATE: "The interpolation set stays degenerate after re-initialisation.",
}


@dataclass(frozen=True, slots=True)
class DudOptions:
    """Options of :func:`~rivercal.optimise.dud.dud` (defaults: thesis Table 4-3 where it gives them).

    Attributes
    ----------
    max_outer
        Maximum number of outer iterations (Table 4-3: 20).
    max_inner
        Maximum number of step reductions in the line search after the full step (Table 4-3: 5), so at
        most ``max_inner + 1`` evaluations per outer iteration.
    abs_tol
        T1: stop when an iteration lowers the cost by at most this much (Table 4-3: 1e-3), or as soon as
        the cost itself is at most this much (no iteration could then lower it by more). 0 disables.
    rel_tol
        T2: stop when an iteration lowers the cost by at most ``rel_tol`` times the new cost (1e-4).
    rel_tol_linear
        T3: stop when the linearised cost of the step, L, predicts a relative decrease
        (S_b − L)/S_b of at most this (1e-4).
    max_rel_step
        Cap on the step measured in units of the interpolation set's spread (‖α‖∞ with δ = Pα; 10).
    initial_step
        Perturbation per parameter that builds the k + 1 initial points (optimiser coordinates; the
        caller computes it from the offset transform, thesis Eq. 2-8, or the factor transform, Eq. 2-9).
        Default: 10 % of |x0| (10 % of a tenth of the bound range where x0 = 0).
    prior_mean, prior_std
        Weak constraint: extra residual rows (x − prior_mean)/prior_std are appended, so the cost becomes
        S + ‖(x − μ)/σ‖². Both or neither.
    shortening_factor
        Backtracking factor s of the line search (0.5): the trial steps are t = 1, s, s², ...
    negative_look_after
        After this many reductions the line search alternates to the opposite direction
        (OpenDA's default sequence 1, ½, ¼, ⅛, 1/16, −1/32, +1/64, ... is ``negative_look_after=4``).
    max_condition
        The interpolation set counts as degenerate when its (scaled, column-normalised) secant matrix has
        a condition number above this; it is then re-initialised around the best point.
    reinit_shrink
        After a failed line search the set is re-initialised with perturbations of
        ``reinit_shrink · min(initial_step, current spread)``.
    confirm_convergence
        When T1, T2 or T3 fires on an interpolation set that has aged (points from earlier iterations),
        re-initialise it around the best point (p runs, one batch) and stop only if the rule fires again
        on the fresh set. Secant models degrade as DuD converges; the fresh set removes premature stops
        (the "magic" restarts of OpenDA issue 449). False gives OpenDA's behaviour.
    parallel_line_search
        After the full step fails, evaluate all remaining trial steps as one batch (more model runs,
        same iterates, less wall time on parallel workers).
    """

    max_outer: int = 20
    max_inner: int = 5
    abs_tol: float = 1e-3
    rel_tol: float = 1e-4
    rel_tol_linear: float = 1e-4
    max_rel_step: float = 10.0
    initial_step: Any = None
    prior_mean: Any = None
    prior_std: Any = None
    shortening_factor: float = 0.5
    negative_look_after: int = 4
    max_condition: float = 1e7
    reinit_shrink: float = 0.3
    confirm_convergence: bool = True
    parallel_line_search: bool = False

    def __post_init__(self) -> None:
        check_int("max_outer", self.max_outer)
        check_int("max_inner", self.max_inner)
        check_int("negative_look_after", self.negative_look_after)
        for name in ("abs_tol", "rel_tol", "rel_tol_linear"):
            check_real(name, getattr(self, name))
        check_real("max_rel_step", self.max_rel_step, strict=True)
        check_real("shortening_factor", self.shortening_factor, strict=True, maximum=1.0 - 1e-12)
        check_real("max_condition", self.max_condition, 1.0, strict=True)
        check_real("reinit_shrink", self.reinit_shrink, strict=True, maximum=1.0)
        optional_array(self, "initial_step", positive=True)
        optional_array(self, "prior_mean")
        optional_array(self, "prior_std", positive=True)
        if (self.prior_mean is None) != (self.prior_std is None):
            raise ValueError("prior_mean and prior_std must be given together")
        for name in ("confirm_convergence", "parallel_line_search"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be a bool, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class DudState:
    """Everything needed to continue a DuD run exactly (``result.extra["state"]``).

    Pass it back as ``dud(..., restart=state)``. The run continues from the start of the iteration that
    was interrupted; the evaluations made in that iteration (``pending``) are replayed without new model
    runs, so an interrupted and restarted run makes the same model runs and reaches the same point as an
    uninterrupted one. Counters continue: ``max_outer`` and ``max_nfev`` apply to the whole run.

    Attributes
    ----------
    method
        ``"dud"`` or ``"sparse_dud"``.
    x0, initial_step
        Start point and unsigned initial perturbations.
    points, residuals, costs
        The interpolation set sorted by cost (row 0 best) with its residual vectors (without prior rows)
        and costs; None if the run stopped before the initial set was complete.
    nit, nfev, n_reinit
        Iterations, model runs and re-initialisations so far.
    fresh
        The set was just re-initialised after a failure (a second failure ends the run).
    history, evaluations
        The run's log so far.
    pending
        ``(x, residuals)`` evaluated after the snapshot, replayed on restart.
    cache
        Recently evaluated points at the snapshot (not rerun when requested again).
    model_state
        State of the secant model (the random generator of Sparse DuD).
    degenerate_streak
        Consecutive re-initialisations because the set was degenerate.
    """

    method: str
    x0: np.ndarray
    initial_step: np.ndarray
    points: np.ndarray | None
    residuals: np.ndarray | None
    costs: np.ndarray | None
    nit: int
    nfev: int
    n_reinit: int
    fresh: bool
    history: tuple[IterationRecord, ...]
    evaluations: tuple[tuple[np.ndarray, float], ...]
    pending: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    cache: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    model_state: Any = field(default=None)
    degenerate_streak: int = 0


class SecantModel(Protocol):
    """What differs between DuD and Sparse DuD."""

    def initial_points(self, x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> list[np.ndarray]:
        """Perturbed points around ``x`` (x itself excluded)."""

    def jacobian(self, points: np.ndarray, residuals: np.ndarray) -> np.ndarray | None:
        """Secant Jacobian of the set (row 0 best), or None if the set is degenerate."""

    def step_size(self, points: np.ndarray, delta: np.ndarray) -> float:
        """Size of ``delta`` in units of the set's spread (compared with ``max_rel_step``)."""

    def get_state(self) -> Any:
        """Model state for :class:`DudState`."""

    def set_state(self, state: Any) -> None:
        """Restore :meth:`get_state`."""


def prior_augment(opts: DudOptions, n: int) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """The weak-constraint rows (x − μ)/σ as an ``augment`` function for :class:`Run`, or None."""
    if opts.prior_mean is None:
        return None
    mean = _broadcast("prior_mean", opts.prior_mean, n)
    std = _broadcast("prior_std", opts.prior_std, n)

    def augment(x: np.ndarray, r: np.ndarray) -> np.ndarray:
        return np.concatenate([r, (x - mean) / std])

    return augment


def _broadcast(name: str, value: np.ndarray, n: int) -> np.ndarray:
    if value.shape[0] == 1:
        return np.full(n, float(value[0]))
    if value.shape[0] != n:
        raise ValueError(f"options.{name} must have length {n} (the length of x0), got {value.shape[0]}")
    return value


class DudEngine:
    """One DuD run: the interpolation set, the outer loop, the line search and the stopping rules."""

    def __init__(self, method: str, run: Run, model: SecantModel, opts: DudOptions, h0: np.ndarray):
        self.method, self.run, self.model, self.opts, self.h0 = method, run, model, opts, h0
        self.X: np.ndarray | None = None
        self.R: np.ndarray | None = None
        self.costs: np.ndarray | None = None
        self.fresh = False
        self.n_reinit = 0
        self.n_obs: int | None = None
        self.degenerate_streak = 0
        self._snapshot = self.snapshot()

    # ---- state --------------------------------------------------------------------------------
    def snapshot(self) -> DudState:
        """The state at this moment (taken at the start of every outer iteration)."""
        run = self.run
        n_obs = self.n_obs
        return DudState(
            method=self.method, x0=run.x0.copy(), initial_step=self.h0.copy(),
            points=None if self.X is None else self.X.copy(),
            residuals=None if self.R is None else self.R[:, :n_obs].copy(),
            costs=None if self.costs is None else self.costs.copy(),
            nit=run.nit, nfev=run.nfev, n_reinit=self.n_reinit, fresh=self.fresh,
            history=tuple(run.history), evaluations=tuple(run.evaluations),
            cache=run.cached(), model_state=self.model.get_state(), degenerate_streak=self.degenerate_streak,
        )

    def mark(self) -> None:
        """Take a snapshot and forget the evaluations kept for replay."""
        self._snapshot = self.snapshot()
        self.run.mark()

    def state_after_stop(self) -> DudState:
        """The last snapshot plus everything evaluated since (to replay on restart)."""
        return dataclasses.replace(self._snapshot, pending=tuple(self.run.since_mark),
                                   evaluations=tuple(self.run.evaluations), nfev=self.run.nfev)

    def restore(self, state: DudState) -> None:
        """Continue from ``state`` (validated by the caller)."""
        run = self.run
        run.nit, run.nfev = state.nit, state.nfev
        run.history, run.evaluations = list(state.history), list(state.evaluations)
        run.preload(state.cache, state.pending)
        self.n_reinit, self.fresh, self.degenerate_streak = state.n_reinit, state.fresh, state.degenerate_streak
        self.model.set_state(state.model_state)
        if state.pending:
            run.m = self.n_obs = len(state.pending[0][1])
        if state.points is not None:
            run.m = self.n_obs = state.residuals.shape[1]
            aug = [run.augment(x, r) if run.augment else r for x, r in zip(state.points, state.residuals, strict=True)]
            self._set(list(state.points), aug)
            run.best_x, run.best_cost, run.best_r = self.X[0].copy(), float(self.costs[0]), self.R[0].copy()
        self._snapshot = dataclasses.replace(state, pending=(), cache=state.cache)

    def _set(self, points: list[np.ndarray], residuals: list[np.ndarray]) -> None:
        costs = np.array([self.run.cost_of(r) for r in residuals])
        order = np.argsort(costs, kind="stable")
        self.X = np.array(points, dtype=float)[order]
        self.R = np.array(residuals, dtype=float)[order]
        self.costs = costs[order]
        if self.n_obs is None:
            self.n_obs = self.run.m

    # ---- the run ------------------------------------------------------------------------------
    def solve(self) -> int:
        """Iterate until a stopping rule fires; return the status (Stop propagates)."""
        if self.X is None:
            self.mark()
            x0 = self.run.x0
            points = [x0, *self.model.initial_points(x0, self.h0, self.run.lb, self.run.ub)]
            self._set(points, self.run.evaluate_many(points))
        while True:
            self.mark()
            status = self.iterate()
            if status is not None:
                self.mark()
                return status

    def iterate(self) -> int | None:
        """One outer iteration (or a re-initialisation); a status when the run ends."""
        opts, run = self.opts, self.run
        s_b = float(self.costs[0])
        if s_b == 0.0:
            return STATUS_ZERO_COST
        if s_b <= opts.abs_tol:  # T1 holds for every further iteration: stop without spending runs on it
            return STATUS_ABS_FLOOR
        if run.nit >= opts.max_outer:
            return STATUS_MAX_ITER
        jac = self.model.jacobian(self.X, self.R)
        if jac is None:
            self.degenerate_streak += 1
            if self.degenerate_streak > 2:
                return STATUS_DEGENERATE
            self.reinit(1.0, "degenerate interpolation set", fresh=False)
            return None
        self.degenerate_streak = 0
        delta, linear = self.step(jac)
        if not s_b - linear > 1e-14 * s_b:
            if self.fresh:
                return STATUS_NO_DECREASE
            self.reinit(opts.reinit_shrink, "no predicted decrease", fresh=True)
            return None
        from_fresh = self.fresh
        accepted = self.line_search(delta)
        if accepted is not None:
            self.replace_worst(*accepted)
            self.fresh = False
        run.iteration(self.X[0], self.costs[0], linear)
        if accepted is not None:
            status = self.converged(s_b, float(self.costs[0]), linear)
            if status is None or from_fresh or not opts.confirm_convergence or status == STATUS_ABS_FLOOR:
                return status
            self.reinit(1.0, "confirming convergence", fresh=True)
            return None
        if self.fresh:
            return STATUS_LINE_SEARCH
        self.reinit(opts.reinit_shrink, "line search failed", fresh=True)
        return None

    def step(self, jac: np.ndarray) -> tuple[np.ndarray, float]:
        """Bounded Gauss-Newton step of the secant model, capped; and its linearised cost."""
        x_b, r_b, run = self.X[0], self.R[0], self.run
        scale = self.spread()
        js = jac * scale
        lo, hi = (run.lb - x_b) / scale, (run.ub - x_b) / scale
        u = np.linalg.lstsq(js, -r_b, rcond=None)[0]
        if np.any(u < lo) or np.any(u > hi):
            u = lsq_linear(js, -r_b, bounds=(lo, hi), method="bvls").x
            u = np.clip(u, lo, hi)
        delta = u * scale
        size = self.model.step_size(self.X, delta)
        if size > self.opts.max_rel_step:
            delta *= self.opts.max_rel_step / size
        return delta, run.cost_of(r_b + jac @ delta)

    def spread(self) -> np.ndarray:
        """Per-parameter extent of the interpolation set around the best point (never zero)."""
        extent = np.max(np.abs(self.X[1:] - self.X[0]), axis=0)
        return np.where(extent >= np.finfo(float).tiny, extent, self.h0)

    def trial_factors(self) -> list[float]:
        """Step fractions t of the line search: 1, s, s², ..., alternating sign after ``negative_look_after``."""
        opts = self.opts
        factors = []
        for k in range(opts.max_inner + 1):
            t = opts.shortening_factor**k
            if k > opts.negative_look_after and (k - opts.negative_look_after) % 2 == 1:
                t = -t
            factors.append(t)
        return factors

    def trial_point(self, delta: np.ndarray, t: float) -> np.ndarray | None:
        """x_b + tδ; a reversed step that leaves the box is halved up to three times, else skipped."""
        x_b, lb, ub = self.X[0], self.run.lb, self.run.ub
        for _ in range(4):
            x = x_b + t * delta
            if t > 0 or (np.all(x >= lb) and np.all(x <= ub)):
                return project(x, lb, ub)
            t *= 0.5
        return None

    def line_search(self, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
        """Backtrack along δ; the first trial that beats the best point, or None if none does."""
        s_b, run = self.costs[0], self.run
        points = [p for p in (self.trial_point(delta, t) for t in self.trial_factors()) if p is not None]
        if self.opts.parallel_line_search:
            first = run.evaluate(points[0])
            residuals = [first] + (run.evaluate_many(points[1:]) if run.cost_of(first) >= s_b else [])
            for x, r in zip(points, residuals, strict=False):
                if run.cost_of(r) < s_b:
                    return x, r, run.cost_of(r)
            return None
        for x in points:
            r = run.evaluate(x)
            cost = run.cost_of(r)
            if cost < s_b:
                return x, r, cost
        return None

    def replace_worst(self, x: np.ndarray, r: np.ndarray, cost: float) -> None:
        """The accepted point replaces the worst stored point (Ralston & Jennrich 1978)."""
        points, residuals = list(self.X), list(self.R)
        points[-1], residuals[-1] = x, r
        self._set(points, residuals)

    def converged(self, s_old: float, s_new: float, linear: float) -> int | None:
        """Stopping rules T1, T2, T3 after an accepted step (also after backtracking)."""
        if s_new == 0.0:
            return STATUS_ZERO_COST
        if s_new <= self.opts.abs_tol:
            return STATUS_ABS_FLOOR
        drop = s_old - s_new
        if drop <= self.opts.abs_tol:
            return STATUS_ABS
        if drop <= self.opts.rel_tol * s_new:
            return STATUS_REL
        if s_old - linear <= self.opts.rel_tol_linear * s_old:
            return STATUS_LINEAR
        return None

    def reinit(self, shrink: float, reason: str, *, fresh: bool) -> None:
        """Fresh perturbations around the best point, evaluated as one batch."""
        x_b = self.X[0]
        extent = np.max(np.abs(self.X[1:] - x_b), axis=0)
        h = np.minimum(self.h0, np.where(extent > 0, extent, self.h0)) * shrink
        floor = 1e-12 * self.h0 + 4 * np.finfo(float).eps * np.abs(x_b)
        h = np.maximum(h, floor)
        points = self.model.initial_points(x_b, h, self.run.lb, self.run.ub)
        log.debug("%s: re-initialising the interpolation set (%s)", self.method, reason)
        residuals = self.run.evaluate_many(points)
        self._set([x_b, *points], [self.R[0], *residuals])
        self.n_reinit += 1
        self.fresh = fresh


def validate_restart(state: Any, method: str, n: int) -> DudState:
    """Check that ``restart`` is a DudState of this method and problem size."""
    if not isinstance(state, DudState):
        raise TypeError(f"restart must be a DudState (result.extra['state']), got {type(state).__name__}")
    if state.method != method:
        raise ValueError(f"restart state comes from {state.method!r}, not {method!r}")
    if state.x0.shape[0] != n:
        raise ValueError(f"restart state has {state.x0.shape[0]} parameters, x0 has {n}")
    return state


def run_dud(method: str, fun: Fun, x0: np.ndarray, lb: np.ndarray, ub: np.ndarray, *, opts: DudOptions,
            model: SecantModel, h0: np.ndarray, callback: Callback | None, batch: Batch | None,
            max_nfev: int | None, deadline: float | None, restart: DudState | None) -> OptimiseResult:
    """Run a DuD-type method and build its result."""
    if restart is not None:
        x0 = restart.x0.copy()   # the run continues from the state, whatever x0 the caller passes now
        if np.any((x0 < lb) | (x0 > ub)):
            raise ValueError("restart state has points outside the bounds [lb, ub]")
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback,
              augment=prior_augment(opts, x0.shape[0]), track_pending=True)
    engine = DudEngine(method, run, model, opts, h0)
    if restart is not None:
        if restart.points is not None and np.any((restart.points < lb) | (restart.points > ub)):
            raise ValueError("restart state has points outside the bounds [lb, ub]")
        engine.restore(restart)
    try:
        status = engine.solve()
        state = engine.snapshot()
    except Stop as stop:
        status = stop.status
        state = engine.state_after_stop()
    jac = None
    if engine.X is not None and engine.X.shape[0] > 1:
        jac = model.jacobian(engine.X, engine.R)
    extra = {"state": state, "n_reinit": engine.n_reinit, "initial_step": h0.copy()}
    return run.result(status, TERMINATION_MESSAGES, method, jac=jac, extra=extra)


def default_steps(opts: DudOptions, x0: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """``options.initial_step`` checked against the problem size, or the default perturbation."""
    h = option_vector("initial_step", opts.initial_step, x0.shape[0])
    return default_initial_step(x0, lb, ub) if h is None else h


__all__ = [
    "TERMINATION_MESSAGES",
    "DudEngine",
    "DudOptions",
    "DudState",
    "SecantModel",
    "default_steps",
    "run_dud",
    "validate_restart",
]
