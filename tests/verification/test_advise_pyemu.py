"""The gauge advice's linear analysis against pyEMU's Schur complement (the data-worth tool of PEST++).

For the same Jacobian (dommel's present stations and the level either side of every structure, a two-day
window, W1…W9 and FA), the same observation noise and the same prior, rivercal's posterior parameter
covariance and each candidate's posterior variances and data worth must agree with pyEMU's
``Schur.posterior_parameter`` and ``Schur.get_added_obs_importance`` within 1 % (relative), and the
five candidates worth most must be the same five in the same order.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from rivercal.analysis.advise import LinearWorth, advice_jacobian, posterior_covariance, prior_std
from rivercal.model import load_model
from rivercal.parameters import ParameterSet
from rivercal.workflows.advise import candidates_of

with warnings.catch_warnings():  # pyEMU warns that its legacy modules need flopy, which these tests do not use
    warnings.simplefilter("ignore")
    import pyemu

NAMES = ["W1", "W2", "W3", "W4", "W5", "W6", "W7", "W8", "W9", "FA"]
FORECAST = "0031.h_down"


@pytest.fixture(scope="module")
def setup():
    model = load_model("dommel")
    defined = {p.name: p for p in model.calibration.parameters}
    params = ParameterSet(defined[n] for n in NAMES)
    window = (pd.Timestamp("2010-09-30", tz="UTC"), pd.Timestamp("2010-10-02", tz="UTC"))
    cands = candidates_of(model, "structures", "level")
    jac = advice_jacobian(model, params, window, candidates=cands, forecasts=[FORECAST], horizon="24h", workers=1)
    lw = LinearWorth(NAMES, jac["base"], cands, jac["blocks"], prior_std(params), scale=jac["scale"],
                     forecasts=jac["forecasts"], base_rows=jac["base_rows"])
    return lw, jac, cands


def _schur(lw: LinearWorth, jac: dict, cands: list):
    """pyEMU's Schur object over the unweighted sensitivities, with the noise and prior as covariances."""
    sigma = jac["sigma"]
    obs, sens, noise, groups = [], [], [], {}
    for i, (sid, row) in enumerate(zip(lw.base_rows, lw.base, strict=True)):
        obs.append(f"b{i}")
        sens.append(-sigma[sid] * row)  # the rows are weighted residuals: −∂ŷ/∂x / σ
        noise.append(sigma[sid] ** 2)
    for c in cands:
        block = lw.blocks[c.id]
        per = block.shape[0] // len(c.series)
        names = []
        for k, row in enumerate(block):
            sid = c.series[k // per]
            names.append(f"{c.id.lower()}_{k}")
            sens.append(-sigma[sid] * row)
            noise.append(sigma[sid] ** 2)
        obs.extend(names)
        groups[c.id] = names
    pars = [n.lower() for n in NAMES]
    jco = pyemu.Jco(x=np.array(sens), row_names=obs, col_names=pars)
    obscov = pyemu.Cov(x=np.array(noise)[:, None], names=obs, isdiagonal=True)
    parcov = pyemu.Cov(x=lw.prior_var[:, None], names=pars, isdiagonal=True)
    y = np.column_stack([lw.forecasts[FORECAST], np.eye(len(NAMES))])
    forecasts = pyemu.Matrix(x=y, row_names=pars, col_names=["fc", *[f"v_{p}" for p in pars]])
    return pyemu.Schur(jco=jco, obscov=obscov, parcov=parcov, forecasts=forecasts, verbose=False), groups


def test_posterior_and_data_worth_agree_with_pyemu(setup):
    lw, jac, cands = setup
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc, groups = _schur(lw, jac, cands)
        base_obs = [f"b{i}" for i in range(lw.base.shape[0])]
        post = sc.get(par_names=sc.jco.col_names, obs_names=base_obs).posterior_parameter.x
        added = sc.get_added_obs_importance(obslist_dict={k: list(v) for k, v in groups.items()},
                                            base_obslist=base_obs, reset_zero_weight=0.0)
    ours = posterior_covariance(lw.information([]), lw.prior_var)
    assert np.allclose(np.diag(ours), np.diag(post), rtol=0.01)
    assert np.allclose(ours, post, rtol=0.01, atol=1e-3 * np.sqrt(np.outer(np.diag(ours), np.diag(ours))).max())
    # rivercal's targets are the forecast (FORECAST given); its table also holds every parameter's σ
    table = lw.worth_table()
    base_var = float(added.loc["base", "fc"])
    assert lw.target_variance(lw.information([]))[0] == pytest.approx(base_var, rel=0.01)
    for c in cands:
        assert table.loc[c.id, f"var:{FORECAST}"] == pytest.approx(added.loc[c.id, "fc"], rel=0.01)
        assert table.loc[c.id, "worth"] == pytest.approx(1.0 - added.loc[c.id, "fc"] / base_var, rel=0.01)
        for n in NAMES:
            assert table.loc[c.id, f"std:{n}"] ** 2 == pytest.approx(added.loc[c.id, f"v_{n.lower()}"], rel=0.01)
    pyemu_worth = 1.0 - added.drop(index="base")["fc"] / base_var
    assert list(table["worth"].sort_values(ascending=False).index[:5]) == list(
        pyemu_worth.sort_values(ascending=False).index[:5])
    # and the candidates do differ: the ranking is not a tie
    top = table["worth"].sort_values(ascending=False).to_numpy()[:6]
    assert np.all(np.diff(top) < 0)


def test_parameter_worth_agrees_with_pyemu(setup):
    """With the parameters as targets (no forecast): each candidate's worth is pyEMU's mean fractional reduction."""
    lw, jac, cands = setup
    plain = LinearWorth(NAMES, lw.base, cands, lw.blocks, np.sqrt(lw.prior_var), scale=lw.scale, base_rows=lw.base_rows)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc, groups = _schur(lw, jac, cands)
        base_obs = [f"b{i}" for i in range(lw.base.shape[0])]
        added = sc.get_added_obs_importance(obslist_dict={k: list(v) for k, v in groups.items()},
                                            base_obslist=base_obs, reset_zero_weight=0.0)
    cols = [f"v_{n.lower()}" for n in NAMES]
    theirs = (1.0 - added.loc[:, cols].div(added.loc["base", cols], axis=1)).drop(index="base").mean(axis=1)
    table = plain.worth_table()
    for c in cands:
        assert table.loc[c.id, "worth"] == pytest.approx(theirs[c.id], rel=0.01)
    assert list(table["worth"].sort_values(ascending=False).index[:5]) == list(
        theirs.sort_values(ascending=False).index[:5])
