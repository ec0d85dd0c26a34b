"""Finite-difference Jacobians and the parameter covariance (thesis Eq. 2-10, 2-12, 2-13): the one place.

Every optimiser that differentiates (TRF, BFGS, CG, the final Jacobian of DuD and Sparse DuD), the
identifiability analysis and the on-line service's gate use these two functions:

- :func:`fd_jacobian` differentiates a residual function r(x) by forward or central differences, all
  points as ONE batch, with steps that point into the box [lb, ub]. Given the function's *noise* (the
  size of the numerical jitter of each residual, e.g. a hydrodynamic model's iteration tolerance times
  the weight), it checks that every column's difference stands ``min_signal`` (10) times above that noise and
  enlarges the steps of the columns that do not (one more batch), because a difference of the size of
  the noise is noise, not a derivative.
- :func:`covariance` turns a Jacobian J of *weighted* residuals into cov = (JᵀJ)⁻¹ (thesis Eq. 2-12;
  the pseudo-inverse when JᵀJ is singular), the standard deviations √diag(cov) and the correlations
  cov_ij / √(cov_ii cov_jj) (Eq. 2-13). It works on the singular value decomposition of J diag(d) with
  columns scaled to comparable size, so that parameters of different units do not spoil the rank test.

This module knows nothing of rivers: x is a vector in the caller's coordinates, r a vector of numbers.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Covariance", "FiniteDifferences", "covariance", "difference_steps", "fd_jacobian", "inward_steps",
           "parameter_statistics"]

Evaluate = Callable[[list[np.ndarray]], Sequence[np.ndarray]]

#: A column's difference must stand this many times above the function's noise (see :func:`fd_jacobian`):
#: a jitter as large as the noise level then spoils the derivative by at most about 10 %. A model's
#: tolerance is an upper bound of its jitter (the embedded engine's is about a tenth of its Picard
#: tolerance), so the usual error is near 1 %; larger steps would trade it for truncation error (forward
#: differences of a weakly seen weir crest: 14 % at 3 % of its range, 1.4 % at 0.3 %).
MIN_SIGNAL = 10.0


def inward_steps(x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """Signed perturbations of size ``h`` that keep ``x + step`` inside the bounds.

    Prefer +h; if that leaves the box use −h; if neither fits (the range is narrower than h) step
    towards the farther bound by the room available there. A point at or near a bound is therefore
    always perturbed inwards and the perturbed points never collapse onto x (OpenDA's DuD can collapse them otherwise).
    """
    up, down = ub - x, x - lb
    step = np.where(h <= up, h, np.where(h <= down, -h, 0.0))
    squeezed = step == 0.0
    step[squeezed] = np.where(up[squeezed] >= down[squeezed], up[squeezed], -down[squeezed])
    return step


def difference_steps(x: np.ndarray, rel_step: float, typical: np.ndarray) -> np.ndarray:
    """Step sizes h_j = rel_step · max(|x_j|, 10⁻³ typical_j) (unsigned).

    Relative to |x_j| rather than scipy's max(1, |x_j|), so that parameters of order 10⁻⁹ (NIST Hahn1) get
    a step of their own order; ``typical`` (the parameter's scale) guards x_j ≈ 0.
    """
    return rel_step * np.maximum(np.abs(x), 1e-3 * typical)


@dataclass(frozen=True)
class FiniteDifferences:
    """A finite-difference Jacobian and how it was made.

    Attributes
    ----------
    jacobian
        ∂r/∂x, shape (m, p), per unit of each x_j.
    x
        The point.
    residuals
        r(x).
    steps
        Per column, the difference of x_j between the two points it was taken from (forward: the signed
        step; central: the spread x⁺ − x⁻).
    scheme
        ``forward`` or ``central``.
    nfev
        Function evaluations this Jacobian asked for (points already known to the caller's evaluator,
        such as x itself, included).
    signal
        Per column, the largest |Δr_i| / noise_i of its difference (NaN without ``noise``).
    """

    jacobian: np.ndarray
    x: np.ndarray
    residuals: np.ndarray
    steps: np.ndarray
    scheme: str
    nfev: int
    signal: np.ndarray


def _points(x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray, cols: np.ndarray,
            scheme: str) -> tuple[list[np.ndarray], list[tuple[int, int | None, int | None]]]:
    """Perturbed points for columns ``cols`` and, per column, (j, index of x⁺, index of x⁻) (None: x itself)."""
    points: list[np.ndarray] = []
    where: list[tuple[int, int | None, int | None]] = []

    def add(j: int, step: float) -> int:
        p = x.copy()
        p[j] = min(max(x[j] + step, lb[j]), ub[j])
        points.append(p)
        return len(points) - 1

    if scheme == "forward":
        steps = inward_steps(x, h, lb, ub)
        for j in cols:
            where.append((j, add(j, steps[j]), None))   # a backward step gives a negative difference of x
    else:
        up, down = np.minimum(h, ub - x), np.minimum(h, x - lb)
        for j in cols:
            where.append((j, add(j, up[j]) if up[j] > 0 else None, add(j, -down[j]) if down[j] > 0 else None))
    return points, where


def fd_jacobian(evaluate: Evaluate, x: Any, lb: Any, ub: Any, steps: Any, *, scheme: str = "forward",
                r0: np.ndarray | None = None, noise: Any = None, min_signal: float = MIN_SIGNAL,
                max_step: Any = None) -> FiniteDifferences:
    """Finite-difference Jacobian of r at ``x``; the points go out as one batch (two with a noise check).

    Parameters
    ----------
    evaluate
        ``evaluate(list_of_x) -> list_of_r``: the residuals at several points (e.g. a process pool).
    x, lb, ub
        The point and the box (1-D; ±inf allowed). The perturbed points stay inside the box: a step
        that would leave it points the other way (forward) or is cut at the bound (central).
    steps
        Step size h_j per parameter (positive; see :func:`difference_steps`).
    scheme
        ``forward`` (p runs besides x) or ``central`` (2p runs; one-sided where a bound is closer than h).
    r0
        r(x) if the caller has it (x is then not evaluated).
    noise
        The size of the function's numerical jitter per residual (scalar or length m), or None. A
        column whose largest |Δr_i| is below ``min_signal`` · noise_i gets a larger step (up to
        ``max_step``), taken in one more batch.
    min_signal
        See ``noise`` (default :data:`MIN_SIGNAL`, 10).
    max_step
        Largest step per parameter for that enlargement (default 100 h).

    Returns
    -------
    FiniteDifferences

    Examples
    --------
    >>> import numpy as np
    >>> a = np.array([[1.0, 2.0], [3.0, -1.0], [0.5, 0.5]])
    >>> fd = fd_jacobian(lambda xs: [a @ p for p in xs], [0.2, 0.3], -1.0, 1.0, [1e-6, 1e-6], scheme="central")
    >>> np.allclose(fd.jacobian, a)
    True
    """
    x = np.array(x, dtype=float).reshape(-1)
    p = x.size
    lb = np.broadcast_to(np.asarray(lb, dtype=float), (p,))
    ub = np.broadcast_to(np.asarray(ub, dtype=float), (p,))
    h = np.broadcast_to(np.asarray(steps, dtype=float), (p,)).copy()
    if scheme not in ("forward", "central"):
        raise ValueError(f"scheme must be 'forward' or 'central', got {scheme!r}")
    if not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ValueError(f"difference steps must be positive finite numbers, got {h}")
    if np.any(x < lb) or np.any(x > ub):
        raise ValueError(f"the point {x} lies outside the bounds")
    cols = np.arange(p)
    points, where = _points(x, h, lb, ub, cols, scheme)
    results = [np.asarray(r, dtype=float) for r in evaluate(([] if r0 is not None else [x]) + points)]
    nfev = len(results)
    if r0 is None:
        r0, results = results[0], results[1:]
    r0 = np.asarray(r0, dtype=float)
    jac, used = np.empty((r0.size, p)), np.empty(p)
    _fill(jac, used, x, r0, points, results, where)
    signal = np.full(p, np.nan)
    if noise is not None:
        level = np.broadcast_to(np.asarray(noise, dtype=float), r0.shape)
        signal = _signal(jac, used, level)
        cap = 100.0 * h if max_step is None else np.broadcast_to(np.asarray(max_step, dtype=float), (p,))
        weak = np.flatnonzero((signal < min_signal) & (h < cap))
        if weak.size:
            grow = np.where(signal[weak] > 0, 1.5 * min_signal / np.maximum(signal[weak], 1e-300), np.inf)
            h[weak] = np.minimum(cap[weak], h[weak] * np.maximum(grow, 2.0))
            points, where = _points(x, h, lb, ub, weak, scheme)
            results = [np.asarray(r, dtype=float) for r in evaluate(points)]
            nfev += len(results)
            _fill(jac, used, x, r0, points, results, where)
            signal[weak] = _signal(jac[:, weak], used[weak], level)
    return FiniteDifferences(jacobian=jac, x=x, residuals=r0, steps=used, scheme=scheme, nfev=nfev, signal=signal)


def _fill(jac: np.ndarray, used: np.ndarray, x: np.ndarray, r0: np.ndarray, points: list[np.ndarray],
          results: list[np.ndarray], where: list[tuple[int, int | None, int | None]]) -> None:
    for j, hi, lo in where:
        x_hi = x[j] if hi is None else points[hi][j]
        x_lo = x[j] if lo is None else points[lo][j]
        r_hi = r0 if hi is None else results[hi]
        r_lo = r0 if lo is None else results[lo]
        used[j] = x_hi - x_lo
        jac[:, j] = (r_hi - r_lo) / used[j]


def _signal(jac: np.ndarray, used: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Largest |Δr_i| / noise_i per column (inf where the noise is zero and the difference is not)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(jac * used) / level[:, None]
    ratio = np.where(np.isnan(ratio), 0.0, ratio)
    return ratio.max(axis=0) if ratio.size else np.zeros(jac.shape[1])


# --------------------------------------------------------------------------------------------------
# covariance (thesis Eq. 2-12 / 2-13)
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Covariance:
    """(JᵀJ)⁻¹ and what follows from it, in the units of x.

    Attributes
    ----------
    matrix
        The covariance (the pseudo-inverse when ``singular``).
    std
        √diag(matrix); inf for a parameter that loads on a direction the Jacobian does not see.
    correlation
        Thesis Eq. 2-13 (NaN for a parameter without any effect).
    singular
        Whether JᵀJ is singular to the tolerance ``rcond``.
    singular_values, vectors
        Singular values (descending, p of them) and right singular vectors (columns) of J diag(scale).
    scale
        The column scales d used.
    """

    matrix: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    singular: bool
    singular_values: np.ndarray
    vectors: np.ndarray
    scale: np.ndarray


def scaled_svd(jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values (length p, zeros appended when m < p) and right singular vectors with a fixed sign.

    Each vector has its largest component positive, so that the result does not depend on LAPACK's choice.
    """
    m, p = jac.shape
    # The full V (p x p) needs full matrices only when there are fewer rows than parameters; otherwise
    # they would also build the m x m left factor, 3 GB and minutes for a season of hourly residuals.
    _, s, vt = np.linalg.svd(jac, full_matrices=m < p)
    v = vt.T
    s = np.concatenate([s, np.zeros(p - s.size)])
    largest = v[np.argmax(np.abs(v), axis=0), np.arange(p)]  # each column's largest component (the first of ties)
    v[:, largest < 0] *= -1.0
    return s, v


def covariance(jac: Any, *, scale: Any = None, rcond: float | None = None) -> Covariance:
    """Cov = (JᵀJ)⁻¹ (thesis Eq. 2-12), std and correlation (Eq. 2-13), via the SVD of J diag(d).

    Parameters
    ----------
    jac
        J = ∂r/∂x of the weighted residuals, (m, p).
    scale
        Column scales d (positive, units of x). Default: the column norms of J (parameters without
        effect: 1), which makes the rank test independent of the parameters' units.
    rcond
        Singular values of J diag(d) at or below rcond · s₁ count as zero (then ``singular``, and the
        covariance is the pseudo-inverse over the others). Default max(m, p) · machine epsilon.

    Raises
    ------
    ValueError
        For a Jacobian that is not 2-D and finite, or bad scales.
    """
    jac = np.asarray(jac, dtype=float)
    if jac.ndim != 2 or jac.shape[1] == 0 or not np.all(np.isfinite(jac)):
        raise ValueError(f"the Jacobian must be a finite 2-D array with at least one column, got shape {jac.shape}")
    m, p = jac.shape
    if scale is None:
        norms = np.linalg.norm(jac, axis=0)
        d = np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 1.0)
    else:
        d = np.broadcast_to(np.asarray(scale, dtype=float), (p,)).copy()
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise ValueError(f"scale must hold {p} positive finite numbers, got {d}")
    tol = max(m, p) * np.finfo(float).eps if rcond is None else rcond
    s, v = scaled_svd(jac * d)
    keep = (s > tol * s[0]) if s[0] > 0 else np.zeros(p, dtype=bool)
    singular = not bool(keep.all())
    cov = (v[:, keep] / s[keep] ** 2) @ v[:, keep].T * np.outer(d, d)
    cov = 0.5 * (cov + cov.T)  # symmetric to the last bit (the product's round-off is not)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if singular:
        std = np.where(np.sum(v[:, ~keep] ** 2, axis=1) > 1e-12, np.inf, std)
    return Covariance(matrix=cov, std=std, correlation=_correlation(cov), singular=singular, singular_values=s,
                      vectors=v, scale=d)


def _correlation(cov: np.ndarray) -> np.ndarray:
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(std, std)
    corr[~np.isfinite(corr)] = np.nan
    corr = np.clip(corr, -1.0, 1.0)
    corr[np.diag_indices_from(corr)] = np.where(std > 0, 1.0, np.nan)
    return corr


def parameter_statistics(jac: Any, cost: float) -> dict[str, np.ndarray] | None:
    """Covariance (JᵀJ)⁻¹, standard deviations, correlations and the s²-scaled deviations.

    ``std`` is right when the weights are 1/σ² with the true σ; ``std_scaled`` = std · s with
    s² = S/(m − p), the residual variance the fit itself shows, is right when σ is known only up to a
    common factor (e.g. uniform ±a noise weighted as σ = a: the true σ is a/√3). Returns None when the
    Jacobian is not finite or JᵀJ is singular to working precision (a parameter without influence, or
    two parameters with identical influence).
    """
    jac = np.asarray(jac, dtype=float)
    if jac.ndim != 2 or jac.shape[1] == 0 or not np.all(np.isfinite(jac)) or jac.shape[0] < jac.shape[1]:
        return None
    cov = covariance(jac)
    if cov.singular:
        return None
    dof = jac.shape[0] - jac.shape[1]
    s = math.sqrt(cost / dof) if dof > 0 else math.nan
    return {"covariance": cov.matrix, "std": cov.std, "correlation": cov.correlation, "std_scaled": cov.std * s}
