"""The link runs the kernels loop over: every link once, in order, with end points and edges stepping by one;
and the momentum runs: every channel link once, simple links (inner links of a branch) in contiguous runs."""

import numpy as np
import pytest

from rivercal.engine.kernels.codes import (
    FRICTION_CHEZY,
    FRICTION_MANNING,
    LINK_CHANNEL,
    LINK_PUMP,
    RUN_COUNT,
    RUN_EDGE,
    RUN_GENERAL,
    RUN_K1,
    RUN_K2,
    RUN_LINK,
)
from rivercal.engine.plan import link_runs, momentum_runs
from rivercal.model import load_model


@pytest.mark.parametrize("case", ["synthetic", "dommel"])
def test_runs_cover_the_links_in_order_and_reproduce_their_points_and_edges(case: str) -> None:
    a = load_model(case).compiled.arrays
    runs = a.lk_runs.astype(np.int64)
    assert runs[0, RUN_LINK] == 0
    assert np.array_equal(runs[1:, RUN_LINK], runs[:-1, RUN_LINK] + runs[:-1, RUN_COUNT])
    assert runs[-1, RUN_LINK] + runs[-1, RUN_COUNT] == a.lk_k1.size
    k1 = np.concatenate([r[RUN_K1] + np.arange(r[RUN_COUNT]) for r in runs])
    k2 = np.concatenate([r[RUN_K2] + np.arange(r[RUN_COUNT]) for r in runs])
    edge = np.concatenate([r[RUN_EDGE] + np.arange(r[RUN_COUNT]) for r in runs])
    assert np.array_equal(k1, a.lk_k1) and np.array_equal(k2, a.lk_k2)
    assert np.array_equal(edge[a.lk_type != LINK_PUMP], a.lk_edge[a.lk_type != LINK_PUMP])
    # the branches are numbered along their length: most links sit in a few long runs
    assert runs.shape[0] < a.lk_k1.size / 10


def test_a_general_link_is_a_run_of_its_own_and_runs_break_where_the_numbering_jumps() -> None:
    k1 = np.array([0, 1, 2, 7, 8, 3, 4, 5])
    k2 = np.array([1, 2, 3, 8, 9, 4, 5, 6])
    edge = np.array([0, 1, 2, 3, 4, -1, 5, 6])
    general = np.array([False, False, False, False, False, True, False, False])
    runs = link_runs(k1, k2, edge, general).astype(np.int64)
    expected = [
        (0, 3, 0, 1, 0, 0),  # links 0-2
        (3, 2, 7, 8, 3, 0),  # links 3-4: the points jump
        (5, 1, 3, 4, 0, 1),  # link 5: a pump, general
        (6, 2, 4, 5, 5, 0),  # links 6-7
    ]
    assert [tuple(r) for r in runs[:, [RUN_LINK, RUN_COUNT, RUN_K1, RUN_K2, RUN_EDGE, RUN_GENERAL]]] == expected


@pytest.mark.parametrize("case", ["synthetic", "dommel"])
def test_momentum_runs_cover_each_channel_link_once_and_hold_only_inner_links(case: str) -> None:
    a = load_model(case).compiled.arrays
    runs = a.mo_runs.astype(np.int64)
    in_runs = np.concatenate([r[0] + np.arange(r[1]) for r in runs])
    k1 = np.concatenate([r[2] + np.arange(r[1]) for r in runs])
    covered = np.sort(np.concatenate([in_runs, a.mo_other.astype(np.int64)]))
    assert np.array_equal(covered, np.flatnonzero(a.lk_type == LINK_CHANNEL))
    assert np.array_equal(k1, a.lk_k1[in_runs]) and np.array_equal(a.lk_k2[in_runs], k1 + 1)
    # an inner link's upwind neighbours are the links before and after it along the branch
    assert np.array_equal(a.lk_nb1[in_runs], in_runs - 1) and np.array_equal(a.lk_nb2[in_runs], in_runs + 1)
    # most links of a branch are inner links
    assert in_runs.size > 3 * a.mo_other.size


def test_junctions_structures_laterals_and_chezy_friction_break_the_momentum_runs() -> None:
    # branch A: links 0-3 (points 0-4); a weir (link 4) from point 4 to 5; branch B: links 5-8 (points 5-9),
    # Chezy on link 7, a lateral at point 7
    n = 9
    lk_type = np.full(n, LINK_CHANNEL)
    lk_type[4] = 99  # a structure
    lk_k1 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8])
    lk_k2 = lk_k1 + 1
    nb = np.array([[-2, 0, 1, 2, -2, -2, 5, 6, 7], [1, 2, 3, -2, -2, 6, 7, 8, -2]])
    ns = np.array([[1, 1, 1, 1, 1, 1, 1, 1, 1], [-1, -1, -1, -1, -1, -1, -1, -1, -1]])
    ftype = np.full(n, FRICTION_MANNING)
    ftype[7] = FRICTION_CHEZY
    runs, other = momentum_runs(lk_type, lk_k1, lk_k2, nb, ns, ftype, np.array([7]))
    # simple: 1, 2 (0 and 3 are branch ends); 5 and 8 are ends, 6 touches the lateral point 7, 7 is Chezy
    assert [tuple(r) for r in runs.astype(np.int64)] == [(1, 2, 1)]
    assert list(other.astype(np.int64)) == [0, 3, 5, 6, 7, 8]
