"""What the parts of a SOBEK 3 import share: the files read, the ledger, the case being built, ids and series."""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import pandas as pd

from rivercal.errors import CaseError, OptionError
from rivercal.io.ledger import Ledger
from rivercal.io.sobek3._ini import Section, read_ini

__all__ = ["FILE_KEYS", "MIN_DT", "Context", "ImportOptions", "Sobek3Ledger", "load_model"]

#: Shortest time step a case takes, s (the case's ``engine.dt``).
MIN_DT = 0.1

_BAD = re.compile(r"[^A-Za-z0-9_.\-]")

#: The keys of the md1d's [Files] section the import reads, and whether the model needs the file.
FILE_KEYS = {
    "networkFile": True,
    "crossLocFile": True,
    "crossDefFile": True,
    "roughnessFile": False,
    "structureFile": False,
    "obsPointsFile": False,
    "initialWaterLevelFile": False,
    "initialWaterDepthFile": False,
    "initialDischargeFile": False,
    "boundLocFile": False,
    "latDischargeLocFile": False,
    "boundCondFile": False,
    "sobekSimIniFile": False,
    "retentionFile": False,
    "windShieldingFile": False,
    "initialSalinityFile": False,
    "initialTemperatureFile": False,
}


class Sobek3Ledger(Ledger):
    """The import's account (:class:`rivercal.io.ledger.Ledger`), titled for a SOBEK 3 model in ``import.md``."""

    MODEL: ClassVar[str] = "SOBEK 3"


@dataclass(frozen=True)
class ImportOptions:
    """Options of an import.

    Attributes
    ----------
    allow_partial
        Write the case even when objects that change the hydraulics were refused (they are left out).
    dt
        Time step of the case, s (default: the model's own ``TimeStep``); at least 0.1 s. A longer step than the
        case's longest (3600 s) is cut to it, and one that does not divide the output interval is shortened until
        it does; ``import.md`` says so.

    Raises
    ------
    OptionError
        When ``dt`` is not a number of at least 0.1 s.
    """

    allow_partial: bool = False
    dt: float | None = None

    def __post_init__(self) -> None:
        if self.dt is not None and not (isinstance(self.dt, int | float) and math.isfinite(self.dt)
                                        and self.dt >= MIN_DT):
            raise OptionError(f"dt {self.dt!r}: the time step must be a number of at least {MIN_DT:g} s (the "
                              "case's shortest)", option="dt")


@dataclass
class Model:
    """The SOBEK 3 files of a model, read.

    Attributes
    ----------
    md1d
        The model definition file.
    md
        Its sections.
    files
        Per key of its ``[Files]`` section, the files it names (several for ``roughnessFile``) that exist.
    sections
        The sections of every file read, by key.
    """

    md1d: Path
    md: list[Section]
    files: dict[str, list[Path]] = field(default_factory=dict)
    sections: dict[str, list[list[Section]]] = field(default_factory=dict)

    def _settings(self) -> list[Section]:
        """The md1d's sections, then those of the SobekSim.ini it names (SOBEK 3 reads both)."""
        return [*self.md, *self.blocks("sobekSimIniFile")]

    def setting_section(self, section: str, key: str) -> Section | None:
        """The first md1d (or SobekSim.ini) section of that name that has the key."""
        return next((s for s in self._settings() if s.kind == section.lower() and s.has(key)), None)

    def setting(self, section: str, key: str, default=None):
        """The text of a key of an md1d section (or, failing that, of SobekSim.ini)."""
        s = self.setting_section(section, key)
        return s.text(key) if s is not None else default

    def number(self, section: str, key: str, default=None):
        """A number of an md1d section (or, failing that, of SobekSim.ini); ``default`` when absent."""
        s = self.setting_section(section, key)
        return s.number(key) if s is not None else default

    def blocks(self, key: str, kind: str | None = None) -> list[Section]:
        """The sections of the files of ``key`` (all files), optionally only those named ``kind``."""
        out = [s for sections in self.sections.get(key, []) for s in sections]
        return [s for s in out if kind is None or s.kind == kind.lower()]


def load_model(md1d: Path, ledger: Ledger) -> Model:
    """Read ``Flow1D.md1d`` and every file its ``[Files]`` section names.

    A file the model needs (network, cross-section locations and definitions) must exist; a missing optional
    file is a warning in the ledger.

    Raises
    ------
    CaseError
        When the md1d or a needed file cannot be read (the message names the file and, where there is one,
        the line and the key).
    """
    md1d = Path(md1d)
    if not md1d.is_file():
        raise CaseError("no such file (give the model's Flow1D.md1d)", file=str(md1d))
    md = read_ini(md1d)
    names = [s.kind for s in md]
    if "files" not in names:
        raise CaseError("this is not a SOBEK 3 model definition: it has no [Files] section", file=str(md1d))
    files_section = next(s for s in md if s.kind == "files")
    model = Model(md1d=md1d, md=md)
    for key, needed in FILE_KEYS.items():
        item = files_section.find(key)
        if item is None or not item.value:
            if needed:
                raise files_section.error(key, f"the model names no {key}; a SOBEK 3 model needs it")
            continue
        paths = []
        for name in item.value.split(";"):
            name = name.strip()
            if not name:
                continue
            path = (md1d.parent / name).resolve()
            if not path.is_file():
                if needed:
                    raise CaseError(f"{key} names {name!r}, which does not exist next to the md1d ({path})",
                                    file=files_section.where(item), field=key)
                ledger.warn(f"{md1d.name}: {key} names {name!r}, which does not exist; read as empty")
                continue
            paths.append(path)
        model.files[key] = paths
        model.sections[key] = [read_ini(p) for p in paths]
    known = {k.lower() for k in FILE_KEYS} | {"logfile"}
    for item in files_section.items:
        if item.key.lower() not in known:
            ledger.warn(f"{md1d.name}:{item.line}: [Files] {item.key} = {item.value} is not read by the import")
    return model


class IdMap:
    """Ids of one kind of object, made valid for a case (letters, digits, ``_ - .``; at most 64 characters)."""

    def __init__(self, kind: str, ledger: Ledger, *, no_dot: bool = False):
        self.kind = kind
        self._ledger = ledger
        self._no_dot = no_dot
        self._map: dict[str, str] = {}
        self._used: set[str] = set()
        self._reserved: set[str] = set()

    def _valid(self, key: str) -> str:
        new = _BAD.sub("_", key) or "unnamed"
        if self._no_dot:
            new = new.replace(".", "_")
        if len(new) > 64:
            new = new[:55] + "_" + hashlib.sha1(key.encode()).hexdigest()[:8]
        return new

    def reserve(self, originals) -> None:
        """Keep the ids among ``originals`` that are valid as written for themselves: a renamed id never takes them."""
        for original in originals:
            key = str(original).strip()
            if self._valid(key) == key:
                self._reserved.add(key)

    def __call__(self, original: str) -> str:
        """The case id of a SOBEK 3 id (the same id each time it is asked)."""
        key = str(original).strip()
        if key in self._map:
            return self._map[key]
        new = self._valid(key)
        base, k = new, 2
        while new in self._used or (new != key and new in self._reserved):
            new = f"{base[:60]}_{k}"
            k += 1
        self._map[key] = new
        self._used.add(new)
        if new != key:
            self._ledger.renamed.setdefault(self.kind, {})[key] = new
        return new

    def known(self, original: str) -> bool:
        """Whether this SOBEK 3 id was given a case id."""
        return str(original).strip() in self._map


@dataclass
class Context:
    """The state of one import: the model, the options, the ledger, the case being built, its series.

    Attributes
    ----------
    model
        The files read (:class:`Model`).
    options
        :class:`ImportOptions`.
    ledger
        The account written to ``import.md``.
    case
        The ``case.toml`` being built (a dict of tables).
    places
        ``file:line`` of the block each structure of the case was made from, by case id.
    compounds, pieces, parallel
        The compound structures to set side by side (name, members' case ids); the branches cut for them (id →
        the pieces' ids) and the branches added beside a stretch (:mod:`rivercal.io.sobek3._compound`).
    series
        Time series for the case's CSV files, by file name and column (UTC index).
    start, end
        The simulated period (UTC).
    """

    model: Model
    options: ImportOptions
    ledger: Ledger
    start: pd.Timestamp
    end: pd.Timestamp
    case: dict = field(default_factory=dict)
    series: dict[str, dict[str, pd.Series]] = field(default_factory=dict)
    ids: dict[str, IdMap] = field(default_factory=dict)
    branches: dict[str, dict] = field(default_factory=dict)
    origins: dict[str, tuple[str, str]] = field(default_factory=dict)
    profiles: dict[str, tuple[dict | None, float, str]] = field(default_factory=dict)
    definitions: dict[str, Section] = field(default_factory=dict)
    used_definitions: set[str] = field(default_factory=set)
    claimed: dict[tuple[str, str], Section] = field(default_factory=dict)
    places: dict[str, str] = field(default_factory=dict)
    compounds: list[tuple[str, list[str]]] = field(default_factory=list)
    pieces: dict[str, list[str]] = field(default_factory=dict)
    parallel: set[str] = field(default_factory=set)

    def id(self, kind: str, original: str) -> str:
        """The case id of a SOBEK 3 id of a kind (``node``, ``branch``, ``profile``, ``structure``, ...)."""
        return self._map(kind)(original)

    def known(self, kind: str, original: str) -> bool:
        """Whether a SOBEK 3 id of a kind was given a case id."""
        return kind in self.ids and self.ids[kind].known(original)

    def reserve(self, kind: str, blocks: list[Section], *keys: str) -> None:
        """Tell the ids of a kind before they are converted, so that a valid one keeps its name (:class:`IdMap`)."""
        self._map(kind).reserve(s.text(*keys) for s in blocks if s.has(*keys))

    def _map(self, kind: str) -> IdMap:
        if kind not in self.ids:
            self.ids[kind] = IdMap(kind, self.ledger, no_dot=(kind == "station"))
        return self.ids[kind]

    def claim(self, kind: str, s: Section, key: str = "id") -> str:
        """The SOBEK 3 id of a block (its ``key``); an error naming both blocks when another of the kind has it.

        SOBEK 3 requires the ids of one kind of object to be unique (the kernel looks objects up by id); two
        blocks with one id are a mistake in the model files, reported where the second is.
        """
        original = s.text(key).strip()
        first = self.claimed.setdefault((kind, original), s)
        if first is not s:
            raise s.error(key, f"{kind} id {original!r} is used twice: here and at {first.where(first.find(key))}")
        return original

    def origin(self, case_id: str, kind: str) -> tuple[str, str]:
        """The ledger kind and SOBEK 3 id of a structure or station of the case (``kind`` if unknown)."""
        return self.origins.get(case_id, (kind, case_id))

    def add_series(self, file: str, column: str, series: pd.Series) -> dict[str, str]:
        """Store a series for a CSV file of the case; returns the case's ``{file, column}`` reference."""
        self.series.setdefault(file, {})[column] = series
        return {"file": file, "column": column}
