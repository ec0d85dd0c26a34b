"""Property: whatever the box and wherever x0 sits in it (bounds included), no point outside is run."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rivercal.optimise import get_optimiser
from tests.optimise.problems import SETTINGS


@st.composite
def boxes(draw):
    n = draw(st.integers(1, 3))
    lb = np.array(draw(st.lists(st.floats(-5.0, 4.0), min_size=n, max_size=n)))
    width = np.array(draw(st.lists(st.floats(1e-3, 5.0), min_size=n, max_size=n)))
    ub = lb + width
    where = np.array(draw(st.lists(st.sampled_from([0.0, 1.0, 0.5, 0.999]), min_size=n, max_size=n)))
    target = np.array(draw(st.lists(st.floats(-8.0, 8.0), min_size=n, max_size=n)))
    return lb + where * width, lb, ub, target


@pytest.mark.parametrize("method", ["dud", "sparse_dud", "trf", "bfgs", "cg", "nelder_mead", "powell", "sce_ua", "dds"])
@settings(max_examples=15, deadline=None)
@given(box=boxes())
def test_never_outside_the_box(method, box):
    x0, lb, ub, target = box

    def fun(x):
        assert np.all(x >= lb) and np.all(x <= ub), (x, lb, ub)
        return np.concatenate([x - target, [np.sum(np.sin(x))]])

    opts = {k: v for k, v in SETTINGS[method].options.items() if k in ("seed",)}
    res = get_optimiser(method)(fun, x0, lb, ub, options=opts, max_nfev=200)
    assert np.all(res.x >= lb) and np.all(res.x <= ub)
