"""Name → optimiser function (and its options class), for callers that choose the algorithm by name."""

from __future__ import annotations

import difflib
from collections.abc import Callable

from rivercal.optimise.bfgs import BfgsOptions, bfgs
from rivercal.optimise.cg import CgOptions, cg
from rivercal.optimise.dds import DdsOptions, dds
from rivercal.optimise.dud import DudOptions, dud
from rivercal.optimise.glue import GlueOptions, glue
from rivercal.optimise.grid import GridOptions, grid
from rivercal.optimise.nelder_mead import NelderMeadOptions, nelder_mead
from rivercal.optimise.powell import PowellOptions, powell
from rivercal.optimise.result import OptimiseResult
from rivercal.optimise.sce_ua import SceOptions, sce_ua
from rivercal.optimise.sparse_dud import SparseDudOptions, sparse_dud
from rivercal.optimise.trf import TrfOptions, trf

__all__ = ["OPTIMISERS", "OPTIONS", "RENAMED", "get_optimiser"]

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

#: The options dataclass of every optimiser, by name.
OPTIONS: dict[str, type] = {
    "dud": DudOptions,
    "sparse_dud": SparseDudOptions,
    "trf": TrfOptions,
    "sce_ua": SceOptions,
    "dds": DdsOptions,
    "nelder_mead": NelderMeadOptions,
    "powell": PowellOptions,
    "cg": CgOptions,
    "bfgs": BfgsOptions,
    "grid": GridOptions,
    "glue": GlueOptions,
}

#: Former names → what the optimiser is called now (asking for a former name raises with this hint).
RENAMED: dict[str, str] = {
    "lm": "trf (scipy's trust-region reflective method; it was called 'lm' but is not Levenberg-Marquardt)",
}


def _key(name: str) -> str:
    if not isinstance(name, str):
        raise TypeError(f"optimiser name must be a string, got {type(name).__name__}")
    return name.strip().lower().replace("-", "_").replace(" ", "_")


def get_optimiser(name: str) -> Callable[..., OptimiseResult]:
    """The optimiser called ``name`` (case-insensitive; ``-`` and spaces count as ``_``).

    Raises
    ------
    ValueError
        For an unknown name; the message lists the valid names (or says what a former name is called now).
    """
    key = _key(name)
    if key in OPTIMISERS:
        return OPTIMISERS[key]
    if key in RENAMED:
        raise ValueError(f"unknown optimiser {name!r}: it is now called {RENAMED[key]}")
    close = difflib.get_close_matches(key, OPTIMISERS, n=1)
    hint = f" Did you mean {close[0]!r}?" if close else ""
    raise ValueError(f"unknown optimiser {name!r}.{hint} Available: {', '.join(OPTIMISERS)}")
