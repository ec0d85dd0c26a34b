"""The Dask benchmark's schedule model: the makespan of starting jobs longest first on the first free worker."""

from __future__ import annotations

import itertools

import pytest

from rivercal.bench.dask import list_schedule


def test_the_makespan_of_longest_first_matches_hand_worked_schedules() -> None:
    # Two workers, jobs 5, 4, 3, 3, 3: 5 | 4 → 5 | 4+3=7 → 5+3=8 | 7 → 8 | 7+3=10: makespan 10.
    assert list_schedule([3, 5, 3, 4, 3], 2) == pytest.approx(10.0)
    assert list_schedule([2.0] * 6, 3) == pytest.approx(4.0)  # equal jobs: ceil(6 / 3) rounds
    assert list_schedule([1.0, 7.0, 2.0], 64) == pytest.approx(7.0)  # more workers than jobs: the longest job
    assert list_schedule([1.5, 2.5], 1) == pytest.approx(4.0)  # one worker: the sum
    assert list_schedule([], 4) == 0.0


def test_longest_first_is_within_grahams_bound_of_the_best_schedule() -> None:
    """Graham (1969): longest-first is at most (4/3 - 1/(3m)) times the optimal makespan on m workers."""
    jobs = [7.0, 6.0, 5.0, 4.0, 3.0, 3.0, 2.0, 2.0, 1.0]
    for workers in (2, 3):
        best = min(max(sum(j for j, w in zip(jobs, assign, strict=True) if w == k) for k in range(workers))
                   for assign in itertools.product(range(workers), repeat=len(jobs)))
        assert best <= list_schedule(jobs, workers) <= (4 / 3 - 1 / (3 * workers)) * best + 1e-12


def test_the_makespan_in_the_order_given_can_leave_a_tail() -> None:
    # Two workers, jobs 3, 3, 6 in that order: 3 | 3 → 3+6=9 | 3: makespan 9; longest first: 6 | 3+3: 6.
    assert list_schedule([3.0, 3.0, 6.0], 2, longest_first=False) == pytest.approx(9.0)
    assert list_schedule([3.0, 3.0, 6.0], 2) == pytest.approx(6.0)
