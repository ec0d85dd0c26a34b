"""The batched engine: every member is bit-identical to its single run, whatever the threads."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.engine import Simulator
from rivercal.engine.ensemble import run_ensemble
from rivercal.errors import EngineDivergedError
from rivercal.model import load_model


@pytest.fixture(scope="module")
def dommel():
    sim = load_model("dommel")
    start = sim.start + pd.Timedelta("5D")
    _, state = sim.simulate(end=start)
    return sim, start, state


def _perturbed_model(sim, factor):
    """The case with every lateral multiplied by a factor varying in time (a member's forcing perturbation)."""
    series = dict(sim.forcing)
    for key in sim.compiled.forcing_keys:
        if key.startswith("lateral:"):
            s = series[key]
            series[key] = s * (1.0 + factor * np.sin(np.arange(len(s)) / 7.0))
    return Simulator(sim.case, forcing=series)


def _assert_same(single, state, ens, m):
    assert np.array_equal(single.series.to_numpy(), ens.values[m], equal_nan=True), m
    for name in ("z", "dz", "vol", "u", "q", "pump_on"):
        assert np.array_equal(getattr(state, name), getattr(ens.states[m], name)), (m, name)
    assert ens.states[m].time == state.time


@pytest.mark.parametrize("n_threads", [1, 2])
def test_members_with_own_parameters_states_and_forcing_equal_their_single_runs(dommel, n_threads):
    sim, start, state = dommel
    end = start + pd.Timedelta("1D")
    n_steps = round((end - start).total_seconds() / sim.dt)
    models = [sim, _perturbed_model(sim, 0.3), _perturbed_model(sim, -0.2)]
    params = [{"friction:global": 16.0}, {"friction:global": 12.5}, {"friction:global": 22.0}]
    _, later = sim.simulate(start=start, end=start + pd.Timedelta("2h"), state=state)
    later.time = start  # another state at the same time: a member's own initial condition
    states = [state, later, state]
    forcing = np.stack([m.forcing_matrix(start, n_steps) for m in models])
    ens = run_ensemble(sim, params, start, end, states, forcing=forcing, n_threads=n_threads, snapshots=True)
    assert ens.members == 3 and not ens.failures
    for m, (model, p, s) in enumerate(zip(models, params, states, strict=True)):
        single, after = model.simulate(p, start, end, s, snapshots=True)
        _assert_same(single, after, ens, m)
        assert np.array_equal(single.levels.to_numpy(), ens.levels[m])
        assert np.array_equal(single.discharges.to_numpy(), ens.discharges[m])
    # the members really differ
    assert not np.array_equal(ens.values[0], ens.values[1])


def test_cold_start_members_spin_up_like_single_runs():
    sim = load_model("synthetic")
    end = sim.start + pd.Timedelta("12h")
    params = [{"friction:global": v} for v in (20.0, 30.0)]
    ens = run_ensemble(sim, params, sim.start, end)
    for m, p in enumerate(params):
        single, after = sim.simulate(p, sim.start, end)
        _assert_same(single, after, ens, m)
    assert ens.series(1).equals(sim.simulate(params[1], sim.start, end)[0].series)


def test_a_diverging_member_follows_the_policy_and_leaves_the_others_alone(dommel):
    sim, start, state = dommel
    end = start + pd.Timedelta("6h")
    n_steps = round((end - start).total_seconds() / sim.dt)
    good = sim.forcing_matrix(start, n_steps)
    bad = good.copy()
    bad[:, 0] = 1.0e6   # a million m³/s into the upstream boundary
    forcing = np.stack([good, bad, good])
    params = [None, None, {"friction:global": 20.0}]
    with pytest.raises(EngineDivergedError, match="member 1"):
        run_ensemble(sim, params, start, end, [state] * 3, forcing=forcing)
    ens = run_ensemble(sim, params, start, end, [state] * 3, forcing=forcing, on_failure="report")
    assert list(ens.failures) == [1] and ens.states[1] is None and np.isnan(ens.values[1]).all()
    for m in (0, 2):
        single, after = sim.simulate(params[m], start, end, state)
        _assert_same(single, after, ens, m)


def test_bad_ensemble_input_is_named(dommel):
    sim, start, state = dommel
    end = start + pd.Timedelta("1h")
    with pytest.raises(ValueError, match="forcing must have shape"):
        run_ensemble(sim, [None, None], start, end, [state, state], forcing=np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match="1 states for 2 members"):
        run_ensemble(sim, [None, None], start, end, [state])
    with pytest.raises(ValueError, match="threads must be between"):
        run_ensemble(sim, [None], start, end, [state], n_threads=0)
    with pytest.raises(ValueError, match="member 0: the state is at"):
        run_ensemble(sim, [None], start + pd.Timedelta("1h"), end + pd.Timedelta("1h"), [state])


@pytest.mark.parametrize("n_threads", [1, 2])
def test_controlled_members_carry_their_own_controllers_like_single_runs(n_threads):
    """dommel-controlled: members with their own setpoints and controller states, cold and hot start."""
    sim = load_model("dommel-controlled")
    start = sim.start + pd.Timedelta("2D")
    end = start + pd.Timedelta("12h")
    params = [None, {"control:W2.setpoint": 12.5}, {"control:W1.kp": 0.5, "friction:global": 20.0}]
    cold = run_ensemble(sim, params, sim.start, start, n_threads=n_threads)
    assert not cold.failures
    states = []
    for m, p in enumerate(params):
        single, after = sim.simulate(p, sim.start, start)
        _assert_same(single, after, cold, m)
        assert np.array_equal(after.ctl, cold.states[m].ctl)
        states.append(after)
    # the controllers really act and differ between members (W2's crest follows its own setpoint)
    assert not np.array_equal(cold.values[0][:, -8:], cold.values[1][:, -8:])
    assert states[0].ctl.shape[0] == len(sim.controls) and np.any(states[0].ctl != states[1].ctl)
    hot = run_ensemble(sim, params, start, end, cold.states, n_threads=n_threads)
    for m, p in enumerate(params):
        single, after = sim.simulate(p, start, end, states[m])
        _assert_same(single, after, hot, m)
        assert np.array_equal(after.ctl, hot.states[m].ctl)
    # a hot start continues the controllers exactly: the two halves equal the whole
    whole, _ = sim.simulate(params[1], sim.start, end)
    assert np.array_equal(whole.series.to_numpy()[-hot.values.shape[1]:], hot.values[1])
    assert hot.observables == tuple(sim.observables)
    with pytest.raises(ValueError, match="member 0: the state holds 0 controllers"):
        plain = load_model("dommel").simulate(end=sim.start + pd.Timedelta("1h"))[1]
        run_ensemble(sim, [None], plain.time, plain.time + pd.Timedelta("1h"), [plain])
