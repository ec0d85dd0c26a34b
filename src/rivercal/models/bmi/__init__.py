"""The Basic Model Interface both ways (optional extra ``bmi``: bmipy).

- :class:`~rivercal.models.bmi.engine.RivercalBmi`: the embedded engine as a BMI component;
- :class:`~rivercal.models.bmi.adapter.BmiModel`: any BMI component behind the model contract.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["BmiModel", "BmiState", "RivercalBmi"]

_WHERE = {"BmiModel": "adapter", "BmiState": "adapter", "RivercalBmi": "engine"}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        value = getattr(importlib.import_module(f"rivercal.models.bmi.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rivercal.models.bmi' has no attribute {name!r}")
