"""Machinery shared by the optimisers: validation, the run log, budgets (differences: :mod:`.jacobian`).

An algorithm never calls ``fun`` itself: it asks a :class:`Run` to evaluate one point or a batch of
points. The run checks the bounds, the evaluation budget and the deadline, validates the residuals,
records every evaluation, remembers the best point, and raises :class:`Stop` when the run must end from
outside the algorithm (budget, deadline, callback). The algorithm catches :class:`Stop` at its top level
and reports the best point so far.
"""

from __future__ import annotations

import dataclasses
import difflib
import logging
import math
import numbers
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

from rivercal.optimise.jacobian import parameter_statistics
from rivercal.optimise.result import (
    ABORT_STATUSES,
    STATUS_CALLBACK,
    STATUS_DEADLINE,
    STATUS_MAX_NFEV,
    IterationRecord,
    NonFiniteResidualsError,
    OptimiseResult,
)

log = logging.getLogger(__name__)

Fun = Callable[[np.ndarray], np.ndarray]
Batch = Callable[[list[np.ndarray]], Sequence[np.ndarray]]
Callback = Callable[[IterationRecord], Any]
OptionsT = TypeVar("OptionsT")

_CACHE_SIZE = 16


class Stop(Exception):
    """Internal signal: end the run now with ``status`` (budget, deadline or callback).

    ``partial`` holds, when the budget or the deadline ran out inside a batch, the residuals of the points of
    that batch that were run (None for the others), so that samplers can keep them.
    """

    def __init__(self, status: int, partial: list[np.ndarray | None] | None = None):
        super().__init__(status)
        self.status = status
        self.partial = partial


# --------------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------------


def as_vector(name: str, value: Any, n: int | None = None) -> np.ndarray:
    """Return ``value`` as a 1-D float array (scalars broadcast to length ``n``); ValueError naming ``name``."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0 and n is not None:
        arr = np.full(n, float(arr))
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have length {n} (the length of x0), got {arr.shape[0]}")
    return arr.copy()


def validate_problem(x0: Any, lb: Any, ub: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check x0 and the bounds like ``scipy.optimize.least_squares`` does; return float copies."""
    x0 = np.asarray(x0, dtype=float)
    if x0.ndim == 0:
        x0 = x0.reshape(1)
    x0 = as_vector("x0", x0)
    n = x0.shape[0]
    if n == 0:
        raise ValueError("x0 must have at least one element")
    if not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be finite, got {x0}")
    lb = as_vector("lb", lb, n)
    ub = as_vector("ub", ub, n)
    for name, bound in (("lb", lb), ("ub", ub)):
        if np.any(np.isnan(bound)):
            raise ValueError(f"{name} contains NaN at index {int(np.flatnonzero(np.isnan(bound))[0])}")
    bad = np.flatnonzero(~(lb < ub))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"each lb must be strictly less than ub; at index {i} lb={float(lb[i])!r}, "
                         f"ub={float(ub[i])!r}")
    bad = np.flatnonzero((x0 < lb) | (x0 > ub))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"x0 is infeasible: x0[{i}]={float(x0[i])!r} is outside [lb, ub] = "
                         f"[{float(lb[i])!r}, {float(ub[i])!r}]")
    return x0, lb, ub


def require_finite_bounds(method: str, lb: np.ndarray, ub: np.ndarray) -> None:
    """Raise ValueError when a sampling method gets an infinite bound."""
    for name, bound in (("lb", lb), ("ub", ub)):
        bad = np.flatnonzero(~np.isfinite(bound))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"{method} needs finite bounds; {name}[{i}]={float(bound[i])!r}")


def validate_controls(max_nfev: Any, deadline: Any, callback: Any, batch: Any, fun: Any) -> None:
    """Check the keyword arguments every optimiser shares."""
    if not callable(fun):
        raise TypeError(f"fun must be callable, got {type(fun).__name__}")
    if max_nfev is not None and (isinstance(max_nfev, bool) or not isinstance(max_nfev, numbers.Integral)
                                 or max_nfev < 1):
        raise ValueError(f"max_nfev must be None or a positive integer, got {max_nfev!r}")
    if deadline is not None and (isinstance(deadline, bool) or not isinstance(deadline, numbers.Real)
                                 or not math.isfinite(deadline) or deadline <= 0):
        raise ValueError(f"deadline must be None or a positive number of seconds, got {deadline!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {type(callback).__name__}")
    if batch is not None and not callable(batch):
        raise TypeError(f"batch must be callable or None, got {type(batch).__name__}")


def coerce_options(options: Any, cls: type[OptionsT]) -> OptionsT:
    """Turn ``None``, an instance of ``cls`` or a mapping into an instance of the options dataclass.

    Unknown keys raise ValueError naming the key (and the closest valid name); OpenDA silently ignores
    misspelled options, rivercal does not.
    """
    if options is None:
        return cls()
    if isinstance(options, cls):
        return options
    if isinstance(options, Mapping):
        names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        for key in options:
            if key not in names:
                close = difflib.get_close_matches(str(key), names, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise ValueError(f"unknown option {key!r} for {cls.__name__}{hint} Valid options: {', '.join(names)}")
        return cls(**options)
    raise TypeError(f"options must be None, a {cls.__name__} or a dict, got {type(options).__name__}")


def check_int(name: str, value: Any, minimum: int = 0) -> None:
    """ValueError unless ``value`` is an integer ≥ ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def check_real(name: str, value: Any, minimum: float = 0.0, *, strict: bool = False, maximum: float = math.inf) -> None:
    """ValueError unless ``value`` is a finite real in [minimum, maximum] (or (minimum, maximum] if strict)."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (value > minimum if strict else value >= minimum) and value <= maximum
    if not ok:
        relation = ">" if strict else ">="
        upper = f" and <= {maximum}" if math.isfinite(maximum) else ""
        raise ValueError(f"{name} must be a finite number {relation} {minimum}{upper}, got {value!r}")


def check_choice(name: str, value: Any, choices: Sequence[str]) -> None:
    """ValueError unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}; got {value!r}")


def optional_array(owner: Any, name: str, *, positive: bool = False) -> None:
    """Convert an optional array-valued option of a frozen dataclass to a read-only float array."""
    value = getattr(owner, name)
    if value is None:
        return
    arr = np.array(value, dtype=float, ndmin=1)
    if arr.ndim != 1 or not np.all(np.isfinite(arr)) or (positive and np.any(arr <= 0)):
        kind = "positive finite numbers" if positive else "finite numbers"
        raise ValueError(f"{name} must be a 1-D array of {kind}, got {value!r}")
    arr.setflags(write=False)
    object.__setattr__(owner, name, arr)


def option_vector(name: str, value: np.ndarray | None, n: int) -> np.ndarray | None:
    """Check that an array option matches the problem size (scalars broadcast)."""
    if value is None:
        return None
    if value.shape[0] == 1 and n != 1:
        return np.full(n, float(value[0]))
    if value.shape[0] != n:
        raise ValueError(f"options.{name} must have length {n} (the length of x0), got {value.shape[0]}")
    return np.array(value, dtype=float)


# --------------------------------------------------------------------------------------------------
# scales, steps and bounds
# --------------------------------------------------------------------------------------------------


def default_scale(x0: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """Typical magnitude per parameter: |x0|, or a tenth of the bound range (1 if unbounded) where x0 = 0."""
    width = ub - lb
    fallback = np.where(np.isfinite(width), 0.1 * width, 1.0)
    return np.where(x0 != 0.0, np.abs(x0), fallback)


def default_initial_step(x0: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """The perturbation used when the caller gives none: 10 % of :func:`default_scale`."""
    return 0.1 * default_scale(x0, lb, ub)


def project(x: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """Clip into the box (used to remove round-off from steps that were computed to be feasible)."""
    return np.minimum(np.maximum(x, lb), ub)


# --------------------------------------------------------------------------------------------------
# the run log
# --------------------------------------------------------------------------------------------------


def start_first(n: int, keep: int | None) -> list[int]:
    """The indices 0 … n-1 with ``keep`` (a batch's kept start point) moved to the front."""
    order = list(range(n))
    if keep is not None:
        order.remove(keep)
        order.insert(0, keep)
    return order


def until_deadline(points: Sequence[np.ndarray], deadline: float, keep: int | None,
                   run: Callable[[list[np.ndarray]], Sequence[np.ndarray]], width: int = 1) -> list[np.ndarray | None]:
    """``run`` over ``points`` in groups of ``width``, no group started after ``deadline`` (``time.monotonic``).

    The point ``keep`` goes first and runs whatever the time (alone, when the deadline has passed); a group
    that is running at the deadline finishes. Each group is in the order of the points. None for the points
    not run. This is ``batch.within`` for batches that run in this process (the serial default here, and
    :meth:`rivercal.evaluate.Evaluator.within`).
    """
    order = start_first(len(points), keep)
    out: list[np.ndarray | None] = [None] * len(points)
    n = 0
    while n < len(order):
        late = time.monotonic() >= deadline
        if late and not (n == 0 and keep is not None):
            break
        group = sorted(order[n: n + (1 if late else width)])
        for i, r in zip(group, run([points[i] for i in group]), strict=True):
            out[i] = r
        n += len(group)
    return out


class _Serial:
    """The default batch: ``fun`` at each point in turn; :meth:`within` a deadline, after which only ``keep`` starts."""

    def __init__(self, fun: Fun):
        self.fun = fun

    def __call__(self, points: list[np.ndarray]) -> list[np.ndarray]:
        return [self.fun(p) for p in points]

    def within(self, points: list[np.ndarray], deadline: float, *, keep: int | None = None) -> list[np.ndarray | None]:
        return until_deadline(points, deadline, keep, self)


class Run:
    """Book-keeping of one optimiser call.

    Parameters
    ----------
    fun, batch
        The residual function and the (optional) batch evaluator from the caller.
    x0, lb, ub
        Validated start and bounds.
    max_nfev, deadline, callback
        The caller's budget, wall-clock limit (seconds from now) and callback.
    augment
        Optional ``(x, r) -> r_aug`` applied to every residual vector before its cost is taken (DuD's
        prior rows). The evaluation log stores the augmented cost.
    track_pending
        Keep the raw residual vectors evaluated since the last :meth:`mark` (for exact restarts).
    """

    def __init__(self, fun: Fun, batch: Batch | None, x0: np.ndarray, lb: np.ndarray, ub: np.ndarray, *,
                 max_nfev: int | None, deadline: float | None, callback: Callback | None,
                 augment: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None, track_pending: bool = False):
        self.fun = fun
        self.batch = batch if batch is not None else _Serial(fun)
        self.x0, self.lb, self.ub = x0, lb, ub
        self.max_nfev = max_nfev if max_nfev is not None else math.inf
        self.t_end = time.monotonic() + deadline if deadline is not None else math.inf
        self.callback = callback
        self.augment = augment
        self.nfev = 0
        self.nit = 0
        self.m: int | None = None
        self.evaluations: list[tuple[np.ndarray, float]] = []
        self.history: list[IterationRecord] = []
        self.best_x = x0.copy()
        self.best_cost = math.inf
        self.best_r: np.ndarray | None = None
        self.replay: dict[bytes, np.ndarray] = {}
        self.track_pending = track_pending
        self.since_mark: list[tuple[np.ndarray, np.ndarray]] = []
        self._cache: OrderedDict[bytes, np.ndarray] = OrderedDict()
        self._cache_size = max(_CACHE_SIZE, 2 * x0.shape[0] + 2)
        self._x0_key = x0.tobytes()

    # ---- evaluation ---------------------------------------------------------------------------
    def evaluate(self, x: np.ndarray) -> np.ndarray:
        """Residuals (augmented) at one point."""
        return self.evaluate_many([x])[0]

    def cost_of(self, r: np.ndarray) -> float:
        """S = Σ r² (inf if it overflows)."""
        with np.errstate(over="ignore"):
            return float(np.dot(r, r))

    def evaluate_many(self, points: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Residuals (augmented) at several independent points, run through ``batch``.

        Points seen recently (or saved in a restart state) are not run again. If the budget cannot
        take all new points, the first ones that fit are run and :class:`Stop` is raised afterwards.
        """
        xs = [np.array(p, dtype=float) for p in points]
        raw: list[np.ndarray | None] = [None] * len(xs)
        todo = []
        for i, x in enumerate(xs):
            self._check_bounds(x)
            key = x.tobytes()
            if key in self.replay:
                raw[i] = self.replay.pop(key)
                self._remember(x, raw[i], record=False)
            elif key in self._cache:
                raw[i] = self._cache[key]
            else:
                todo.append(i)
        if todo:
            try:
                self._run(xs, raw, todo)
            except Stop as stop:
                stop.partial = [None if r is None else self._augmented(x, r) for x, r in zip(xs, raw, strict=True)]
                raise
        return [self._augmented(x, r) for x, r in zip(xs, raw, strict=True)]  # type: ignore[arg-type]

    def _run(self, xs: list[np.ndarray], raw: list[np.ndarray | None], todo: list[int]) -> None:
        if self.nfev > 0 and time.monotonic() >= self.t_end:   # the start point always runs
            raise Stop(STATUS_DEADLINE)
        room = self.max_nfev - self.nfev
        if room < 1:
            raise Stop(STATUS_MAX_NFEV)
        now = todo[: int(min(room, len(todo)))]
        results = self._batch([xs[i].copy() for i in now])
        if len(results) != len(now):
            raise ValueError(f"batch returned {len(results)} residual vectors for {len(now)} points")
        for i, r in zip(now, results, strict=True):
            if r is None:
                continue
            raw[i] = self._check_residuals(xs[i], r)
            self.nfev += 1
            self._remember(xs[i], raw[i], record=True)
        if any(r is None for r in results):
            raise Stop(STATUS_DEADLINE)
        if len(now) < len(todo):
            raise Stop(STATUS_MAX_NFEV)

    def _batch(self, points: list[np.ndarray]) -> list[np.ndarray | None]:
        """The batch's results; under a deadline, through its ``within`` where it has one (None: not run in time).

        The first batch keeps its start point (x0, else its first point) whatever the time: it validates the
        problem and is the result of a run cut at once.
        """
        within = getattr(self.batch, "within", None)
        if not math.isfinite(self.t_end) or within is None:
            return list(self.batch(points))
        keep = None
        if self.nfev == 0:
            keep = next((n for n, p in enumerate(points) if p.tobytes() == self._x0_key), 0)
        return list(within(points, self.t_end, keep=keep))

    def _check_bounds(self, x: np.ndarray) -> None:
        if x.shape != self.x0.shape or np.any(x < self.lb) or np.any(x > self.ub):
            raise RuntimeError(f"internal error: an optimiser asked for a point outside the bounds: {x}")

    def _check_residuals(self, x: np.ndarray, r: Any) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        if r.ndim == 0:
            r = r.reshape(1)
        if r.ndim != 1:
            raise ValueError(f"fun must return a 1-D array of residuals, got shape {r.shape}")
        if self.m is None:
            self.m = r.shape[0]
        elif r.shape[0] != self.m:
            raise ValueError(f"fun returned {r.shape[0]} residuals at x={x}, earlier {self.m}")
        if not np.all(np.isfinite(r)):
            bad = int(np.count_nonzero(~np.isfinite(r)))
            where = "in the initial point x0" if x.tobytes() == self._x0_key else f"at x={x}"
            raise NonFiniteResidualsError(
                f"Residuals are not finite {where} ({bad} of {r.shape[0]} entries NaN or inf); "
                "an optimiser never uses them as a cost - return a finite penalty instead")
        return r.copy()

    def _remember(self, x: np.ndarray, r: np.ndarray, *, record: bool) -> None:
        aug = self._augmented(x, r)
        cost = self.cost_of(aug)
        if record:
            self.evaluations.append((x.copy(), cost))
        if self.track_pending:
            self.since_mark.append((x.copy(), r))
        self._cache[x.tobytes()] = r
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        if cost < self.best_cost:
            self.best_x, self.best_cost, self.best_r = x.copy(), cost, aug

    def _augmented(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        return self.augment(x, r) if self.augment is not None else r

    def mark(self) -> None:
        """Forget the evaluations kept for a restart state (a consistent snapshot was just taken)."""
        self.since_mark = []

    def cached(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The recently evaluated points and raw residuals (so a restart does not rerun them)."""
        return tuple((np.frombuffer(k, dtype=float).copy(), r) for k, r in self._cache.items())

    def preload(self, cache: Sequence[tuple[np.ndarray, np.ndarray]],
                replay: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
        """Restore the recent-points cache and the evaluations to replay without new runs."""
        for x, r in cache:
            self._cache[np.asarray(x, dtype=float).tobytes()] = np.asarray(r, dtype=float)
        self.replay = {np.asarray(x, dtype=float).tobytes(): np.asarray(r, dtype=float) for x, r in replay}

    def check_deadline(self) -> None:
        """Raise :class:`Stop` if the deadline passed."""
        if time.monotonic() >= self.t_end:
            raise Stop(STATUS_DEADLINE)

    # ---- iterations ---------------------------------------------------------------------------
    def iteration(self, x: np.ndarray, cost: float, linear_cost: float = math.nan) -> None:
        """Record one finished iteration and call the callback (which may abort the run)."""
        self.nit += 1
        record = IterationRecord(self.nit, np.array(x, dtype=float), float(cost), float(linear_cost), self.nfev)
        self.history.append(record)
        log.debug("iteration %d: cost %.6g, nfev %d", record.nit, record.cost, record.nfev)
        if self.callback is not None and self.callback(record):
            raise Stop(STATUS_CALLBACK)

    # ---- result ---------------------------------------------------------------------------------
    def result(self, status: int, messages: Mapping[int, str], method: str, *, jac: np.ndarray | None = None,
               extra: Mapping[str, Any] | None = None) -> OptimiseResult:
        """Build the :class:`OptimiseResult` around the best point seen."""
        extra = dict(extra or {})
        extra["residuals"] = self.best_r
        stats = parameter_statistics(jac, self.best_cost) if jac is not None else None
        if stats is not None:
            extra["covariance"] = stats["covariance"]
            extra["std_scaled"] = stats["std_scaled"]
        log.info("%s finished: status %d, cost %.6g, nfev %d", method, status, self.best_cost, self.nfev)
        return OptimiseResult(
            x=self.best_x.copy(), cost=self.best_cost, nfev=self.nfev, nit=self.nit, status=status,
            message=messages[status], success=status > 0, aborted=status in ABORT_STATUSES,
            history=tuple(self.history), evaluations=tuple(self.evaluations),
            std=None if stats is None else stats["std"],
            correlation=None if stats is None else stats["correlation"],
            jac=jac, method=method, extra=extra,
        )
