"""DuD's options, restart state and status table (shared by DuD and Sparse DuD)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rivercal.optimise._core import check_choice, check_int, check_real, optional_array
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, IterationRecord

__all__ = [
    "STOPPING",
    "TERMINATION_MESSAGES",
    "DudOptions",
    "DudState",
]

STATUS_ABS = 1
STATUS_REL = 2
STATUS_LINEAR = 3
STATUS_NO_DECREASE = 4
STATUS_LINE_SEARCH = 5
STATUS_ZERO_COST = 6
STATUS_NEGLIGIBLE = 7
STATUS_DEGENERATE = -4

#: The two sets of stopping rules (see :class:`DudOptions`).
STOPPING = ("rivercal", "openda")

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_MAX_ITER: "The maximum number of outer iterations (max_outer) is reached.",
    STATUS_ABS: "T1: the cost decreased by no more than abs_tol (times the residual variance; OpenDA rules: "
                "absolute) in the last iteration.",
    STATUS_REL: "T2: the relative decrease of the cost in the last iteration is at most rel_tol.",
    STATUS_LINEAR: "T3: the relative decrease predicted by the linearised cost is at most rel_tol_linear.",
    STATUS_NO_DECREASE: "The secant model of a freshly re-initialised interpolation set predicts no decrease: "
                        "the (projected) gradient vanishes at the best point.",
    STATUS_LINE_SEARCH: "The line search found no lower cost along the step of a freshly re-initialised "
                        "interpolation set: the best point is a local minimum to the resolution of the secant model.",
    STATUS_ZERO_COST: "The cost is zero: the residuals vanish at the best point.",
    STATUS_NEGLIGIBLE: "The cost is negligible: at most negligible_cost times the cost change that one initial "
                       "perturbation causes, so the estimate is settled to a small fraction of that perturbation.",
    STATUS_DEGENERATE: "The interpolation set stays degenerate after re-initialisation.",
}


@dataclass(frozen=True, slots=True)
class DudOptions:
    """Options of :func:`~rivercal.optimise.dud.dud` (defaults: thesis Table 4-3 where it gives them).

    Every stopping rule of the default (``stopping="rivercal"``) set is invariant to a common scale of the
    weights: multiplying every σ by the same factor changes no iterate and no decision. The cost S = Σ r²
    of weighted residuals has no natural unit; the rules measure it against the fit's own scales:

    - s² = S/(m − p), the residual variance the fit shows (m residual rows, p parameters); with correct
      weights s² ≈ 1, and T1 is then the thesis' absolute rule;
    - S_h, the smallest cost change that one initial perturbation causes (from the first interpolation
      set: ‖r(x₀ + h_j e_j) − r(x₀)‖² for DuD).

    Attributes
    ----------
    max_outer
        Maximum number of outer iterations (Table 4-3: 20).
    max_inner
        Maximum number of step reductions in the line search after the full step (Table 4-3: 5), so at
        most ``max_inner + 1`` evaluations per outer iteration.
    abs_tol
        T1: stop when an iteration lowers the cost by at most ``abs_tol`` · s² (Table 4-3: 1e-3): the
        estimate moved by about √abs_tol of its standard error. 0 disables.
    rel_tol
        T2: stop when an iteration lowers the cost by at most ``rel_tol`` times the new cost (1e-4).
    rel_tol_linear
        T3: stop when the linearised cost of the step, L, predicts a relative decrease
        (S_b − L)/S_b of at most this (1e-4).
    negligible_cost
        Stop at once when the cost is at most this times S_h (1e-6): the misfit left is what a move of
        about √negligible_cost initial perturbations would cause (a noise-free twin fitted to round-off,
        or a warm start that is already at the answer). 0 disables.
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
    stall_ratio
        After a line search that had to shorten its step, re-initialise the set around the best point
        when the cost fell by at most this fraction of the decrease the secant model predicted for the
        shortened step, or when the model predicted no decrease for it (a reversed step): the model no
        longer describes the cost along its own step. 0 (default) disables it; e.g. 0.01 for a model
        whose runs are so expensive that a re-initialisation's batch (p runs, Sparse DuD's k + 1) on
        parallel workers costs less than more shortened steps in a row (``stopping="rivercal"`` only). It
        may stop a hard problem early: on the NIST problems it saved 28 % of the runs, but ended ENSO from
        start 1 at 3.2 correct digits (5.7 without).
    reinit_shrink
        After a failed line search the set is re-initialised with perturbations of
        ``reinit_shrink · min(initial_step, current spread)``.
    confirm_convergence
        When T1, T2 or T3 fires on an interpolation set that has aged (points from earlier iterations),
        re-initialise it around the best point (p runs, one batch) and stop only if the rule fires again
        on the fresh set. Secant models degrade as DuD converges; the fresh set removes premature stops
        (the unexplained restarts reported against OpenDA's DuD). False stops on the aged set at once (this is not
        OpenDA's behaviour: use ``stopping="openda"`` for that).
    stopping
        ``"rivercal"`` (default): the rules above, and T1 and T2 never fire right after a line search that
        had to shorten its step (a shortened step lowers the cost little because it is short, not
        because the minimum is near). ``"openda"``: OpenDA's rules (reference note §1): after every
        accepted step, with d = ½(S₁ − S₀) the gap between the two best stored costs in OpenDA's cost
        ½ S, stop when d ≤ ``abs_tol`` (absolute, so not invariant to the scale of the weights),
        d ≤ ``rel_tol`` · ½ S₀, or ε_lin = |S_try − L| / |S₀ − L| of the full step ≤ ``rel_tol_linear``;
        never after a step that backtracked; no confirmation round and no ``negligible_cost`` rule.
    final_jacobian
        Where ``jac``, ``std`` and ``correlation`` come from. ``"auto"`` (default): from the secant
        model when the run stopped on its initial set (e.g. a warm start already at the answer), and with
        OpenDA's rules; otherwise from a fresh finite-difference Jacobian at the best point with steps
        ``jacobian_step`` (DuD: forward differences, p runs; Sparse DuD: central differences along its
        k + 1 mixed directions, 2(k + 1) runs, or DuD's p runs where that is no more), followed by a
        Gauss-Newton step with it (1 run) that is kept if it lowers the cost; while such a step lowers the
        cost by more than T1 or T2 allow, the Jacobian is taken again there and another step follows (at
        most 3 rounds; none after a negligible cost). ``"fresh"``: always so; ``"secant"``: never (the aged
        secant Jacobian can be far off near convergence, and the point the secant iterations stop at
        depends on their path).
    jacobian_step
        Difference steps of that Jacobian (optimiser coordinates; default 10⁻³ · ``initial_step``).
        Choose them above the model's numerical noise; see ``noise``.
    noise
        Size of the numerical jitter of each residual (weighted units; scalar or one per residual row):
        a column of the final Jacobian whose difference is below 10 times this is taken again with a
        larger step. None: no check.
    parallel_line_search
        After the full step fails, evaluate all remaining trial steps as one batch (more model runs,
        same iterates, less wall time on parallel workers).
    """

    max_outer: int = 20
    max_inner: int = 5
    abs_tol: float = 1e-3
    rel_tol: float = 1e-4
    rel_tol_linear: float = 1e-4
    negligible_cost: float = 1e-6
    max_rel_step: float = 10.0
    initial_step: Any = None
    prior_mean: Any = None
    prior_std: Any = None
    shortening_factor: float = 0.5
    negative_look_after: int = 4
    max_condition: float = 1e7
    reinit_shrink: float = 0.3
    stall_ratio: float = 0.0
    confirm_convergence: bool = True
    stopping: str = "rivercal"
    final_jacobian: str = "auto"
    jacobian_step: Any = None
    noise: Any = None
    parallel_line_search: bool = False

    def __post_init__(self) -> None:
        check_int("max_outer", self.max_outer)
        check_int("max_inner", self.max_inner)
        check_int("negative_look_after", self.negative_look_after)
        for name in ("abs_tol", "rel_tol", "rel_tol_linear", "negligible_cost"):
            check_real(name, getattr(self, name))
        check_real("max_rel_step", self.max_rel_step, strict=True)
        check_real("shortening_factor", self.shortening_factor, strict=True, maximum=1.0 - 1e-12)
        check_real("max_condition", self.max_condition, 1.0, strict=True)
        check_real("reinit_shrink", self.reinit_shrink, strict=True, maximum=1.0)
        check_real("stall_ratio", self.stall_ratio, maximum=1.0)
        check_choice("stopping", self.stopping, STOPPING)
        check_choice("final_jacobian", self.final_jacobian, ("auto", "fresh", "secant"))
        optional_array(self, "initial_step", positive=True)
        optional_array(self, "jacobian_step", positive=True)
        optional_array(self, "noise", positive=True)
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
    step_cost
        S_h of the ``negligible_cost`` rule (None before the first set is complete).
    centred
        Every point of the set is a perturbation of the best point (no step accepted since the last
        (re-)initialisation).
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
    step_cost: float | None = None
    centred: bool = False
