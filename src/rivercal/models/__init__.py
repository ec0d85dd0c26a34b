"""Model adapters behind the model contract (layer 4½: below problem and evaluate, above case and engine).

- :mod:`~rivercal.models.contract`: the contract itself (quantities, calibration setup, states);
- :mod:`~rivercal.models.embedded`: the embedded 1D engine of a case;
- :mod:`~rivercal.models.transition`: a wrapper whose parameter jumps at a time (thesis §6-3);
- :mod:`~rivercal.models.blackbox`: an external program described by a ``model.toml`` (templates in,
  files out);
- :mod:`~rivercal.models.swmm`: EPA SWMM 5 through pyswmm / swmm-toolkit (optional extra ``swmm``);
- :mod:`~rivercal.models.bmi`: the Basic Model Interface both ways (optional extra ``bmi``).

:func:`load_model` takes a case (folder or packaged name) or a ``model.toml`` and returns the model.
"""

from rivercal.models.contract import (
    CalibrationSetup,
    FileState,
    Model,
    Quantity,
    check_parameters,
    check_settable,
)
from rivercal.models.embedded import EmbeddedModel, build_model
from rivercal.models.load import load_model

__all__ = [
    "CalibrationSetup",
    "EmbeddedModel",
    "FileState",
    "Model",
    "Quantity",
    "build_model",
    "check_parameters",
    "check_settable",
    "load_model",
]
