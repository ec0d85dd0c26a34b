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

``kernel(inline=True)`` has LLVM always inline the kernel into its callers (numba's ``forceinline``). A kernel that
LLVM keeps as a function of its own receives every array of the named tuples it is passed, flattened into some
950 arguments for the network and the scratch arrays, which the caller copies onto the stack at each call; the
per-step kernels that take them (the step itself, the Picard iterations and their solve, the fluxes) are inlined
(measured on the synthetic network: a step 9 % faster, results bit for bit the same, the compile as long).
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


def kernel(func=None, *, inline=False):
    """Compile a non-allocating kernel for calls from other kernels (cached, no reference counting, no GIL).

    With ``inline`` LLVM always inlines it into its callers (``@kernel(inline=True)``).
    """
    if func is None:
        return lambda f: kernel(f, inline=inline)
    if config.DISABLE_JIT:
        return func
    options = {**_OPTIONS, "nopython": True, "no_cpython_wrapper": True, "no_cfunc_wrapper": True}
    if inline:
        options["forceinline"] = True
    dispatcher = InnerKernel(py_func=func, locals={}, targetoptions=options)
    dispatcher.enable_caching()
    return dispatcher


def entry(func):
    """Compile a non-allocating kernel that Python code calls too (cached, no reference counting, no GIL)."""
    return njit(cache=True, **_OPTIONS)(func)
