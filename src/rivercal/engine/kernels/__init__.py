"""Numba kernels of the engine: functions over flat arrays and scalars only.

No pandas, no logging, no I/O. Every kernel is compiled with ``cache=True``; its pure-Python
version stays reachable as ``kernel.py_func`` for unit tests.
"""
