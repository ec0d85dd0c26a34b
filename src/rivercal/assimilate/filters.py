"""Ensemble Kalman filter analyses: the stochastic EnKF and the ensemble transform filter (ETKF).

Both take the forecast ensemble as a matrix X of shape (n, N) — one column per member, one row per
state variable (levels and discharges of the calculation points, followed by any parameters of a
joint state–parameter estimation: the augmented state of Evensen 2009, IEEE Control Syst. Mag.
29(3):83–104) — together with each member's predicted observations H(x) of shape (m, N), the
observations y (m,) and their error variances (m,), R = diag(r). The observation operator is
applied by the caller, so it may be nonlinear (a level interpolated between points, a discharge).

Stochastic EnKF (Burgers, van Leeuwen & Evensen 1998, Mon. Wea. Rev. 126:1719–1724; Evensen 2003,
Ocean Dyn. 53:343–367): every member is updated with its own perturbed observations y + εⱼ, εⱼ ~ N(0, R),
``Xᵃ = X + K (Y − H(X))``, ``K = (ρ_xy ∘ P_xy)(ρ_yy ∘ P_yy + R)⁻¹``,
with P_xy = A Bᵀ/(N − 1), P_yy = B Bᵀ/(N − 1), A and B the anomalies of X and H(X); ρ the localisation
tapers (Houtekamer & Mitchell 2001). Without the perturbations the analysis spread would be too small.

ETKF (Bishop, Etherton & Majumdar 2001, Mon. Wea. Rev. 129:420–436) in the form of Hunt, Kostelich &
Szunyogh (2007, Physica D 230:112–126, Eqs. 20–24): the analysis is a combination of the forecast
members, x̄ᵃ = x̄ + A w̄ and Aᵃ = A Wᵃ, with
``P̃ᵃ = [(N − 1) I + Bᵀ R⁻¹ B]⁻¹``, ``w̄ = P̃ᵃ Bᵀ R⁻¹ (y − ȳ)``, ``Wᵃ = [(N − 1) P̃ᵃ]^½`` (symmetric root),
so no observation is perturbed and the analysis covariance is exactly the Kalman one of the sample
covariance. Localisation is the local ETKF's (Hunt et al. 2007, §2.3): each state row gets its own
analysis in which observation k's inverse variance is weighted by ρ(row, k).

Inflation: the forecast anomalies are multiplied by λ ≥ 1 before the analysis (Anderson & Anderson
1999, Mon. Wea. Rev. 127:2741–2758), which counters the spread an ensemble loses to sampling error and
to model error the perturbations miss.

Missing observations (NaN) are dropped, never treated as zero. Pure numerics: no I/O, no logging of data.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import linalg

__all__ = ["FILTERS", "enkf_analysis", "etkf_analysis"]


def _checked(ensemble, predicted, observed, obs_variance, inflation, rho_state):
    x = np.asarray(ensemble, dtype=float)
    hx = np.asarray(predicted, dtype=float)
    y = np.asarray(observed, dtype=float).ravel()
    r = np.broadcast_to(np.asarray(obs_variance, dtype=float), y.shape).copy()
    if x.ndim != 2 or x.shape[1] < 2:
        raise ValueError(f"the ensemble must be a matrix (state variables, members) of at least 2 members, "
                         f"got shape {x.shape}")
    if hx.shape != (y.size, x.shape[1]):
        raise ValueError(f"predicted observations must have shape (observations, members) = {(y.size, x.shape[1])}, "
                         f"got {hx.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(hx))):
        raise ValueError("the ensemble or its predicted observations contain NaN or inf")
    if not np.all(r[np.isfinite(y)] > 0):
        raise ValueError(f"observation error variances must be positive, got {r.min():g}")
    if not inflation > 0 or not np.isfinite(inflation):
        raise ValueError(f"inflation must be a positive factor, got {inflation}")
    rho = None
    if rho_state is not None:
        rho = np.asarray(rho_state, dtype=float)
        if rho.shape != (x.shape[0], y.size):
            raise ValueError(f"the state localisation must have shape (state variables, observations) = "
                             f"{(x.shape[0], y.size)}, got {rho.shape}")
    keep = np.isfinite(y)
    return x, hx[keep], y[keep], r[keep], None if rho is None else rho[:, keep], keep


def _inflated(x, hx, inflation):
    xm = x.mean(axis=1, keepdims=True)
    ym = hx.mean(axis=1, keepdims=True)
    return xm, inflation * (x - xm), ym, inflation * (hx - ym)


def enkf_analysis(ensemble: np.ndarray, predicted: np.ndarray, observed: np.ndarray, obs_variance: np.ndarray, *,
                  rng: np.random.Generator, inflation: float = 1.0, rho_state: np.ndarray | None = None,
                  rho_obs: np.ndarray | None = None) -> np.ndarray:
    """The stochastic EnKF analysis (perturbed observations; module docstring).

    Parameters
    ----------
    ensemble
        Forecast ensemble X, shape (n state variables, N members), in the state's units (m AD, m³/s, …).
    predicted
        H(X): each member's predicted observations, shape (m, N), in the observations' units.
    observed
        Observations y, shape (m,); NaN: missing (dropped).
    obs_variance
        Observation error variances, shape (m,) or a scalar, in the observations' units squared (m²).
    rng
        Source of the observation perturbations.
    inflation
        Multiplicative inflation λ of the forecast anomalies (1: none).
    rho_state, rho_obs
        Localisation tapers between state variables and observations (n, m) and among observations (m, m);
        None: no localisation.

    Returns
    -------
    numpy.ndarray
        The analysis ensemble, shape (n, N).
    """
    x, hx, y, r, rho, keep = _checked(ensemble, predicted, observed, obs_variance, inflation, rho_state)
    xm, a, ym, b = _inflated(x, hx, inflation)
    n_mem = x.shape[1]
    if y.size == 0:
        return xm + a
    pxy = a @ b.T / (n_mem - 1)
    pyy = b @ b.T / (n_mem - 1)
    if rho is not None:
        pxy = rho * pxy
    if rho_obs is not None:
        rho_yy = np.asarray(rho_obs, dtype=float)
        if rho_yy.shape != (keep.size, keep.size):
            raise ValueError(f"the observation localisation must have shape {(keep.size, keep.size)}, "
                             f"got {rho_yy.shape}")
        pyy = rho_yy[np.ix_(keep, keep)] * pyy
    perturbed = y[:, None] + np.sqrt(r)[:, None] * rng.standard_normal((y.size, n_mem))
    innovations = perturbed - (ym + b)
    gain_t = linalg.solve(pyy + np.diag(r), pxy.T, assume_a="sym")
    return xm + a + gain_t.T @ innovations


def etkf_analysis(ensemble: np.ndarray, predicted: np.ndarray, observed: np.ndarray, obs_variance: np.ndarray, *,
                  inflation: float = 1.0, rho_state: np.ndarray | None = None,
                  rng: np.random.Generator | None = None) -> np.ndarray:
    """The ensemble transform analysis (square root, no perturbed observations; module docstring).

    Parameters are those of :func:`enkf_analysis` (``rng`` is accepted and unused, so that the two
    filters can be called alike); with ``rho_state`` each group of state rows with the same taper gets its
    own local analysis (Hunt et al. 2007, §2.3).

    Returns
    -------
    numpy.ndarray
        The analysis ensemble, shape (n, N); its mean is x̄ + A w̄, its anomalies A Wᵃ.
    """
    x, hx, y, r, rho, _ = _checked(ensemble, predicted, observed, obs_variance, inflation, rho_state)
    xm, a, ym, b = _inflated(x, hx, inflation)
    if y.size == 0:
        return xm + a
    d = y - ym[:, 0]
    if rho is None:
        return xm + _transformed(a, b, 1.0 / r, d)
    groups, which = np.unique(rho, axis=0, return_inverse=True)
    if y.size <= x.shape[1]:
        return xm + _local_transformed(a, b, groups / r, d, which.ravel())
    return xm + _local_transformed_members(a, b, groups / r, d, which.ravel())


def _transformed(a: np.ndarray, b: np.ndarray, r_inv: np.ndarray, d: np.ndarray) -> np.ndarray:
    """A (w̄ + Wᵃ): the ETKF analysis of anomalies A, for observation anomalies B (m, N), R⁻¹ and innovation d.

    With S = R^(-½) B / √(N − 1) = U Σ Vᵀ (thin SVD, at most m directions), (N − 1) P̃ᵃ = (I + SᵀS)⁻¹ =
    I + V[(1 + Σ²)⁻¹ − I]Vᵀ and its symmetric root is I + V[(1 + Σ²)^(-½) − I]Vᵀ: O(m²N + nmN) instead of
    an eigendecomposition of an N × N matrix and a product with it.
    """
    n_mem = b.shape[1]
    s = (np.sqrt(r_inv)[:, None] * b) / np.sqrt(n_mem - 1)
    _, sv, vt = linalg.svd(s, full_matrices=False)
    g = sv * sv
    c_d = b.T @ (r_inv * d)                                   # Bᵀ R⁻¹ d
    w_mean = (c_d + vt.T @ ((1.0 / (1.0 + g) - 1.0) * (vt @ c_d))) / (n_mem - 1)
    av = a @ vt.T
    return (a @ w_mean)[:, None] + a + (av * (1.0 / np.sqrt(1.0 + g) - 1.0)) @ vt


def _local_transformed(a: np.ndarray, b: np.ndarray, r_inv: np.ndarray, d: np.ndarray, which: np.ndarray, *,
                       block: int = 1 << 20) -> np.ndarray:
    """Every row's local ETKF analysis of anomalies A at once: row i with the inverse variances ``r_inv[which[i]]``.

    The analysis of :func:`_transformed` per group of rows, computed in the m-dimensional space of the observations
    (for m ≤ N) instead of by a thin SVD per group: with Sᵢ = Dᵢ B / √(N − 1), Dᵢ = diag(√(R⁻¹ρᵢ)), and the
    eigendecomposition Sᵢ Sᵢᵀ = U diag(g) Uᵀ (the groups' m × m matrices in batched calls),
    V f(Σ²) Vᵀ = Sᵢᵀ U diag(f(g)/g) Uᵀ Sᵢ for f(0) = 0, so that with E = A Bᵀ (one product for all rows)

    - the mean: aᵢ w̄ᵢ = eᵢ · [R⁻¹ρᵢ d + Dᵢ U diag(−1/(1 + g)) Uᵀ Dᵢ B Bᵀ R⁻¹ρᵢ d / (N − 1)] / (N − 1);
    - the anomalies: aᵢ Wᵃᵢ = aᵢ + [Dᵢ U diag(h(g)) Uᵀ Dᵢ eᵢ]ᵀ B / (N − 1), with
      h(g) = ((1 + g)^(-½) − 1)/g = −1/(√(1 + g)(1 + √(1 + g))), finite at g = 0 (a direction the observations do
      not see contributes nothing, as in the SVD form).

    The results equal those of :func:`_transformed` per group to rounding (a few 1e-13 of the anomalies): the
    operations differ, not the analysis. ``r_inv`` is (groups, m); a group of zero weights (rows beyond every
    observation's cut-off) leaves its rows' anomalies as they are. ``block`` bounds the doubles of the m × m
    matrices held at once.
    """
    nm1 = b.shape[1] - 1.0
    m = b.shape[0]
    e = a @ b.T                                                     # (n, m): B aᵢᵀ per row
    q = b @ b.T                                                     # (m, m)
    out = a.copy()
    active = np.flatnonzero(np.any(r_inv > 0, axis=1))
    slot = np.full(r_inv.shape[0], -1, dtype=np.int64)
    slot[active] = np.arange(active.size)
    row_slot = slot[which]
    order = np.argsort(row_slot, kind="stable")
    order = order[row_slot[order] >= 0]                             # the rows of active groups, by group
    sorted_slot = row_slot[order]
    step = max(1, block // (m * m))
    for lo in range(0, active.size, step):
        ri = r_inv[active[lo : lo + step]]                          # (G, m)
        sq = np.sqrt(ri)
        g, u = np.linalg.eigh(sq[:, :, None] * q[None] * sq[:, None, :] / nm1)
        g = np.clip(g, 0.0, None)
        root = np.sqrt(1.0 + g)
        ut = np.swapaxes(u, 1, 2)
        k_mean = (u * (-1.0 / (1.0 + g))[:, None, :]) @ ut          # U diag(−1/(1 + g)) Uᵀ
        k_root = (u * (-1.0 / (root * (1.0 + root)))[:, None, :]) @ ut   # U diag(h) Uᵀ
        rd = ri * d                                                 # R⁻¹ρ d per group
        mu = rd + sq * np.einsum("gij,gj->gi", k_mean, sq * (rd @ q)) / nm1  # (G, m); q is symmetric
        lmat = sq[:, :, None] * k_root * sq[:, None, :]             # Dᵢ U diag(h) Uᵀ Dᵢ
        first, last = np.searchsorted(sorted_slot, [lo, lo + ri.shape[0]])
        for start in range(first, last, step):
            at = order[start : min(last, start + step)]
            grp = sorted_slot[start : min(last, start + step)] - lo
            z = np.einsum("rij,rj->ri", lmat[grp], e[at])
            mean = np.einsum("ri,ri->r", e[at], mu[grp])
            out[at] += (z @ b + mean[:, None]) / nm1
    return out


def _local_transformed_members(a: np.ndarray, b: np.ndarray, r_inv: np.ndarray, d: np.ndarray, which: np.ndarray, *,
                               block: int = 1 << 22) -> np.ndarray:
    """:func:`_local_transformed` for more readings than members (m > N): in the N-dimensional ensemble space.

    Per group of rows, Cᵢ = SᵢᵀSᵢ = Bᵀ diag(R⁻¹ρᵢ) B / (N − 1) = V diag(g) Vᵀ (the groups' N × N matrices in
    batched eigendecompositions), the mean weights w̄ᵢ = V diag(1/(1 + g)) Vᵀ Bᵀ R⁻¹ρᵢ d / (N − 1) and the
    transform Wᵢ = V diag((1 + g)^(-½)) Vᵀ (Hunt et al. 2007, Eqs. 21-24); row i of the analysis anomalies is
    aᵢ (w̄ᵢ 1ᵀ + Wᵢ). The same analysis as :func:`_transformed` per group, to rounding. A group of zero weights
    leaves its rows as they are. ``block`` bounds the doubles of the N × N matrices held at once.
    """
    nm1 = b.shape[1] - 1.0
    n_mem = b.shape[1]
    out = a.copy()
    active = np.flatnonzero(np.any(r_inv > 0, axis=1))
    step = max(1, block // (n_mem * n_mem))
    rows_of = np.argsort(which, kind="stable")
    bounds = np.searchsorted(which[rows_of], np.arange(r_inv.shape[0] + 1))
    bd = b * d[:, None]                                             # B weighted by the innovation, (m, N)
    for lo in range(0, active.size, step):
        grp = active[lo : lo + step]
        ri = r_inv[grp]                                             # (G, m)
        c = np.einsum("gm,mk,ml->gkl", ri, b, b, optimize=True) / nm1
        g, v = np.linalg.eigh(c)
        g = np.clip(g, 0.0, None)
        vt = np.swapaxes(v, 1, 2)
        cd = ri @ bd / nm1                                          # Bᵀ R⁻¹ρ d / (N − 1), (G, N)
        w_mean = np.einsum("gkl,gl->gk", (v * (1.0 / (1.0 + g))[:, None, :]) @ vt, cd)
        w = (v * (1.0 / np.sqrt(1.0 + g))[:, None, :]) @ vt         # (G, N, N)
        w += w_mean[:, :, None] * np.ones(n_mem)[None, None, :]     # w̄ 1ᵀ + W: the row's weights per member
        for k, group in enumerate(grp):
            rows = rows_of[bounds[group] : bounds[group + 1]]
            out[rows] = a[rows] @ w[k]
    return out


#: The analyses by name (``enkf``: stochastic, ``etkf``: square root), all called as :func:`enkf_analysis`.
FILTERS: dict[str, Callable[..., np.ndarray]] = {"enkf": enkf_analysis, "etkf": etkf_analysis}
