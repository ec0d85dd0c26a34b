"""Robust costs of a calibration problem: each weighted residual r becomes r̃ = sign(r) √(2 ρ(r)).

Observations with outliers or a model with structural error make a few residuals much larger than
the rest; ``loss`` makes the cost robust to them (Huber 1964; a Student-t likelihood, Lange et al. 1989)
by replacing each weighted residual r with r̃ = sign(r) √(2 ρ(r)), so that Σ r̃² = 2 Σ ρ(r) and every
least-squares optimiser minimises the robust cost unchanged:

- ``huber``: ρ(r) = r²/2 for |r| ≤ c, c |r| − c²/2 beyond (c = ``loss_scale``, default 1.345: 95 %
  efficiency under Gaussian errors); r̃ = r inside, √(2c|r| − c²) beyond — like weights 1 inside and
  c/|r| beyond (iteratively reweighted least squares);
- ``student-t``: ρ(r) = (ν c²/2) ln(1 + r²/(ν c²)) with ν = 4 degrees of freedom and c = ``loss_scale``
  (default 1): weights (1 + r²/(ν c²))⁻¹, a large residual barely counts;
- ``l2`` (default): r̃ = r, thesis Eq. 2-3.

c is in units of the weighted residual, i.e. of σ.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LOSSES", "STUDENT_T_DOF", "robust_residuals"]

#: Robust costs of :class:`CalibrationProblem` (module docstring) and their default scale c (in σ).
LOSSES = {"l2": None, "huber": 1.345, "student-t": 1.0}
#: Degrees of freedom of the Student-t cost.
STUDENT_T_DOF = 4.0


def robust_residuals(r: np.ndarray, loss: str, scale: float | None = None) -> np.ndarray:
    """Weighted residuals r → r̃ = sign(r) √(2 ρ(r)) of a robust cost (module docstring); ``l2`` returns r.

    Examples
    --------
    >>> robust_residuals(np.array([0.5, -3.0]), "huber", 1.0).round(4).tolist()
    [0.5, -2.2361]
    """
    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")
    if loss == "l2":
        return r
    c = float(LOSSES[loss] if scale is None else scale)
    a = np.abs(r)
    if loss == "huber":
        out = np.where(a <= c, a, np.sqrt(np.maximum(2.0 * c * a - c * c, 0.0)))
    else:
        nc2 = STUDENT_T_DOF * c * c
        out = np.sqrt(nc2 * np.log1p(a * a / nc2))
    return np.sign(r) * out
