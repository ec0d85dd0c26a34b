"""Identifiability and uniqueness of parameters (thesis §2-3-1-2, Eq. 2-10 … 2-13; Figs. 4-6 and 4-7).

The Jacobian J (thesis Eq. 2-10) is that of the *weighted* residuals r = √W (y − ŷ) with respect to the
optimiser's vector x, by finite differences: x and the perturbed points are evaluated as one batch
(:func:`fd_jacobian`). The step of parameter j is relative to its *scale* d_j, by default its physical
range in optimiser units (ub − lb): h_j = ``rel_step`` · d_j, 1 % by default — 0.013 m for a crest with a
1.3 m range, 0.32 m^(1/3)/s for a Strickler coefficient in 8 … 40. A step relative to |x| (as
:func:`rivercal.optimise.fd_jacobian_of` uses) would be 10⁻⁵ m for a crest 10 m above datum, far below
the numerical noise of a hydrodynamic model. Steps point into the bounds.

Parameters of different units are made comparable by scaling the Jacobian's columns with the same
scales: J_D = J · diag(d), so that column j is the change of the weighted residuals when parameter j
moves over its whole range (linearised). Its singular value decomposition J_D = U Σ Vᵀ (thesis
Eq. 2-11) gives the singular values (how strongly each combination of parameters is seen, dimensionless)
and the right singular vectors v_j (columns of V: which parameters make up the combination). The
covariance is (JᵀJ)⁻¹ in optimiser units (thesis Eq. 2-12; the pseudo-inverse when JᵀJ is singular) and
the correlation follows from thesis Eq. 2-13; the correlation does not depend on the scaling. With the
weights 1/σ², √diag(cov) is the standard deviation of each estimate for observation errors of σ.

The *parameter identifiability index* of Doherty and Hunt (2009) for k significant singular values is

    ident_i = Σ_{j ≤ k} V_ij²,

the squared length of the projection of parameter i's unit vector onto the space of the k best-seen
combinations: 1 when the observations fix the parameter, 0 when it lies wholly in the space the
observations cannot see. (Doherty, J., Hunt, R.J., 2009. Two statistics for evaluating parameter
identifiability and error reduction. Journal of Hydrology 366, 119–127.) ident_i depends on the scaling
of the parameters, hence the explicit ``scale``.

The verdict (:class:`IdentifiabilityOptions` holds every threshold) is deterministic:

1. A singular value is *significant* when s_j ≥ ``sv_threshold`` · s_1; k is their number (or given).
2. A parameter with ident < ``unidentifiable`` is **not identifiable**: the observations do not see it.
3. Among the others, correlations are recomputed with the not-identifiable parameters held fixed
   (they would be fixed in a calibration, and their noise-level columns would otherwise spoil the
   correlations of well-seen parameters). A parameter with ident ≥ ``identifiable`` and no such
   |correlation| > ``correlation`` is **identifiable**; the rest are **only in combination**: they share
   a weak singular vector (both load V_ij² ≥ ``loading`` on a vector beyond k) or are strongly correlated.
4. Clusters are suggested over the parameters that are not identifiable on their own: groups connected by
   a shared weak singular vector or a full-matrix |correlation| > ``correlation``. A group is worth one
   clustered parameter (like the thesis' Wc: every member at the same fraction of its range) when moving
   all members together is seen (‖J_D 1‖/√g ≥ ``sv_threshold`` · s_1 for g members); otherwise its members
   are best fixed.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.analysis._common import Batch, Context, batch_for, context_from_problem, station_of
from rivercal.optimise import parameter_statistics
from rivercal.optimise._core import inward_steps, project

__all__ = [
    "COMBINATION",
    "DOHERTY_HUNT_2009",
    "IDENTIFIABLE",
    "NOT_IDENTIFIABLE",
    "ClusterSuggestion",
    "Identifiability",
    "IdentifiabilityOptions",
    "Jacobian",
    "analyse_jacobian",
    "fd_jacobian",
    "identifiability",
    "identifiability_index",
]

log = logging.getLogger(__name__)

DOHERTY_HUNT_2009 = ("Doherty, J., Hunt, R.J., 2009. Two statistics for evaluating parameter identifiability and "
                     "error reduction. Journal of Hydrology 366, 119-127.")

IDENTIFIABLE = "identifiable"
COMBINATION = "only in combination"
NOT_IDENTIFIABLE = "not identifiable"


@dataclass(frozen=True)
class IdentifiabilityOptions:
    """Thresholds of the verdict (see the module docstring).

    Attributes
    ----------
    sv_threshold
        A singular value s_j is significant when s_j ≥ sv_threshold · s_1 (dimensionless, default 0.01: a
        combination seen at least 1 % as strongly as the best-seen one).
    k
        Number of significant singular values for the identifiability index; None: from ``sv_threshold``.
    identifiable
        ident_i at or above which a parameter is identifiable (unless strongly correlated), default 0.9.
    unidentifiable
        ident_i below which a parameter is not identifiable, default 0.1.
    correlation
        |correlation| above which two parameters are identifiable only in combination, default 0.9.
    loading
        A parameter takes part in singular vector j when V_ij² ≥ loading (its share of the unit vector),
        default 0.1.
    rcond
        Singular values below rcond · s_1 count as zero: JᵀJ is then singular and the covariance is the
        pseudo-inverse. Default 1e-10, above the round-off of a finite-difference Jacobian (whose columns
        for two parameters with identical effects differ by ~1e-14).
    """

    sv_threshold: float = 0.01
    k: int | None = None
    identifiable: float = 0.9
    unidentifiable: float = 0.1
    correlation: float = 0.9
    loading: float = 0.1
    rcond: float = 1e-10

    def __post_init__(self) -> None:
        for name in ("sv_threshold", "identifiable", "unidentifiable", "correlation", "loading", "rcond"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, int | float) and 0.0 < value < 1.0):
                raise ValueError(f"{name} must be a number in (0, 1), got {value!r}")
        if not self.unidentifiable < self.identifiable:
            raise ValueError(f"unidentifiable ({self.unidentifiable}) must be below identifiable ({self.identifiable})")
        if self.k is not None and (isinstance(self.k, bool) or not isinstance(self.k, int) or self.k < 0):
            raise ValueError(f"k must be None or a non-negative integer, got {self.k!r}")


# --------------------------------------------------------------------------------------------------
# the Jacobian
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Jacobian:
    """A finite-difference Jacobian of a problem's weighted residuals (thesis Eq. 2-10).

    Attributes
    ----------
    matrix
        ∂r/∂x, shape (m residuals, p parameters); per optimiser unit of each parameter (per m for a crest).
    x
        The point, optimiser units.
    steps
        The signed steps h_j (forward: x_j + h_j; central: the spread x_j + h⁺ − (x_j − h⁻)).
    residuals
        r(x), the weighted residuals at the point.
    names
        Parameter names (columns).
    rows
        The series id of every row.
    scale
        The parameter scales d_j (optimiser units) the steps are relative to.
    scheme
        ``forward`` or ``central``.
    nfev
        Model runs used.
    """

    matrix: np.ndarray
    x: np.ndarray
    steps: np.ndarray
    residuals: np.ndarray
    names: tuple[str, ...]
    rows: tuple[str, ...]
    scale: np.ndarray
    scheme: str
    nfev: int

    def to_frame(self) -> pd.DataFrame:
        """The matrix with a (series, row) index and parameter columns."""
        index = pd.MultiIndex.from_arrays([list(self.rows), _row_numbers(self.rows)], names=["series", "row"])
        return pd.DataFrame(self.matrix, index=index, columns=list(self.names))


def _row_numbers(rows: Sequence[str]) -> list[int]:
    seen: dict[str, int] = {}
    out = []
    for r in rows:
        out.append(seen.get(r, 0))
        seen[r] = out[-1] + 1
    return out


def _scales(problem: Any, scale: Sequence[float] | np.ndarray | None) -> np.ndarray:
    lb, ub = problem.bounds
    if scale is None:
        d = np.asarray(ub, dtype=float) - np.asarray(lb, dtype=float)
    else:
        d = np.asarray(scale, dtype=float).reshape(-1)
    if d.shape != (len(problem.parameters),) or not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"scale must hold {len(problem.parameters)} positive finite numbers, got {d}")
    return d


def fd_jacobian(problem: Any, x: np.ndarray | None = None, *, rel_step: float = 0.01,
                scale: Sequence[float] | np.ndarray | None = None, scheme: Literal["forward", "central"] = "forward",
                batch: Batch | None = None, workers: int | None = None) -> Jacobian:
    """Finite-difference Jacobian of ``problem.residuals`` at ``x``, all runs as one batch.

    Parameters
    ----------
    problem
        A :class:`~rivercal.problem.CalibrationProblem`.
    x
        The point in optimiser units (default: the initial values, ``problem.x0``).
    rel_step
        Step as a fraction of each parameter's scale: h_j = rel_step · d_j (default 1 %).
    scale
        The scales d_j in optimiser units (default: the parameter ranges ub − lb).
    scheme
        ``forward`` (p + 1 runs) or ``central`` (2p + 1 runs; one-sided where a bound is within a step).
    batch
        A batch evaluator over ``problem.residuals`` (e.g. a shared
        :class:`~rivercal.evaluate.Evaluator`); default: a new one with ``workers`` processes.
    workers
        Worker processes when no ``batch`` is given (None: all cores).

    Raises
    ------
    ValueError
        For a bad step, scale, scheme or a point outside the bounds.
    """
    if not (isinstance(rel_step, int | float) and 0.0 < rel_step <= 0.5):
        raise ValueError(f"rel_step must be in (0, 0.5], got {rel_step!r}")
    if scheme not in ("forward", "central"):
        raise ValueError(f"scheme must be 'forward' or 'central', got {scheme!r}")
    lb, ub = (np.asarray(b, dtype=float) for b in problem.bounds)
    x = np.array(problem.x0 if x is None else x, dtype=float)
    if x.shape != lb.shape or np.any(x < lb) or np.any(x > ub):
        raise ValueError(f"the point {x} lies outside the bounds")
    d = _scales(problem, scale)
    h = rel_step * d
    p = x.size
    points = [x]
    if scheme == "forward":
        steps = inward_steps(x, h, lb, ub)
        for j in range(p):
            xp = x.copy()
            xp[j] += steps[j]
            points.append(project(xp, lb, ub))
    else:
        up, down = np.minimum(h, ub - x), np.minimum(h, x - lb)
        for j in range(p):
            for s in (up[j], -down[j]):
                xp = x.copy()
                xp[j] += s
                points.append(project(xp, lb, ub))
    with batch_for(problem, batch, workers) as run:
        results = [np.asarray(r, dtype=float) for r in run(points)]
    r0 = results[0]
    jac = np.empty((r0.size, p))
    if scheme == "forward":
        for j in range(p):
            jac[:, j] = (results[j + 1] - r0) / (points[j + 1][j] - x[j])
        used = np.array([points[j + 1][j] - x[j] for j in range(p)])
    else:
        used = np.empty(p)
        for j in range(p):
            hi, lo = points[1 + 2 * j], points[2 + 2 * j]
            r_hi, r_lo = results[1 + 2 * j], results[2 + 2 * j]
            if hi[j] == x[j]:
                r_hi = r0
            if lo[j] == x[j]:
                r_lo = r0
            used[j] = hi[j] - lo[j]
            jac[:, j] = (r_hi - r_lo) / used[j]
    rows = tuple(s.id for s in problem.observations for _ in range(len(s)))
    log.info("Jacobian of %d residuals and %d parameters from %d runs", r0.size, p, len(points))
    return Jacobian(matrix=jac, x=x, steps=used, residuals=r0, names=tuple(problem.parameters.names), rows=rows,
                    scale=d, scheme=scheme, nfev=len(points))


# --------------------------------------------------------------------------------------------------
# the analysis
# --------------------------------------------------------------------------------------------------


def identifiability_index(vectors: np.ndarray, k: int) -> np.ndarray:
    """Doherty and Hunt (2009): ident_i = Σ_{j ≤ k} V_ij² for right singular vectors V (columns)."""
    v = np.asarray(vectors, dtype=float)
    return np.sum(v[:, :k] ** 2, axis=1)


@dataclass(frozen=True)
class ClusterSuggestion:
    """A group of parameters that the observations cannot tell apart.

    Attributes
    ----------
    members
        Parameter names.
    action
        ``cluster`` (estimate them as one parameter) or ``fix`` (keep them at their current values).
    strength
        ‖J_D 1‖ / (√g s_1) for g members: how strongly moving every member by the same fraction of its range
        is seen, relative to the best-seen combination (dimensionless, at most 1).
    explanation
        In words.
    """

    members: tuple[str, ...]
    action: Literal["cluster", "fix"]
    strength: float
    explanation: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly."""
        return {"members": list(self.members), "action": self.action, "strength": self.strength,
                "explanation": self.explanation}


@dataclass(frozen=True)
class Identifiability:
    """Outcome of :func:`analyse_jacobian` / :func:`identifiability`.

    Attributes
    ----------
    names
        Parameter names.
    jacobian
        ∂r/∂x, (m, p), per optimiser unit.
    scale
        The scales d_j (optimiser units) of J_D = J · diag(d).
    singular_values
        Singular values of J_D, descending (dimensionless: weighted residual change per parameter range).
    vectors
        Right singular vectors of J_D as columns (p, p), in the order of ``singular_values``; each has
        its largest component positive (a deterministic sign).
    k
        Number of significant singular values used for ``index``.
    index
        Identifiability index per parameter (Doherty and Hunt 2009), in [0, 1].
    covariance
        (JᵀJ)⁻¹ in optimiser units (pseudo-inverse when ``singular``).
    std
        √diag(covariance), optimiser units: the standard deviation of each estimate for observation
        errors of the weights' σ.
    correlation
        Thesis Eq. 2-13 (NaN for a parameter without any effect).
    singular
        Whether JᵀJ was singular to working precision (pseudo-inverse used).
    verdict
        One row per parameter: ``verdict``, ``index``, ``std``, ``dominant_vector`` (1-based) and
        ``dominant_share`` (V_ij² there), ``partners``, ``max_correlation`` and ``correlated_with``
        (not-identifiable parameters held fixed), ``top_station`` and ``top_station_share`` (share of
        the parameter's squared sensitivity at that station), ``explanation``.
    clusters
        Suggested groups.
    options
        The thresholds used.
    rows
        Series id of every Jacobian row (None when unknown).
    """

    names: tuple[str, ...]
    jacobian: np.ndarray
    scale: np.ndarray
    singular_values: np.ndarray
    vectors: np.ndarray
    k: int
    index: np.ndarray
    covariance: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    singular: bool
    verdict: pd.DataFrame
    clusters: tuple[ClusterSuggestion, ...]
    options: IdentifiabilityOptions
    rows: tuple[str, ...] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    # -- frames ------------------------------------------------------------------------------------

    def singular_frame(self) -> pd.DataFrame:
        """Singular values: index vector 1…p; columns value, relative (s_j / s_1), significant."""
        s = self.singular_values
        rel = s / s[0] if s.size and s[0] > 0 else np.zeros_like(s)
        return pd.DataFrame({"singular_value": s, "relative": rel, "significant": np.arange(s.size) < self.k},
                            index=pd.RangeIndex(1, s.size + 1, name="vector"))

    def vectors_frame(self) -> pd.DataFrame:
        """Right singular vectors: rows parameters, columns v1 … vp."""
        return pd.DataFrame(self.vectors, index=pd.Index(self.names, name="parameter"),
                            columns=[f"v{j + 1}" for j in range(self.vectors.shape[1])])

    def correlation_frame(self) -> pd.DataFrame:
        """Correlation matrix (thesis Eq. 2-13)."""
        return pd.DataFrame(self.correlation, index=pd.Index(self.names, name="parameter"), columns=list(self.names))

    def covariance_frame(self) -> pd.DataFrame:
        """Covariance matrix (thesis Eq. 2-12), optimiser units."""
        return pd.DataFrame(self.covariance, index=pd.Index(self.names, name="parameter"), columns=list(self.names))

    def summary(self) -> dict[str, Any]:
        """JSON-friendly summary."""
        s = self.singular_values
        return {
            "parameters": list(self.names),
            "singular_values": [float(v) for v in s],
            "relative_singular_values": [float(v / s[0]) if s[0] > 0 else 0.0 for v in s],
            "k": self.k,
            "identifiability_index": {n: float(v) for n, v in zip(self.names, self.index, strict=True)},
            "verdict": {n: str(self.verdict.loc[n, "verdict"]) for n in self.names},
            "explanations": {n: str(self.verdict.loc[n, "explanation"]) for n in self.names},
            "std": {n: _finite(v) for n, v in zip(self.names, self.std, strict=True)},
            "clusters": [c.to_dict() for c in self.clusters],
            "singular": self.singular,
            "options": {**self.options.__dict__},
            "reference": DOHERTY_HUNT_2009,
        }

    def text(self) -> str:
        """The verdict in words, one paragraph per parameter and per suggested cluster."""
        lines = [str(self.verdict.loc[n, "explanation"]) for n in self.names]
        lines += [f"Suggestion: {c.explanation}" for c in self.clusters]
        return "\n".join(lines)


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _covariance(jac: np.ndarray, d: np.ndarray, s: np.ndarray, v: np.ndarray,
                rcond: float) -> tuple[np.ndarray, bool]:
    """(JᵀJ)⁻¹ via :func:`rivercal.optimise.parameter_statistics`, or the pseudo-inverse when singular.

    ``s`` and ``v`` are the singular values and right vectors of J diag(d); singular values below
    ``rcond`` · s_1 count as zero.
    """
    singular = s.size == 0 or s[0] == 0.0 or s[-1] <= rcond * s[0]
    stats = parameter_statistics(jac, 0.0) if not singular and jac.shape[0] >= jac.shape[1] else None
    if stats is not None:
        return stats["covariance"], False
    keep = s > rcond * (s[0] if s.size else 0.0)
    cov_z = (v[:, keep] / s[keep] ** 2) @ v[:, keep].T
    return cov_z * np.outer(d, d), True


def _correlation(cov: np.ndarray) -> np.ndarray:
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(std, std)
    corr[~np.isfinite(corr)] = np.nan
    corr = np.clip(corr, -1.0, 1.0)
    ok = std > 0
    corr[np.diag_indices_from(corr)] = np.where(ok, 1.0, np.nan)
    return corr


def _reduced_correlation(jac: np.ndarray, keep: np.ndarray, rcond: float) -> np.ndarray:
    """Correlations among the ``keep`` parameters with the others held fixed (NaN elsewhere)."""
    p = jac.shape[1]
    out = np.full((p, p), np.nan)
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        return out
    sub = jac[:, idx]
    norms = np.linalg.norm(sub, axis=0)
    norms[norms == 0] = 1.0
    sub = sub / norms  # correlations do not depend on column scaling
    s, v = _svd(sub)
    cov, _ = _covariance(sub, np.ones(idx.size), s, v, rcond)
    out[np.ix_(idx, idx)] = _correlation(cov)
    return out


def _svd(jd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values (length p, zeros appended when m < p) and right singular vectors with a fixed sign."""
    m, p = jd.shape
    # The full V (p x p) needs full matrices only when there are fewer rows than parameters; otherwise
    # they would also build the m x m left factor, 3 GB and minutes for a season of hourly residuals.
    _, s, vt = np.linalg.svd(jd, full_matrices=m < p)
    v = vt.T
    s = np.concatenate([s, np.zeros(p - s.size)])
    for j in range(p):  # deterministic sign: the largest component positive
        i = int(np.argmax(np.abs(v[:, j])))
        if v[i, j] < 0:
            v[:, j] = -v[:, j]
    return s, v


def analyse_jacobian(jacobian: np.ndarray, names: Sequence[str], *, scale: Sequence[float] | np.ndarray | None = None,
                     rows: Sequence[str] | None = None,
                     options: IdentifiabilityOptions | Mapping[str, Any] | None = None, context: Context | None = None,
                     sqrt_weights: np.ndarray | None = None, scale_words: str = "its scale") -> Identifiability:
    """Singular values and vectors, covariance, correlation, identifiability index and a verdict.

    Parameters
    ----------
    jacobian
        J = ∂r/∂x of the weighted residuals, shape (m, p), per optimiser unit.
    names
        Parameter names, length p.
    scale
        Scales d_j (optimiser units) of J_D = J diag(d); default ones (no scaling).
    rows
        Series id (``"<station>.<quantity>"``) of every row, to tell which station sees which parameter.
    options
        Thresholds (:class:`IdentifiabilityOptions` or a dict of its fields).
    context
        Words for parameters and stations (see :func:`~rivercal.analysis._common.context_from_problem`).
    sqrt_weights
        √W of every row, to state effects in the units of the observations (m, m³/s).
    scale_words
        How the verdict names the scales (``"its whole range"`` when they are the parameter ranges).

    Returns
    -------
    Identifiability

    Raises
    ------
    ValueError
        For inconsistent shapes or non-finite entries.
    """
    jac = np.asarray(jacobian, dtype=float)
    names = tuple(names)
    if jac.ndim != 2 or jac.shape[1] != len(names) or jac.shape[1] == 0:
        raise ValueError(f"the Jacobian must have shape (m, {len(names)}), got {jac.shape}")
    if not np.all(np.isfinite(jac)):
        raise ValueError("the Jacobian has non-finite entries")
    if rows is not None and len(rows) != jac.shape[0]:
        raise ValueError(f"rows must name {jac.shape[0]} rows, got {len(rows)}")
    if options is None:
        opts = IdentifiabilityOptions()
    elif isinstance(options, IdentifiabilityOptions):
        opts = options
    else:
        opts = IdentifiabilityOptions(**dict(options))
    p = len(names)
    d = np.ones(p) if scale is None else np.asarray(scale, dtype=float).reshape(-1)
    if d.shape != (p,) or np.any(~np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"scale must hold {p} positive finite numbers, got {d}")
    context = context or Context()

    jd = jac * d
    s, v = _svd(jd)
    if opts.k is not None:
        k = min(opts.k, p)
    else:
        k = int(np.count_nonzero((s > 0) & (s >= opts.sv_threshold * s[0]))) if s[0] > 0 else 0
    index = identifiability_index(v, k)
    cov, singular = _covariance(jac, d, s, v, opts.rcond)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if singular:  # a parameter in an unseen direction is not determined at all
        null = s <= opts.rcond * s[0]
        std = np.where(np.sum(v[:, null] ** 2, axis=1) > 1e-12, np.inf, std)
    corr = _correlation(cov)

    not_id = index < opts.unidentifiable
    reduced = _reduced_correlation(jac, ~not_id, opts.rcond)
    weak = range(k, p)
    loads = v**2 >= opts.loading
    verdicts, partners, max_corr, corr_with = [], [], [], []
    for i in range(p):
        share_partners = sorted({q for j in weak if loads[i, j] for q in range(p) if q != i and loads[q, j]})
        row = np.abs(np.nan_to_num(reduced[i], nan=0.0))
        row[i] = 0.0
        c_idx = int(np.argmax(row)) if p > 1 else i
        strong = sorted(q for q in range(p) if q != i and row[q] > opts.correlation)
        if not_id[i]:
            verdict = NOT_IDENTIFIABLE
        elif not strong and index[i] >= opts.identifiable:
            verdict = IDENTIFIABLE
        else:
            verdict = COMBINATION
        verdicts.append(verdict)
        partners.append(tuple(names[q] for q in sorted(set(share_partners) | set(strong))))
        max_corr.append(float(reduced[i, c_idx]) if p > 1 and c_idx != i and row[c_idx] > 0 else np.nan)
        corr_with.append(names[c_idx] if p > 1 and c_idx != i and row[c_idx] > 0 else "")

    series_share = _series_shares(jac, rows)
    station_share = [_by_station(sh) for sh in series_share]
    dominant = np.argmax(v**2, axis=1)
    effect = _effects(jac, d, rows, sqrt_weights)
    frame = pd.DataFrame({
        "verdict": verdicts,
        "index": index,
        "std": std,
        "dominant_vector": dominant + 1,
        "dominant_share": v[np.arange(p), dominant] ** 2,
        "partners": [", ".join(x) for x in partners],
        "max_correlation": max_corr,
        "correlated_with": corr_with,
        "top_station": [max(sh, key=sh.get) if sh else "" for sh in station_share],
        "top_station_share": [max(sh.values()) if sh else np.nan for sh in station_share],
    }, index=pd.Index(names, name="parameter"))

    result_args = dict(names=names, jacobian=jac, scale=d, singular_values=s, vectors=v, k=k, index=index,
                       covariance=cov, std=std, correlation=corr, singular=singular, options=opts,
                       rows=tuple(rows) if rows is not None else None)
    words = _Words(context, names, d, s, v, k, opts, series_share, effect, jd, scale_words)
    frame["explanation"] = [words.parameter(i, frame) for i in range(p)]
    clusters = _clusters(frame, names, corr, s, v, k, opts, jd, words)
    return Identifiability(verdict=frame, clusters=clusters, **result_args)


def _series_shares(jac: np.ndarray, rows: Sequence[str] | None) -> list[dict[str, float]]:
    """Per parameter, the share of Σ J_ri² that falls on each series (empty without rows or effect)."""
    p = jac.shape[1]
    if rows is None:
        return [{} for _ in range(p)]
    labels = np.asarray(rows)
    order = list(dict.fromkeys(rows))
    out = []
    for i in range(p):
        sq = jac[:, i] ** 2
        total = float(sq.sum())
        out.append({sid: float(sq[labels == sid].sum() / total) for sid in order} if total > 0 else {})
    return out


def _by_station(shares: dict[str, float]) -> dict[str, float]:
    out: dict[str, float] = {}
    for sid, f in shares.items():
        out[station_of(sid)] = out.get(station_of(sid), 0.0) + f
    return out


def _effects(jac: np.ndarray, d: np.ndarray, rows: Sequence[str] | None,
             sqrt_weights: np.ndarray | None) -> np.ndarray:
    """Largest change of an observed level (m) when a parameter moves over its scale (linearised); NaN if unknown."""
    p = jac.shape[1]
    if rows is None or sqrt_weights is None:
        return np.full(p, np.nan)
    sw = np.asarray(sqrt_weights, dtype=float)
    levels = np.array([not r.endswith(".Q") for r in rows])
    if not levels.any():
        return np.full(p, np.nan)
    change = np.abs(jac[levels] * d / sw[levels, None])
    return change.max(axis=0)


def _and(items: Sequence[str]) -> str:
    """``A``, ``A and B``, ``A, B and C``."""
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _pct(fraction: float) -> str:
    """A share as a percentage with the digits that matter (25%, 2.4%, 0.009%)."""
    if fraction < 1e-6:
        return "practically 0%"
    if fraction >= 0.1:
        return f"{fraction:.0%}"
    if fraction >= 0.001:
        return f"{fraction:.1%}"
    return f"{100 * fraction:.1g}%"


class _Words:
    """Plain-language sentences for the verdict."""

    def __init__(self, context: Context, names: tuple[str, ...], d: np.ndarray, s: np.ndarray, v: np.ndarray, k: int,
                 opts: IdentifiabilityOptions, shares: list[dict[str, float]], effect: np.ndarray, jd: np.ndarray,
                 scale_words: str):
        self.c, self.names, self.d, self.s, self.v, self.k, self.opts = context, names, d, s, v, k, opts
        self.shares, self.effect, self.jd, self.scale_words = shares, effect, jd, scale_words

    def label(self, i: int) -> str:
        desc = self.c.descriptions.get(self.names[i], "")
        return f"{self.names[i]} ({desc})" if desc else self.names[i]

    def amount(self, i: int, value: float) -> str:
        """A difference of parameter i in its unit (levels in cm below 1 m)."""
        unit = self.c.units.get(self.names[i], "")
        if unit in ("m AD", "m", "m NAP"):
            return f"{100 * value:.2g} cm" if abs(value) < 1 else f"{value:.3g} m"
        return f"{value:.3g} {unit}".strip()

    def station(self, st: str) -> str:
        what = self.c.stations.get(st)
        return f"station {st}, which measures {what}," if what else f"station {st}"

    def where(self, i: int, *, little: bool = False) -> str:
        """Which station sees parameter i (the share of its squared sensitivity)."""
        series = self.shares[i]
        if not series:
            return ""
        stations = _by_station(series)
        top = max(stations, key=lambda st: (stations[st], st))
        in_top = {sid: f for sid, f in series.items() if station_of(sid) == top}
        top_series = max(in_top, key=lambda sid: (in_top[sid], sid))
        mostly = f"mostly in {top_series}" if len(in_top) > 1 else top_series
        signal = "its small signal" if little else "its signal"
        if top in self.c.at.get(self.names[i], ()):
            return f"station {top} measures right at this weir ({_pct(stations[top])} of {signal}, {mostly})"
        if stations[top] >= 0.5:
            return f"{_pct(stations[top])} of {signal} is at {self.station(top)} {mostly}"
        ranked = sorted(stations.items(), key=lambda kv: (-kv[1], kv[0]))[:3]
        return f"{signal} is spread over several stations (" + ", ".join(
            f"{st} {_pct(f)}" for st, f in ranked) + ")"

    def parameter(self, i: int, frame: pd.DataFrame) -> str:
        name = self.names[i]
        row = frame.iloc[i]
        verdict, ident = row["verdict"], row["index"]
        if verdict == IDENTIFIABLE:
            text = f"{self.label(i)} is identifiable (identifiability index {ident:.2f})"
            where = self.where(i)
            text += f": {where}" if where else ""
            if math.isfinite(row["std"]):
                text += f". With the observation errors it is determined to ±{self.amount(i, row['std'])}"
            mixed = self.mixed_with(i)
            if mixed:
                text += (f". Its effect is mixed with that of {_and(mixed)} in the best-seen directions, but these "
                         "are all seen clearly, so the observations still separate them")
            return text + "."
        if verdict == NOT_IDENTIFIABLE:
            strength = float(np.linalg.norm(self.jd[:, i]) / self.s[0]) if self.s[0] > 0 else 0.0
            text = f"{self.label(i)} is not identifiable (identifiability index {ident:.2f}): "
            if strength == 0.0:
                return text + "no observation changes at all when it changes. Keep it at its current value."
            text += (f"moving it over {self.scale_words} ({self.amount(i, self.d[i])}) is seen only {_pct(strength)} "
                     "as strongly as the best-seen parameter combination")
            if math.isfinite(self.effect[i]):
                text += f" and changes the observed levels by at most about {self.amount_level(self.effect[i])}"
            where = self.where(i, little=True)
            if where and name not in self.c.at:
                text += f". No station measures at this weir; {where}"
            elif where:
                text += f"; even so, {where}"
            return text + ". Keep it at its current value, or add a measurement near it."
        return self.combination(i, row)

    @staticmethod
    def amount_level(value: float) -> str:
        return f"{100 * value:.2g} cm" if value < 1 else f"{value:.3g} m"

    def mixed_with(self, i: int) -> list[str]:
        """Parameters that take part in a significant singular vector together with parameter i."""
        loads = self.v**2 >= self.opts.loading
        return [self.names[q] for q in range(len(self.names))
                if q != i and any(loads[i, j] and loads[q, j] for j in range(self.k))]

    def combination(self, i: int, row: pd.Series) -> str:
        partners = [p for p in str(row["partners"]).split(", ") if p]
        text = f"{self.label(i)} is identifiable only in combination"
        text += f" with {', '.join(partners)}" if partners else ""
        text += f" (identifiability index {row['index']:.2f})"
        j = self.shared_weak_vector(i)
        if j is not None:
            return text + ": " + self.direction(j) + "."
        if row["correlated_with"]:
            return (text + f": its effect on the stations resembles that of {row['correlated_with']} "
                    f"(correlation {row['max_correlation']:+.2f}), so the observations fix only a mix of the two.")
        return text + f": only {_pct(row['index'])} of it lies in the combinations the observations see."

    def shared_weak_vector(self, i: int) -> int | None:
        """The weakest singular vector beyond k in which parameter i and another parameter take part."""
        loads = self.v**2 >= self.opts.loading
        for j in range(self.v.shape[1] - 1, self.k - 1, -1):
            if loads[i, j] and np.count_nonzero(loads[:, j]) >= 2:
                return j
        return None

    def direction(self, j: int) -> str:
        """Describe singular vector j as a change of parameters that the stations hardly notice."""
        vj = self.v[:, j]
        members = [q for q in np.argsort(-vj, kind="stable") if vj[q] ** 2 >= self.opts.loading]
        c = 0.1 / max(abs(vj[q]) for q in members)  # the largest move: 10 % of that parameter's scale
        moves = []
        for q in members:
            delta = c * vj[q] * self.d[q]
            moves.append(f"{'raising' if delta > 0 else 'lowering'} {self.names[q]} by {self.amount(q, abs(delta))}")
        rel = self.s[j] / self.s[0] if self.s[0] > 0 else 0.0
        together = moves[0] + "".join(f" together with {m}" for m in moves[1:])
        return (f"{together} changes what the stations measure hardly at all (singular vector {j + 1}, seen "
                f"{_pct(rel)} as strongly as the best-seen combination), so the observations cannot tell them apart")


def _clusters(frame: pd.DataFrame, names: tuple[str, ...], corr: np.ndarray, s: np.ndarray, v: np.ndarray, k: int,
              opts: IdentifiabilityOptions, jd: np.ndarray, words: _Words) -> tuple[ClusterSuggestion, ...]:
    p = len(names)
    candidates = [i for i in range(p) if frame.iloc[i]["verdict"] != IDENTIFIABLE]
    loads = v**2 >= opts.loading
    parent = {i: i for i in candidates}

    def find(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for a in candidates:
        for b in candidates:
            if b <= a:
                continue
            shared = any(loads[a, j] and loads[b, j] for j in range(k, p))
            c = corr[a, b]
            if shared or (np.isfinite(c) and abs(c) > opts.correlation):
                ra, rb = find(a), find(b)
                parent[max(ra, rb)] = min(ra, rb)
    groups: dict[int, list[int]] = {}
    for i in candidates:
        groups.setdefault(find(i), []).append(i)
    out = []
    unseen = []
    for members in sorted(groups.values(), key=lambda g: g[0]):
        if len(members) == 1:
            if frame.iloc[members[0]]["verdict"] == NOT_IDENTIFIABLE:
                unseen.append(members[0])
            continue
        out.append(_group(members, names, s, jd, opts, "they cannot be told apart"))
    if unseen:
        out.append(_group(unseen, names, s, jd, opts, "none of them is seen on its own"))
    return tuple(out)


def _group(members: list[int], names: tuple[str, ...], s: np.ndarray, jd: np.ndarray, opts: IdentifiabilityOptions,
           why: str) -> ClusterSuggestion:
    """Cluster (moved together they are seen) or fix (even together they are not)."""
    labels = tuple(names[i] for i in members)
    together = jd[:, members].sum(axis=1) / np.sqrt(len(members))  # unit-length direction (1, …, 1)/√g
    strength = float(np.linalg.norm(together) / s[0]) if s[0] > 0 else 0.0
    listed = _and(labels)
    if len(members) == 1:
        return ClusterSuggestion(labels, "fix", strength, f"fix {listed} at its current value: the stations hardly "
                                 f"see it (seen {_pct(strength)} as strongly as the best-seen combination).")
    if strength >= opts.sv_threshold:
        return ClusterSuggestion(labels, "cluster", strength, (
            f"cluster {listed} into one parameter ({why}; as the thesis' Wc does, every member at the same fraction "
            f"of its range): moved together they are seen {_pct(strength)} as strongly as the best-seen combination, "
            "enough to estimate the cluster."))
    return ClusterSuggestion(labels, "fix", strength, (
        f"fix {listed} at their current values ({why}): even moved together, every one at the same fraction of its "
        f"range, they are seen only {_pct(strength)} as strongly as the best-seen combination."))


def identifiability(problem: Any, x: np.ndarray | None = None, *, rel_step: float = 0.01,
                    scheme: Literal["forward", "central"] = "forward",
                    scale: Sequence[float] | np.ndarray | None = None,
                    options: IdentifiabilityOptions | Mapping[str, Any] | None = None, batch: Batch | None = None,
                    workers: int | None = None, context: Context | None = None,
                    jacobian: Jacobian | None = None) -> Identifiability:
    """Identifiability analysis of a calibration problem at ``x`` (thesis §4-5-1, Figs. 4-6 and 4-7).

    Parameters
    ----------
    problem
        A :class:`~rivercal.problem.CalibrationProblem`.
    x
        The point (optimiser units; default the initial values).
    rel_step, scheme, scale
        Finite differences (see :func:`fd_jacobian`); ``scale`` also scales the SVD (default: ranges).
    options
        Verdict thresholds (:class:`IdentifiabilityOptions`).
    batch, workers
        Batch evaluator or number of worker processes for the p + 1 (or 2p + 1) runs.
    context
        Words for the verdict (default: from the problem's parameters and the model's stations).
    jacobian
        A Jacobian computed before (no model runs then).

    Returns
    -------
    Identifiability
        With ``extra["nfev"]`` (model runs) and ``extra["jacobian"]`` (the :class:`Jacobian`).
    """
    jac = jacobian or fd_jacobian(problem, x, rel_step=rel_step, scale=scale, scheme=scheme, batch=batch,
                                  workers=workers)
    result = analyse_jacobian(jac.matrix, jac.names, scale=jac.scale, rows=jac.rows, options=options,
                              context=context or context_from_problem(problem), sqrt_weights=problem.sqrt_weights,
                              scale_words="its whole range" if scale is None else "its scale")
    result.extra.update(nfev=jac.nfev, jacobian=jac)
    return result
