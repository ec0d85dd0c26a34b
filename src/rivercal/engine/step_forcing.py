"""The forcing a time step takes from a series: its value for the step and its course within the step.

Numerics only (no I/O): a series is its times t (s after the run's start) and values, linear between them; the
steps are given by their edges (s). :meth:`rivercal.engine.Simulator.forcing_matrix` and
:meth:`~rivercal.engine.Simulator.forcing_edges` build the engine's forcing arrays from it, column by column.
"""

from __future__ import annotations

import numpy as np

__all__ = ["step_forcing"]


def step_forcing(t: np.ndarray, v: np.ndarray, edges: np.ndarray, *, level: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per step the value a whole step takes, and the course of the series within each step (two rows per step).

    A level (m AD) takes its value at the step's end; a discharge (m³/s) its mean over the step. The course holds
    per step ``n``, in rows ``2n`` and ``2n + 1``, the ends of the straight line that the sub-steps of a divided
    step follow: the values at the step's edges, or for a discharge whose series has a time inside the step the
    line of the same volume nearest to the series (:func:`_within_steps`).
    """
    at = np.interp(edges, t, v)
    course = np.empty(2 * (edges.size - 1))
    course[0::2] = at[:-1]
    course[1::2] = at[1:]
    if level:
        return at[1:], course
    mean = 0.5 * (at[:-1] + at[1:])
    _within_steps(t, v, edges, mean, course)
    return mean, course


def _within_steps(t: np.ndarray, v: np.ndarray, edges: np.ndarray, mean: np.ndarray, course: np.ndarray) -> None:
    """The mean and the course of a discharge within each step where its series has a time inside the step.

    The series has times ``t`` (s) and values ``v`` (m³/s), linear between them; the steps have the edges
    ``edges`` (s). Per step with a time of the series inside it: its exact mean (m³/s, into ``mean``) and the
    ends of the line of the same volume nearest to the series over the step (its least-squares fit, m³/s, into
    ``course``, rows ``2n`` and ``2n + 1``).

    The mean of the values at a step's edges, which holds where the series is straight within the step, would
    take a value held up to one edge and the next value from it as their average over the whole step; a value
    held over a step, as a coupled model's inflow over its coupling interval, is held within it.
    """
    inside = t[(t > edges[0]) & (t < edges[-1])]
    step = np.searchsorted(edges, inside, side="right") - 1
    keep = inside > edges[step]
    inside, step = inside[keep], step[keep]
    if not inside.size:
        return
    steps = np.unique(step)
    ta = np.unique(np.concatenate([edges[steps], edges[steps + 1], inside]))   # sorted
    n = np.searchsorted(edges, ta[:-1], side="right") - 1   # the step of each piece between two of them
    piece = ta[1:] <= edges[n + 1]   # not a gap between two steps apart
    n, a, b = n[piece], ta[:-1][piece], ta[1:][piece]
    length = edges[n + 1] - edges[n]
    sa = (a - edges[n]) / length   # the piece's ends as fractions of its step
    sb = (b - edges[n]) / length
    qa, qb = np.interp(a, t, v), np.interp(b, t, v)
    width = sb - sa
    volume = np.bincount(n, 0.5 * (qa + qb) * width, minlength=mean.size)   # ∫ q ds over the step
    moment = np.bincount(n, width * (qa * (2.0 * sa + sb) + qb * (sa + 2.0 * sb)) / 6.0,
                         minlength=mean.size)   # ∫ q s ds
    m = volume[steps]
    slope = 12.0 * (moment[steps] - 0.5 * m)   # the fit m + slope (s - 1/2)
    mean[steps] = m
    course[2 * steps] = m - 0.5 * slope
    course[2 * steps + 1] = m + 0.5 * slope
