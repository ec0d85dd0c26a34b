"""Which observed series each parameter moves: the dependency map of Sparse DuD, measured.

Sparse DuD (:mod:`rivercal.optimise.sparse_dud`) starts from k + 1 perturbed runs instead of p + 1, k the
most parameters one residual depends on, and its final Jacobian takes 2(k + 1) runs where that is fewer
than p. In a lowland network nearly every station depends a little on every parameter (a level change travels
upstream past drowned weirs, a discharge sums its catchment), so the map cannot come from the network's
topology alone: it has to say which dependencies are too weak to count.

This module measures it. From the finite-difference Jacobian J of a problem's weighted residuals
(:func:`~rivercal.analysis.jacobian.fd_jacobian`, p + 1 runs) the *effect* of parameter j on series i is
the largest change of the series' weighted residuals when the parameter moves by its first DuD step λ_j
(thesis Eq. 2-8 / 2-9):

    e_ij = max over the rows of series i of |J_rj| · λ_j,

in units of the series' σ (the residuals are weighted by 1/σ). Series i depends on parameter j when
e_ij exceeds a threshold, 0.1 σ by default: a change ten times smaller than the measurement error. A
parameter that moves no series by that much keeps its strongest series, so that its block can be fitted.

The map belongs to the network, its stations and its parameters, and a little to the flow: a drowned weir
passes a level change that a weir in free flow stops. Measure it once over a window with high water, look
at it (``dependency.csv`` of ``rivercal analyse``), and give it to every calibration and cycle. A series
the map does not name depends on every parameter, and a parameter it does not name is seen by
every series: a map never makes a dependency disappear that it did not measure.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.analysis._common import Batch
from rivercal.analysis.jacobian import Jacobian, fd_jacobian

__all__ = ["DEPENDENCY_THRESHOLD", "DependencyMap", "dependency_map", "effects_of"]

log = logging.getLogger(__name__)

#: Default threshold of a dependency: the effect of one first DuD step, in σ of the series.
DEPENDENCY_THRESHOLD = 0.1


@dataclass(frozen=True)
class DependencyMap:
    """Measured effects of each parameter on each series, and the threshold above which they count.

    Attributes
    ----------
    effects
        Index: series ids; columns: parameter names; values: e_ij, the largest change of the series'
        weighted residuals for a first DuD step of the parameter (σ, dimensionless).
    threshold
        Effects above it count as a dependency (σ).
    """

    effects: pd.DataFrame
    threshold: float = DEPENDENCY_THRESHOLD

    def __post_init__(self) -> None:
        if not (isinstance(self.threshold, int | float) and np.isfinite(self.threshold) and self.threshold >= 0):
            raise ValueError(f"the dependency threshold must be a number >= 0 (σ), got {self.threshold!r}")
        values = self.effects.to_numpy(dtype=float)
        if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values < 0):
            raise ValueError("the dependency effects must be a non-empty table of finite numbers >= 0 (σ)")

    @property
    def seen(self) -> pd.DataFrame:
        """Booleans (series × parameters): the dependencies, each parameter with at least its strongest series."""
        seen = self.effects > self.threshold
        for name in seen.columns[~seen.any(axis=0).to_numpy()]:
            seen.loc[self.effects[name].idxmax(), name] = True
        return seen

    @property
    def k(self) -> int:
        """The most parameters one series depends on."""
        return int(self.seen.sum(axis=1).max())

    def rows(self, problem: Any) -> np.ndarray:
        """The map for the residual rows of ``problem``: booleans (rows × the problem's parameters).

        The rows of each observed series (in the order of ``problem.observations``) take the series' row
        of :attr:`seen`; a series or a parameter the map does not name depends on everything.
        """
        names = list(problem.parameters.names)
        seen = self.seen
        known = [n for n in names if n in seen.columns]
        blocks = []
        for s in problem.observations:
            row = np.ones(len(names), dtype=bool)
            if s.id in seen.index:
                row[[names.index(n) for n in known]] = seen.loc[s.id, known].to_numpy(dtype=bool)
            blocks.append(np.tile(row, (len(s), 1)))
        matrix = np.concatenate(blocks)
        for j in np.flatnonzero(~matrix.any(axis=0)):  # seen only by series this window does not observe
            matrix[:, j] = True
            log.warning("dependency map: no series observed in this window depends on %s, so every series counts as "
                        "depending on it (Sparse DuD then needs one more direction for every series)", names[j])
        return matrix

    def to_csv(self, path: str | Path) -> Path:
        """Write the effects (σ) as CSV: a ``series`` column, then one column per parameter."""
        path = Path(path)
        self.effects.rename_axis("series").to_csv(path, float_format="%.6g")
        return path

    @classmethod
    def from_csv(cls, path: str | Path, threshold: float = DEPENDENCY_THRESHOLD) -> DependencyMap:
        """Read :meth:`to_csv`'s file (as ``rivercal analyse`` writes it).

        Raises
        ------
        ValueError
            When the file cannot be read or is not such a table; the message names the file.
        """
        path = Path(path)
        try:
            frame = pd.read_csv(path, dtype={"series": str})
        except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
            raise ValueError(f"{path}: cannot read the dependency map: {exc}") from None
        if frame.columns[0] != "series" or frame.shape[1] < 2:
            raise ValueError(f"{path}: a dependency map has a first column 'series' and one column per parameter "
                             f"(as rivercal analyse writes dependency.csv); found columns {list(frame.columns)}")
        if frame["series"].duplicated().any():
            raise ValueError(f"{path}: series {frame['series'][frame['series'].duplicated()].iloc[0]!r} appears twice")
        effects = frame.set_index("series")
        bad = [c for c in effects.columns if not pd.api.types.is_numeric_dtype(effects[c]) or effects[c].isna().any()
               or (effects[c] < 0).any()]
        if bad:
            raise ValueError(f"{path}: column {bad[0]!r} must hold a number >= 0 (an effect in σ) on every row")
        return cls(effects.astype(float), threshold)


def effects_of(jacobian: Jacobian, steps: np.ndarray) -> pd.DataFrame:
    """e_ij = max over the rows of series i of |J_rj| · λ_j (σ): the series × parameters table of a Jacobian."""
    change = pd.DataFrame(np.abs(jacobian.matrix) * np.abs(np.asarray(steps, dtype=float)),
                          columns=list(jacobian.names))
    change["series"] = list(jacobian.rows)
    return change.groupby("series", sort=False).max()


def dependency_map(problem: Any, *, threshold: float = DEPENDENCY_THRESHOLD, rel_step: float = 0.01,
                   batch: Batch | None = None, workers: int | None = None) -> DependencyMap:
    """Measure the dependency map of ``problem`` at its initial values (p + 1 model runs, one batch).

    Parameters
    ----------
    problem
        A :class:`~rivercal.problem.CalibrationProblem`.
    threshold
        Effects above it count (σ; default :data:`DEPENDENCY_THRESHOLD`).
    rel_step, batch, workers
        As for :func:`~rivercal.analysis.jacobian.fd_jacobian`.
    """
    jac = fd_jacobian(problem, rel_step=rel_step, batch=batch, workers=workers)
    result = DependencyMap(effects_of(jac, problem.parameters.initial_steps()), threshold)
    log.info("dependency map of %d series and %d parameters: at most %d parameters per series (threshold %g σ)",
             len(result.effects), len(result.effects.columns), result.k, threshold)
    return result
