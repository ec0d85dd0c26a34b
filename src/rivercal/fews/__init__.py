"""The Delft-FEWS General Adapter module (layer 7½): PI run file in; PI time series, state and diagnostics out.

:func:`~rivercal.fews.adapter.run_module` is what ``rivercal fews RUN_INFO.xml`` runs; :mod:`rivercal.fews.pi`
reads and writes the PI run file, state description and diagnostics file.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "PROPERTIES",
    "AdapterError",
    "DiagLine",
    "FewsOutcome",
    "RunFile",
    "StateLocation",
    "read_run_file",
    "read_state_description",
    "run_module",
    "write_diag",
    "write_state_description",
]

#: Where each public name lives; imported on first use, so that ``rivercal --help`` does not load pandas.
_HOME = {"PROPERTIES": "properties", "AdapterError": "properties", "FewsOutcome": "adapter", "run_module": "adapter"}


def __getattr__(name: str) -> Any:
    if name in __all__:
        return getattr(importlib.import_module(f"rivercal.fews.{_HOME.get(name, 'pi')}"), name)
    raise AttributeError(f"module 'rivercal.fews' has no attribute {name!r}")
