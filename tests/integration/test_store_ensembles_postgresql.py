"""Ensembles and bands in the store (tests/unit/test_store_ensembles.py) on a real PostgreSQL server."""

from __future__ import annotations

import pytest

from tests.on_postgresql import store_tests
from tests.unit import test_store_ensembles as unit


@pytest.fixture
def location(pg_url: str) -> str:
    return pg_url


globals().update(store_tests(unit, {"location"}))
