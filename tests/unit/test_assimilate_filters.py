"""The ensemble filters against the exact Kalman filter on a linear-Gaussian chain of linear reservoirs.

The reference is the closed-form Kalman filter (Kalman 1960) written out below: for a linear model
with Gaussian errors it is the exact posterior, so an ensemble filter's mean and covariance must
converge to it as the ensemble grows (Evensen 2003, §3.3).
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.assimilate import enkf_analysis, etkf_analysis, gaspari_cohn, network_distances

# A chain of four linear reservoirs (S_k in m³, outflow S_k/T_k into the next), 1 h steps: storage
# m³, inflow 2 m³/s into the first; the levels of the second and fourth are observed (area 10⁴ m²).
DT = 3600.0
T_RES = np.array([4.0, 6.0, 5.0, 8.0]) * 3600.0   # residence times, s
AREA = 1.0e4                                       # m²
N_RES = T_RES.size


def _chain():
    f = np.eye(N_RES) - np.diag(DT / T_RES)
    for k in range(1, N_RES):
        f[k, k - 1] = DT / T_RES[k - 1]
    u = np.zeros(N_RES)
    u[0] = 2.0 * DT
    q = np.diag((np.array([400.0, 300.0, 300.0, 200.0])) ** 2)   # model error, m⁶ per step
    h = np.zeros((2, N_RES))
    h[0, 1] = h[1, 3] = 1.0 / AREA
    r = np.array([0.02, 0.02]) ** 2                              # level error, m²
    m0 = np.array([25e3, 40e3, 30e3, 50e3])
    p0 = np.diag(np.array([5e3, 5e3, 5e3, 5e3]) ** 2)
    return f, u, q, h, r, m0, p0


def _observations(steps, seed=7):
    f, u, q, h, r, m0, p0 = _chain()
    rng = np.random.default_rng(seed)
    x = rng.multivariate_normal(m0, p0)
    ys = []
    for _ in range(steps):
        x = f @ x + u + rng.multivariate_normal(np.zeros(N_RES), q)
        ys.append(h @ x + np.sqrt(r) * rng.standard_normal(2))
    return ys


def kalman_filter(ys):
    """The exact Kalman filter: analysis means and covariances after every observation."""
    f, u, q, h, r, m, p = _chain()
    out = []
    for y in ys:
        m = f @ m + u
        p = f @ p @ f.T + q
        k = p @ h.T @ np.linalg.inv(h @ p @ h.T + np.diag(r))
        m = m + k @ (y - h @ m)
        ikh = np.eye(N_RES) - k @ h
        p = ikh @ p @ ikh.T + k @ np.diag(r) @ k.T   # Joseph form
        out.append((m, p))
    return out


def ensemble_filter(ys, analysis, n_members, seed, **kwargs):
    """The same problem with an ensemble: members forecast with sampled model error, then analysed."""
    f, u, q, h, r, m0, p0 = _chain()
    rng = np.random.default_rng(seed)
    x = rng.multivariate_normal(m0, p0, size=n_members).T
    lq = np.linalg.cholesky(q)
    out = []
    for y in ys:
        x = f @ x + u[:, None] + lq @ rng.standard_normal((N_RES, n_members))
        x = analysis(x, h @ x, y, r, rng=rng, **kwargs)
        out.append((x.mean(axis=1), np.cov(x)))
    return out


def _z_scores(kf, ens, n_members):
    """Errors of the ensemble mean and covariance in standard errors of an N-member sample of the KF posterior."""
    zm, zc = [], []
    for (m, p), (xm, c) in zip(kf, ens, strict=True):
        zm.append((xm - m) / np.sqrt(np.diag(p) / n_members))
        d = np.diag(p)
        zc.append((c - p) / np.sqrt((np.outer(d, d) + p * p) / (n_members - 1)))
    return np.array(zm), np.array(zc)


STEPS = 24


REPLICATES = 16


@pytest.mark.parametrize("analysis", [enkf_analysis, etkf_analysis], ids=["enkf", "etkf"])
def test_ensemble_filters_agree_with_the_kalman_filter_within_three_standard_errors_at_1000_members(analysis):
    """Mean and covariance after the last of 24 analyses, every entry.

    A cycled filter's error carries the sampling error of the earlier cycles (for the unobserved
    reservoirs, measured: up to 2.4 times √(P/N), the standard error of a 1000-member sample of the
    posterior itself), so the standard error is measured rather than assumed: over 16 independent
    1000-member ensembles. Their average must lie within three standard errors of the Kalman filter.
    """
    ys = _observations(STEPS)
    kf = kalman_filter(ys)
    runs = [ensemble_filter(ys, analysis, 1000, seed=s) for s in range(REPLICATES)]
    upper = np.triu_indices(N_RES)
    for t in (STEPS - 1,):
        m, p = kf[t]
        means = np.array([r[t][0] for r in runs])
        covs = np.array([r[t][1][upper] for r in runs])
        for est, exact in ((means, m), (covs, p[upper])):
            se = est.std(axis=0, ddof=1) / np.sqrt(REPLICATES)
            z = (est.mean(axis=0) - exact) / se
            assert np.abs(z).max() < 3.0, (t, z)


def test_enkf_converges_to_the_kalman_filter_as_the_ensemble_grows():
    ys = _observations(STEPS)
    kf = kalman_filter(ys)
    err = {}
    for n in (30, 1000):
        errs = []
        for seed in range(4):
            ens = ensemble_filter(ys, enkf_analysis, n, seed=100 + seed)
            errs.append(np.mean([np.abs(xm - m).mean() for (m, _), (xm, _) in zip(kf, ens, strict=True)]))
        err[n] = float(np.mean(errs))
    # sampling error shrinks like 1/√N: √(1000/30) ≈ 5.8; demand at least 3
    assert err[1000] < err[30] / 3.0, err


@pytest.mark.parametrize("n_members", [20, 100])
def test_etkf_error_is_below_the_stochastic_enkfs_at_equal_ensemble_size(n_members):
    ys = _observations(STEPS)
    kf = kalman_filter(ys)

    def errors(analysis):
        mean_err, cov_err = [], []
        for seed in range(6):
            for (m, p), (xm, c) in zip(kf, ensemble_filter(ys, analysis, n_members, seed=200 + seed), strict=True):
                mean_err.append(np.sqrt(np.mean((xm - m) ** 2 / np.diag(p))))
                cov_err.append(np.linalg.norm(c - p) / np.linalg.norm(p))
        return np.mean(mean_err), np.mean(cov_err)

    enkf_mean, enkf_cov = errors(enkf_analysis)
    etkf_mean, etkf_cov = errors(etkf_analysis)
    assert etkf_mean < enkf_mean
    assert etkf_cov < enkf_cov


def test_etkf_is_the_kalman_update_of_the_sample_mean_and_covariance():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(6, 15)) * np.arange(1, 7)[:, None]
    h = rng.normal(size=(3, 6))
    y = rng.normal(size=3)
    r = np.array([0.5, 1.0, 2.0])
    xa = etkf_analysis(x, h @ x, y, r)
    p = np.cov(x)
    k = p @ h.T @ np.linalg.inv(h @ p @ h.T + np.diag(r))
    np.testing.assert_allclose(xa.mean(axis=1), x.mean(axis=1) + k @ (y - h @ x.mean(axis=1)), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(np.cov(xa), (np.eye(6) - k @ h) @ p, rtol=1e-9, atol=1e-10)


def test_inflation_scales_the_forecast_anomalies():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(3, 10))
    h = np.eye(1, 3)
    inflated = etkf_analysis(x, h @ x, [np.nan], [1.0], inflation=1.5)  # nothing observed: only the inflation
    np.testing.assert_allclose(inflated - inflated.mean(axis=1, keepdims=True),
                               1.5 * (x - x.mean(axis=1, keepdims=True)))


@pytest.mark.parametrize("analysis", [enkf_analysis, etkf_analysis], ids=["enkf", "etkf"])
def test_localisation_leaves_state_beyond_the_cut_off_alone(analysis):
    rng = np.random.default_rng(5)
    base = rng.normal(size=40)
    x = base + 0.1 * rng.normal(size=(4, 40))   # all strongly correlated with the observed variable 0
    h = np.eye(1, 4)
    rho = gaspari_cohn(np.array([[0.0], [500.0], [1500.0], [5000.0]]), 1000.0)
    xa = analysis(x, h @ x, [2.0], [0.1], rng=rng, rho_state=rho)
    np.testing.assert_allclose(xa[3], x[3], rtol=0, atol=1e-12)   # 5 km away, beyond 2c = 2 km: untouched
    moved = np.abs(xa - x).mean(axis=1)
    assert moved[0] > moved[1] > moved[2] > 0.0   # the update fades with distance
    assert not np.allclose(xa[0], x[0])


def test_missing_observations_are_dropped():
    rng = np.random.default_rng(6)
    x = rng.normal(size=(2, 12))
    h = np.eye(2)
    both = etkf_analysis(x, h @ x, [0.3, np.nan], [0.2, 0.2])
    one = etkf_analysis(x, (h @ x)[:1], [0.3], [0.2])
    np.testing.assert_allclose(both, one)


def test_bad_input_is_named():
    x = np.zeros((3, 5))
    with pytest.raises(ValueError, match="predicted observations must have shape"):
        etkf_analysis(x, np.zeros((2, 4)), [1.0, 2.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="variances must be positive"):
        etkf_analysis(x + np.arange(5), np.zeros((1, 5)) + np.arange(5), [1.0], [0.0])
    with pytest.raises(ValueError, match="at least 2 members"):
        etkf_analysis(np.zeros((3, 1)), np.zeros((1, 1)), [1.0], [1.0])


def test_gaspari_cohn_is_eq_4_10():
    c = 1000.0
    d = np.array([0.0, 500.0, 1000.0, 1500.0, 2000.0, 3000.0])
    rho = gaspari_cohn(d, c)
    assert rho[0] == 1.0
    assert rho[2] == pytest.approx(5.0 / 24.0)          # both branches give 5/24 at d = c
    assert rho[3] == pytest.approx(1.5**5 / 12 - 1.5**4 / 2 + 5 / 8 * 1.5**3 + 5 / 3 * 1.5**2 - 5 * 1.5 + 4
                                   - 2 / (3 * 1.5))
    assert rho[4] == pytest.approx(0.0, abs=1e-12) and rho[5] == 0.0
    fine = gaspari_cohn(np.linspace(0, 2 * c, 2001), c)
    assert np.all(np.diff(fine) <= 1e-15)                 # monotone
    assert np.abs(np.diff(fine)).max() < 2e-3             # continuous (no jump at c)
    # positive definite on the line: the tapered matrix of 60 points spaced 100 m has no negative eigenvalue
    pts = np.arange(60) * 100.0
    assert np.linalg.eigvalsh(gaspari_cohn(pts[:, None] - pts[None, :], c)).min() > -1e-12
    assert np.all(gaspari_cohn(d, np.inf) == 1.0)


def test_network_distances_follow_the_links():
    # a confluence: 0 -1000 m- 1 -2000 m- 2 and 3 -500 m- 1; 4 is not connected
    d = network_distances(5, np.array([0, 1, 3]), np.array([1, 2, 1]), np.array([1000.0, 2000.0, 500.0]))
    assert d[0, 2] == 3000.0 and d[3, 2] == 2500.0 and d[0, 3] == 1500.0 and d[2, 0] == 3000.0
    assert np.isinf(d[0, 4])
    rows = network_distances(5, np.array([0, 1, 3]), np.array([1, 2, 1]), np.array([1000.0, 2000.0, 500.0]),
                             sources=np.array([3]))
    np.testing.assert_array_equal(rows, d[[3]])
    with pytest.raises(ValueError, match="must be positive"):
        network_distances(2, np.array([0]), np.array([1]), np.array([0.0]))
