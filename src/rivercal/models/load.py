"""One door to every model: a case (folder or packaged name) or a ``model.toml`` of an adapter."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rivercal.models.embedded import load_case_model

__all__ = ["load_model"]


def load_model(source: str | Path) -> Any:
    """The model of a case folder, a packaged case name, or a ``model.toml`` (or a folder holding one).

    Examples
    --------
    >>> from rivercal.models import load_model
    >>> sim = load_model("dommel")
    >>> sim.observables[:2]
    ['0028.h_up', '0028.h_down']
    """
    return load_case_model(source)
