"""Shared machinery: options, validation, residual checks, statistics, registry, helpers."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import (
    OPTIMISERS,
    DudOptions,
    NonFiniteResidualsError,
    dud,
    fd_jacobian_of,
    get_optimiser,
    parameter_statistics,
    trf,
)
from rivercal.optimise._core import coerce_options
from rivercal.optimise.jacobian import inward_steps
from rivercal.optimise.result import COMMON_MESSAGES
from tests.optimise.problems import A, linear


def test_coerce_options():
    assert coerce_options(None, DudOptions) == DudOptions()
    assert coerce_options({"max_outer": 5}, DudOptions).max_outer == 5
    with pytest.raises(ValueError, match="unknown option 'rel_tolerance' for DudOptions; did you mean 'rel_tol'"):
        coerce_options({"rel_tolerance": 1e-3}, DudOptions)


def test_inward_steps():
    lb, ub = np.zeros(4), np.array([1.0, 1.0, 1.0, 0.3])
    steps = inward_steps(np.array([0.5, 1.0, 0.0, 0.1]), np.full(4, 0.25), lb, ub)
    np.testing.assert_allclose(steps, [0.25, -0.25, 0.25, 0.2])


def test_residual_shape_errors():
    with pytest.raises(ValueError, match="1-D array of residuals"):
        trf(lambda x: np.ones((2, 2)), [0.0], [-1.0], [1.0])
    calls = []

    def growing(x):
        calls.append(1)
        return np.ones(len(calls))

    with pytest.raises(ValueError, match="fun returned 2 residuals"):
        trf(growing, [0.0], [-1.0], [1.0])


def test_non_finite_error_is_a_value_error():
    assert issubclass(NonFiniteResidualsError, ValueError)
    with pytest.raises(NonFiniteResidualsError, match="at x="):
        dud(lambda x: np.array([1.0 / x[0] if x[0] != 0.5 else np.inf]), [0.2], [0.0], [1.0],
            options={"initial_step": [0.3]})


def test_batch_must_return_one_vector_per_point():
    with pytest.raises(ValueError, match="batch returned 1 residual vectors for 4 points"):
        dud(linear, np.zeros(3), -1.0, 1.0, batch=lambda xs: [linear(xs[0])])


def test_parameter_statistics():
    stats = parameter_statistics(A, cost=2.0)
    cov = np.linalg.inv(A.T @ A)
    np.testing.assert_allclose(stats["covariance"], cov)
    np.testing.assert_allclose(stats["std_scaled"], np.sqrt(np.diag(cov) * 2.0 / 3.0))
    assert parameter_statistics(np.array([[1.0, 2.0], [2.0, 4.0]]), 1.0) is None   # singular JᵀJ


def test_fd_jacobian_helper():
    np.testing.assert_allclose(fd_jacobian_of(linear, np.zeros(3), -1.0, 1.0), A, atol=1e-5)
    np.testing.assert_allclose(fd_jacobian_of(linear, np.ones(3), -1.0, 1.0), A, atol=1e-5)  # at the upper bound


def test_registry():
    assert set(OPTIMISERS) == {"dud", "sparse_dud", "trf", "sce_ua", "dds", "nelder_mead", "powell", "cg", "bfgs",
                               "grid", "glue"}
    assert get_optimiser("SCE-UA") is OPTIMISERS["sce_ua"] and get_optimiser("Nelder Mead") is OPTIMISERS["nelder_mead"]
    with pytest.raises(ValueError, match=r"unknown optimiser 'simplex'.*Available: dud, sparse_dud"):
        get_optimiser("simplex")


def test_every_module_has_a_full_message_table():
    import importlib

    for name, fun in OPTIMISERS.items():
        table = importlib.import_module(fun.__module__).TERMINATION_MESSAGES
        assert set(COMMON_MESSAGES) - {-3} <= set(table), name
        assert any(status > 0 for status in table), name


def test_optimise_knows_nothing_of_rivers():
    import ast
    from pathlib import Path

    import rivercal.optimise

    forbidden = ("rivercal.engine", "rivercal.network", "rivercal.case", "rivercal.hydrology")
    for path in Path(rivercal.optimise.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            assert not any(n.startswith(forbidden) for n in names), (path.name, names)
