"""The linear worth of candidate gauges: information, posterior covariance, verdicts and the greedy choice.

The numerics of :mod:`rivercal.analysis.advise`, whose module docstring gives the notation and the equations.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from rivercal.analysis.identifiability import (
    IDENTIFIABLE,
    Identifiability,
    IdentifiabilityOptions,
    analyse_jacobian,
)
from rivercal.analysis.verdict import identifiability_index, verdict_labels
from rivercal.optimise import covariance

__all__ = ["Assessment", "Candidate", "LinearWorth", "Step", "posterior_covariance"]


@dataclass(frozen=True)
class Candidate:
    """A place where a gauge could be added.

    Attributes
    ----------
    id
        Station id of the place; its series are ``"<id>.<quantity>"``.
    series
        The series the gauge would measure.
    name
        The place in words.
    cost
        What the gauge there costs (any unit, the same for all candidates), or None.
    location
        The model's :class:`~rivercal.models.capabilities.Location` (branch, chainage, structure, point, x, y).
    """

    id: str
    series: tuple[str, ...]
    name: str = ""
    cost: float | None = None
    location: Any = None



def posterior_covariance(information: np.ndarray, prior_var: np.ndarray) -> np.ndarray:
    """Σ = (F + C_p⁻¹)⁻¹ for information F (p × p, or a stack (n, p, p)) and prior variances (p,).

    Solved in units of the prior σ (F̃ = S F S with S = diag(σ_p): F̃ + I is well conditioned), then
    scaled back.
    """
    f = np.asarray(information, dtype=float)
    s = np.sqrt(np.asarray(prior_var, dtype=float))
    scaled = f * s[:, None] * s[None, :]
    eye = np.eye(s.size)
    inv = np.linalg.inv(scaled + eye)
    inv = 0.5 * (inv + np.swapaxes(inv, -1, -2))
    return inv * s[:, None] * s[None, :]


def _factor(information: np.ndarray) -> np.ndarray:
    """R (p × p) with RᵀR = F for a symmetric positive semi-definite F (eigenvalues below zero count as zero)."""
    w, q = np.linalg.eigh(0.5 * (information + information.T))
    return np.sqrt(np.clip(w, 0.0, None))[:, None] * q.T


@dataclass(frozen=True)
class Assessment:
    """What a set of gauges gives: identifiability and posterior uncertainty.

    Attributes
    ----------
    gauges
        The added candidates' ids (the present stations are always in).
    identifiability
        The analysis of the stacked Jacobian (:class:`~rivercal.analysis.identifiability.Identifiability`).
    identifiable
        Number of parameters whose verdict is identifiable.
    smallest_singular_value
        Smallest singular value of J_D (dimensionless: the weighted-residual change when the least-seen
        combination of parameters moves over its scale).
    posterior_std
        Posterior σ per parameter, optimiser units (physical for offset parameters).
    forecast_std
        Posterior σ per forecast, its unit (m or m³/s).
    relative_variance
        Mean over the targets of σ_t²(S) / σ_t²(prior): 1 before any data, 0 for a perfectly known target.
    """

    gauges: tuple[str, ...]
    identifiability: Identifiability
    identifiable: int
    smallest_singular_value: float
    posterior_std: np.ndarray
    forecast_std: dict[str, float]
    relative_variance: float

    @property
    def verdicts(self) -> dict[str, str]:
        """The verdict per parameter."""
        ident = self.identifiability
        return {n: str(ident.verdict.loc[n, "verdict"]) for n in ident.names}

    def summary(self) -> dict[str, Any]:
        """JSON-friendly."""
        ident = self.identifiability
        return {"gauges": list(self.gauges), "identifiable": self.identifiable,
                "parameters": len(ident.names), "verdict": self.verdicts,
                "identifiability_index": {n: float(v) for n, v in zip(ident.names, ident.index, strict=True)},
                "singular_values": [float(v) for v in ident.singular_values],
                "smallest_singular_value": self.smallest_singular_value,
                "posterior_std": {n: float(v) for n, v in zip(ident.names, self.posterior_std, strict=True)},
                "forecast_std": dict(self.forecast_std), "relative_variance": self.relative_variance}


@dataclass(frozen=True)
class Step:
    """One pick of the greedy choice.

    Attributes
    ----------
    number
        1 for the first gauge added.
    candidate
        The id picked.
    worth
        Its worth given the gauges picked before (mean fractional variance reduction of the targets).
    assessment
        The set after the pick.
    """

    number: int
    candidate: str
    worth: float
    assessment: Assessment


class LinearWorth:
    """The linear analysis of present stations, candidate gauges and forecasts (module docstring).

    Parameters
    ----------
    names
        Parameter names (p).
    base
        J₀, the weighted Jacobian of the present stations (m₀ × p, per optimiser unit; rows in units of σ).
    candidates
        The candidates, in order.
    blocks
        Per candidate id its weighted Jacobian J_c (m_c × p).
    prior_std
        Prior σ per parameter (p,), optimiser units.
    scale
        The scales d (p,) of the identifiability analysis (default: ones).
    forecasts
        Per forecast name its sensitivity y_f = ∂f/∂x (p,), forecast unit per optimiser unit.
    options
        Thresholds of the verdict.
    base_rows
        Series id of every row of ``base`` (for the final analysis' station shares).
    """

    def __init__(self, names: Sequence[str], base: np.ndarray, candidates: Sequence[Candidate],
                 blocks: Mapping[str, np.ndarray], prior_std: np.ndarray, *, scale: np.ndarray | None = None,
                 forecasts: Mapping[str, np.ndarray] | None = None,
                 options: IdentifiabilityOptions | None = None, base_rows: Sequence[str] | None = None):
        self.names = tuple(names)
        p = len(self.names)
        self.base = np.asarray(base, dtype=float).reshape(-1, p)
        self.candidates = tuple(candidates)
        ids = [c.id for c in self.candidates]
        if len(set(ids)) != len(ids):
            raise ValueError(f"candidate ids must be unique; {sorted({i for i in ids if ids.count(i) > 1})[0]!r} "
                             "appears twice")
        missing = [i for i in ids if i not in blocks]
        if missing:
            raise ValueError(f"no Jacobian rows for candidate {missing[0]!r}")
        self.blocks = {i: np.asarray(blocks[i], dtype=float).reshape(-1, p) for i in ids}
        self.prior_var = np.asarray(prior_std, dtype=float) ** 2
        if self.prior_var.shape != (p,) or not np.all(np.isfinite(self.prior_var)) or np.any(self.prior_var <= 0):
            raise ValueError(f"prior_std must hold {p} positive finite numbers")
        self.scale = np.ones(p) if scale is None else np.asarray(scale, dtype=float)
        self.forecasts = {k: np.asarray(v, dtype=float).reshape(p) for k, v in (forecasts or {}).items()}
        self.options = options or IdentifiabilityOptions()
        self.base_rows = tuple(base_rows) if base_rows is not None else None
        self.base_info = self.base.T @ self.base
        self.info = {i: b.T @ b for i, b in self.blocks.items()}
        # the targets of the worth: the forecasts' sensitivities, else the parameters' unit vectors
        if self.forecasts:
            self.targets = tuple(self.forecasts)
            self.target_vectors = np.array([self.forecasts[k] for k in self.targets])
        else:
            self.targets = self.names
            self.target_vectors = np.eye(p)
        self.prior_target_var = np.einsum("tp,p,tp->t", self.target_vectors, self.prior_var, self.target_vectors)
        if np.any(self.prior_target_var <= 0):
            zero = [t for t, v in zip(self.targets, self.prior_target_var, strict=True) if v <= 0]
            raise ValueError(f"forecast {zero[0]!r} does not depend on any parameter (its sensitivities are zero)")
        self.costs = {c.id: c.cost for c in self.candidates}

    # -- numbers of one set --------------------------------------------------------------------------

    def information(self, gauges: Iterable[str]) -> np.ndarray:
        """F(S) = J₀ᵀJ₀ + Σ J_cᵀJ_c (p × p)."""
        out = self.base_info.copy()
        for g in gauges:
            out += self.info[g]
        return out

    def target_variance(self, information: np.ndarray) -> np.ndarray:
        """σ_t² of every target for information F (or a stack of them: (n, targets))."""
        cov = posterior_covariance(information, self.prior_var)
        y = self.target_vectors
        return np.einsum("tp,...pq,tq->...t", y, cov, y)

    def assess(self, gauges: Sequence[str], *, rows: bool = False) -> Assessment:
        """Identifiability and posterior uncertainty with ``gauges`` added.

        ``rows``: analyse the stacked Jacobian itself (series shares, effects), not its p × p factor.
        """
        info = self.information(gauges)
        if rows:
            jac = np.vstack([self.base, *(self.blocks[g] for g in gauges)])
            names = (self.base_rows or ("",) * self.base.shape[0]) + tuple(
                s for g in gauges for s in self._row_names(g))
            ident = analyse_jacobian(jac, self.names, scale=self.scale, rows=names, options=self.options)
        else:
            ident = analyse_jacobian(_factor(info), self.names, scale=self.scale, options=self.options)
        cov = posterior_covariance(info, self.prior_var)
        var = np.einsum("tp,pq,tq->t", self.target_vectors, cov, self.target_vectors)
        forecast_std = {}
        for name, y in self.forecasts.items():
            forecast_std[name] = float(math.sqrt(max(float(y @ cov @ y), 0.0)))
        n_id = int((ident.verdict["verdict"] == IDENTIFIABLE).sum())
        s = ident.singular_values
        return Assessment(gauges=tuple(gauges), identifiability=ident, identifiable=n_id,
                          smallest_singular_value=float(s[-1]) if s.size else 0.0,
                          posterior_std=np.sqrt(np.clip(np.diag(cov), 0.0, None)), forecast_std=forecast_std,
                          relative_variance=float(np.mean(var / self.prior_target_var)))

    def verdicts(self, information: np.ndarray) -> tuple[dict[str, str], np.ndarray]:
        """The verdict per parameter and the singular values of J_D for information F.

        Steps 1-3 of the verdict of :mod:`rivercal.analysis.identifiability` on R with RᵀR = F, without the
        cluster suggestions and words (what ranking a candidate needs).
        """
        r, opts = _factor(information), self.options
        cov = covariance(r, scale=self.scale, rcond=opts.rcond)
        s, v = cov.singular_values, cov.vectors
        if opts.k is not None:
            k = min(opts.k, len(self.names))
        else:
            k = int(np.count_nonzero((s > 0) & (s >= opts.sv_threshold * s[0]))) if s[0] > 0 else 0
        return dict(zip(self.names, verdict_labels(r, identifiability_index(v, k), opts), strict=True)), s

    def _row_names(self, candidate: str) -> list[str]:
        c = next(c for c in self.candidates if c.id == candidate)
        n = self.blocks[candidate].shape[0]
        per = n // max(len(c.series), 1)
        return [s for s in c.series for _ in range(per)] if per * len(c.series) == n else [c.id] * n

    # -- every candidate at once ----------------------------------------------------------------------

    def worth_table(self, gauges: Sequence[str] = (), among: Sequence[str] | None = None) -> pd.DataFrame:
        """Every candidate not in ``gauges``, added to them: its worth and what the set then gives.

        ``among`` limits the table to those candidates (their rows are the same as in the whole table: each row
        depends only on ``gauges`` and its own candidate).

        Returns
        -------
        DataFrame
            Index: candidate id. Columns ``name``, ``cost``, ``worth`` (mean fractional variance reduction of
            the targets), ``worth_per_cost``, ``identifiable`` (parameters identifiable with it),
            ``smallest_singular_value``, ``relative_variance``, ``verdict:<parameter>``,
            ``std:<parameter>`` (posterior σ, optimiser units), ``var:<target>`` (posterior variance of each
            target); sorted by identifiable, then worth (per cost where there are costs), descending.
        """
        chosen = set(gauges)
        left = [c for c in self.candidates if c.id not in chosen and (among is None or c.id in among)]
        if not left:
            return pd.DataFrame()
        base_info = self.information(gauges)
        now = self.target_variance(base_info)
        stack = np.array([base_info + self.info[c.id] for c in left])
        cov = posterior_covariance(stack, self.prior_var)
        var = np.einsum("tp,npq,tq->nt", self.target_vectors, cov, self.target_vectors)
        worth = np.mean(1.0 - var / now, axis=1)
        rows = []
        for i, c in enumerate(left):
            verdicts, sv = self.verdicts(stack[i])
            row: dict[str, Any] = {"candidate": c.id, "name": c.name, "cost": c.cost, "worth": float(worth[i]),
                                   "identifiable": sum(v == IDENTIFIABLE for v in verdicts.values()),
                                   "smallest_singular_value": float(sv[-1]),
                                   "relative_variance": float(np.mean(var[i] / self.prior_target_var))}
            row.update({f"verdict:{n}": v for n, v in verdicts.items()})
            row.update({f"std:{n}": float(math.sqrt(max(cov[i, j, j], 0.0))) for j, n in enumerate(self.names)})
            row.update({f"var:{t}": float(var[i, k]) for k, t in enumerate(self.targets)})
            rows.append(row)
        table = pd.DataFrame(rows).set_index("candidate")
        table["worth_per_cost"] = [w / c if c else np.nan for w, c in zip(table["worth"], table["cost"], strict=True)]
        return table.sort_values(["identifiable", self._rank_column(), "smallest_singular_value"],
                                 ascending=False, kind="stable")

    def _rank_column(self) -> str:
        return "worth_per_cost" if any(c is not None for c in self.costs.values()) else "worth"

    # -- the choice ----------------------------------------------------------------------------------

    def greedy(self, k: int | None = None, *, exchange: bool = True, max_add: int | None = None,
               progress: Callable[[str], None] | None = None) -> list[Step]:
        """Choose gauges one at a time, re-evaluating every candidate after each pick (module docstring).

        Parameters
        ----------
        k
            Number of gauges to add; None: until every parameter is identifiable (at most ``max_add``,
            default p), or until no candidate adds anything.
        exchange
            Improve the chosen set by one-for-one swaps afterwards (the steps are then those of the greedy
            order within the improved set).
        max_add
            Upper bound of the picks without ``k``.
        progress
            Called with a line per pick.
        """
        p = len(self.names)
        limit = len(self.candidates) if k is None else min(k, len(self.candidates))
        if k is None:
            limit = min(limit, max_add if max_add is not None else p)
        chosen: list[str] = []
        while len(chosen) < limit:
            now = self.assess(chosen)
            if k is None and now.identifiable == p:
                break
            table = self.worth_table(chosen)
            if table.empty:
                break
            best = table.index[0]
            if k is None and table.iloc[0]["identifiable"] <= now.identifiable and table.iloc[0]["worth"] <= 1e-9:
                break  # nothing left adds anything
            chosen.append(str(best))
            if progress:
                progress(f"gauge {len(chosen)}: {best} ({table.iloc[0]['name']}), {int(table.iloc[0]['identifiable'])} "
                         f"of {p} identifiable")
        if exchange and chosen:
            improved = self.exchange(chosen)
            if set(improved) != set(chosen):
                chosen = self._order(improved)
        return self.steps(chosen)

    def _score(self, gauges: Sequence[str]) -> tuple[int, float]:
        """(identifiable parameters, − mean fractional variance of the targets) of a set: higher is better."""
        info = self.information(gauges)
        verdicts, _ = self.verdicts(info)
        return sum(v == IDENTIFIABLE for v in verdicts.values()), -float(np.mean(self.target_variance(info)
                                                                       / self.prior_target_var))

    def exchange(self, chosen: Sequence[str], *, passes: int = 3) -> list[str]:
        """One-for-one swaps of chosen gauges for others while the set's score improves (module docstring)."""
        best = list(chosen)
        score = self._score(best)
        others = [c.id for c in self.candidates]
        for _ in range(passes):
            better = False
            for i in range(len(best)):
                for c in others:
                    if c in best:
                        continue
                    trial = [*best[:i], c, *best[i + 1:]]
                    s = self._score(trial)
                    if s > (score[0], score[1] + 1e-9):
                        best, score, better = trial, s, True
            if not better:
                break
        return best

    def _order(self, gauges: Sequence[str]) -> list[str]:
        """``gauges`` in greedy order among themselves."""
        left, out = list(gauges), []
        while left:
            table = self.worth_table(out, among=left)
            pick = next(i for i in table.index if i in left)
            out.append(str(pick))
            left.remove(pick)
        return out

    def steps(self, gauges: Sequence[str]) -> list[Step]:
        """The gain of each gauge in turn (the worth of gauge i given gauges 1 … i − 1)."""
        out = []
        for i, g in enumerate(gauges):
            before = self.information(gauges[:i])
            after = before + self.info[g]
            v0, v1 = self.target_variance(before), self.target_variance(after)
            worth = float(np.mean(1.0 - v1 / v0))
            out.append(Step(i + 1, g, worth, self.assess(list(gauges[: i + 1]))))
        return out


