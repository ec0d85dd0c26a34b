"""Numba kernels of the engine: functions over flat arrays and scalars only.

No pandas, no logging, no I/O. The phases of a time step each have their module (see
:mod:`.timeloop`); the integer codes of the arrays are named in :mod:`.codes`. Every kernel is
compiled with ``cache=True``; its pure-Python version stays reachable as ``kernel.py_func`` for
unit tests. Only the kernels made with ``entry`` can be called from Python (the time loops, the look-ups
and the solver); the others are compiled for calls from kernels only (see :mod:`._jit`).

Developers: numba validates a cached kernel against its own source file only. After changing a
kernel that others call, a code in :mod:`.codes` or the decorator in :mod:`._jit`, remove the stale
caches with ``make clean-cache`` (``find src -name '*.nb[ic]' -delete``); installed copies are
unaffected.
"""
