"""The decorators for engine kernels: ``kernel`` (called from compiled code only) and ``entry`` (also from Python).

Both compile with ``cache=True`` (kept where :mod:`rivercal._kernel_cache` places them), numpy's
floating-point error model (a division by zero gives inf or NaN, which the time loop's divergence check reports as
:class:`~rivercal.errors.EngineDivergedError`, instead of raising ``ZeroDivisionError`` from inside
compiled code), without numba's reference counting (``_nrt=False``), and releasing the interpreter lock
while they run (``nogil=True``: the members of an ensemble run on Python threads, each in a compiled call).
With reference counting on, every array argument is incremented and decremented atomically on
each call; for a look-up called once per point per step with a dozen table arrays that costs
~20 times the arithmetic (measured: 242 ns vs 11 ns per call). A kernel compiled this way must
not allocate arrays: scratch arrays are allocated by the caller (:func:`.timeloop.make_work`).

``kernel`` also leaves out the two wrappers numba builds for a call from Python (``no_cpython_wrapper``,
``no_cfunc_wrapper``): a wrapper converts each argument from its Python object, and for the network's
named tuple of some eighty arrays building it took about two thirds of each kernel's compile (measured: a
caller of eight such kernels compiled in 10.3 s with the wrappers, 4.2 s without). Calling such a kernel
from Python raises ``TypeError`` (without the wrapper there would be nothing to call); its pure-Python
version stays reachable as ``kernel.py_func``. ``entry`` keeps them: the time loops, and the look-ups and
solvers that Python code calls too.
"""

from __future__ import annotations

from numba import config, njit
from numba.core.registry import CPUDispatcher

from rivercal._kernel_cache import install

__all__ = ["entry", "kernel"]

install()  # the compiled kernels are kept per user and version of the engine's sources (rivercal._kernel_cache)

_OPTIONS = {"error_model": "numpy", "_nrt": False, "nogil": True}


class InnerKernel(CPUDispatcher):
    """A compiled kernel without wrappers for Python: callable from other kernels only."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is compiled for calls from other "
                        "kernels only (no Python wrapper); call a kernel made with 'entry', or its py_func")


def kernel(func):
    """Compile a non-allocating kernel for calls from other kernels (cached, no reference counting, no GIL)."""
    if config.DISABLE_JIT:
        return func
    dispatcher = InnerKernel(py_func=func, locals={},
                             targetoptions={**_OPTIONS, "nopython": True, "no_cpython_wrapper": True,
                                            "no_cfunc_wrapper": True})
    dispatcher.enable_caching()
    return dispatcher


def entry(func):
    """Compile a non-allocating kernel that Python code calls too (cached, no reference counting, no GIL)."""
    return njit(cache=True, **_OPTIONS)(func)
