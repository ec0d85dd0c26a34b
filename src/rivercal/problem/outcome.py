"""The outcome of a calibration (:class:`Calibration`): estimates in physical units, σ, history, fit report."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from rivercal.optimise import OptimiseResult

__all__ = ["Calibration", "outcome"]


@dataclass(frozen=True)
class Calibration:
    """The outcome of :func:`calibrate`.

    Attributes
    ----------
    result
        The optimiser's :class:`~rivercal.optimise.OptimiseResult` (optimiser coordinates).
    estimates
        Estimated values by parameter name, physical units.
    std
        Standard deviations by name in physical units (thesis Eq. 2-12) for observation errors of the
        weights' σ, where the method gives them.
    std_scaled
        The same scaled by s = √(S/(m − p)), the residual standard deviation the fit shows: right when
        the σ of the weights are right only up to a common factor (e.g. uniform ±a noise weighted as
        σ = a, whose true σ is a/√3).
    initial
        Initial values by name.
    wall_time
        Wall-clock time of the optimisation, s.
    algorithm
        Optimiser name.
    history
        Per iteration (iteration 0: the start point): ``iteration``, ``cost``, ``linear_cost``, ``nfev``
        and the values by name.
    units
        Unit of each parameter, by name (for reports).
    """

    result: OptimiseResult
    estimates: dict[str, float]
    std: dict[str, float]
    initial: dict[str, float]
    wall_time: float
    algorithm: str
    history: list[dict[str, float]] = field(default_factory=list)
    std_scaled: dict[str, float] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """A JSON-friendly summary."""
        r = self.result
        return {
            "algorithm": self.algorithm,
            "estimates": self.estimates,
            "std": self.std,
            "std_scaled": self.std_scaled,
            "initial": self.initial,
            "cost": r.cost,
            "iterations": r.nit,
            "model_runs": r.nfev,
            "wall_s": round(self.wall_time, 3),
            "status": r.status,
            "message": r.message,
            "success": r.success,
            "aborted": r.aborted,
        }

    # -- views -------------------------------------------------------------------------------------

    def __repr__(self) -> str:
        values = ", ".join(f"{n}={v:.6g}" + (f"±{self.std[n]:.2g}" if n in self.std else "")
                           for n, v in self.estimates.items())
        r = self.result
        return (f"Calibration({self.algorithm}, {outcome(r)}, cost {r.cost:.6g}, {r.nfev} runs, {values})")

    def to_frame(self) -> pd.DataFrame:
        """The estimates as a table, one row per parameter (values in the parameters' units).

        Columns ``estimate``, ``std`` (thesis Eq. 2-12), ``std_scaled``, ``initial`` and ``unit``; NaN where
        the method gives no standard deviation.
        """
        rows = [{"name": n, "estimate": v, "std": self.std.get(n, np.nan), "std_scaled": self.std_scaled.get(n, np.nan),
                 "initial": self.initial.get(n, np.nan), "unit": self.units.get(n, "")}
                for n, v in self.estimates.items()]
        columns = ["name", "estimate", "std", "std_scaled", "initial", "unit"]
        return pd.DataFrame(rows, columns=columns).set_index("name")

    def correlation_frame(self) -> pd.DataFrame | None:
        """The correlation of the estimates (thesis Eq. 2-13), labelled by name; None without it."""
        cor = self.result.correlation
        if cor is None:
            return None
        names = list(self.estimates)
        return pd.DataFrame(np.asarray(cor, dtype=float), index=names, columns=names)

    def history_frame(self) -> pd.DataFrame:
        """:attr:`history` as a table indexed by iteration (cost dimensionless, values in their units)."""
        return pd.DataFrame(self.history).set_index("iteration") if self.history else pd.DataFrame()

    def fit_report(self, *, min_correlation: float = 0.1) -> str:
        """A plain-text report of the fit: method and outcome, cost, runs, estimates with σ, correlations.

        Parameters
        ----------
        min_correlation
            Correlations of a smaller magnitude are left out of the list.

        Returns
        -------
        str
            Lines like those of lmfit's ``fit_report``: ``[[Fit]]`` (method, status and message, cost S of
            thesis Eq. 2-3, iterations, model runs, wall time, residuals), ``[[Estimates]]`` (estimate ± σ
            of thesis Eq. 2-12, the scaled σ, the initial value, the unit) and ``[[Correlations]]`` (Eq. 2-13).
        """
        r = self.result
        start = self.history[0]["cost"] if self.history and self.history[0].get("iteration") == 0 else None
        residuals = r.extra.get("residuals")
        lines = [
            "[[Fit]]",
            f"    method       = {self.algorithm}",
            f"    outcome      = {outcome(r)} (status {r.status}): {r.message}",
            f"    cost S       = {r.cost:.6g}" + (f" (start: {start:.6g})" if start is not None else ""),
            f"    iterations   = {r.nit}",
            f"    model runs   = {r.nfev}",
            f"    wall time    = {self.wall_time:.3g} s",
        ]
        if residuals is not None:
            m, p = len(residuals), len(self.estimates)
            lines.append(f"    residuals    = {m} (S/(m - p) = {r.cost / (m - p):.4g})" if m > p else
                         f"    residuals    = {m}")
        lines.append("[[Estimates]]")
        width = max(len(n) for n in self.estimates) if self.estimates else 0
        for n, v in self.estimates.items():
            sigma = f" +/- {self.std[n]:.4g}" if n in self.std else " (no σ)"
            scaled = f", scaled σ {self.std_scaled[n]:.4g}" if n in self.std_scaled else ""
            unit = f" {self.units[n]}" if self.units.get(n) else ""
            lines.append(f"    {n + ':':<{width + 1}} {v:.6g}{sigma}{unit} (initial {self.initial.get(n, np.nan):.6g}"
                         f"{scaled})")
        cor = self.correlation_frame()
        if cor is not None and len(cor) > 1:
            pairs = sorted(((a, b, float(cor.loc[a, b])) for i, a in enumerate(cor.index) for b in cor.index[i + 1:]),
                           key=lambda t: -abs(t[2]) if np.isfinite(t[2]) else 0.0)
            shown = [t for t in pairs if not abs(t[2]) < min_correlation]
            lines.append(f"[[Correlations]] (those below {min_correlation:g} in magnitude are not shown)")
            lines += [f"    C({a}, {b}) = {c:+.3f}" for a, b, c in shown] or ["    (none)"]
        return "\n".join(lines)


def outcome(result: OptimiseResult) -> str:
    """``converged``, ``aborted`` or ``not converged`` (one word or two for reports)."""
    return "converged" if result.success else "aborted" if result.aborted else "not converged"
