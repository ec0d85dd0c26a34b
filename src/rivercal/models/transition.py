"""A model whose parameter jumps at a time (thesis §6-3): value before, value after, transition time τ.

A single value per calibration window averages a sudden change (mowing, a lowered weir) that happens
inside the window: the estimate matches neither the value before nor the value after. Thesis §6-3
proposes to discretise the parameter into three: the value before the transition, the value after it,
and the time of the transition. This module does that as a *model adapter* like the others of :mod:`rivercal.models`, so
that the calibration core (:class:`~rivercal.problem.CalibrationProblem`, any optimiser) estimates the
three numbers without knowing about transitions:

- :class:`TransitionModel` follows the model contract. Besides the quantities of the model it wraps it
  declares three of its own, ``transition:before``, ``transition:after`` (the parameter's value, its
  unit and bounds) and ``transition:time`` (τ, h since the adapter's ``reference`` time, usually the
  window start), and runs the wrapped model in segments from one state: the value before up to τ,
  the value after from τ. τ at or before the run start means the value after throughout; at or
  after the end, the value before. It uses only the wrapped model's contract (``dt``, period,
  ``output_interval``, ``quantities``, ``simulate``).
- :meth:`TransitionModel.parameter_set` builds the three :class:`~rivercal.parameters.Parameter` of a
  window: the parameter's physical bounds for before and after, the window for τ.

The search for a start of the three-value fit and the test whether a window holds a transition are in
:mod:`rivercal.online.transition_search`; the estimator that runs both fits is
:func:`rivercal.online.transition.estimate_transition`.

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
:func:`~rivercal.online.transition_search.transition_start` in 8 runs either way. ``substep`` is the
default because it is the one that works with every optimiser of :mod:`rivercal.optimise`, for one
extra engine step.

Above ``dt`` the cost has kinks at the observation times where part of the response is faster than the
sampling (the discharge at a weir adjusts within minutes): between two observations such a response is
invisible, so a fit started far from τ can stall on a tread (on a channel at steady flow, DuD from
mid-window stopped 2-3 h late). :func:`~rivercal.online.transition.estimate_transition` therefore
starts the three-value fit from :func:`~rivercal.online.transition_search.transition_start`, which
places τ between the right pair of observations.

Output times are those of a plain run (``start + k · output_interval``): the segments that do not start
or end on that grid run with an output interval of ``dt`` and only the grid rows are kept.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any, Literal

import pandas as pd

from rivercal.models.contract import Quantity, utc
from rivercal.parameters import Parameter, ParameterSet

__all__ = ["AFTER", "BEFORE", "TIME", "TransitionModel"]

#: Quantity of the adapter: the parameter's value before the transition (the parameter's unit).
BEFORE = "transition:before"
#: Quantity of the adapter: the parameter's value after the transition (the parameter's unit).
AFTER = "transition:after"
#: Quantity of the adapter: the transition time τ, h since the adapter's reference time.
TIME = "transition:time"
_OWN = (BEFORE, AFTER, TIME)


class TransitionModel:
    """A model whose parameter jumps from a value before to a value after at a time τ.

    Parameters
    ----------
    model
        A model of the model contract (e.g. :func:`rivercal.models.load_model`); runs of any length on
        its ``dt`` grid with any output interval that is a multiple of ``dt``.
    parameter
        What changes: a settable quantity of the model (``friction:global``, ``weir:<id>.crest_level``,
        …) or a :class:`~rivercal.parameters.Parameter` whose value maps to its targets or cluster (e.g. FA).
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
        if isinstance(parameter, str) and parameter in _OWN:
            raise ValueError(f"the changing quantity {parameter!r} is itself a quantity of the transition")
        targets = parameter.quantities(parameter.initial) if isinstance(parameter, Parameter) else {parameter: 0.0}
        unknown = [t for t in targets if t not in model.quantities]
        if unknown:
            raise ValueError(f"the changing quantity {unknown[0]!r} is not a settable quantity of model "
                             f"{getattr(model, 'name', '?')!r}")
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
    def output_interval(self) -> float:
        """Default output interval of the wrapped model, s."""
        return float(self.model.output_interval)

    @property
    def numerical_noise(self) -> float | None:
        """The wrapped model's numerical noise (units of its series: m, m³/s), None where it declares none."""
        return getattr(self.model, "numerical_noise", None)

    @property
    def name(self) -> str:
        """The wrapped model's name."""
        return self.model.name

    @property
    def calibration(self) -> Any:
        """The wrapped model's calibration setup."""
        return self.model.calibration

    @property
    def changing(self) -> str:
        """Name of the changing parameter (the Parameter's name, or the model quantity)."""
        return self.parameter.name if isinstance(self.parameter, Parameter) else self.parameter

    @property
    def quantities(self) -> dict[str, Quantity]:
        """The wrapped model's quantities and the adapter's own.

        Before and after take the parameter's unit and bounds (or those of the changing quantity), τ is in h.
        """
        own = dict(self.model.quantities)
        if isinstance(self.parameter, Parameter):
            unit, low, high = self.parameter.unit, self.parameter.min, self.parameter.max
        else:
            q = own[self.parameter]
            unit, low, high = q.unit, q.min, q.max
        own[BEFORE] = Quantity(BEFORE, unit, low, high, f"value of {self.changing} before the transition")
        own[AFTER] = Quantity(AFTER, unit, low, high, f"value of {self.changing} after the transition")
        own[TIME] = Quantity(TIME, "h", None, None, f"transition time, h since {self.reference.isoformat()}")
        return own

    def default_parameters(self) -> dict[str, float]:
        """The wrapped model's own values."""
        return self.model.default_parameters()

    @property
    def state_format(self) -> str:
        """The wrapped model's state format."""
        return self.model.state_format

    def save_state(self, state: Any) -> bytes:
        """The wrapped model's state as bytes."""
        return self.model.save_state(state)

    def load_state(self, data: bytes, fmt: str) -> Any:
        """A state of the wrapped model."""
        return self.model.load_state(data, fmt)

    def time_of(self, tau: float) -> pd.Timestamp:
        """The transition time τ (h since :attr:`reference`) as a UTC timestamp."""
        return self.reference + pd.Timedelta(hours=float(tau))

    def targets_of(self, value: float) -> dict[str, float]:
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
        name = _short_name(self.changing)
        common = {"min": lo, "max": hi, "transform": transform, "perturbation": step,
                  "unit": unit if unit is not None else (p.unit if p is not None else "")}
        return ParameterSet([
            Parameter(name=f"{name}_before", targets=[BEFORE], initial=before, **common),
            Parameter(name=f"{name}_after", targets=[AFTER], initial=after, **common),
            Parameter(name=f"{name}_time", targets=[TIME], min=t_lo, max=t_hi,
                      initial=0.5 * (t_lo + t_hi) if time is None else time, transform="offset",
                      perturbation=time_step if time_step is not None else (t_hi - t_lo) / 8.0, unit="h"),
        ])

    # -- running ----------------------------------------------------------------------------------

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: Any = None, *, output_interval: float | None = None, **options: Any) -> tuple[Any, Any]:
        """Run the wrapped model with the parameter switching from before to after at τ.

        Parameters
        ----------
        parameters
            Model quantities; ``transition:before``, ``transition:after`` (parameter unit) and
            ``transition:time`` (h since :attr:`reference`), all three or none.
            Without them the wrapped model runs as it is. Other quantities go to every segment.
        start, end, state, output_interval
            As for the wrapped model (``end - start`` a multiple of the output interval, s).
        options
            Further keywords of the wrapped model's ``simulate`` (e.g. ``snapshots`` of the embedded one).

        Returns
        -------
        (SimulationResult, state)
            The series at the output times of a plain run (first row: the start state) and the state at
            ``end``.

        Raises
        ------
        ValueError
            When only some of the transition's quantities are given, one is not finite, the changing quantity is also
            set directly, or the period does not fit the output interval.
        """
        rest, values = self._split(parameters or {})
        if values is None:
            return self.model.simulate(rest, start, end, state, output_interval=output_interval, **options)
        start = self.model.start if start is None else utc(start)
        end = self.model.end if end is None else utc(end)
        interval = float(output_interval) if output_interval is not None else self.output_interval
        interval_ns = round(interval * 1e9)
        if interval_ns % self._dt_ns or (end - start).value % interval_ns or not end > start:
            raise ValueError(f"the period {start} .. {end} must be a positive multiple of the output interval "
                             f"({interval:g} s), itself a multiple of dt ({self.dt:g} s)")
        before, after, tau = values
        pieces = []
        for t0, t1, value in self.segments(before, after, tau, start, end):
            q = self.targets_of(value)
            clash = sorted(set(q) & set(rest))
            if clash:
                raise ValueError(f"{clash[0]} is set both directly and by the transition of {self.changing}")
            for a, b, every in _pieces(t0, t1, start, interval_ns, self._dt_ns):
                result, state = self.model.simulate({**rest, **q}, a, b, state, output_interval=every,
                                                    **options)
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
            if key in _OWN:
                found[key] = float(value)
            else:
                rest[key] = value
        if not found:
            return rest, None
        missing = [k for k in _OWN if k not in found]
        if missing:
            raise ValueError(f"the transition of {self.changing} needs {', '.join(_OWN)}; missing {', '.join(missing)}")
        for k, v in found.items():
            if not math.isfinite(v):
                raise ValueError(f"{k}: value {v} is not finite")
        return rest, (found[BEFORE], found[AFTER], found[TIME])



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



def _short_name(name: str) -> str:
    """A parameter name (ASCII letters, digits, _; ≤ 25 characters, room for ``_before``) from a name or quantity."""
    clean = "".join(c if c.isascii() and c.isalnum() else "_" for c in name).strip("_") or "p"
    if not clean[0].isalpha():
        clean = "p_" + clean
    return clean[:25]

