"""EPA SWMM 5 through swmm-toolkit.

The adapter, the ``.inp`` editor, the output reader, a case converter, black-box templates and SWMM's
command-line runner.

Needs the optional extra ``swmm`` (``pip install rivercal[swmm]``: swmm-toolkit, the EPA SWMM engine).
The names below are imported on first use (the runner must start fast).
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["SwmmModel", "SwmmRunError"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        value = getattr(importlib.import_module("rivercal.models.swmm.model"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rivercal.models.swmm' has no attribute {name!r}")
