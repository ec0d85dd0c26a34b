"""The forcing a time step takes from a series: its value for the step and its course within the step.

Numerics only (no I/O): a series is its times t (s after the run's start) and values, linear between them; the
steps are given by their edges (s). :class:`ForcingSteps` builds the engine's forcing arrays from a case's series
with :func:`step_forcing`, column by column (:meth:`rivercal.engine.Simulator.forcing_matrix` and
:meth:`~rivercal.engine.Simulator.forcing_edges`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

__all__ = ["ForcingSteps", "step_forcing"]


class ForcingSteps:
    """The time loop's forcing arrays from a case's forcing series, for the last few periods asked.

    Parameters
    ----------
    series
        The forcing series by key (``"boundary:<id>"``, ``"lateral:<id>"``; m³/s or m AD; UTC index). Kept as
        given, not copied: the simulator passes its own mapping, so that a series it adds later is read too.
    keys
        The keys of the forcing columns, in the order of the time loop's arrays
        (:attr:`rivercal.engine.compile.CompiledNetwork.forcing_keys`).
    is_level
        Per column, whether it is a level (m AD, taken at a step's end) rather than a discharge (m³/s, its mean over
        the step).
    """

    def __init__(self, series: Mapping[str, pd.Series], keys: Sequence[str], is_level: Sequence[bool]):
        self.series = series
        self.keys = keys
        self.is_level = is_level
        self._cache: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._knots: dict[str, tuple[pd.Series, np.ndarray, np.ndarray]] = {}

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_knots"] = {}    # derived from the forcing; each worker makes its own
        return state

    def knots(self, key: str, start: pd.Timestamp) -> tuple[np.ndarray, np.ndarray]:
        """Forcing series ``key``'s times (s after ``start``) and values."""
        series = self.series[key]
        cached = self._knots.get(key)
        if cached is None or cached[0] is not series:   # times as integer ns, values as floats: once per series
            cached = (series, series.index.as_unit("ns").asi8, series.to_numpy(dtype=float))
            self._knots[key] = cached
        _, ns, values = cached
        return (ns - pd.Timestamp(start).as_unit("ns").value) / 1e9, values   # as pandas' total_seconds, to the bit

    def values_at(self, key: str, seconds: np.ndarray, start: pd.Timestamp) -> np.ndarray:
        """Forcing series ``key`` at ``seconds`` (s after ``start``), linear in time."""
        t, values = self.knots(key, start)
        return np.interp(seconds, t, values)

    def arrays(self, start: pd.Timestamp, n_steps: int, dt: float, *,
               constant: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Per step of ``dt`` seconds from ``start``: the forcing of the step and its course within it.

        The first array (steps, columns) holds step-mean discharges (m³/s) and end-of-step levels (m AD); the second
        (two rows per step) the course each column follows within its step (:func:`step_forcing`). With ``constant``
        every step gets the values at ``start`` (a spin-up). The arrays of up to five periods asked are kept, keyed
        by ``start``, ``n_steps`` and ``constant``; the caller does not modify them.
        """
        key = (start, n_steps, constant)
        cached = self._cache.get(key)
        if cached is not None:
            return cached
        edges = np.arange(n_steps + 1, dtype=float) * dt
        if constant:
            edges = np.zeros(n_steps + 1)
        out = np.empty((n_steps, len(self.keys)))
        course = np.empty((2 * n_steps, len(self.keys)))
        for col, fkey in enumerate(self.keys):
            out[:, col], course[:, col] = step_forcing(*self.knots(fkey, start), edges,
                                                       level=bool(self.is_level[col]))
        if len(self._cache) > 4:
            self._cache.clear()
        self._cache[key] = (out, course)
        return out, course


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
