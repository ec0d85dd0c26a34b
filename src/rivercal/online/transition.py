"""Transition discretisation (thesis §6-3): a parameter as value-before, value-after and transition time.

A single value per calibration window averages a sudden change (mowing, a lowered weir) that happens
inside the window: the estimate matches neither the value before nor the value after. Thesis §6-3
proposes to discretise the parameter into three: the value before the transition, the value after it,
and the time of the transition. This module does that as a *model wrapper*, so that the calibration
core (:class:`~rivercal.problem.CalibrationProblem`, :func:`~rivercal.problem.calibrate`, any optimiser)
estimates the three numbers without knowing about transitions:

- :class:`TransitionModel` follows the model protocol of DESIGN.md. Its ``simulate`` understands three
  pseudo-quantities, ``transition:before``, ``transition:after`` (the parameter's value, its unit) and
  ``transition:time`` (τ, hours since the wrapper's ``reference`` time, usually the window start), and
  runs the wrapped model in segments from one state: the value before up to τ, the value after from τ.
  τ at or before the run start means the value after throughout; at or after the end, the value before.
- :meth:`TransitionModel.parameter_set` builds the three :class:`~rivercal.parameters.Parameter` of a
  window: the parameter's physical bounds for before and after, the window for τ.
- :func:`transition_test` decides from the costs of the one-value and the three-value fit whether a
  window holds a transition worth estimating; :func:`transition_start` reads a start for the three-value
  fit from the residuals of the one-value fit (a CUSUM); :func:`estimate_transition` runs both fits and
  the test.

Smoothness in τ (measured)
--------------------------
The engine advances in steps of ``dt`` (60 s on the default case). Switching at τ rounded to a step
(``smoothing="none"``) makes the cost a staircase in τ, so a difference quotient over less than a step
is zero: a forward-difference Jacobian (LM's step is ~1e-8 τ) or a converged DuD set sees no gradient.
The default ``smoothing="substep"`` runs the one step that contains τ with the time-weighted value
``w·before + (1 − w)·after`` (w the fraction of the step before τ): the cost is continuous in τ, for one
extra engine step and one more call of the wrapped model. A ramp over several steps was not chosen: one
call per step of the ramp, for a gradual change that the reference scenarios do not have.

Measured on the default case (week 2010-10-28 … 11-04, k_s 16 → 25 m^(1/3)/s at τ = 96 h, hourly
observations at all stations, noise-free): ``none`` gives cost 6.00 for τ − τ* in [−150, −100] s, 4.57 in
[−80, −45] s and 0 in [−30, 15] s; ``substep`` takes the same values on the step grid (−120 s: 6.00,
−60 s: 4.57, 0 s: 0) and varies continuously between them (−100 s: 5.38, −45 s: 2.96, −15 s: 0.45).
LM (forward differences) with ``none`` never moved τ (110 runs, τ left at its start, 30 min off); with
``substep`` it converged to the truth (71 runs). DuD, whose secant steps are minutes to hours, found the
truth with both: from a mid-window start (τ 12 h early) in 40 runs (``substep``) and 31 (``none``), from
:func:`transition_start` in 8 runs either way. ``substep`` is the default because it is the one that
works with every optimiser of :mod:`rivercal.optimise`, for one extra engine step.

Above ``dt`` the cost has kinks at the observation times where part of the response is faster than the
sampling (the discharge at a weir adjusts within minutes): between two observations such a response is
invisible, so a fit started far from τ can stall on a tread (on a channel at steady flow, DuD from
mid-window stopped 2-3 h late). :func:`estimate_transition` therefore starts the three-value fit from
:func:`transition_start`, which places τ between the right pair of observations.

Output times are those of a plain run (``start + k · output_interval``): the segments that do not start
or end on that grid run with an output interval of ``dt`` and only the grid rows are kept.

Pseudo-quantity names and the parameter target pattern
------------------------------------------------------
The target pattern of :class:`~rivercal.parameters.Parameter` only admits weir and friction quantities,
so the parameters of :meth:`TransitionModel.parameter_set` target the aliases of :data:`ALIASES`
(``friction:branch:__transition_before__`` and so on), which the wrapper reads as the pseudo-quantities
and never passes on. A model branch with such an id would be shadowed; none of the shipped cases has one.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import Calibration, CalibrationProblem, calibrate

__all__ = [
    "AFTER",
    "ALIASES",
    "BEFORE",
    "TIME",
    "TransitionEstimate",
    "TransitionModel",
    "TransitionTest",
    "estimate_transition",
    "transition_start",
    "transition_test",
]

log = logging.getLogger(__name__)

#: Pseudo-quantity: the parameter's value before the transition (the parameter's unit).
BEFORE = "transition:before"
#: Pseudo-quantity: the parameter's value after the transition (the parameter's unit).
AFTER = "transition:after"
#: Pseudo-quantity: the transition time τ, h since the wrapper's reference time.
TIME = "transition:time"
#: Aliases of the pseudo-quantities that fit the target pattern of :class:`~rivercal.parameters.Parameter`.
ALIASES = {
    "friction:branch:__transition_before__": BEFORE,
    "friction:branch:__transition_after__": AFTER,
    "friction:branch:__transition_time__": TIME,
}
_PSEUDO = (BEFORE, AFTER, TIME)
_TARGET_OF = {v: k for k, v in ALIASES.items()}


class TransitionModel:
    """A model whose parameter jumps from a value before to a value after at a time τ.

    Parameters
    ----------
    model
        A model following the model protocol with ``.dt`` (s), ``.start`` and ``.observables``, whose
        ``simulate`` takes ``output_interval`` and ``snapshots`` keywords (e.g. the
        :class:`~rivercal.engine.Simulator` of :func:`rivercal.model.load_model`).
    parameter
        What changes: a model quantity (``friction:global``, ``weir:<id>.crest_level``, …) or a
        :class:`~rivercal.parameters.Parameter` whose value maps to its targets or cluster (e.g. FA).
    reference
        Time at which τ = 0 (UTC); usually the calibration window's start.
    smoothing
        ``substep`` (default): the step containing τ runs with the time-weighted value, so the cost is
        continuous in τ; ``none``: switch at τ rounded to the nearest step (see the module docstring).

    Examples
    --------
    Global friction 16 m^(1/3)/s for the first 30 h of the default case, 25 m^(1/3)/s from then on:

    >>> from rivercal.model import load_model
    >>> sim = load_model("dommel")
    >>> tm = TransitionModel(sim, "friction:global", reference=sim.start)
    >>> result, state = tm.simulate({BEFORE: 16.0, AFTER: 25.0, TIME: 30.0}, end=sim.start + pd.Timedelta("2D"))
    >>> len(result.series), str(state.time)
    (49, '2010-09-03 00:00:00+00:00')
    """

    def __init__(self, model: Any, parameter: str | Parameter, reference: Any, *,
                 smoothing: Literal["substep", "none"] = "substep"):
        if smoothing not in ("substep", "none"):
            raise ValueError(f"smoothing must be 'substep' or 'none', got {smoothing!r}")
        if isinstance(parameter, str) and (parameter in _PSEUDO or parameter in ALIASES):
            raise ValueError(f"the changing quantity {parameter!r} is itself a transition pseudo-quantity")
        dt = float(model.dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"the wrapped model's time step dt = {dt!r} s is not a positive number")
        self.model = model
        self.parameter = parameter
        self.reference = utc(reference)
        self.smoothing = smoothing
        self._dt_ns = round(dt * 1e9)

    # -- the wrapped model's facts ------------------------------------------------------------------

    @property
    def observables(self) -> list[str]:
        """Names of the simulated series (those of the wrapped model)."""
        return list(self.model.observables)

    @property
    def dt(self) -> float:
        """Time step of the wrapped model, s."""
        return float(self.model.dt)

    @property
    def start(self) -> pd.Timestamp:
        """Start of the wrapped model's period (UTC)."""
        return self.model.start

    @property
    def end(self) -> pd.Timestamp:
        """End of the wrapped model's period (UTC)."""
        return self.model.end

    @property
    def case(self) -> Any:
        """The wrapped model's case."""
        return self.model.case

    @property
    def name(self) -> str:
        """Name of the changing parameter (the Parameter's name, or the model quantity)."""
        return self.parameter.name if isinstance(self.parameter, Parameter) else self.parameter

    def time_of(self, tau: float) -> pd.Timestamp:
        """The transition time τ (h since :attr:`reference`) as a UTC timestamp."""
        return self.reference + pd.Timedelta(hours=float(tau))

    def quantities(self, value: float) -> dict[str, float]:
        """Model quantities (target → value) of one value of the changing parameter."""
        if isinstance(self.parameter, Parameter):
            return self.parameter.quantities(value)
        return {self.parameter: float(value)}

    # -- parameters for the calibration problem ------------------------------------------------------

    def parameter_set(self, window: tuple[Any, Any], *, before: float | None = None, after: float | None = None,
                      time: float | None = None, bounds: tuple[float, float] | None = None,
                      time_step: float | None = None, unit: str | None = None) -> ParameterSet:
        """The three parameters (before, after, τ) for a calibration window.

        Parameters
        ----------
        window
            (start, end) of the calibration window (UTC); τ is bounded to it (in h since
            :attr:`reference`).
        before, after
            Initial values (the parameter's unit); default the Parameter's initial value.
        time
            Initial τ, h since :attr:`reference`; default the middle of the window.
        bounds
            Physical bounds of before and after; default the Parameter's (required for a plain quantity).
        time_step
            First DuD perturbation of τ, h; default an eighth of the window.
        unit
            Unit of before and after, for reports; default the Parameter's.

        Returns
        -------
        ParameterSet
            ``<name>_before``, ``<name>_after`` (the Parameter's transform and first step; for a plain
            quantity offset, 5 % of the bounds) and ``<name>_time`` (h, offset transform), in this order.

        Raises
        ------
        ValueError
            For an empty window, missing bounds or initial values (plain quantity), or initial values
            outside the bounds (pydantic's ValidationError names the parameter).
        """
        start, end = utc(window[0]), utc(window[1])
        if not end > start:
            raise ValueError(f"the window end {end} is not after its start {start}")
        t_lo = (start - self.reference).total_seconds() / 3600.0
        t_hi = (end - self.reference).total_seconds() / 3600.0
        p = self.parameter if isinstance(self.parameter, Parameter) else None
        if bounds is None and p is None:
            raise ValueError(f"bounds are needed for the plain model quantity {self.parameter!r}")
        lo, hi = bounds if bounds is not None else (p.min, p.max)  # type: ignore[union-attr]
        default = p.initial if p is not None else None
        before = default if before is None else before
        after = default if after is None else after
        if before is None or after is None:
            raise ValueError(f"initial values of before and after are needed for {self.parameter!r}")
        transform, step = (p.transform, p.perturbation) if p is not None else ("offset", 0.05 * (hi - lo))
        name = _short_name(self.name)
        common = {"min": lo, "max": hi, "transform": transform, "perturbation": step,
                  "unit": unit if unit is not None else (p.unit if p is not None else "")}
        return ParameterSet([
            Parameter(name=f"{name}_before", targets=[_TARGET_OF[BEFORE]], initial=before, **common),
            Parameter(name=f"{name}_after", targets=[_TARGET_OF[AFTER]], initial=after, **common),
            Parameter(name=f"{name}_time", targets=[_TARGET_OF[TIME]], min=t_lo, max=t_hi,
                      initial=0.5 * (t_lo + t_hi) if time is None else time, transform="offset",
                      perturbation=time_step if time_step is not None else (t_hi - t_lo) / 8.0, unit="h"),
        ])

    # -- running ----------------------------------------------------------------------------------

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: Any = None, *, output_interval: float | None = None,
                 snapshots: bool = False) -> tuple[Any, Any]:
        """Run the wrapped model with the parameter switching from before to after at τ.

        Parameters
        ----------
        parameters
            Model quantities; ``transition:before``, ``transition:after`` (parameter unit) and
            ``transition:time`` (h since :attr:`reference`), or their :data:`ALIASES`, all three or none.
            Without them the wrapped model runs as it is. Other quantities go to every segment.
        start, end, state, output_interval, snapshots
            As for the wrapped model (``end - start`` a multiple of the output interval, s).

        Returns
        -------
        (SimulationResult, EngineState)
            The series at the output times of a plain run (first row: the start state) and the state at
            ``end``.

        Raises
        ------
        ValueError
            When only some pseudo-quantities are given, one is not finite, the changing quantity is also
            set directly, or the period does not fit the output interval.
        """
        rest, values = self._split(parameters or {})
        if values is None:
            return self.model.simulate(rest, start, end, state, output_interval=output_interval, snapshots=snapshots)
        start = self.model.start if start is None else utc(start)
        end = self.model.end if end is None else utc(end)
        interval = float(output_interval) if output_interval is not None else self._default_interval()
        interval_ns = round(interval * 1e9)
        if interval_ns % self._dt_ns or (end - start).value % interval_ns or not end > start:
            raise ValueError(f"the period {start} .. {end} must be a positive multiple of the output interval "
                             f"({interval:g} s), itself a multiple of dt ({self.dt:g} s)")
        before, after, tau = values
        pieces = []
        for t0, t1, value in self.segments(before, after, tau, start, end):
            q = self.quantities(value)
            clash = sorted(set(q) & set(rest))
            if clash:
                raise ValueError(f"{clash[0]} is set both directly and by the transition of {self.name}")
            for a, b, every in _pieces(t0, t1, start, interval_ns, self._dt_ns):
                result, state = self.model.simulate({**rest, **q}, a, b, state, output_interval=every,
                                                    snapshots=snapshots)
                pieces.append(result)
        return _join(pieces, start, interval_ns), state

    def segments(self, before: float, after: float, tau: float, start: pd.Timestamp,
                 end: pd.Timestamp) -> list[tuple[pd.Timestamp, pd.Timestamp, float]]:
        """The constant-value segments (t0, t1, value) of a run from ``start`` to ``end``.

        ``tau`` is in h since :attr:`reference`; the step grid is ``start + k · dt``.
        """
        t_switch = self.time_of(tau)
        if t_switch <= start:
            return [(start, end, after)]
        if t_switch >= end:
            return [(start, end, before)]
        dt = pd.Timedelta(self._dt_ns, unit="ns")
        offset = (t_switch - start).value
        if self.smoothing == "none":
            t_k = start + ((offset + self._dt_ns // 2) // self._dt_ns) * dt  # nearest step, halves up
            return [(a, b, v) for a, b, v in ((start, t_k, before), (t_k, end, after)) if b > a]
        t_k = start + (offset // self._dt_ns) * dt
        w = (t_switch - t_k).value / self._dt_ns  # fraction of the step [t_k, t_k + dt] before τ
        out = [(start, t_k, before)] if t_k > start else []
        if w > 0.0:
            out.append((t_k, t_k + dt, w * before + (1.0 - w) * after))
            t_k = t_k + dt
        if end > t_k:
            out.append((t_k, end, after))
        return out

    def _split(self, parameters: Mapping[str, float]) -> tuple[dict[str, float], tuple[float, float, float] | None]:
        rest: dict[str, float] = {}
        found: dict[str, float] = {}
        for key, value in parameters.items():
            pseudo = ALIASES.get(key, key)
            if pseudo in _PSEUDO:
                if pseudo in found:
                    raise ValueError(f"{pseudo} is given twice (as {key!r} and as its alias or name)")
                found[pseudo] = float(value)
            else:
                rest[key] = value
        if not found:
            return rest, None
        missing = [k for k in _PSEUDO if k not in found]
        if missing:
            raise ValueError(f"the transition of {self.name} needs {', '.join(_PSEUDO)}; missing {', '.join(missing)}")
        for k, v in found.items():
            if not math.isfinite(v):
                raise ValueError(f"{k}: value {v} is not finite")
        return rest, (found[BEFORE], found[AFTER], found[TIME])

    def _default_interval(self) -> float:
        settings = getattr(self.model, "settings", None)
        value = getattr(settings, "output_interval", None)
        return float(value) if value is not None else self.dt


def _pieces(t0: pd.Timestamp, t1: pd.Timestamp, start: pd.Timestamp, interval_ns: int,
            dt_ns: int) -> list[tuple[pd.Timestamp, pd.Timestamp, float]]:
    """Runs (a, b, output interval in s) covering [t0, t1]: the output grid where it fits, dt elsewhere."""
    off0, off1 = (t0 - start).value, (t1 - start).value
    g0 = -(-off0 // interval_ns) * interval_ns  # first grid time at or after t0
    g1 = off1 // interval_ns * interval_ns  # last grid time at or before t1
    if g1 <= g0:
        return [(t0, t1, dt_ns / 1e9)]
    out = []
    if g0 > off0:
        out.append((t0, start + pd.Timedelta(g0, unit="ns"), dt_ns / 1e9))
    out.append((start + pd.Timedelta(g0, unit="ns"), start + pd.Timedelta(g1, unit="ns"), interval_ns / 1e9))
    if off1 > g1:
        out.append((start + pd.Timedelta(g1, unit="ns"), t1, dt_ns / 1e9))
    return out


def _join(pieces: list[Any], start: pd.Timestamp, interval_ns: int) -> Any:
    """One result from consecutive runs: rows on the output grid, balances added up."""

    def frame(attr: str) -> pd.DataFrame | None:
        frames = [getattr(r, attr) for r in pieces]
        if any(f is None for f in frames):
            return None
        joined = pd.concat([frames[0]] + [f.iloc[1:] for f in frames[1:]])
        joined = joined[(joined.index.as_unit("ns").asi8 - start.value) % interval_ns == 0]
        joined.index = joined.index.as_unit(start.unit)  # the time unit of a plain run from ``start``
        return joined

    first, last = pieces[0], pieces[-1]
    changes: dict[str, Any] = {"series": frame("series"), "wall_time": sum(r.wall_time for r in pieces)}
    if getattr(first, "levels", None) is not None:
        changes.update(levels=frame("levels"), discharges=frame("discharges"))
    if getattr(first, "balance", None) is not None:
        bal = first.balance
        boundaries = {k: sum(r.balance.boundaries[k] for r in pieces) for k in bal.boundaries}
        changes["balance"] = replace(bal, final=last.balance.final, boundaries=boundaries,
                                     laterals=sum(r.balance.laterals for r in pieces))
    return replace(first, **changes)


# -- deciding whether a window holds a transition ------------------------------------------------------


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
    f_statistic, p_value
        F = ((S₁ − S₃)/2) / (S₃/(n − 3)) and its upper-tail probability under F(2, n − 3).
    reduction
        Relative cost reduction (S₁ − S₃)/S₁.
    reason
        The rule's verdict in words.
    """

    transition: bool
    cost_single: float
    cost_transition: float
    n_residuals: int
    f_statistic: float
    p_value: float
    reduction: float
    reason: str


def transition_test(cost_single: float, cost_transition: float, n_residuals: int, *, alpha: float = 1e-3,
                    min_reduction: float = 0.25, min_gain: float = 1.0) -> TransitionTest:
    """Does a window hold a transition? Compare the one-value fit (S₁) with the three-value fit (S₃).

    The three-value model nests the one-value model (before = after), so S₃ ≤ S₁ up to the optimiser's
    tolerance. The rule accepts a transition when both hold:

    - the F-test of nested least-squares models, F = ((S₁ − S₃)/2) / (S₃/(n − 3)) with 2 and n − 3
      degrees of freedom, rejects "no transition" at level ``alpha`` (p < alpha). It is free of the
      scale of the weights (σ need not be right), but only approximate here: it assumes independent
      residuals (hourly residuals of a real model are correlated), and τ means nothing when there is
      no change, so the optimiser picks the τ that fits the noise best and p comes out too small (a
      week without change on the default case gave p = 0.006). Hence the small default ``alpha``;
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
    """
    for label, value in (("cost_single", cost_single), ("cost_transition", cost_transition)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"{label} must be a finite cost >= 0, got {value!r}")
    if n_residuals <= 3:
        raise ValueError(f"n_residuals must exceed the 3 parameters of the transition fit, got {n_residuals}")
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

        f_stat = (gain / 2.0) / (cost_transition / (n_residuals - 3))
        p = float(stats.f.sf(f_stat, 2, n_residuals - 3))
    significant, relevant = p < alpha, reduction >= min_reduction and gain >= min_gain
    if significant and relevant:
        reason = (f"transition: the three-value fit lowers the cost by {reduction:.0%} ({gain:.4g}; "
                  f"F = {f_stat:.3g}, p = {p:.2g})")
    elif gain < min_gain:
        reason = f"no transition: the cost drops by only {gain:.3g} < min_gain = {min_gain:g}"
    elif not significant:
        reason = f"no transition: the cost reduction of {reduction:.1%} is not significant (p = {p:.2g} >= {alpha:g})"
    else:
        reason = (f"no transition worth estimating: significant (p = {p:.2g}) but the cost drops by only "
                  f"{reduction:.1%} < {min_reduction:.0%}")
    return TransitionTest(transition=significant and relevant, cost_single=float(cost_single),
                          cost_transition=float(cost_transition), n_residuals=int(n_residuals),
                          f_statistic=float(f_stat), p_value=p, reduction=float(reduction), reason=reason)


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


# -- one call for the on-line service ------------------------------------------------------------------


@dataclass(frozen=True)
class TransitionEstimate:
    """Outcome of :func:`estimate_transition`.

    Attributes
    ----------
    single
        The one-value calibration over the window (the "average value" of thesis §6-3).
    transition
        The three-value calibration (estimates ``<name>_before``, ``<name>_after``, ``<name>_time``).
    before, after
        Estimated values before and after the transition (the parameter's unit).
    time
        Estimated transition time (UTC).
    tau
        The same as h since the window start.
    test
        The verdict of :func:`transition_test`.
    model_runs
        Model runs of both calibrations (plus the one that re-weights S₁, if needed).
    wall_time
        Wall-clock time of both calibrations, s.
    """

    single: Calibration
    transition: Calibration
    before: float
    after: float
    time: pd.Timestamp
    tau: float
    test: TransitionTest
    model_runs: int
    wall_time: float

    def summary(self) -> dict[str, Any]:
        """A JSON-friendly summary."""
        return {"transition": self.test.transition, "reason": self.test.reason, "before": self.before,
                "after": self.after, "time": self.time.isoformat(), "tau_h": self.tau,
                "single": next(iter(self.single.estimates.values())), "cost_single": self.test.cost_single,
                "cost_transition": self.test.cost_transition, "p_value": self.test.p_value,
                "model_runs": self.model_runs, "wall_s": round(self.wall_time, 3)}


def estimate_transition(model: Any, parameter: Parameter, observations: ObservationSet, window: tuple[Any, Any], *,
                        state: Any = None, warmup: pd.Timedelta | str = "24h", fixed: Mapping[str, float] | None = None,
                        initial: Mapping[str, float] | None = None, algorithm: str = "dud",
                        options: Mapping[str, Any] | None = None, workers: int | None = 1,
                        max_nfev: int | None = None, smoothing: Literal["substep", "none"] = "substep",
                        alpha: float = 1e-3, min_reduction: float = 0.25, min_gain: float = 1.0) -> TransitionEstimate:
    """Fit one value and (before, after, τ) of ``parameter`` over ``window``, and test for a transition.

    The on-line service calls this when the per-cycle estimate jumps: one-value fit, a start for the
    three-value fit from its residuals (:func:`transition_start`), the three-value fit through
    :class:`TransitionModel` with the unchanged calibration core, and :func:`transition_test`.

    Parameters
    ----------
    model
        A model following the model protocol (see :class:`TransitionModel`).
    parameter
        The parameter that may have changed (bounds, transform, first step); its ``initial`` starts the
        one-value fit (in the on-line service: the last accepted estimate).
    observations, window, state, warmup, fixed
        As for :class:`~rivercal.problem.CalibrationProblem`; the state (computed once when None) is
        shared by both fits.
    initial
        Initial ``before``, ``after`` (parameter unit) and ``time`` (h since the window start) of the
        three-value fit; those not given come from :func:`transition_start` (one extra model run).
    algorithm, options, workers
        As for :func:`~rivercal.problem.calibrate`.
    max_nfev
        Budget of model runs of each of the two calibrations.
    smoothing
        See :class:`TransitionModel`.
    alpha, min_reduction, min_gain
        The rule of :func:`transition_test`.
    """
    initial = dict(initial or {})
    unknown = sorted(set(initial) - {"before", "after", "time"})
    if unknown:
        raise ValueError(f"initial: unknown key {unknown[0]!r}; use 'before', 'after' (parameter unit) and 'time' (h)")
    single_problem = CalibrationProblem(model, ParameterSet([parameter]), observations, window, state=state,
                                        warmup=warmup, fixed=fixed)
    t0 = time.perf_counter()
    single = calibrate(single_problem, algorithm, options, workers=workers, max_nfev=max_nfev)
    s = single.estimates[parameter.name]
    runs = single.result.nfev
    if not {"before", "after", "time"} <= set(initial):
        initial = {**transition_start(single_problem, single), **initial}
        runs += 1
    tm = TransitionModel(model, parameter, reference=single_problem.start, smoothing=smoothing)
    params = tm.parameter_set(window, before=initial["before"], after=initial["after"], time=initial["time"])
    problem = CalibrationProblem(tm, params, observations, window, state=single_problem.state, warmup=warmup,
                                 fixed=fixed)
    transition = calibrate(problem, algorithm, options, workers=workers, max_nfev=max_nfev)
    runs += transition.result.nfev
    if all(o.sigma is not None for o in problem.observations):  # 1/σ weights: both costs on one scale
        cost_single = single.result.cost
    else:  # thesis Eq. 2-6 weights depend on each problem's first run: re-evaluate S₁ in the second problem
        cost_single = problem.cost(params.to_x({params.names[0]: s, params.names[1]: s}))
        runs += 1
    wall = time.perf_counter() - t0
    est = transition.estimates
    before, after, tau = (est[p.name] for p in params)
    test = transition_test(cost_single, transition.result.cost, problem.observations.n_values, alpha=alpha,
                           min_reduction=min_reduction, min_gain=min_gain)
    log.info("transition of %s in %s .. %s: %s", parameter.name, problem.start, problem.end, test.reason)
    return TransitionEstimate(single=single, transition=transition, before=before, after=after,
                              time=tm.time_of(tau), tau=tau, test=test, model_runs=runs, wall_time=wall)


def _short_name(name: str) -> str:
    """A parameter name (ASCII letters, digits, _; ≤ 25 characters, room for ``_before``) from a name or quantity."""
    clean = "".join(c if c.isascii() and c.isalnum() else "_" for c in name).strip("_") or "p"
    if not clean[0].isalpha():
        clean = "p_" + clean
    return clean[:25]
