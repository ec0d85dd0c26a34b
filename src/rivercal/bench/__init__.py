"""Benchmarks behind ``rivercal bench`` and ``make bench`` (median wall times, JSON output)."""
