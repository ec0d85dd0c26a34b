"""A filter that stored an ensemble takes its members from memory only while the store holds that very archive."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from rivercal.model import load_model
from rivercal.models.contract import spun_up
from rivercal.observations import measurable
from rivercal.online.assimilation import AssimilationConfig, EnsembleFilter
from rivercal.store import CycleRecord, CycleSpec, Store


def _fields(state) -> dict:
    return {f.name: getattr(state, f.name) for f in dataclasses.fields(state)}


def _same(a, b) -> bool:
    fa, fb = _fields(a), _fields(b)
    return fa.keys() == fb.keys() and all(
        np.array_equal(np.asarray(fa[k]), np.asarray(fb[k])) if isinstance(fa[k], np.ndarray) else fa[k] == fb[k]
        for k in fa)


def _commit(store: Store, run, cycle: int, t0: pd.Timestamp, record) -> None:
    spec = store.begin_cycle(run, CycleSpec(cycle, t0 - pd.Timedelta("1D"), t0, t0))
    store.commit_cycle(run, CycleRecord(spec.cycle, spec.window_start, spec.window_end, spec.issue_time,
                                        algorithm="dud", model_runs=0, ensemble=record))


def test_the_kept_members_are_the_stored_ones_and_another_writers_archive_is_read(tmp_path):
    model = load_model("dommel")
    series = measurable(model.observables)
    config = AssimilationConfig(mode="states", members=4, seed=1)
    writer = EnsembleFilter(model, config, series)
    t0 = model.start + pd.Timedelta("2D")
    state = spun_up(model, {}, t0 - pd.Timedelta("1h"))
    rng = np.random.default_rng(0)
    members, errors = writer.initial(state, rng)
    factors, errors = writer._factors(1, errors, rng)
    members = list(writer._run({}, state.time, t0, members, factors, 3600.0).states)  # four perturbed members at t0
    with Store(tmp_path / "run.sqlite") as store:
        run = store.ensure_run("kept", model.name, {})
        _commit(store, run, 0, t0, writer.to_record(members, errors))
        kept, kept_errors = writer.from_store(store, run, t0)
        # a filter that did not write it (a restarted service) unpacks the archive: the same members and errors
        read, read_errors = EnsembleFilter(model, config, series).from_store(store, run, t0)
        assert not _same(read[0], read[1])                                  # the members differ …
        assert all(_same(a, b) for a, b in zip(kept, read, strict=True))    # … and each is what the store holds
        np.testing.assert_array_equal(kept_errors, read_errors)
        # another writer replaces the run's ensemble: the first filter reads the new archive, not its own members
        other = EnsembleFilter(model, config, series)
        _commit(store, run, 1, t0 + pd.Timedelta("1D"), other.to_record(members[::-1], errors + 1.0))
        now, now_errors = writer.from_store(store, run, t0)
        np.testing.assert_array_equal(now_errors, errors + 1.0)
        assert _same(now[0], members[-1]) and not _same(now[0], members[0])
