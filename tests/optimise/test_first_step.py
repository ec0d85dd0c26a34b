"""Every local optimiser's first trial step has the size of the caller's initial step.

With two finite bounds on every parameter (the usual case for river parameters), L-BFGS-B without
scaling took its first step at full gradient length and evaluated a corner of the box (x = [0, 1.3e5]
from x0 = [8.0, 1.57] on the damped oscillator below, bounds [0, 1e6]), where a model may not run at all.
The first *trial* point is the first evaluated point that is neither x0, nor a perturbation of x0 along
one coordinate by at most the initial step (DuD's initial set, Nelder-Mead's simplex, Powell's first
direction), nor a finite-difference neighbour (all components within 1 % of the initial step). It must
lie within x0 ± 10 initial steps (DuD's ``max_rel_step``) unless the cost on the way there kept falling.
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import OPTIMISERS, bfgs
from tests.optimise.problems import rosenbrock

LOCAL = ("dud", "sparse_dud", "trf", "bfgs", "cg", "nelder_mead", "powell")
T = np.linspace(0.5, 5.0, 10)


def model(x):
    return 10.0 * np.exp(-T / max(x[0], 1e-9)) * np.cos(x[1] * T)


Y = model(np.array([8.5, 1.7])) + 0.1 * np.random.default_rng(1).standard_normal(T.size)


def oscillator(x):
    return (Y - model(x)) / 0.1


PROBLEMS = {
    "oscillator": (oscillator, np.array([8.0, np.pi / 2]), np.zeros(2), np.full(2, 1e6)),
    "rosenbrock": (rosenbrock, np.array([-1.2, 1.0]), np.full(2, -1e3), np.full(2, 1e3)),
}


def first_trial(points: list[np.ndarray], x0: np.ndarray, h: np.ndarray) -> np.ndarray | None:
    for x in points:
        d = np.abs(x - x0) / h
        neighbour = np.all(d <= 1e-2)
        along_one = np.count_nonzero(d > 1e-2) == 1 and np.max(d) <= 1.0 + 1e-12
        if not (neighbour or along_one):
            return x
    return None


@pytest.mark.parametrize("problem", list(PROBLEMS))
@pytest.mark.parametrize("method", LOCAL)
def test_the_first_trial_step_stays_within_a_few_initial_steps(method, problem):
    fun, x0, lb, ub = PROBLEMS[problem]
    h = 0.1 * np.abs(x0)            # every method's default initial step
    points: list[np.ndarray] = []

    def spy(x):
        points.append(np.array(x))
        return fun(x)

    OPTIMISERS[method](spy, x0, lb, ub, max_nfev=40)
    trial = first_trial(points, x0, h)
    assert trial is not None
    assert np.all(np.abs(trial - x0) <= 10.0 * h * (1 + 1e-9)), f"{method}: first trial at {trial} from {x0}"


@pytest.mark.parametrize("method", LOCAL)
def test_the_callers_initial_step_sets_the_first_step(method):
    """A caller's perturbation ten times smaller keeps the first trial ten times closer."""
    fun, x0, lb, ub = PROBLEMS["oscillator"]
    h = 0.01 * np.abs(x0)
    name = "x_scale" if method in ("trf", "bfgs", "cg") else "initial_step"
    points: list[np.ndarray] = []

    def spy(x):
        points.append(np.array(x))
        return fun(x)

    OPTIMISERS[method](spy, x0, lb, ub, options={name: h}, max_nfev=40)
    trial = first_trial(points, x0, h)
    assert trial is not None
    assert np.all(np.abs(trial - x0) <= 10.0 * h * (1 + 1e-9)), f"{method}: first trial at {trial}"


def test_bfgs_no_longer_walks_to_the_box_edge():
    points: list[np.ndarray] = []

    def spy(x):
        points.append(np.array(x))
        return oscillator(x)

    res = bfgs(spy, [8.0, np.pi / 2], [0.0, 0.0], [1e6, 1e6])
    assert max(float(np.max(np.abs(p - [8.0, np.pi / 2]))) for p in points) < 2.0
    assert res.success
    np.testing.assert_allclose(res.x, [8.55, 1.699], atol=0.01)
