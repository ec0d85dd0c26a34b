"""Spun-up states kept on disk: the state from the cache is the spin-up's own, to the last bit.

Each model here is built fresh, so that its own in-process spin-ups cannot answer: whatever it does not
compute, it read from the folder, as another process would. The reference is a cold-started run of a
third model, with the cache off.
"""

from __future__ import annotations

import logging
import os
import time

import numpy as np
import pandas as pd
import pytest

from rivercal.models import load_model, spun_up
from rivercal.models.spinups import ENV_VAR, STALE_PART_S, SpinUpCache, spin_up_cache

FIELDS = ("z", "dz", "vol", "u", "q", "pump_on", "ctl")
PARAMS = {"friction:global": 31.0, "weir:W2.crest_level": 12.7}
T1, T2 = pd.Timestamp("2020-01-03", tz="UTC"), pd.Timestamp("2020-01-04T06:00", tz="UTC")


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    return tmp_path / "spin-ups"


def _reference(at: pd.Timestamp, parameters=PARAMS):
    return load_model("synthetic").simulate(parameters, end=at)[1]


def _same(a, b) -> bool:
    return a.time == b.time and all(np.array_equal(getattr(a, f), getattr(b, f)) for f in FIELDS)


def _states(folder) -> list:
    return sorted(folder.glob("*/*/*.state"))


def test_a_kept_state_is_the_spin_up_to_the_bit_and_a_later_one_continues_from_it(folder) -> None:
    first = spun_up(load_model("synthetic"), PARAMS, T1)
    assert [p.name for p in _states(folder)] == [f"{T1.value}.state"]

    again = load_model("synthetic")
    state = spun_up(again, PARAMS, T1)
    assert again.last_run_stats == {}, "the second model ran its engine instead of reading the kept state"
    assert _same(state, first)

    later = spun_up(again, PARAMS, T2)       # from the kept state at T1: a day and a quarter, not three days
    assert again.last_run_stats["steps"] == (T2 - T1) // pd.Timedelta("60s")
    assert _same(later, _reference(T2))
    assert len(_states(folder)) == 2
    assert _same(state, _reference(T1))


def test_another_run_never_takes_a_kept_state(folder) -> None:
    model = load_model("synthetic")
    key = model.spin_up_key(PARAMS)
    assert load_model("synthetic").spin_up_key(dict(reversed(PARAMS.items()))) == key
    assert model.spin_up_key({**PARAMS, "friction:global": 31.000001}) != key
    defaults = model.default_parameters()
    assert model.spin_up_key({}) == model.spin_up_key(defaults)   # the same arrays in the kernels

    spun_up(model, PARAMS, T1)
    wetter = load_model("synthetic")
    qup = wetter.forcing["boundary:Qup"]
    wetter.forcing["boundary:Qup"] = qup * 1.01
    assert wetter.spin_up_key(PARAMS) != key
    changed = load_model("synthetic")
    changed.forcing["boundary:Qup"] = series = qup.copy()
    assert changed.spin_up_key(PARAMS) == key
    series.iloc[5] += 0.1                                          # changed in place
    assert changed.spin_up_key(PARAMS) != key
    state = spun_up(wetter, PARAMS, T1)
    assert wetter.last_run_stats["steps"] > 0, "a model with other forcing took the kept state"
    assert not _same(state, spun_up(load_model("synthetic"), PARAMS, T1))
    assert len(_states(folder)) == 2


def test_a_damaged_state_is_logged_removed_and_computed_again(folder, caplog) -> None:
    spun_up(load_model("synthetic"), PARAMS, T1)
    (path,) = _states(folder)
    path.write_bytes(b"not a state")
    model = load_model("synthetic")
    with caplog.at_level(logging.WARNING, logger="rivercal.models.spinups"):
        state = spun_up(model, PARAMS, T1)
    assert str(path) in caplog.text and "unusable" in caplog.text
    assert model.last_run_stats["steps"] > 0
    assert _same(state, _reference(T1))
    assert _same(load_model("synthetic").load_state(path.read_bytes(), "rivercal-engine-state-npz-1"), state)


def test_off_keeps_nothing_and_an_unwritable_folder_is_said_once(tmp_path, monkeypatch, caplog) -> None:
    monkeypatch.setenv(ENV_VAR, "off")
    assert _same(spun_up(load_model("synthetic"), PARAMS, T1), _reference(T1))
    assert list(tmp_path.iterdir()) == []

    blocked = tmp_path / "a-file"
    blocked.write_text("")
    monkeypatch.setenv(ENV_VAR, str(blocked))
    model = load_model("synthetic")
    with caplog.at_level(logging.WARNING, logger="rivercal.models.spinups"):
        a, b = spun_up(model, PARAMS, T1), spun_up(model, PARAMS, T2)
    assert caplog.text.count("cannot write") == 1 and str(blocked) in caplog.text
    assert _same(a, _reference(T1)) and _same(b, _reference(T2))


def test_a_killed_writers_part_file_is_never_read_and_goes_when_stale(tmp_path) -> None:
    cache = SpinUpCache(tmp_path)
    cache.keep("ab" * 32, T1, b"whole")
    run = tmp_path / "ab" / ("ab" * 32)
    part = run / "tmp123.part"
    part.write_bytes(b"half")        # what a writer killed before its rename leaves
    assert cache.latest("ab" * 32, T2) == (T1, run / f"{T1.value}.state")
    cache.prune()
    assert part.exists()             # a writer may still be busy with it
    old = time.time() - STALE_PART_S - 60
    os.utime(part, (old, old))
    cache.prune()
    assert not part.exists() and (run / f"{T1.value}.state").read_bytes() == b"whole"


def test_the_least_recently_used_states_go_beyond_the_limit(tmp_path) -> None:
    cache = SpinUpCache(tmp_path, max_bytes=2500)
    names = ["a1" * 32, "b2" * 32, "c3" * 32]
    for i, name in enumerate(names[:2]):
        cache.keep(name, T1, bytes(1000))
        stamp = time.time() - 100 + i
        os.utime(tmp_path / name[:2] / name / f"{T1.value}.state", (stamp, stamp))
    cache.read(cache.latest(names[0], T1)[1])   # used now: the second is now the least recently used
    cache.keep(names[2], T1, bytes(1000))
    assert cache.latest(names[0], T1) is not None and cache.latest(names[2], T1) is not None
    assert cache.latest(names[1], T1) is None and not (tmp_path / "b2" / names[1]).exists()
    assert cache.latest(names[0], T1 - pd.Timedelta("1s")) is None   # nothing before the kept time


def test_the_folder_follows_the_variable_then_xdg_then_home(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "mine"))
    assert spin_up_cache().root == tmp_path / "mine" / "spin-ups"
    monkeypatch.delenv(ENV_VAR)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert spin_up_cache().root == tmp_path / "xdg" / "rivercal" / "spin-ups"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert spin_up_cache().root == tmp_path / "home" / ".cache" / "rivercal" / "spin-ups"
    for off in ("off", "OFF", "0"):
        monkeypatch.setenv(ENV_VAR, off)
        assert spin_up_cache() is None
