"""EngineState survives the round trip through bytes exactly: a hot start from stored bytes continues the run."""

import numpy as np
import pandas as pd
import pytest

from rivercal.engine.state import EngineState
from rivercal.model import load_model


def test_state_bytes_round_trip_continues_the_run_exactly() -> None:
    model = load_model("synthetic")
    start = model.start
    mid = start + (model.end - start) / 4
    mid = mid.floor("h")
    _, state = model.simulate(None, end=mid)
    back = EngineState.from_bytes(state.to_bytes())
    assert back.time == state.time and back.signature == state.signature
    for name in ("z", "dz", "vol", "u", "q", "pump_on", "control", "flicker", "swing"):
        assert np.array_equal(getattr(back, name), getattr(state, name)), name
    end = mid + (model.end - mid) / 8
    end = end.floor("h")
    a, _ = model.simulate(None, start=mid, end=end, state=state)
    b, _ = model.simulate(None, start=mid, end=end, state=back)
    assert np.array_equal(a.series.to_numpy(), b.series.to_numpy())


def test_foreign_bytes_are_refused_with_a_reason() -> None:
    with pytest.raises(ValueError, match="not an engine state archive"):
        EngineState.from_bytes(b"not a state")
    with pytest.raises(ValueError, match="format 'pickle' is not"):
        EngineState.from_bytes(b"", "pickle")


def test_a_run_split_in_two_equals_the_whole_and_does_not_depend_on_earlier_runs() -> None:
    """The hot start is exact: the scratch state a model keeps between runs (the linearised pieces of the
    volume curves) changes how much work a step does, never its result."""
    model = load_model("synthetic")
    start = model.start
    mid, end = start + pd.Timedelta(days=2), start + pd.Timedelta(days=4)
    whole, _ = model.simulate(None, start=start, end=end)
    _, state = load_model("synthetic").simulate(None, start=start, end=mid)
    second, _ = load_model("synthetic").simulate(None, start=mid, end=end, state=state)
    assert np.array_equal(whole.series.loc[mid:].to_numpy(), second.series.to_numpy())
    model.simulate({"friction:global": 25.0}, start=start, end=end)  # other levels, other pieces
    again, _ = model.simulate(None, start=start, end=end)
    assert np.array_equal(whole.series.to_numpy(), again.series.to_numpy())


def test_the_state_holds_the_last_step_whatever_the_number_of_steps() -> None:
    """The time loop swaps its velocity and flux arrays every step instead of copying them; after an odd
    number of steps the last ones are in the other buffer and must still reach the returned state."""
    model = load_model("synthetic")
    _, state = model.simulate(None, end=model.start + pd.Timedelta(hours=6))
    dt = pd.Timedelta(seconds=model.dt)
    t0 = state.time
    for n_steps in (1, 3, 4):
        result, after = model.simulate(None, start=t0, end=t0 + n_steps * dt, state=state,
                                       output_interval=model.dt, snapshots=True)
        assert np.array_equal(after.q, result.discharges.iloc[-1].to_numpy()), n_steps
        assert not np.array_equal(after.q, state.q), n_steps  # the flow changes over a step
    three, _ = model.simulate(None, start=t0, end=t0 + 3 * dt, state=state, output_interval=model.dt)
    _, one = model.simulate(None, start=t0, end=t0 + dt, state=state, output_interval=model.dt)
    rest, _ = model.simulate(None, start=t0 + dt, end=t0 + 3 * dt, state=one, output_interval=model.dt)
    assert np.array_equal(three.series.iloc[1:].to_numpy(), rest.series.to_numpy())


@pytest.mark.parametrize("case", ["synthetic", "dommel-controlled"])
def test_state_at_equals_the_spin_up_from_the_case_start(case: str) -> None:
    """``state_at`` continues from an earlier spin-up with the same parameters: the state is that of a spin-up
    from the case's start, to the last bit, whatever it kept from before (controllers' states included)."""
    model = load_model(case)
    day = pd.Timedelta(days=1)
    other = {"friction:global": 25.0} if case == "synthetic" else {"friction:scale": 1.2}
    asks = [(None, 2 * day), (other, 2 * day), (None, 3 * day), (None, 1 * day), (None, 3 * day)]
    for parameters, offset in asks:
        at = model.start + offset
        got = model.state_at(parameters, at)
        _, fresh = load_model(case).simulate(parameters, end=at)
        assert got.time == at
        for name in ("z", "dz", "vol", "u", "q", "pump_on", "ctl"):
            assert np.array_equal(getattr(got, name), getattr(fresh, name)), (parameters, offset, name)
        got.z[:] = 0.0  # the caller's copy: what the model keeps is untouched
    again = model.state_at(None, model.start + 3 * day)   # the last ask's state, kept before the caller zeroed its copy
    assert np.array_equal(again.z, fresh.z)
