"""``compile_engine``: its choice between one process and two, and what it refuses."""

from __future__ import annotations

import pytest

from rivercal.engine.kernels import timeloop
from rivercal.engine.warmup import VARIANTS, _in_cache, compile_engine


def test_a_warm_cache_takes_the_one_process_way_and_compiles_nothing(compiled_engine, monkeypatch) -> None:
    """After a compile the cache holds both loops; a second compile starts no process and compiles nothing."""
    from rivercal.engine import warmup

    assert _in_cache(timeloop.run) and _in_cache(timeloop.run_ext)

    def no_pool(*args, **kwargs):
        raise AssertionError("a second process was started although the cache holds the extended loop")

    monkeypatch.setattr(warmup, "ProcessPoolExecutor", no_pool)
    misses = {k: sum(k.stats.cache_misses.values()) for k in (timeloop.run, timeloop.run_ext)}
    again = compile_engine(processes=2)
    assert set(again) == set(VARIANTS)
    assert {k: sum(k.stats.cache_misses.values()) for k in misses} == misses


def test_something_without_numba_cache_is_not_in_it() -> None:
    assert not _in_cache(lambda: None)


@pytest.mark.parametrize("processes", [0, -1])
def test_fewer_than_one_process_is_refused(processes: int) -> None:
    with pytest.raises(ValueError, match="at least 1"):
        compile_engine(processes=processes)
