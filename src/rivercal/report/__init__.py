"""Figures and reports (layer 7). Imports matplotlib lazily, inside the functions that draw."""
