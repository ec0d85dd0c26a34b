"""Name → optimiser function, for callers that choose the algorithm by name (configuration, CLI)."""

from __future__ import annotations

import difflib
from collections.abc import Callable

from rivercal.optimise.bfgs import bfgs
from rivercal.optimise.cg import cg
from rivercal.optimise.dds import dds
from rivercal.optimise.dud import dud
from rivercal.optimise.glue import glue
from rivercal.optimise.grid import grid
from rivercal.optimise.nelder_mead import nelder_mead
from rivercal.optimise.powell import powell
from rivercal.optimise.result import OptimiseResult
from rivercal.optimise.sce_ua import sce_ua
from rivercal.optimise.sparse_dud import sparse_dud
from rivercal.optimise.trf import trf

__all__ = ["OPTIMISERS", "RENAMED", "get_optimiser"]

#: Every optimiser by name; each is ``name(fun, x0, lb, ub, *, options, callback, batch, max_nfev, deadline)``.
OPTIMISERS: dict[str, Callable[..., OptimiseResult]] = {
    "dud": dud,
    "sparse_dud": sparse_dud,
    "trf": trf,
    "sce_ua": sce_ua,
    "dds": dds,
    "nelder_mead": nelder_mead,
    "powell": powell,
    "cg": cg,
    "bfgs": bfgs,
    "grid": grid,
    "glue": glue,
}

#: Former names → what the optimiser is called now (asking for a former name raises with this hint).
RENAMED: dict[str, str] = {
    "lm": "trf (scipy's trust-region reflective method; it was called 'lm' but is not Levenberg-Marquardt)",
}


def get_optimiser(name: str) -> Callable[..., OptimiseResult]:
    """The optimiser called ``name`` (case-insensitive; ``-`` and spaces count as ``_``).

    Raises
    ------
    ValueError
        For an unknown name; the message lists the valid names.
    """
    if not isinstance(name, str):
        raise TypeError(f"optimiser name must be a string, got {type(name).__name__}")
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    if key in OPTIMISERS:
        return OPTIMISERS[key]
    if key in RENAMED:
        raise ValueError(f"unknown optimiser {name!r}: it is now called {RENAMED[key]}")
    close = difflib.get_close_matches(key, OPTIMISERS, n=1)
    hint = f" Did you mean {close[0]!r}?" if close else ""
    raise ValueError(f"unknown optimiser {name!r}.{hint} Available: {', '.join(OPTIMISERS)}")
