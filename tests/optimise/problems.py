"""Test problems with known answers and the per-method settings of the shared behaviour suite."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

# A linear least-squares problem with a non-zero residual and a known exact answer: b = A x* + e with e
# orthogonal to the columns of A, so x* minimises ‖A x − b‖² and the minimum is ‖e‖².
A = np.array([[1.0, 2.0, 0.0], [0.5, -1.0, 1.0], [2.0, 0.0, 1.0], [0.0, 1.0, -1.0], [1.0, 1.0, 1.0],
              [-1.0, 0.5, 2.0]])
X_LINEAR = np.array([1.0, -2.0, 0.5])
_U = np.linalg.svd(A)[0]
E_LINEAR = 0.3 * _U[:, -1]
B = A @ X_LINEAR + E_LINEAR
COST_LINEAR = float(E_LINEAR @ E_LINEAR)


def linear(x: np.ndarray) -> np.ndarray:
    """Residuals A x − b."""
    return A @ x - B


def rosenbrock(x: np.ndarray) -> np.ndarray:
    """Rosenbrock's function as residuals: S = 100(x₂ − x₁²)² + (1 − x₁)², minimum 0 at (1, 1)."""
    return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])


LINEAR_START = np.array([0.5, -0.5, 0.2])
LINEAR_LB, LINEAR_UB = np.full(3, -3.0), np.full(3, 3.0)
ROSEN_START = np.array([-1.2, 1.0])
ROSEN_LB, ROSEN_UB = np.full(2, -2.0), np.full(2, 2.0)


@dataclass(frozen=True)
class Setting:
    """How the shared suite runs one method."""

    options: dict[str, Any] = field(default_factory=dict)
    max_nfev: int | None = None
    linear_tol: float = 1e-6       # max |x − x*| on the linear problem
    rosen_tol: float | None = 1e-5  # ... on Rosenbrock; None: only require a large decrease of the cost
    seeded: bool = False           # has a ``seed`` option
    chunked: bool = False          # has a ``chunk_size`` option (grid, glue)


TIGHT_DUD = {"abs_tol": 0.0, "rel_tol": 1e-14, "rel_tol_linear": 0.0, "negligible_cost": 0.0, "max_outer": 200}

SETTINGS: dict[str, Setting] = {
    "dud": Setting(TIGHT_DUD),
    "sparse_dud": Setting(TIGHT_DUD),
    "trf": Setting({"ftol": 1e-14, "xtol": 1e-14, "gtol": 1e-14}),
    "bfgs": Setting({"ftol": 1e-15, "gtol": 1e-12}, linear_tol=1e-5, rosen_tol=1e-4),
    "cg": Setting({"max_iter": 500}, linear_tol=1e-5, rosen_tol=1e-4),
    "nelder_mead": Setting({"xatol": 1e-7, "fatol": 1e-14, "max_iter": 5000}, linear_tol=1e-6, rosen_tol=1e-6),
    "powell": Setting({"xtol": 1e-9, "ftol": 1e-14}, linear_tol=1e-6, rosen_tol=1e-6),
    "sce_ua": Setting({"seed": 3, "peps": 1e-9, "pcento": 0.0, "kstop": 10}, max_nfev=20000, linear_tol=1e-5,
                      rosen_tol=1e-4, seeded=True),
    "dds": Setting({"seed": 3, "max_evaluations": 3000}, linear_tol=0.05, rosen_tol=None, seeded=True),
    "grid": Setting({"ranges": [(-3.0, 3.0, 0.5)] * 3}, linear_tol=0.0, rosen_tol=None, chunked=True),
    "glue": Setting({"seed": 3, "n_samples": 2000, "chunk_size": 500}, linear_tol=0.6, rosen_tol=None,
                    seeded=True, chunked=True),
}

GRID_ROSEN = {"ranges": [(-2.0, 2.0, 0.25)] * 2}
