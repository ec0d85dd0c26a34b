"""The local ETKF's batched analysis against Hunt, Kostelich & Szunyogh's (2007) per-row form, written out here."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.assimilate import etkf_analysis, gaspari_cohn
from rivercal.assimilate.filters import _local_transformed


def _hunt_local(x: np.ndarray, hx: np.ndarray, y: np.ndarray, r: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Each row's own analysis, Hunt et al. (2007) Eqs. 20–24 with R⁻¹ weighted by the row's taper (§2.3).

    P̃ = [(N − 1) I + Bᵀ diag(ρᵢ/r) B]⁻¹ by an N × N eigendecomposition, w̄ = P̃ Bᵀ diag(ρᵢ/r)(y − ȳ),
    Wᵃ = [(N − 1) P̃]^½ (symmetric root): independent of the filter's thin-SVD and m-space forms.
    """
    n_mem = x.shape[1]
    xm, ym = x.mean(axis=1), hx.mean(axis=1)
    a, b = x - xm[:, None], hx - ym[:, None]
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        c = b.T * (rho[i] / r)                                        # Bᵀ R⁻¹ρᵢ
        lam, v = np.linalg.eigh((n_mem - 1) * np.eye(n_mem) + c @ b)
        p = (v / lam) @ v.T
        w_mean = p @ c @ (y - ym)
        w = (v * np.sqrt((n_mem - 1) / lam)) @ v.T
        out[i] = xm[i] + a[i] @ (w_mean[:, None] + w)
    return out


def _case(n: int, n_mem: int, m: int, seed: int):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n, n_mem)) * rng.uniform(0.1, 2.0, (n, 1)) + rng.uniform(-3, 3, (n, 1))
    h = rng.standard_normal((m, n)) / np.sqrt(n)
    hx = h @ x + 0.05 * rng.standard_normal((m, n_mem))
    y = hx.mean(axis=1) + rng.standard_normal(m)
    r = rng.uniform(0.05, 0.5, m)
    where_state, where_obs = rng.uniform(0, 20_000, n), rng.uniform(0, 8_000, m)  # beyond 12 km: no reading
    rho = gaspari_cohn(np.abs(where_state[:, None] - where_obs[None]), 2_000.0)
    rho[: n // 5] = rho[0]                                            # some rows share a taper (a group)
    return x, hx, y, r, rho


@pytest.mark.parametrize(("n", "n_mem", "m"), [(60, 16, 5), (40, 8, 8), (30, 6, 11)],
                         ids=["fewer readings", "as many as members", "more readings than members"])
def test_localised_etkf_is_each_rows_own_analysis(n, n_mem, m):
    x, hx, y, r, rho = _case(n, n_mem, m, seed=n + m)
    xa = etkf_analysis(x, hx, y, r, rho_state=rho)
    reference = _hunt_local(x, hx, y, r, rho)
    np.testing.assert_allclose(xa, reference, rtol=0, atol=1e-10 * np.abs(x).max())
    far = np.flatnonzero(~rho.any(axis=1))
    assert far.size > 0                                               # rows beyond every reading's cut-off …
    # … keep their members (x̄ + (x − x̄): to rounding)
    np.testing.assert_allclose(xa[far], x[far], rtol=0, atol=8 * np.finfo(float).eps * np.abs(x).max())


def test_the_batched_analysis_does_not_depend_on_its_block_size():
    x, hx, y, r, rho = _case(50, 12, 4, seed=3)
    xm, ym = x.mean(axis=1, keepdims=True), hx.mean(axis=1, keepdims=True)
    groups, which = np.unique(rho, axis=0, return_inverse=True)
    args = (x - xm, hx - ym, groups / r, y - ym[:, 0], which.ravel())
    whole = _local_transformed(*args)
    pieces = _local_transformed(*args, block=2 * 16)                # two groups (and rows of two groups) at a time
    np.testing.assert_allclose(pieces, whole, rtol=0, atol=1e-13 * np.abs(whole).max())


def test_the_ensemble_space_analysis_does_not_depend_on_its_block_size():
    from rivercal.assimilate.filters import _local_transformed_members

    x, hx, y, r, rho = _case(50, 6, 20, seed=5)                      # more readings than members
    xm, ym = x.mean(axis=1, keepdims=True), hx.mean(axis=1, keepdims=True)
    groups, which = np.unique(rho, axis=0, return_inverse=True)
    args = (x - xm, hx - ym, groups / r, y - ym[:, 0], which.ravel())
    whole = _local_transformed_members(*args)
    pieces = _local_transformed_members(*args, block=2 * 36)        # two groups at a time
    np.testing.assert_allclose(pieces, whole, rtol=0, atol=1e-13 * np.abs(whole).max())
    np.testing.assert_allclose(xm + whole, _hunt_local(x, hx, y, r, rho), rtol=0, atol=1e-10 * np.abs(x).max())
