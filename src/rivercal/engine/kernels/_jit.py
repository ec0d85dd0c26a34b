"""The decorator for engine kernels.

``kernel`` compiles with ``cache=True``, numpy's floating-point error model (a division by zero gives
inf or NaN, which the time loop's divergence check reports as
:class:`~rivercal.errors.EngineDivergedError`, instead of raising ``ZeroDivisionError`` from inside
compiled code), without numba's reference counting (``_nrt=False``), and releasing the interpreter lock
while it runs (``nogil=True``: the members of an ensemble run on Python threads, each in a compiled call).
With reference counting on, every array argument is incremented and decremented atomically on
each call; for a look-up called once per point per step with a dozen table arrays that costs
~20 times the arithmetic (measured: 242 ns vs 11 ns per call). A kernel compiled this way must
not allocate arrays: scratch arrays are allocated by the caller (:func:`.timeloop.make_work`).
"""

from __future__ import annotations

from numba import njit

__all__ = ["kernel"]


def kernel(func):
    """Compile a non-allocating kernel (cached, no reference counting, without the interpreter lock)."""
    return njit(cache=True, error_model="numpy", _nrt=False, nogil=True)(func)
