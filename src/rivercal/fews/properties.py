"""The run-file properties the Delft-FEWS module reads, and their checks (an error names the property)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rivercal.errors import CaseError

if TYPE_CHECKING:
    from rivercal.fews.pi import RunFile

__all__ = ["PROPERTIES", "AdapterError", "duration", "number", "prop"]

#: The run-file properties the module reads: key -> (default, meaning). ``None``: required.
PROPERTIES: dict[str, tuple[str | None, str]] = {
    "case": (None, "the case: a folder (relative to the work folder) or the name of a packaged case"),
    "parameters": ("FA,Wd", "parameters to estimate, comma-separated names from the case's parameters table"),
    "window": ("7D", "calibration window ending at time zero (e.g. 7D)"),
    "horizon": ("48h", "forecast horizon after time zero"),
    "warmup": ("24h", "simulated time before the window whose residuals do not count"),
    "period": ("1D", "time between forecasts; the model state for the next run's hot start is taken one period "
                     "after this run's warm-up start"),
    "timeStep": ("1h", "time step of the forecasts and of the model output the calibration compares (e.g. 1h, "
                       "10min); a whole multiple of the model's own time step"),
    "algorithm": ("dud", "optimiser"),
    "deadline": ("60", "wall-clock limit of the calibration, s (the last accepted estimate is kept on expiry)"),
    "maxChange": ("", "largest change per forecast, e.g. FA=5,Wd=0.1 (default: none)"),
    "alertK": ("3", "alert when an estimate moves more than this many σ"),
    "run": ("fews", "name of the run in the state's store (a new name starts a new history)"),
    "stateFile": ("state/rivercal.sqlite", "the state file when FEWS exports no state description (relative to "
                                           "the work folder, and inside it)"),
    "estimatesLocationId": ("", "locationId of the parameter-estimate series (default: the case name)"),
    "workers": ("1", "worker processes of the calibration (1 to the cores of the machine)"),
    "piSchemaDir": ("", "folder (relative to the work folder) with the PI schemas pi_timeseries.xsd and pi_state.xsd "
                        "to check the written time series and state description against (needs the fews extra: "
                        "xmlschema); default: no check"),
}


class AdapterError(CaseError):
    """Bad input to the module (a property, a series, the state): named in the message."""


def prop(run: RunFile, key: str) -> str:
    """The property ``key`` as text (its default when absent).

    A required property that is missing, and an empty value of one that has a default, are errors.
    """
    default, _ = PROPERTIES[key]
    value = run.properties.get(key, default)
    if value is None or (default is None and not str(value).strip()):
        raise AdapterError(f"property {key!r} is required ({PROPERTIES[key][1]})", file=str(run.path),
                           field="properties")
    if default and not str(value).strip():
        raise AdapterError(f"property {key!r} is empty; give a value or leave the property out (default {default})",
                           file=str(run.path), field="properties")
    return str(value).strip()


def duration(run: RunFile, key: str, allow_zero: bool = False) -> str:
    """A duration property (e.g. ``7D``, ``48h``) as text, checked to be positive (or zero when allowed)."""
    import pandas as pd

    text = prop(run, key)
    try:
        value = pd.Timedelta(text)
    except ValueError:
        value = None
    if value is None or pd.isna(value) or value < pd.Timedelta(0) or (value == pd.Timedelta(0) and not allow_zero):
        raise AdapterError(f"property {key!r}: {text!r} is not a {'non-negative' if allow_zero else 'positive'} "
                           "duration (e.g. 7D, 48h, 90min)", file=str(run.path), field="properties")
    return text


def number(run: RunFile, key: str, low: float = 0.0) -> float:
    """A number property, checked to be finite and above ``low``."""
    text = prop(run, key)
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > low):
        raise AdapterError(f"property {key!r}: {text!r} must be a number above {low:g}", file=str(run.path),
                           field="properties")
    return value


