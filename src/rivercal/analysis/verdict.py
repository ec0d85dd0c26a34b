"""The identifiability verdict's rules (steps 1-4 of :mod:`rivercal.analysis.identifiability`) and thresholds.

Deterministic: fixed thresholds, no random numbers. Given the singular values and vectors of the scaled
Jacobian, the identifiability index and the correlations, this module decides per parameter whether it is
identifiable, identifiable only in combination or not identifiable, and which groups to cluster or fix.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.optimise import covariance

__all__ = [
    "COMBINATION",
    "DOHERTY_HUNT_2009",
    "IDENTIFIABLE",
    "NOT_IDENTIFIABLE",
    "ClusterSuggestion",
    "IdentifiabilityOptions",
    "group_strength",
    "identifiability_index",
    "suggest_clusters",
    "verdict_frame",
]

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
    reason
        ``indistinct`` (they share a weak direction or are strongly correlated) or ``unseen`` (none of
        them is seen on its own).
    """

    members: tuple[str, ...]
    action: Literal["cluster", "fix"]
    strength: float
    reason: Literal["indistinct", "unseen"]

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly."""
        return {"members": list(self.members), "action": self.action, "strength": self.strength,
                "reason": self.reason}


def _reduced_correlation(jac: np.ndarray, keep: np.ndarray, rcond: float) -> np.ndarray:
    """Correlations among the ``keep`` parameters with the others held fixed (NaN elsewhere)."""
    p = jac.shape[1]
    out = np.full((p, p), np.nan)
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        return out
    sub = jac[:, idx]
    norms = np.linalg.norm(sub, axis=0)
    out[np.ix_(idx, idx)] = covariance(sub, scale=1.0 / np.where(norms > 0, norms, 1.0), rcond=rcond).correlation
    return out


def _verdicts(index: np.ndarray, reduced: np.ndarray, opts: IdentifiabilityOptions) -> list[str]:
    """Step 2: the verdict per parameter from its identifiability index and its reduced correlations."""
    others = np.abs(np.nan_to_num(reduced, nan=0.0))
    np.fill_diagonal(others, 0.0)
    strong = np.any(others > opts.correlation, axis=1)  # correlated with another parameter beyond the threshold
    return [NOT_IDENTIFIABLE if ident < opts.unidentifiable else
            IDENTIFIABLE if not corr and ident >= opts.identifiable else COMBINATION
            for ident, corr in zip(index.tolist(), strong.tolist(), strict=True)]


def verdict_labels(jac: np.ndarray, index: np.ndarray, opts: IdentifiabilityOptions) -> list[str]:
    """Step 2 alone: the verdict per parameter, as :func:`verdict_frame` gives it (for ranking many sets fast)."""
    reduced = _reduced_correlation(jac, index >= opts.unidentifiable, opts.rcond)
    return _verdicts(index, reduced, opts)


def verdict_frame(jac: np.ndarray, names: tuple[str, ...], s: np.ndarray, v: np.ndarray, k: int, index: np.ndarray,
             std: np.ndarray, opts: IdentifiabilityOptions) -> pd.DataFrame:
    """Steps 2 and 3: the verdict per parameter, its partners and strongest correlation."""
    p = len(names)
    not_id = index < opts.unidentifiable
    reduced = _reduced_correlation(jac, ~not_id, opts.rcond)
    loads = v**2 >= opts.loading
    verdicts = _verdicts(index, reduced, opts)
    partners, max_corr, corr_with = [], [], []
    for i in range(p):
        share_partners = sorted({q for j in range(k, p) if loads[i, j] for q in range(p) if q != i and loads[q, j]})
        row = np.abs(np.nan_to_num(reduced[i], nan=0.0))
        row[i] = 0.0
        c_idx = int(np.argmax(row)) if p > 1 else i
        strong = sorted(q for q in range(p) if q != i and row[q] > opts.correlation)
        partners.append(", ".join(names[q] for q in sorted(set(share_partners) | set(strong))))
        seen = p > 1 and c_idx != i and row[c_idx] > 0
        max_corr.append(float(reduced[i, c_idx]) if seen else np.nan)
        corr_with.append(names[c_idx] if seen else "")
    dominant = np.argmax(v**2, axis=1)
    return pd.DataFrame({
        "verdict": verdicts,
        "index": index,
        "std": std,
        "dominant_vector": dominant + 1,
        "dominant_share": v[np.arange(p), dominant] ** 2,
        "partners": partners,
        "max_correlation": max_corr,
        "correlated_with": corr_with,
    }, index=pd.Index(names, name="parameter"))


def suggest_clusters(frame: pd.DataFrame, correlation: np.ndarray, vectors: np.ndarray, k: int,
                     opts: IdentifiabilityOptions,
                     strength: Callable[[list[int]], float]) -> tuple[ClusterSuggestion, ...]:
    """Step 4: groups of parameters not identifiable on their own; ``strength(members)`` as :func:`group_strength`."""
    v = vectors
    names = tuple(frame.index)
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
            c = correlation[a, b]
            if shared or (np.isfinite(c) and abs(c) > opts.correlation):
                ra, rb = find(a), find(b)
                parent[max(ra, rb)] = min(ra, rb)
    groups: dict[int, list[int]] = {}
    for i in candidates:
        groups.setdefault(find(i), []).append(i)
    out, unseen = [], []
    for members in sorted(groups.values(), key=lambda g: g[0]):
        if len(members) == 1:
            if frame.iloc[members[0]]["verdict"] == NOT_IDENTIFIABLE:
                unseen.append(members[0])
            continue
        out.append(_group(names, members, "indistinct", opts, strength))
    if unseen:
        out.append(_group(names, unseen, "unseen", opts, strength))
    return tuple(out)


def _group(names: tuple[str, ...], members: list[int], reason: Literal["indistinct", "unseen"],
           opts: IdentifiabilityOptions, strength: Callable[[list[int]], float]) -> ClusterSuggestion:
    """Cluster (moved together they are seen) or fix (even together they are not)."""
    seen = strength(members)
    action: Literal["cluster", "fix"] = "cluster" if len(members) > 1 and seen >= opts.sv_threshold else "fix"
    return ClusterSuggestion(tuple(names[i] for i in members), action, seen, reason)


def group_strength(jd: np.ndarray, s1: float, members: Sequence[int]) -> float:
    """‖J_D 1‖ / (√g s_1): how strongly moving the g ``members`` together (same fraction of scale) is seen."""
    together = jd[:, list(members)].sum(axis=1) / np.sqrt(len(members))
    return float(np.linalg.norm(together) / s1) if s1 > 0 else 0.0


