"""Model adapters behind the model contract (layer 4½: below problem and evaluate, above case and engine).

- :mod:`~rivercal.models.contract`: the contract itself (quantities, calibration setup, states);
- :mod:`~rivercal.models.capabilities`: what only some models can do (batches, ensembles, states as arrays …);
- :mod:`~rivercal.models.embedded`: the embedded 1D engine of a case;
- :mod:`~rivercal.models.transition`: a wrapper whose parameter jumps at a time (thesis §6-3);
- :mod:`~rivercal.models.blackbox`: an external program described by a ``model.toml`` (templates in,
  files out);
- :mod:`~rivercal.models.swmm`: EPA SWMM 5 through swmm-toolkit (optional extra ``swmm``);
- :mod:`~rivercal.models.bmi`: the Basic Model Interface both ways (optional extra ``bmi``).

:func:`load_model` takes a case (folder or packaged name) or a ``model.toml`` and returns the model.
The names below are imported on first use, so that a light submodule (SWMM's command-line runner) does
not load the engine.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "CalibrationSetup",
    "EmbeddedModel",
    "FileState",
    "Location",
    "Model",
    "Quantity",
    "VirtualStations",
    "build_model",
    "check_parameters",
    "check_settable",
    "load_model",
    "spun_up",
]

_WHERE = {
    "CalibrationSetup": "contract", "FileState": "contract", "Model": "contract", "Quantity": "contract",
    "check_parameters": "contract", "check_settable": "contract", "EmbeddedModel": "embedded",
    "build_model": "embedded", "load_model": "load", "spun_up": "contract", "Location": "capabilities",
    "VirtualStations": "capabilities",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        value = getattr(importlib.import_module(f"rivercal.models.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rivercal.models' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
