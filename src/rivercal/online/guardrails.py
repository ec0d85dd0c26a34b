"""The on-line service's guardrails: the identifiability gate, the jump test and the alerts.

Identifiability gate
    The final Jacobian J of the weighted residuals (the DuD secant matrix, or the optimiser's
    finite-difference Jacobian) is scaled column-wise by each parameter's *resolution* d (the
    smallest change that matters to the operator: 0.5 m^(1/3)/s of friction, 1 cm of crest;
    :func:`rivercal.online.config.default_resolution`). J is the optimiser's, with respect to the
    parameters in optimiser units (the log of a ``transform = "ln"`` parameter), so d is converted to those
    units at the estimate first (:func:`optimiser_resolution`: d/θ for ``ln``): a Manning n of 0.035 with a
    resolution of 0.0005 s/m^(1/3) is a step of 0.014 in ln n, not 0.0005. A
    singular value s_j of J·diag(d) is the square root of the cost increase when the parameters move
    by their resolutions along singular vector j; directions with s_j < ``gate_sv`` (default 1: less
    than one σ in the whole window) are unseen. A parameter whose identifiability index (Doherty and
    Hunt 2009) over the seen directions is below ``gate_index`` is held at its previous value and the
    estimate is stored as not accepted, with the reason. Holding it does not spoil the others: by
    construction their cost hardly depends on it.

Jump test
    An estimate *jumps* when it moves from the last accepted value, or from the value accepted one window
    earlier, by more than its resolution and by more than ``alert_k`` standard deviations σ of the fit.
    The service passes the σ scaled by the residual variance (thesis Eq. 2-12 times √(S/(n − p))): with
    the observations' σ as weights alone, a model that differs from the river gets a σ so small that
    every move is tens of σ. The second reference catches a change that a week-long window averages in:
    the daily estimate then creeps by a share of the change per cycle, each share below the resolution.
    The test is a trigger, not a verdict: under real data (correlated residuals, a model that differs
    from the river) it fires on many ordinary windows, and the service then asks the transition
    estimator (:mod:`rivercal.online.intervention`), whose significance test decides whether the window
    holds a change and an alert is raised. The first cycle of a run has no previous estimate to jump from.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from rivercal._format import unit_suffix
from rivercal.analysis.identifiability import IdentifiabilityOptions, analyse_jacobian, fd_jacobian
from rivercal.errors import ModelRunError
from rivercal.problem import CalibrationProblem
from rivercal.store import AlertRecord, CycleSpec, Run, Store

__all__ = ["accepted_at", "data_alerts", "gate", "jump_alert", "jumps", "limit_alerts", "optimiser_resolution",
           "unobserved_series"]

log = logging.getLogger(__name__)


def gate(problem: CalibrationProblem, result: Any, resolution: Mapping[str, float], units: Mapping[str, str], *,
         gate_sv: float, gate_index: float, algorithm: str, workers: int | None) -> tuple[dict[str, str], int]:
    """Parameters the window cannot see, with the reason (module docstring); and the model runs it took.

    The Jacobian is the optimiser's (DuD's secant one); when it has none, a forward-difference one at
    the estimate (p + 1 runs in one batch).
    """
    if gate_sv <= 0:
        return {}, 0
    jac, extra = result.jac, 0
    if jac is None or not np.all(np.isfinite(jac)):
        # e.g. DuD's secant set degenerated: a gate that is skipped would accept anything, so measure it
        log.info("no usable Jacobian from %s; finite differences at the estimate", algorithm)
        try:
            fd = fd_jacobian(problem, np.asarray(result.x, dtype=float), workers=workers)
        except ModelRunError as exc:
            reason = f"the identifiability gate could not run ({exc}); held at its last accepted value"
            return dict.fromkeys(problem.parameters.names, reason), 0
        jac, extra = fd.matrix, fd.nfev
    names = problem.parameters.names
    scale = optimiser_resolution(problem.parameters, np.asarray(result.x, dtype=float), resolution)
    seen = int(np.count_nonzero(np.linalg.svd(jac * scale, compute_uv=False) >= gate_sv))
    ident = analyse_jacobian(jac, names, scale=scale, options=IdentifiabilityOptions(k=seen))
    held = {}
    for i, n in enumerate(names):
        if ident.index[i] < gate_index:
            step = f"{resolution[n]:g}{unit_suffix(units.get(n))}"
            if seen == 0:  # the window sees no parameter: no direction to take the index over
                why = (f"a change of {step} in {n}, or of any estimated parameter by its resolution, moves the cost "
                       f"by less than {gate_sv:g}")
            else:
                why = (f"identifiability index {ident.index[i]:.2f} < {gate_index:g} over the {seen} "
                       f"direction{'s' if seen != 1 else ''} whose singular value reaches {gate_sv:g} (a change "
                       f"of {step} moves the cost by less than that)")
            held[n] = f"this window cannot see {n}: {why}; held at its last accepted value"
    return held, extra


def optimiser_resolution(parameters: Any, x: np.ndarray, resolution: Mapping[str, float]) -> np.ndarray:
    """Each parameter's resolution (its physical unit) as a step in optimiser units at the point ``x``.

    The step from the value θ at ``x`` to θ + d, through the parameter's transform: d for ``offset`` and
    ``factor`` (whose optimiser value is the physical one), ln(1 + d/θ) ≈ d/θ for ``ln`` (θ > 0 there).

    Parameters
    ----------
    parameters
        The :class:`~rivercal.parameters.ParameterSet` of ``x``.
    x
        The point, optimiser units.
    resolution
        Per parameter name, d in the parameter's unit.

    Returns
    -------
    numpy.ndarray
        The steps, optimiser units, in the order of the parameters.
    """
    return np.array([abs(p.to_x(p.from_x(float(xi)) + abs(float(resolution[p.name]))) - float(xi))
                     for p, xi in zip(parameters, np.asarray(x, dtype=float), strict=True)])


def jumps(warm: Mapping[str, float], accepted: Mapping[str, float], sigma: Mapping[str, float],
          held: Mapping[str, str], resolution: Mapping[str, float], alert_k: float,
          earlier: Mapping[str, float] | None = None) -> dict[str, float]:
    """The parameters whose estimate jumped: name → |Δθ|/σ (inf when σ is unknown).

    Δθ is the move from the warm start (the last accepted value) or, when ``earlier`` is given, from the
    value accepted one window earlier, whichever is larger. A change inside a week-long window moves the
    daily estimate by only a share of the change per cycle (thesis §6-3); each share can stay below the
    resolution while their sum since the window's start does not.
    """
    out = {}
    for n, value in accepted.items():
        if n in held:
            continue
        change = max((value - ref[n] for ref in (warm, earlier or {}) if n in ref), key=abs)
        s = sigma.get(n, math.nan)
        k = abs(change) / s if s and math.isfinite(s) and s > 0 else math.inf
        if abs(change) > resolution[n] and k > alert_k:
            out[n] = k
    return out


def accepted_at(store: Store, run: Run, at: Any) -> dict[str, float]:
    """Per parameter, the value accepted one window earlier: by the last cycle issued at or before ``at``.

    A cycle that carried a transition (:mod:`rivercal.online.intervention`) after ``at`` takes its place:
    the moves of the value after a change while the service followed it are refinements, not a new jump.
    Empty when no such cycle accepted anything.
    """
    est = store.estimates(run, accepted_only=True)
    if est.empty:
        return {}
    old = est["cycle"][est["issue_time"] <= at]
    moves = store.transitions(run)
    last = max([*old.iloc[-1:].tolist(), *moves["cycle"].iloc[-1:].tolist()], default=None)
    if last is None:
        return {}
    rows = est[est["cycle"] <= last]
    return {str(n): float(g["value"].iloc[-1]) for n, g in rows.groupby("parameter")}


def jump_alert(name: str, unit: str, before: float, after: float, k: float, spec: CycleSpec,
               detail: str) -> AlertRecord:
    """The ``jump`` alert of a probable intervention."""
    return AlertRecord(
        "jump", f"{name} changed from {before:.4g} to {after:.4g}{unit_suffix(unit)} ({after - before:+.3g}"
        + (f", {k:.0f} σ" if math.isfinite(k) else "") + f") {detail} in the window "
        f"{spec.window_start:%Y-%m-%d %H:%M} – {spec.window_end:%Y-%m-%d %H:%M}: a probable intervention (mowing, "
        "a changed weir setting)", parameter=name, magnitude=k if math.isfinite(k) else None)


def limit_alerts(parameters: Any, warm: Mapping[str, float], estimates: Mapping[str, float],
                 max_change: Mapping[str, float]) -> list[AlertRecord]:
    """``limit`` alerts of estimates stopped by the per-cycle change bound (inside the parameter's range)."""
    out = []
    for p in parameters:
        n = p.name
        if n in max_change:
            step = max_change[n]
            at_box = abs(abs(estimates[n] - warm[n]) - step) <= 1e-6 * max(1.0, step)
            inside = p.min < estimates[n] < p.max
            if at_box and inside:
                out.append(AlertRecord(
                    "limit", f"{n} stopped at the per-cycle change bound ±{step:g}{unit_suffix(p.unit)}; the true "
                    "change may be larger and the next cycles will continue", parameter=n))
    return out


def data_alerts(observations: Any, window: Any, interval_s: float, min_coverage: float, *, store: Any = None,
                first: bool = True) -> list[AlertRecord]:
    """``data`` alerts of a window's observations (interval in s).

    A series that covers less than ``min_coverage`` of the window's values (one per ``interval_s``) gets
    an alert every cycle: a gauge that fell silent or thinned out matters each time. A series the
    configuration names but of which the store holds no reading at all (a station declared with ``h`` and
    ``Q`` whose discharge nobody measures; :func:`unobserved_series`, asked only when ``store`` is given) is
    not a thin series: it is named once, in the run's first cycle (``first``), and left out of the coverage
    check until readings arrive.
    """
    import pandas as pd

    expected = int(pd.Timedelta(window) / pd.Timedelta(seconds=interval_s)) + 1
    coverage = {s.id: len(s) / expected for s in observations}
    never = set(unobserved_series(store, [k for k, v in coverage.items() if v == 0])) if store is not None else set()
    thin = {k: v for k, v in coverage.items() if v < min_coverage and k not in never}
    out = []
    if never and first:
        named = sorted(never)
        shown = ", ".join(named[:DATA_ALERT_NAMES]) + (f" and {len(named) - DATA_ALERT_NAMES} more series"
                                                        if len(named) > DATA_ALERT_NAMES else "")
        rest = ("it is" if len(never) == 1 else "they are") + (" left out of the calibration and the coverage check "
                                                               "until readings arrive (said once, in the run's first "
                                                               "cycle)")
        observed = len(coverage) - len(never)
        if len(never) > observed:  # most of the model's series: an imported model's structures, a few of them gauged
            text = (f"readings of {observed} of the {len(coverage)} series the run follows are stored; none of the "
                    f"other {len(never)} ({shown}): {rest}")
        else:
            text = f"no reading of {shown} is stored: {rest}"
        out.append(AlertRecord("data", text))
    if thin:
        out.append(AlertRecord("data", f"observations cover less than {min_coverage:.0%} of the window at "
                               + _thin_words(thin, len(coverage))))
    return out


def unobserved_series(store: Any, series: Sequence[str]) -> list[str]:
    """The series of which ``store`` holds no reading at all, from any source at any time (in the given order)."""
    if not series:
        return []
    known = set(store.availability(list(series))["series"])
    return [s for s in series if s not in known]


#: A data alert names at most this many series; beyond, it counts them and names the worst.
DATA_ALERT_NAMES = 8


def _thin_words(thin: dict[str, float], total: int) -> str:
    """The series of a data alert: all of them when few, else counts, the worst few and where the rest are."""
    ranked = sorted(thin.items(), key=lambda kv: (kv[1], kv[0]))
    if len(ranked) <= DATA_ALERT_NAMES:
        return ", ".join(f"{k} ({v:.0%})" for k, v in sorted(thin.items()))
    empty = sum(v == 0 for v in thin.values())
    shown = ", ".join(f"{k} ({v:.0%})" for k, v in ranked[:5])
    return (f"{len(ranked)} of {total} series" + (f" ({empty} without any value)" if empty else "") + f": {shown} "
            f"and {len(ranked) - 5} more (the report of the run, `rivercal report`, lists every series in "
            "data_coverage.csv)")
