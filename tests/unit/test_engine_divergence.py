"""A run that goes non-physical raises EngineDivergedError naming the time and the place; it never returns NaN.

The expected time and place are found independently: by stepping the same run one time step at a time
(hot starts, which are exact) and looking at the state after each step.
"""

import tomllib

import numpy as np
import pandas as pd
import pytest

from rivercal.case import case_from_dict
from rivercal.case.load import resolve_case_path
from rivercal.engine import Simulator
from rivercal.errors import EngineDivergedError


def _synthetic(**engine) -> Simulator:
    root = resolve_case_path("synthetic")
    data = tomllib.loads((root / "case.toml").read_text(encoding="utf-8"))
    data["engine"].update(engine)
    return Simulator(case_from_dict(data, root))


def test_a_velocity_above_the_limit_is_reported_at_its_first_step_and_link() -> None:
    normal = _synthetic()
    _, state = normal.simulate(None, end=normal.start + pd.Timedelta(hours=6))
    speeds = np.abs(state.u)
    limit = float(np.quantile(speeds[speeds > 0], 0.9))  # reached somewhere, not everywhere
    dt = pd.Timedelta(seconds=normal.dt)
    expected = None
    t, s = state.time, state
    for _ in range(120):
        _, s = normal.simulate(None, start=t, end=t + dt, state=s, output_interval=normal.dt)
        t = t + dt
        over = np.flatnonzero(~(np.abs(s.u) <= limit))
        if over.size:
            expected = (t, normal.compiled.link_label[over[0]])
            break
    assert expected is not None

    strict = _synthetic(max_velocity=limit)
    with pytest.raises(EngineDivergedError) as info:
        strict.simulate(None, start=state.time, end=state.time + pd.Timedelta(hours=2), state=state)
    err = info.value
    assert pd.Timestamp(err.time) == expected[0]
    assert err.location == expected[1]
    assert f"exceeds engine.max_velocity ({limit} m/s)" in err.detail


def test_an_absurd_inflow_is_reported_as_a_level_not_returned_as_numbers() -> None:
    sim = _synthetic()
    start = sim.start
    flood = pd.Series([1.0e9, 1.0e9], index=pd.DatetimeIndex([start, sim.end]))
    absurd = Simulator(sim.case, forcing={"lateral:L2": flood})
    state = absurd.initial_state(start)
    with pytest.raises(EngineDivergedError) as info:
        absurd.simulate(None, start=start, end=start + pd.Timedelta(hours=1), state=state)
    err = info.value
    assert pd.Timestamp(err.time) == start + pd.Timedelta(seconds=sim.dt)  # the first step
    index = sim.compiled.hp_label.index(err.location)
    assert err.detail.startswith("level ") and err.detail.endswith(" m AD")
    level = float(err.detail.split()[1])
    assert abs(level - sim.compiled.arrays.hp_bed[index]) > 1.0e4
