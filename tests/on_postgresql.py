"""Run a unit module's store tests again on a real PostgreSQL server (the integration tier's copy of them).

The store's contract is the same on SQLite and PostgreSQL. The unit modules test it on a SQLite file, in
the test's own process; an integration module takes the tests that use a store (those that ask for one of
``fixtures``) and gives them a fresh database on the session's PostgreSQL server instead.
"""

from __future__ import annotations

import inspect
from types import ModuleType


def store_tests(module: ModuleType, fixtures: set[str]) -> dict[str, object]:
    """The test functions of ``module`` that take any of ``fixtures`` (directly), by name."""
    return {name: test for name, test in vars(module).items()
            if name.startswith("test_") and callable(test) and fixtures & set(inspect.signature(test).parameters)}
