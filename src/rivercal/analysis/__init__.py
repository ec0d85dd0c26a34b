"""Sensitivity, identifiability and residual analysis (layer 6; thesis §2-3 and §4-5-1).

- :mod:`~rivercal.analysis.sensitivity`: one-at-a-time scenarios (thesis Table 4-4, Fig. 4-5, C-1 … C-5),
  all runs in one parallel batch, costs in total, per station and per series.
- :mod:`~rivercal.analysis.jacobian`: the finite-difference Jacobian of a problem's weighted residuals
  (Eq. 2-10), rows and columns named;
- :mod:`~rivercal.analysis.identifiability`: its singular values and vectors (Eq. 2-10, 2-11; Fig. 4-6),
  covariance and correlation (Eq. 2-12, 2-13; Fig. 4-7), the identifiability index of Doherty and Hunt
  (2009) and a verdict (the sentences that explain it: :mod:`rivercal.report.identifiability`).
- :mod:`~rivercal.analysis.dependency`: which series each parameter moves, from that Jacobian: the measured
  dependency map of Sparse DuD;
- :mod:`~rivercal.analysis.residuals`: cost, RMSE, bias and standard deviation of errors (Tables 4-6 … 4-12),
  the moving-window bias of Eq. 2-14 (Fig. 4-11) and its significance test; model-independent.
- :mod:`~rivercal.analysis.figures`: the figures (matplotlib, imported lazily).
"""

from rivercal.analysis._common import Context, context_from_problem
from rivercal.analysis.dependency import DEPENDENCY_THRESHOLD, DependencyMap, dependency_map
from rivercal.analysis.identifiability import (
    COMBINATION,
    DOHERTY_HUNT_2009,
    IDENTIFIABLE,
    NOT_IDENTIFIABLE,
    ClusterSuggestion,
    Identifiability,
    IdentifiabilityOptions,
    analyse_jacobian,
    identifiability,
    identifiability_index,
)
from rivercal.analysis.jacobian import Jacobian, fd_jacobian
from rivercal.analysis.residuals import (
    BIAS_FACTOR,
    bias_significance,
    error_statistics,
    errors,
    moving_bias,
    residual_statistics,
    summary_statistics,
)
from rivercal.analysis.sensitivity import SensitivityResult, scenario_table, sensitivity, thesis_scenarios

__all__ = [
    "BIAS_FACTOR",
    "COMBINATION",
    "DEPENDENCY_THRESHOLD",
    "DOHERTY_HUNT_2009",
    "IDENTIFIABLE",
    "NOT_IDENTIFIABLE",
    "ClusterSuggestion",
    "Context",
    "DependencyMap",
    "Identifiability",
    "IdentifiabilityOptions",
    "Jacobian",
    "SensitivityResult",
    "analyse_jacobian",
    "bias_significance",
    "context_from_problem",
    "dependency_map",
    "error_statistics",
    "errors",
    "fd_jacobian",
    "identifiability",
    "identifiability_index",
    "moving_bias",
    "residual_statistics",
    "scenario_table",
    "sensitivity",
    "summary_statistics",
    "thesis_scenarios",
]
