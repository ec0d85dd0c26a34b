"""rivercal: keep river-network models honest while they are in use.

The package contains an embedded 1D De Saint-Venant network engine (staggered Delft scheme,
compiled with numba), a calibration core and an on-line parameter-estimation service. Importing
``rivercal`` is cheap: the main names below are imported on first use, so that ``import rivercal``
loads neither the engine (numba), nor pandas, nor matplotlib.

The main names, by task:

- models: :func:`load_case`, :func:`load_model`, :func:`build_model`, :class:`Simulator`,
  :class:`EmbeddedModel`;
- calibration: :class:`Parameter`, :class:`ParameterSet`, :class:`ObservationSeries`,
  :class:`ObservationSet`, :class:`CalibrationProblem`, :func:`calibrate` (returns a
  :class:`Calibration`), :func:`twin_truth`;
- the optimisers: :func:`dud`, :func:`sparse_dud`, :func:`trf`, :func:`sce_ua`, :func:`dds`,
  :func:`nelder_mead`, :func:`powell`, :func:`cg`, :func:`bfgs`, :func:`grid`, :func:`glue`, by name
  through :data:`OPTIMISERS`; each returns an :class:`OptimiseResult`;
- analysis: :func:`identifiability`, :func:`sensitivity`;
- the on-line service: :class:`OnlineService`, :class:`OnlineConfig`, :class:`Store`;
- errors: :class:`RivercalError`, :class:`CaseError`, :class:`ModelRunError`.

Examples
--------
>>> import rivercal
>>> model = rivercal.load_model("synthetic")
>>> model.quantities["friction:global"].unit
'm^(1/3)/s'
"""

from __future__ import annotations

import importlib
import logging
from typing import Any

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

#: Where each main name lives (imported on first use).
_LAZY = {
    "load_case": "rivercal.case",
    "load_model": "rivercal.models",
    "build_model": "rivercal.models",
    "Simulator": "rivercal.engine",
    "EmbeddedModel": "rivercal.models",
    "Parameter": "rivercal.parameters",
    "ParameterSet": "rivercal.parameters",
    "ObservationSeries": "rivercal.observations",
    "ObservationSet": "rivercal.observations",
    "CalibrationProblem": "rivercal.problem",
    "Calibration": "rivercal.problem",
    "calibrate": "rivercal.problem",
    "twin_truth": "rivercal.twin",
    "OPTIMISERS": "rivercal.optimise",
    "OptimiseResult": "rivercal.optimise",
    "bfgs": "rivercal.optimise",
    "cg": "rivercal.optimise",
    "dds": "rivercal.optimise",
    "dud": "rivercal.optimise",
    "glue": "rivercal.optimise",
    "grid": "rivercal.optimise",
    "nelder_mead": "rivercal.optimise",
    "powell": "rivercal.optimise",
    "sce_ua": "rivercal.optimise",
    "sparse_dud": "rivercal.optimise",
    "trf": "rivercal.optimise",
    "identifiability": "rivercal.analysis",
    "sensitivity": "rivercal.analysis",
    "OnlineConfig": "rivercal.online",
    "OnlineService": "rivercal.online",
    "Store": "rivercal.store",
    "RivercalError": "rivercal.errors",
    "CaseError": "rivercal.errors",
    "ModelRunError": "rivercal.errors",
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rivercal' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
