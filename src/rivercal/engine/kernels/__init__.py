"""Numba kernels of the engine: functions over flat arrays and scalars only.

No pandas, no logging, no I/O. Every kernel is compiled with ``cache=True``; its pure-Python
version stays reachable as ``kernel.py_func`` for unit tests.

Developers: numba validates a cached kernel against its own source file only. After changing a
kernel that others call (or the decorator in :mod:`._jit`), remove the stale caches with
``make clean-cache`` (``find src -name '*.nb[ic]' -delete``); installed copies are unaffected.
"""
