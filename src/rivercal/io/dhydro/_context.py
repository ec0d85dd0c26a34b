"""What the parts of an import share: the model read, the options, the ledger, the ids, the series collected."""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._read import LoadedModel

__all__ = ["Context", "IdMap", "ImportOptions", "unquote"]

_BAD = re.compile(r"[^A-Za-z0-9_.\-]")


def unquote(text: object) -> str:
    """A D-Flow FM id as D-Flow FM reads it: ``#Main#`` (a delimited string) is ``Main``."""
    value = str(text).strip()
    if len(value) >= 2 and value.startswith("#") and value.endswith("#"):
        value = value[1:-1].strip()
    return value


def _numbers(text: str) -> list[float]:
    """The numbers of a value written as numbers separated by spaces; [] when one is not a number."""
    try:
        return [float(v) for v in text.split()]
    except ValueError:
        return []


@dataclass(frozen=True)
class ImportOptions:
    """Options of an import.

    Attributes
    ----------
    realtime
        DIMR exchange files (NetCDF) whose series supply the ``realtime`` laterals and structure
        settings (``laterals/<id>/water_discharge``, ``weirs/<id>/crestLevel``, ``pumps/<id>/capacity``, ...).
    realtime_lateral
        Constant inflow (m³/s) of a ``realtime`` lateral that no exchange file supplies; None
        refuses such laterals.
    allow_partial
        Write the case even when objects that change the hydraulics were refused (they are left out).
    dt
        Time step of the case, s (default: the case's own from ``rivercal.ini`` when rivercal exported the model,
        else the largest divisor of the output interval that is at most min(DtMax, 60 s)).
    """

    realtime: tuple[Path, ...] = ()
    realtime_lateral: float | None = None
    allow_partial: bool = False
    dt: float | None = None


class IdMap:
    """Ids of one kind of object, made valid for a case (letters, digits, ``_ - .``; at most 64 characters)."""

    def __init__(self, kind: str, ledger: Ledger, *, no_dot: bool = False):
        self.kind = kind
        self._ledger = ledger
        self._no_dot = no_dot
        self._map: dict[str, str] = {}
        self._used: set[str] = set()

    def __call__(self, original: object) -> str:
        """The case id of a D-Flow FM id (the same id each time it is asked)."""
        key = unquote(original)
        if key in self._map:
            return self._map[key]
        new = _BAD.sub("_", key) or "unnamed"
        if self._no_dot:
            new = new.replace(".", "_")
        if len(new) > 64:
            new = new[:55] + "_" + hashlib.sha1(key.encode()).hexdigest()[:8]
        base, k = new, 2
        while new in self._used:
            new = f"{base[:60]}_{k}"
            k += 1
        self._map[key] = new
        self._used.add(new)
        if new != key:
            self._ledger.renamed.setdefault(self.kind, {})[str(original)] = new
        return new

    def known(self, original: object) -> bool:
        """Whether this D-Flow FM id was given a case id."""
        return unquote(original) in self._map


@dataclass
class Context:
    """The state of one import.

    Attributes
    ----------
    model
        The D-Flow FM model as read by hydrolib-core.
    options
        :class:`ImportOptions`.
    ledger
        The account written to ``import.md``.
    case
        The ``case.toml`` being built (a dict of tables).
    series
        Time series for the case's CSV files, by file name and column (UTC index).
    exchange
        Series of the DIMR exchange files by D-Flow FM quantity (``laterals/<id>/water_discharge``).
    start, end
        The simulated period (UTC).
    refdate
        The model's reference date (UTC).
    friction_entries
        The roughness files' ``[Branch]`` blocks as case entries, by group id and D-Flow FM branch id.
    main_group
        Whether D-Flow FM's default friction group ``Main`` stays a friction group (it varies along a branch or
        with the level) instead of becoming the global and the branches' own friction.
    """

    model: LoadedModel
    options: ImportOptions
    ledger: Ledger
    start: pd.Timestamp
    end: pd.Timestamp
    refdate: pd.Timestamp
    case: dict = field(default_factory=dict)
    series: dict[str, dict[str, pd.Series]] = field(default_factory=dict)
    exchange: dict[str, pd.Series] = field(default_factory=dict)
    exchange_used: set[str] = field(default_factory=set)
    ids: dict[str, IdMap] = field(default_factory=dict)
    branch_nodes: dict[str, tuple[str, str]] = field(default_factory=dict)
    branch_length: dict[str, float] = field(default_factory=dict)
    origins: dict[str, tuple[str, str]] = field(default_factory=dict)
    used_definitions: set[str] = field(default_factory=set)
    blocks: dict[tuple[str, str], Any] = field(default_factory=dict)
    compounds: list[tuple[str, list[str]]] = field(default_factory=list)
    pieces: dict[str, list[str]] = field(default_factory=dict)
    parallel: set[str] = field(default_factory=set)
    friction_entries: dict[str, dict[str, dict]] = field(default_factory=dict)
    main_group: bool = False

    def source(self, table: str, case_id: str, obj: Any) -> None:
        """Remember the D-Flow FM block (hydrolib-core object) a case object was made from."""
        self.blocks[(table, case_id)] = obj

    def where(self, table: str, case_id: str) -> str:
        """``file, line N`` of the block a case object was made from (the model file when unknown)."""
        obj = self.blocks.get((table, case_id))
        if isinstance(obj, str):
            return obj
        found = self.model.sources.where(obj) if obj is not None else ""
        return found or self.model.mdu.name

    def origin(self, case_id: str, kind: str) -> tuple[str, str]:
        """The ledger kind and D-Flow FM id of a structure or station of the case (``kind`` if unknown)."""
        return self.origins.get(case_id, (kind, case_id))

    def id(self, kind: str, original: object) -> str:
        """The case id of a D-Flow FM id of a kind (``node``, ``branch``, ``profile``, ``structure``, ...)."""
        if kind not in self.ids:
            self.ids[kind] = IdMap(kind, self.ledger, no_dot=(kind == "station"))
        return self.ids[kind](original)

    def add_series(self, file: str, column: str, series: pd.Series) -> dict[str, str]:
        """Store a series for a CSV file of the case; returns the case's ``{file, column}`` reference."""
        self.series.setdefault(file, {})[column] = series
        return {"file": file, "column": column}
