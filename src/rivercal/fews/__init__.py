"""The Delft-FEWS General Adapter module (layer 7½): PI run file in; PI time series, state and diagnostics out.

:func:`~rivercal.fews.adapter.run_module` is what ``rivercal fews RUN_INFO.xml`` runs; :mod:`rivercal.fews.pi`
reads and writes the PI run file, state description and diagnostics file.
"""

from rivercal.fews.adapter import PROPERTIES, AdapterError, FewsOutcome, run_module
from rivercal.fews.pi import (
    DiagLine,
    RunFile,
    StateLocation,
    read_run_file,
    read_state_description,
    write_diag,
    write_state_description,
)

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
