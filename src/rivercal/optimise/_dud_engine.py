"""The DuD iteration shared by :func:`~rivercal.optimise.dud.dud` and :func:`~rivercal.optimise.sparse_dud.sparse_dud`.

DuD ("doesn't use derivatives", Ralston & Jennrich 1978) keeps a set of k + 1 evaluated points and
linearises the residual vector through them: r(x_b + δ) ≈ r_b + J δ, with J the secant Jacobian that
interpolates (DuD) or fits by least squares (Sparse DuD) the stored residual vectors. Each outer
iteration solves the bounded linear least-squares problem min ‖r_b + J δ‖², lb ≤ x_b + δ ≤ ub, caps
the step, and backtracks along it until the cost decreases; the new point replaces the worst stored
point. The stopping rules are in :mod:`._dud_stopping`, the options in :mod:`._dud_options`. How this
differs from OpenDA's implementation (reference note §1) is listed in :mod:`rivercal.optimise.dud`.

A *secant model* supplies what differs between the two methods: the perturbed points of a (re-)
initialisation, the Jacobian of a set of points (None when the set is degenerate), the size of a
step in units of the set's spread (for ``max_rel_step``) and a fresh Jacobian at the end.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from scipy.optimize import lsq_linear

from rivercal.optimise._core import Batch, Callback, Fun, Run, Stop, default_initial_step, option_vector, project
from rivercal.optimise._dud_options import (
    STATUS_DEGENERATE,
    STATUS_LINE_SEARCH,
    STATUS_NEGLIGIBLE,
    STATUS_NO_DECREASE,
    STATUS_ZERO_COST,
    TERMINATION_MESSAGES,
    DudOptions,
    DudState,
)
from rivercal.optimise._dud_stopping import AcceptedStep, negligible, openda_rules, rivercal_rules
from rivercal.optimise.result import STATUS_MAX_ITER, OptimiseResult

log = logging.getLogger(__name__)

#: Most Gauss-Newton steps with fresh Jacobians after the stop (see :meth:`DudEngine.polish`).
POLISH_ROUNDS = 3


class SecantModel(Protocol):
    """What differs between DuD and Sparse DuD."""

    def initial_points(self, x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> list[np.ndarray]:
        """Perturbed points around ``x`` (x itself excluded)."""

    def jacobian(self, points: np.ndarray, residuals: np.ndarray) -> np.ndarray | None:
        """Secant Jacobian of the set (row 0 best), or None if the set is degenerate."""

    def step_size(self, points: np.ndarray, delta: np.ndarray) -> float:
        """Size of ``delta`` in units of the set's spread (compared with ``max_rel_step``)."""

    def fresh_jacobian(self, run: Run, x: np.ndarray, r: np.ndarray, h: np.ndarray,
                       noise: np.ndarray | None) -> np.ndarray | None:
        """A new Jacobian at ``x`` (residuals ``r``) from perturbations of size ``h`` (runs through ``run``)."""

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
    """One DuD run: the interpolation set, the outer loop, the line search and when to stop."""

    def __init__(self, method: str, run: Run, model: SecantModel, opts: DudOptions, h0: np.ndarray):
        self.method, self.run, self.model, self.opts, self.h0 = method, run, model, opts, h0
        self.X: np.ndarray | None = None
        self.R: np.ndarray | None = None
        self.costs: np.ndarray | None = None
        self.fresh = False
        self.centred = False
        self.n_reinit = 0
        self.n_obs: int | None = None
        self.degenerate_streak = 0
        self.step_cost: float | None = None
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
            step_cost=self.step_cost, centred=self.centred,
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
        self.step_cost, self.centred = state.step_cost, state.centred
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

    @property
    def dof(self) -> int:
        """Residual rows (with prior rows) minus parameters, at least 1."""
        return max(1, self.R.shape[1] - self.X.shape[1])

    # ---- the run ------------------------------------------------------------------------------
    def solve(self) -> int:
        """Iterate until a stopping rule fires; return the status (Stop propagates)."""
        if self.X is None:
            self.mark()
            x0 = self.run.x0
            points = [x0, *self.model.initial_points(x0, self.h0, self.run.lb, self.run.ub)]
            residuals = self.run.evaluate_many(points)
            self.step_cost = self._step_cost(points, residuals)
            self._set(points, residuals)
            self.centred = True
        while True:
            self.mark()
            status = self.iterate()
            if status is not None:
                self.mark()
                return status

    def _step_cost(self, points: list[np.ndarray], residuals: list[np.ndarray]) -> float:
        """S_h: the smallest cost change one initial perturbation causes, ‖Δr_i‖² per (‖d_i / h‖∞)²."""
        changes = [float(np.sum((r - residuals[0]) ** 2)) / float(np.max(np.abs(p - points[0]) / self.h0)) ** 2
                   for p, r in zip(points[1:], residuals[1:], strict=True)]
        return min(changes) if changes else 0.0

    def iterate(self) -> int | None:
        """One outer iteration (or a re-initialisation); a status when the run ends."""
        opts, run = self.opts, self.run
        s_b = float(self.costs[0])
        if s_b == 0.0:
            return STATUS_ZERO_COST
        if opts.stopping == "rivercal" and negligible(opts, s_b, self.step_cost):
            return STATUS_NEGLIGIBLE   # e.g. a warm start already at the answer: no run is spent confirming it
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
        delta, j_delta, linear = self.step(jac)
        if not s_b - linear > 1e-14 * s_b:
            if self.fresh:
                return STATUS_NO_DECREASE
            self.reinit(opts.reinit_shrink, "no predicted decrease", fresh=True)
            return None
        from_fresh = self.fresh
        r_b = self.R[0]
        accepted = self.line_search(delta)
        if accepted is not None:
            x, r, cost, t, first = accepted
            self.replace_worst(x, r, cost)
            self.fresh = self.centred = False
        run.iteration(self.X[0], self.costs[0], linear)
        if accepted is None:
            if self.fresh:
                return STATUS_LINE_SEARCH
            self.reinit(opts.reinit_shrink, "line search failed", fresh=True)
            return None
        predicted = linear if t == 1.0 else float(run.cost_of(r_b + t * j_delta))
        step = AcceptedStep(s_old=s_b, s_new=float(self.costs[0]), linear=linear, first_trial=first,
                            shortened=t != 1.0, second_best=float(self.costs[1]), dof=self.dof, predicted=predicted)
        log.debug("%s: took %g of the step: cost %.6g -> %.6g, the secant model predicted %.6g (%.6g for the whole "
                  "step, which cost %.6g)", self.method, t, s_b, step.s_new, predicted, linear, first)
        if opts.stopping == "openda":
            return openda_rules(opts, step)
        status, refresh = rivercal_rules(opts, step, self.step_cost)
        if refresh:
            self.reinit(1.0, "small decrease after a shortened step", fresh=True)
            return None
        if status is None or from_fresh or not opts.confirm_convergence or status in (STATUS_ZERO_COST,
                                                                                         STATUS_NEGLIGIBLE):
            return status
        self.reinit(1.0, "confirming convergence", fresh=True)
        return None

    def step(self, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Bounded Gauss-Newton step δ of the secant model, capped; J δ; and the step's linearised cost."""
        delta = self.gauss_newton(jac, self.spread())
        size = self.model.step_size(self.X, delta)
        if size > self.opts.max_rel_step:
            delta *= self.opts.max_rel_step / size
        j_delta = jac @ delta
        return delta, j_delta, self.run.cost_of(self.R[0] + j_delta)

    def gauss_newton(self, jac: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """Argmin ‖r_b + J δ‖² subject to lb ≤ x_b + δ ≤ ub (solved in units of ``scale``)."""
        x_b, r_b, run = self.X[0], self.R[0], self.run
        js = jac * scale
        lo, hi = (run.lb - x_b) / scale, (run.ub - x_b) / scale
        u = np.linalg.lstsq(js, -r_b, rcond=None)[0]
        if np.any(u < lo) or np.any(u > hi):
            u = lsq_linear(js, -r_b, bounds=(lo, hi), method="bvls").x
            u = np.clip(u, lo, hi)
        return u * scale

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

    def trial_point(self, delta: np.ndarray, t: float) -> tuple[np.ndarray, float] | None:
        """x_b + tδ and t; a reversed step that leaves the box is halved up to three times, else skipped."""
        x_b, lb, ub = self.X[0], self.run.lb, self.run.ub
        for _ in range(4):
            x = x_b + t * delta
            if t > 0 or (np.all(x >= lb) and np.all(x <= ub)):
                return project(x, lb, ub), t
            t *= 0.5
        return None

    def line_search(self, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float, float] | None:
        """Backtrack along δ: the first trial (x, r, cost, t) that beats the best point, and the cost at t = 1."""
        s_b, run = self.costs[0], self.run
        trials = [p for p in (self.trial_point(delta, t) for t in self.trial_factors()) if p is not None]
        if self.opts.parallel_line_search:
            first = run.evaluate(trials[0][0])
            more = run.evaluate_many([x for x, _ in trials[1:]]) if run.cost_of(first) >= s_b else []
            residuals = [first, *more]
        else:
            residuals = []
            for x, _ in trials:
                residuals.append(run.evaluate(x))
                if run.cost_of(residuals[-1]) < s_b:
                    break
        first_cost = run.cost_of(residuals[0])
        for (x, t), r in zip(trials, residuals, strict=False):
            cost = run.cost_of(r)
            if cost < s_b:
                return x, r, cost, t, first_cost
        return None

    def replace_worst(self, x: np.ndarray, r: np.ndarray, cost: float) -> None:
        """The accepted point replaces the worst stored point (Ralston & Jennrich 1978)."""
        points, residuals = list(self.X), list(self.R)
        points[-1], residuals[-1] = x, r
        self._set(points, residuals)

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
        self.centred = True

    # ---- the end ------------------------------------------------------------------------------
    def final_jacobian(self, status: int) -> np.ndarray | None:
        """The Jacobian behind ``std``: the secant one, or a fresh one and Gauss-Newton steps with it.

        See ``DudOptions.final_jacobian``. Runs only after the run ended by its own rules (status > 0,
        other than a zero cost); a budget, deadline or callback that cuts it short leaves the secant one.
        """
        secant = self.model.jacobian(self.X, self.R) if self.X is not None and self.X.shape[0] > 1 else None
        mode = self.opts.final_jacobian
        if mode == "auto" and ((self.centred and self.n_reinit == 0) or self.opts.stopping == "openda"):
            mode = "secant"
        if status <= 0 or status == STATUS_ZERO_COST or mode == "secant":
            return secant
        h = self.jacobian_steps()
        try:
            jac = self.fresh_jacobian(h)
            if jac is not None and status != STATUS_NEGLIGIBLE:
                jac = self.polish(jac, h)
        except Stop:
            return secant
        return jac if jac is not None else secant

    def fresh_jacobian(self, h: np.ndarray) -> np.ndarray | None:
        """A fresh Jacobian at the best point (None if it is not finite)."""
        jac = self.model.fresh_jacobian(self.run, self.X[0].copy(), self.R[0].copy(), h, self.noise())
        return jac if jac is not None and np.all(np.isfinite(jac)) else None

    def polish(self, jac: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Gauss-Newton steps with fresh Jacobians (at most ``POLISH_ROUNDS``) while they lower the cost much.

        The stopping rules end the iterations where a step changes the cost little; near a minimum with
        non-zero residuals the secant iterations converge only linearly, and the point they stop at
        depends on the path (for Sparse DuD: on its random directions). A Gauss-Newton step with an
        accurate Jacobian (1 run) brings every path close to the same point; while such a step still
        lowers the cost by more than T1 or T2 allow, the Jacobian is taken again there and another step
        follows. The run keeps the best point evaluated; the Jacobian returned is the last one taken.
        """
        run, opts = self.run, self.opts
        for k in range(POLISH_ROUNDS):
            s = float(self.costs[0])
            delta = self.gauss_newton(jac, np.maximum(self.spread(), h))
            if not s - run.cost_of(self.R[0] + jac @ delta) > 1e-12 * s:
                break
            x = project(self.X[0] + delta, run.lb, run.ub)
            r = run.evaluate(x)
            s_new = run.cost_of(r)
            if not s_new < s:
                break
            self.replace_worst(x, r, s_new)
            drop = s - s_new
            if drop <= opts.abs_tol * s_new / self.dof or drop <= opts.rel_tol * s_new or k + 1 == POLISH_ROUNDS:
                break
            fresh = self.fresh_jacobian(h)
            if fresh is None:
                break
            jac = fresh
        return jac

    def jacobian_steps(self) -> np.ndarray:
        """``options.jacobian_step`` checked against the problem size, or 10⁻³ of the initial steps."""
        h = option_vector("jacobian_step", self.opts.jacobian_step, self.h0.shape[0])
        return 1e-3 * self.h0 if h is None else h

    def noise(self) -> np.ndarray | None:
        """``options.noise`` per augmented residual row (prior rows: no noise check, inf)."""
        if self.opts.noise is None:
            return None
        rows = self.R.shape[1]
        noise = np.full(rows, np.inf)
        value = self.opts.noise
        if value.shape[0] == 1:
            noise[: self.n_obs] = float(value[0])
        elif value.shape[0] == self.n_obs:
            noise[: self.n_obs] = value
        else:
            raise ValueError(f"options.noise must be a scalar or have one value per residual ({self.n_obs}), "
                             f"got {value.shape[0]}")
        return noise


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
    n_before = run.nfev
    jac = engine.final_jacobian(status) if engine.X is not None else None
    extra = {"state": state, "n_reinit": engine.n_reinit, "initial_step": h0.copy(),
             "final_jacobian_nfev": run.nfev - n_before}
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
