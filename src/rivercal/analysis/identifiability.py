"""Identifiability and uniqueness of parameters (thesis §2-3-1-2, Eq. 2-10 … 2-13; Figs. 4-6 and 4-7): the numbers.

The Jacobian J (thesis Eq. 2-10) of the *weighted* residuals r = √W (y − ŷ) with respect to the
optimiser's vector x comes from :mod:`rivercal.analysis.jacobian`. Parameters of different units are made
comparable by scaling its columns with the parameters' scales d (by default their ranges): J_D = J · diag(d),
so that column j is the change of the weighted residuals when parameter j moves over its whole range
(linearised). Its singular value decomposition J_D = U Σ Vᵀ (thesis Eq. 2-11) gives the singular values
(how strongly each combination of parameters is seen, dimensionless) and the right singular vectors v_j
(columns of V: which parameters make up the combination). The covariance is (JᵀJ)⁻¹ in optimiser units
(thesis Eq. 2-12; the pseudo-inverse when JᵀJ is singular) and the correlation follows from thesis
Eq. 2-13 (both from :func:`rivercal.optimise.covariance`); the correlation does not depend on the scaling.
With the weights 1/σ², √diag(cov) is the standard deviation of each estimate for observation errors of σ.

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

This module computes numbers and verdicts only; the sentences that explain them to a user are written by
:mod:`rivercal.report.identifiability`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.analysis._common import Batch, Context, context_from_problem, station_of
from rivercal.analysis.jacobian import Jacobian, fd_jacobian
from rivercal.analysis.verdict import (
    COMBINATION,
    DOHERTY_HUNT_2009,
    IDENTIFIABLE,
    NOT_IDENTIFIABLE,
    ClusterSuggestion,
    IdentifiabilityOptions,
    group_strength,
    identifiability_index,
    suggest_clusters,
    verdict_frame,
)
from rivercal.optimise import covariance

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



# --------------------------------------------------------------------------------------------------
# the analysis
# --------------------------------------------------------------------------------------------------


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
        errors of the weights' σ (inf in a direction the observations do not see).
    correlation
        Thesis Eq. 2-13 (NaN for a parameter without any effect).
    singular
        Whether JᵀJ was singular to working precision (pseudo-inverse used).
    verdict
        One row per parameter: ``verdict``, ``index``, ``std``, ``dominant_vector`` (1-based) and
        ``dominant_share`` (V_ij² there), ``partners``, ``max_correlation`` and ``correlated_with``
        (not-identifiable parameters held fixed), ``top_station`` and ``top_station_share`` (share of
        the parameter's squared sensitivity at that station), ``effect`` (the largest change of an
        observed level when the parameter moves over its scale, linearised, m; NaN if unknown).
    clusters
        Suggested groups.
    options
        The thresholds used.
    rows
        Series id of every Jacobian row (None when unknown).
    series_shares
        Per parameter, the share of its squared sensitivity Σ J_ri² on each series (empty without rows).
    context
        Descriptions of the parameters and stations (for the words of :mod:`rivercal.report.identifiability`).
    scale_name
        What the scales are (``"its whole range"`` when they are the parameter ranges, else ``"its scale"``).
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
    series_shares: tuple[dict[str, float], ...] = ()
    context: Context = field(default_factory=Context)
    scale_name: str = "its scale"
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
        """JSON-friendly summary (numbers and verdicts; :func:`rivercal.report.identifiability.summary` adds words)."""
        s = self.singular_values
        return {
            "parameters": list(self.names),
            "singular_values": [float(v) for v in s],
            "relative_singular_values": [float(v / s[0]) if s[0] > 0 else 0.0 for v in s],
            "k": self.k,
            "identifiability_index": {n: float(v) for n, v in zip(self.names, self.index, strict=True)},
            "verdict": {n: str(self.verdict.loc[n, "verdict"]) for n in self.names},
            "std": {n: _finite(v) for n, v in zip(self.names, self.std, strict=True)},
            "clusters": [c.to_dict() for c in self.clusters],
            "singular": self.singular,
            "options": {**self.options.__dict__},
            "reference": DOHERTY_HUNT_2009,
        }

    def mixed_with(self, i: int) -> list[str]:
        """Parameters that take part in a significant singular vector together with parameter i."""
        loads = self.vectors**2 >= self.options.loading
        return [self.names[q] for q in range(len(self.names))
                if q != i and any(loads[i, j] and loads[q, j] for j in range(self.k))]

    def shared_weak_vector(self, i: int) -> int | None:
        """The weakest singular vector beyond k in which parameter i and another parameter take part."""
        loads = self.vectors**2 >= self.options.loading
        for j in range(self.vectors.shape[1] - 1, self.k - 1, -1):
            if loads[i, j] and np.count_nonzero(loads[:, j]) >= 2:
                return j
        return None

    def strength(self, members: Sequence[int]) -> float:
        """‖J_D 1‖ / (√g s_1): how strongly moving the g ``members`` together (same fraction of scale) is seen."""
        s1 = float(self.singular_values[0]) if self.singular_values.size else 0.0
        return group_strength(self.jacobian * self.scale, s1, members)


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _options(options: IdentifiabilityOptions | Mapping[str, Any] | None) -> IdentifiabilityOptions:
    if options is None:
        return IdentifiabilityOptions()
    if isinstance(options, IdentifiabilityOptions):
        return options
    return IdentifiabilityOptions(**dict(options))


def analyse_jacobian(jacobian: np.ndarray, names: Sequence[str], *, scale: Sequence[float] | np.ndarray | None = None,
                     rows: Sequence[str] | None = None,
                     options: IdentifiabilityOptions | Mapping[str, Any] | None = None, context: Context | None = None,
                     sqrt_weights: np.ndarray | None = None, scale_name: str = "its scale") -> Identifiability:
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
        Descriptions of parameters and stations, kept for the words (see
        :func:`~rivercal.analysis._common.context_from_problem`).
    sqrt_weights
        √W of every row, to state effects in the units of the observations (m, m³/s).
    scale_name
        What the scales are (``"its whole range"`` when they are the parameter ranges).

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
    opts = _options(options)
    p = len(names)
    d = np.ones(p) if scale is None else np.asarray(scale, dtype=float).reshape(-1)
    if d.shape != (p,) or np.any(~np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"scale must hold {p} positive finite numbers, got {d}")

    cov = covariance(jac, scale=d, rcond=opts.rcond)
    s, v = cov.singular_values, cov.vectors
    if opts.k is not None:
        k = min(opts.k, p)
    else:
        k = int(np.count_nonzero((s > 0) & (s >= opts.sv_threshold * s[0]))) if s[0] > 0 else 0
    index = identifiability_index(v, k)
    frame = verdict_frame(jac, names, s, v, k, index, cov.std, opts)
    shares = _series_shares(jac, rows)
    station_share = [_by_station(sh) for sh in shares]
    frame["top_station"] = [max(sh, key=sh.get) if sh else "" for sh in station_share]
    frame["top_station_share"] = [max(sh.values()) if sh else np.nan for sh in station_share]
    frame["effect"] = _effects(jac, d, rows, sqrt_weights)
    result = Identifiability(names=names, jacobian=jac, scale=d, singular_values=s, vectors=v, k=k, index=index,
                             covariance=cov.matrix, std=cov.std, correlation=cov.correlation, singular=cov.singular,
                             verdict=frame, clusters=(), options=opts, rows=tuple(rows) if rows is not None else None,
                             series_shares=tuple(shares), context=context or Context(), scale_name=scale_name)
    object.__setattr__(result, "clusters", suggest_clusters(frame, cov.correlation, v, k, opts, result.strength))
    return result


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


def _by_station(shares: Mapping[str, float]) -> dict[str, float]:
    out: dict[str, float] = {}
    for sid, f in shares.items():
        out[station_of(sid)] = out.get(station_of(sid), 0.0) + f
    return out


def station_shares(ident: Identifiability, i: int) -> dict[str, float]:
    """Share of parameter i's squared sensitivity per station."""
    return _by_station(ident.series_shares[i]) if ident.series_shares else {}


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


#: With the Jacobian scaled by the parameters' ranges, a largest singular value below this means that no
#: combination of the parameters, moved over their whole ranges, changes the weighted misfit by one observation
#: error σ: the window sees none of them, however the others compare with the largest (the on-line service's
#: identifiability gate uses the same bound of 1, on the parameters' resolutions).
UNSEEN_SV = 1.0


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
        Finite differences (see :func:`~rivercal.analysis.jacobian.fd_jacobian`); ``scale`` also scales the
        SVD (default: ranges).
    options
        Verdict thresholds (:class:`IdentifiabilityOptions`).
    batch, workers
        Batch evaluator or number of worker processes for the p + 1 (or 2p + 1) runs.
    context
        Descriptions of parameters and stations (default: from the problem's parameters and the model's
        stations).
    jacobian
        A Jacobian computed before (no model runs then).

    Returns
    -------
    Identifiability
        With ``extra["nfev"]`` (model runs), ``extra["jacobian"]`` (the :class:`Jacobian`) and ``extra["unseen"]``:
        True when, over the parameters' whole ranges, the largest singular value is below :data:`UNSEEN_SV` (the
        window sees no parameter: every one is not identifiable).
    """
    jac = jacobian or fd_jacobian(problem, x, rel_step=rel_step, scale=scale, scheme=scheme, batch=batch,
                                  workers=workers)
    opts = _options(options)
    kwargs = dict(scale=jac.scale, rows=jac.rows, context=context or context_from_problem(problem),
                  sqrt_weights=problem.sqrt_weights, scale_name="its whole range" if scale is None else "its scale")
    result = analyse_jacobian(jac.matrix, jac.names, options=opts, **kwargs)
    unseen = opts.k is None and scale is None and bool(result.singular_values.size) \
        and float(result.singular_values[0]) < UNSEEN_SV
    if unseen:  # the significance of a singular value is relative to the largest: not when that one sees nothing
        result = analyse_jacobian(jac.matrix, jac.names, options=replace(opts, k=0), **kwargs)
    result.extra.update(nfev=jac.nfev, jacobian=jac, unseen=unseen)
    return result
