"""The optional capabilities of the model contract, on every adapter that has them, against the models' own results.

- the embedded engine: levels written into a state set the volumes of the same levels (the engine's own
  geometry) and a run from the state keeps its water balance; perturbed members are one batched call, and a
  member with factors of one is the single run, also where the engine divides its steps;
- SWMM: the hotstart file read as arrays holds the heads SWMM itself reports at the stations, in SWMM's node
  order; heads written into it are what the next SWMM run starts from; scaled inflows are SWMM's scale
  factors, and a variant's scaled series gives the same run;
- a model without a capability is refused with its name and what needed it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.model import load_model
from rivercal.models.capabilities import CAPABILITIES, MissingCapability, has_capability, require, run_members

T0 = pd.Timestamp("2010-10-22", tz="UTC")


@pytest.fixture(scope="module")
def dommel():
    return load_model("dommel")


@pytest.fixture(scope="module")
def swmm():
    return load_model("dommel-swmm")


@pytest.fixture(scope="module")
def swmm_state(swmm):
    _, state = swmm.simulate(None, start=T0 - pd.Timedelta("1D"), end=T0)
    return state


def test_the_embedded_engine_has_every_capability_and_a_wrapper_none(dommel) -> None:
    from rivercal.models.transition import TransitionModel

    assert all(has_capability(dommel, name) for name in CAPABILITIES)
    wrapped = TransitionModel(dommel, dommel.calibration.parameter("FA"), T0)
    assert not has_capability(wrapped, "state arrays")
    with pytest.raises(MissingCapability) as missing:
        require(wrapped, "state arrays", "perturbable forcing", purpose="state updating")
    text = str(missing.value)
    assert "state updating needs a model with 'state arrays' and 'perturbable forcing'" in text
    assert "TransitionModel" in text and "lacks 'state arrays' and 'perturbable forcing'" in text
    with pytest.raises(KeyError, match="unknown model capability 'teleport'"):
        has_capability(dommel, "teleport")


def test_embedded_levels_written_into_a_state_set_their_volumes_and_the_balance_holds(dommel) -> None:
    from rivercal.engine.kernels.batch import volumes  # the engine's own geometry, as the reference

    t0 = dommel.start + pd.Timedelta("2D")
    state = dommel.state_at(None, t0)
    z, q = dommel.state_arrays(state)
    raised = dommel.with_state_arrays(state, z + 0.05, 1.1 * q)
    z2, q2 = dommel.state_arrays(raised)
    assert np.array_equal(z2, np.maximum(z + 0.05, dommel.state_layout().floor))
    expected = np.empty_like(z2)
    volumes(dommel.compiled.arrays, z2, expected)
    assert np.array_equal(raised.vol, expected) and (raised.vol > state.vol).all()
    moving = np.abs(state.u) > 1e-9
    assert np.allclose(q2[moving], 1.1 * q[moving]) and np.allclose(raised.u[moving], 1.1 * state.u[moving])
    assert np.array_equal(state.z, z)  # the state itself is not changed
    result, _ = dommel.simulate(None, start=t0, end=t0 + pd.Timedelta("6h"), state=raised)
    assert abs(result.balance.relative_error) < 1e-9
    # an analysed discharge that would push a link's water faster than half the engine's largest velocity is
    # taken at that speed, in its direction (through a nearly dry link of the D-HYDRO model c01 an analysis gave
    # 53 m/s, and 7 of 16 members diverged in the next step); the other links keep the discharge given
    k = int(np.flatnonzero(moving)[0])
    area = state.q[k] / state.u[k]
    limit = 0.5 * dommel.settings.max_velocity
    pushed = q.copy()
    pushed[k] = -50.0 * limit * area
    fast = dommel.with_state_arrays(state, z, pushed)
    assert fast.u[k] == -limit and fast.q[k] == pytest.approx(-limit * area, rel=1e-12)
    others = np.arange(q.size) != k
    assert np.array_equal(fast.q[others & moving], pushed[others & moving])


def test_perturbed_members_in_one_call_equal_their_runs_one_by_one(dommel) -> None:
    t0 = dommel.start + pd.Timedelta("2D")
    state = dommel.state_at(None, t0)
    k = len(dommel.perturbable_forcing())
    factors = np.stack([np.full((3, k), 1.0), np.full((3, k), 1.5)])
    end = t0 + pd.Timedelta("3h")
    together = dommel.run_members(None, t0, end, [state, state], factors=factors, interval=3600.0)

    class OneByOne:  # the contract's fallback for a model without ensemble runs: simulate_perturbed per member
        def __init__(self, model):
            self.model = model
            self.observables = model.observables

        def perturbable_forcing(self):
            return self.model.perturbable_forcing()

        def simulate_perturbed(self, *args, **kwargs):
            return self.model.simulate_perturbed(*args, **kwargs)

    alone = run_members(OneByOne(dommel), None, t0, end, [state, state], factors=factors, interval=3600.0)
    assert np.array_equal(together.values, alone.values)
    q = dommel.observables.index("0029.Q")
    assert (together.values[1, 1:, q] > together.values[0, 1:, q]).all()  # 50 % more inflow, more discharge


def test_a_member_with_factors_of_one_is_the_single_run_also_where_steps_are_divided(tmp_path) -> None:
    """dommel at a 1-hour step: the engine divides every step (its hourly inflows change within one), and a
    member's divided steps follow the inflows' course within the step, scaled by its factor, as the single run's
    do (holding each step's mean instead moved the series by up to 4e-5)."""
    import shutil
    from importlib import resources
    from pathlib import Path

    case = tmp_path / "dommel"
    shutil.copytree(Path(str(resources.files("rivercal.cases") / "dommel")), case)
    text = (case / "case.toml").read_text(encoding="utf-8")
    assert text.count("dt = 60.0") == 1
    (case / "case.toml").write_text(text.replace("dt = 60.0", "dt = 3600.0"), encoding="utf-8")
    model = load_model(case)
    t0 = model.start + pd.Timedelta("30D")
    state = model.state_at(None, t0)
    single, _ = model.simulate(None, start=t0, end=t0 + pd.Timedelta("12h"), state=state)
    assert model.last_run_stats["divided_steps"] == 12
    k = len(model.perturbable_forcing())
    member = model.run_members(None, t0, t0 + pd.Timedelta("12h"), [state, state],
                               factors=np.stack([np.ones((12, k)), np.full((12, k), 1.2)]), interval=3600.0)
    assert np.array_equal(member.values[0], single.series.to_numpy())
    q = model.observables.index("0029.Q")
    assert (member.values[1, 1:, q] > member.values[0, 1:, q]).all()


def test_the_swmm_hotstart_file_holds_the_heads_swmm_reports(tmp_path, swmm, swmm_state) -> None:
    from swmm.toolkit import shared_enum, solver

    result, state = swmm.simulate(None, start=T0, end=T0 + pd.Timedelta("1h"), state=swmm_state)
    levels, flows = swmm.state_arrays(state)
    layout = swmm.state_layout()
    for obs, value in result.series.iloc[-1].items():  # SWMM's own output at the run's end (single precision)
        got = levels[layout.places[obs]] if obs.rpartition(".")[2] != "Q" else \
            flows[layout.discharges.index("link:" + swmm.stations[obs].partition(":")[2])]
        assert got == pytest.approx(value, abs=2e-4), obs
    # SWMM numbers its nodes and links as the layout says: ask SWMM itself
    inp = tmp_path / "model.inp"
    inp.write_text(swmm.render({}, T0, T0 + pd.Timedelta("1h"), 3600.0, hot=False), encoding="utf-8")
    solver.swmm_open(str(inp), str(tmp_path / "model.rpt"), str(tmp_path / "model.out"))
    try:
        nodes = [solver.project_get_id(shared_enum.ObjectType.NODE, i)
                 for i in range(solver.project_get_count(shared_enum.ObjectType.NODE))]
        links = [solver.project_get_id(shared_enum.ObjectType.LINK, i)
                 for i in range(solver.project_get_count(shared_enum.ObjectType.LINK))]
    finally:
        solver.swmm_close()
    assert [f"node:{n}" for n in nodes] == list(layout.levels)
    assert [f"link:{n}" for n in links] == list(layout.discharges)


def test_heads_written_into_the_hotstart_file_are_where_swmm_starts(swmm, swmm_state) -> None:
    levels, flows = swmm.state_arrays(swmm_state)
    layout = swmm.state_layout()
    written = swmm.with_state_arrays(swmm_state, levels + 0.10, flows)
    assert np.allclose(swmm.state_arrays(written)[0], levels + 0.10, atol=1e-5)
    assert swmm.state_arrays(swmm_state)[0] == pytest.approx(levels)  # the state itself is not changed
    plain, _ = swmm.simulate(None, start=T0, end=T0 + pd.Timedelta("1h"), state=swmm_state)
    raised, _ = swmm.simulate(None, start=T0, end=T0 + pd.Timedelta("1h"), state=written)
    heads = [s for s in plain.series.columns if s.rpartition(".")[2] != "Q"]
    # SWMM reads the heads right after it applied the hotstart file: the written ones
    for s in heads:
        assert raised.series[s].iloc[0] == pytest.approx(levels[layout.places[s]] + 0.10, abs=2e-4)
    assert (raised.series[heads].iloc[-1] > plain.series[heads].iloc[-1]).all()  # the extra water is still there


def test_scaled_swmm_inflows_are_its_scale_factors_and_a_variant_scales_the_series(swmm, swmm_state) -> None:
    k = len(swmm.perturbable_forcing())
    end = T0 + pd.Timedelta("2h")
    one, _ = swmm.simulate_perturbed(None, T0, end, swmm_state, np.ones((2, k)), 3600.0)
    two, _ = swmm.simulate_perturbed(None, T0, end, swmm_state, np.full((2, k), 2.0), 3600.0)
    assert (two.series["0029.Q"].iloc[1:] > one.series["0029.Q"].iloc[1:]).all()
    hours = pd.date_range(swmm.start, swmm.end, freq="1h")
    variant = swmm.variant(forcing_factors={key: pd.Series(2.0, index=hours) for key in swmm.perturbable_forcing()})
    scaled, _ = variant.simulate(None, start=T0, end=end, state=swmm_state)
    # the series times 2 run as the scale factor 2 (SWMM multiplies each series value by its factor)
    assert np.allclose(scaled.series.to_numpy(), two.series.to_numpy(), atol=1e-4)
    with pytest.raises(ValueError, match="makes variants of its inflows only"):
        swmm.variant(grid_factor=0.5)


def test_a_structural_error_on_a_model_without_branches_is_refused_as_bad_input(swmm) -> None:
    from rivercal.errors import OptionError
    from rivercal.twin.truth_model import truth_model

    with pytest.raises(MissingCapability) as refused:
        truth_model(swmm, "realistic")
    assert isinstance(refused.value, OptionError)  # the request is wrong, not rivercal: the CLI's exit 2
    assert "model 'dommel-swmm' (SwmmModel) has no branches to vary" in str(refused.value)
    assert truth_model(swmm, "noisy") is swmm
