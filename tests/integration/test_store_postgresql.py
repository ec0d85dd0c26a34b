"""The store's API (tests/unit/test_store.py) on a real PostgreSQL server: same tests, a fresh database each."""

from __future__ import annotations

import pytest

from tests.on_postgresql import store_tests
from tests.unit import test_store as unit
from tests.unit.test_store import run_id, store  # noqa: F401  (the fixtures the tests take, made on this server)


@pytest.fixture
def location(pg_url: str) -> str:
    return pg_url


globals().update(store_tests(unit, {"location", "store", "run_id"}))
