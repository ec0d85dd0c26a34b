"""Reading a D-Flow FM model with hydrolib-core, checking what it returns.

Real models are written by many tools and versions, and some are damaged, so nothing that
hydrolib-core returns is taken on trust:

- **Files.** Only files inside the model folder are read (:mod:`._source`). A referenced file
  that is missing, outside the folder, unreadable or not an INI file of its kind is refused by
  name; when it holds objects that change the hydraulics (structures, cross-sections, roughness,
  boundaries and laterals, storage, the initial state), the refusal stops the import unless
  partial imports are allowed.
- **Unknown and repeated keywords.** hydrolib-core rejects an MDU or INI file whose sections carry
  keywords its schema does not know, and a key given twice. The model is read with the first
  turned into a warning per file, line and key, and the second resolved as D-Flow FM does (the
  first value counts) with a warning naming both lines.
- **Silent fall-backs.** Where a file fails hydrolib-core's validation, :class:`FMModel` keeps it
  as an opaque ``DiskOnlyFileModel`` without an error, or fails as a whole. Such a file is read
  again block by block (hydrolib-core's INI parser, then the block's own model), so that one bad
  block costs that block, named, and not the file. A few known inconsistencies between tools are
  repaired with a warning (:data:`REPAIRS`).
- **Values.** Every number of every block is screened (:func:`_screen`): a value that is not a
  finite number, a negative width, length or coefficient, a level beyond ±10 km or a negative
  chainage is an error naming the file, the line and the key. Errors never pass with
  ``--allow-partial``: the file has to be corrected.
"""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from rivercal.errors import CaseError
from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._source import IniIndex, RawSection, Sources, is_file, reading

__all__ = ["ExtBlocks", "FileBlocks", "LoadedModel", "load_fm_model"]

#: MDU file keys that the import reads: (section, key) → what the file holds and whether losing it changes
#: the hydraulics.
FILE_KEYS: dict[tuple[str, str], tuple[str, bool]] = {
    ("geometry", "netfile"): ("the network", True),
    ("geometry", "crossdeffile"): ("cross-section definitions", True),
    ("geometry", "crosslocfile"): ("cross-section locations", True),
    ("geometry", "frictfile"): ("roughness", True),
    ("geometry", "structurefile"): ("structures", True),
    ("geometry", "storagenodefile"): ("storage nodes", True),
    ("geometry", "inifieldfile"): ("initial fields", True),
    ("external_forcing", "extforcefilenew"): ("boundaries and laterals", True),
    ("external_forcing", "extforcefile"): ("old-format forcing", False),
    ("output", "obsfile"): ("observation points", False),
    ("output", "crsfile"): ("observation cross-sections", False),
}
#: The MDU sections of those keys as written in a file.
_SECTION_NAMES = {"geometry": "Geometry", "external_forcing": "External Forcing", "output": "Output", "time": "Time",
                  "physics": "Physics", "numerics": "Numerics", "general": "General"}


@dataclass
class FileBlocks:
    """The blocks of one file: the parsed objects and the blocks that failed (kind, id, reason)."""

    path: Path
    objects: list[Any] = field(default_factory=list)
    failed: list[tuple[str, str, str]] = field(default_factory=list)


@dataclass
class ExtBlocks:
    """The ``[Boundary]``, ``[Lateral]``, ``[Meteo]`` and ``[SourceSink]`` blocks of an external forcing file."""

    path: Path
    boundary: list[Any] = field(default_factory=list)
    lateral: list[Any] = field(default_factory=list)
    meteo: list[Any] = field(default_factory=list)
    sourcesink: list[Any] = field(default_factory=list)
    failed: list[tuple[str, str, str]] = field(default_factory=list)


@dataclass
class LoadedModel:
    """A D-Flow FM model as hydrolib-core objects, each file checked for its type.

    Attributes
    ----------
    mdu
        Path of the MDU file.
    fm
        The ``FMModel`` (file keys that hydrolib-core could not take are left out of it and read here).
    network
        The ``Network`` of the net file (mesh1d).
    crossdefs, crosslocs, structures, frictions, storage_nodes, observations, cross_observations
        Blocks of those files (a file that hydrolib-core could not validate as a whole is read
        block by block).
    ext
        Blocks of the external forcing file, or None.
    sources
        Files, lines and keys of what was read (:class:`~._source.Sources`).
    net_path
        The net file.
    """

    mdu: Path
    fm: Any
    network: Any
    crossdefs: FileBlocks
    crosslocs: FileBlocks
    structures: list[FileBlocks]
    frictions: list[FileBlocks]
    storage_nodes: FileBlocks | None
    observations: list[FileBlocks]
    cross_observations: list[FileBlocks]
    ext: ExtBlocks | None
    sources: Sources
    net_path: Path | None = None


def load_fm_model(mdu: Path, ledger: Ledger, sources: Sources | None = None) -> LoadedModel:
    """Read an MDU and the files it refers to with hydrolib-core.

    Raises
    ------
    CaseError
        When the MDU or its network file cannot be read at all, or a value of the MDU is not usable.
    """
    mdu = Path(mdu)
    if not is_file(mdu):
        raise CaseError("the D-Flow FM model file does not exist or is not a readable file", file=str(mdu))
    sources = sources or Sources(root=mdu.parent)
    try:
        index = sources.ini(mdu)
    except OSError as exc:
        raise CaseError(f"cannot read the model file: {exc.strerror or exc}", file=str(mdu)) from None
    if not index.sections:
        raise CaseError("not a D-Flow FM model file: it has no [section] (an MDU starts with [General], [Geometry], "
                        "...)", file=str(mdu))
    _check_lines(index, sources, ledger, "model")
    fm = _load_mdu(mdu, index, sources, ledger)
    net_path, network = _network(fm, mdu, index, sources)
    base = mdu.parent
    relative_to_parent = bool(getattr(fm.general, "pathsrelativetoparent", False))
    reader = _Reader(sources, ledger, base, relative_to_parent)
    def files(section: str, key: str) -> list[Any]:
        return _file_models(fm, index, sources, section, key)

    crossdefs = reader.blocks(files("geometry", "crossdeffile"), "cross-section definitions", "Definition",
                              _crossdef_kind)
    crosslocs = reader.blocks(files("geometry", "crosslocfile"), "cross-section locations", "CrossSection",
                              lambda _: ("cross-section location", _crossloc_model()))
    structures = reader.blocks(files("geometry", "structurefile"), "structures", "Structure", _structure_kind)
    frictions = reader.blocks(files("geometry", "frictfile"), "roughness", ("Global", "Branch"), _friction_kind)
    storage = reader.blocks(files("geometry", "storagenodefile"), "storage nodes", "StorageNode",
                            lambda _: ("storage node", _storage_model()))
    observations = reader.blocks(files("output", "obsfile"), "observation points", "ObservationPoint",
                                 lambda _: ("observation point", _obs_model()))
    cross_obs = reader.blocks(files("output", "crsfile"), "observation cross-sections", "ObservationCrossSection",
                              lambda _: ("observation cross-section", _obscrs_model()))
    ext_models = files("external_forcing", "extforcefilenew")
    ext = reader.ext(ext_models[0]) if ext_models else None
    model = LoadedModel(mdu=mdu, fm=fm, network=network, crossdefs=_first(crossdefs), crosslocs=_first(crosslocs),
                        structures=structures, frictions=frictions,
                        storage_nodes=storage[0] if storage else None, observations=observations,
                        cross_observations=cross_obs, ext=ext, sources=sources, net_path=net_path)
    for blocks in [model.crossdefs, model.crosslocs, *structures, *frictions, *storage, *observations, *cross_obs]:
        blocks.objects = [o for o in blocks.objects if _screen(o, sources, ledger)]
    if ext is not None:
        for name in ("boundary", "lateral"):
            setattr(ext, name, [o for o in getattr(ext, name) if _screen(o, sources, ledger)])
    return model


def _first(found: list[FileBlocks]) -> FileBlocks:
    return found[0] if found else FileBlocks(Path(""))


# -- the MDU ---------------------------------------------------------------------------------------------


def _load_mdu(mdu: Path, index: IniIndex, sources: Sources, ledger: Ledger) -> Any:
    """The FMModel; file keys whose files fail hydrolib-core are left out (and read block by block later)."""
    from hydrolib.core.dflowfm.mdu.models import FMModel

    for section, lines in index.duplicates():
        _warn_duplicate(sources, ledger, index.path, section, lines)
    unknown: list[tuple[str, list[str]]] = []
    fm = None
    for _ in range(len(FILE_KEYS) + 8):
        unknown.clear()
        try:
            with reading(sources, unknown), warnings.catch_warnings():
                # hydrolib-core warns that [Initial] blocks of initial-field files are deprecated in newer D-Flow FM
                # versions; real models still carry them, and the import reads them as they are
                warnings.filterwarnings("ignore", category=DeprecationWarning, module="pydantic")
                fm = FMModel(filepath=mdu)
            break
        except ValidationError as exc:
            errors = exc.errors(include_url=False)
            droppable, other = [], []
            for err in errors:
                loc = _mdu_loc(err.get("loc", ()))
                raw = [str(x) for x in err.get("loc", ())]
                if len(loc) >= 2 and str(loc[1]).endswith("file") and (loc[0], loc[1]) not in sources.dropped:
                    droppable.append((loc[0], loc[1]))
                elif not loc and err.get("type") == "extra_forbidden" and raw and (raw[-1], "") not in sources.dropped:
                    droppable.append((raw[-1], ""))  # a section hydrolib-core does not know
                    section = next((x for x in index.sections if _header_key(x.header) == raw[-1]), None)
                    ledger.warn(f"{mdu.name}, line {section.line if section else '?'}: section "
                                f"[{section.header if section else raw[-1]}] is not an MDU section known to "
                                "hydrolib-core: read past (D-Flow FM does not read it either)")
                else:
                    other.append(err)
            if other:
                raise CaseError(_mdu_problem(other, index, sources), file=str(mdu)) from None
            if not droppable:  # pragma: no cover - every error above is either dropped or reported
                raise CaseError(_mdu_problem(errors, index, sources), file=str(mdu)) from None
            sources.dropped.update(droppable)
        except (OSError, UnicodeError) as exc:
            raise CaseError(f"hydrolib-core cannot read the model: {' '.join(str(exc).split())}",
                            file=str(mdu)) from None
        except (ValueError, TypeError, KeyError, IndexError, AttributeError, RuntimeError) as exc:
            last = next((a for a in reversed(sources.access)), None)
            where = f" (the file it was reading last: {sources.rel(last.path)})" if last else ""
            raise CaseError(f"hydrolib-core fails on this model{where}: {type(exc).__name__}: "
                            f"{' '.join(str(exc).split())[:300]}", file=str(mdu)) from None
    if fm is None:  # pragma: no cover - every round drops at least one key
        raise CaseError("hydrolib-core cannot read the model", file=str(mdu))
    for header, keys in unknown:
        sections = index.of(header) or [s for s in index.sections if s.header.replace(" ", "").lower()
                                        == str(header).replace(" ", "").lower()]
        shown = []
        for key in keys:
            raw = sections[0].first(key) if sections else None
            shown.append(f"{raw.key} (line {raw.line})" if raw else key)
        ledger.warn(f"{mdu.name}: unknown keyword(s) in [{header}] read past (not known to hydrolib-core's schema, "
                    f"ignored by the import): {', '.join(shown)}")
    _check_mdu_numbers(fm, index, sources)
    return fm


def _mdu_loc(loc: tuple) -> tuple:
    """A validation error's location without hydrolib-core's leading file label (```Flow1D.mdu```, ``Flow1D.mdu``)."""
    from hydrolib.core.dflowfm.mdu.models import FMModel

    parts = [str(x) for x in loc]
    while parts and parts[0] not in FMModel.model_fields:
        parts = parts[1:]
    return tuple(parts)


def _mdu_problem(errors: list[dict], index: IniIndex, sources: Sources) -> str:
    """The MDU values hydrolib-core rejects, each with its line and key."""
    shown = []
    for err in errors[:4]:
        loc = _mdu_loc(err.get("loc", ()))
        if loc and loc[0] == "comments":
            loc = loc[1:]
        where = ".".join(loc)
        if len(loc) >= 2:
            section = next((s for s in index.sections if _header_key(s.header) == loc[0]), None)
            key = loc[-1] if loc[-2] == "comments" else loc[1]
            raw = section.first(key) if section else None
            if section is not None and raw is None:
                raw = next((r for lines in section.keys.values() for r in lines if _field_key(r.key) == key), None)
            if raw is not None:
                where = f"line {raw.line}, [{section.header}] {raw.key} = {raw.value!r}"
        shown.append(f"{where}: {' '.join(str(err.get('msg', '')).split())}")
    more = f" (and {len(errors) - 4} more)" if len(errors) > 4 else ""
    return "; ".join(shown) + more


def _header_key(header: str) -> str:
    from hydrolib.core.base.utils import to_key

    return to_key(header)


def _field_key(key: str) -> str:
    from hydrolib.core.base.utils import to_key

    return to_key(key)


def _warn_duplicate(sources: Sources, ledger: Ledger, path: Path, section: RawSection, lines: list) -> None:
    values = {r.value for r in lines}
    same = "the same value" if len(values) == 1 else "different values"
    where = ", ".join(f"line {r.line} ({r.key} = {r.value})" for r in lines)
    block = f" {section.block_id!r}" if section.block_id and section.header.lower() != "general" else ""
    ledger.warn(f"{sources.rel(path)}: [{section.header}]{block} gives {lines[0].key} more than once, with {same}: "
                f"{where}; D-Flow FM reads the first (line {lines[0].line}), and so does the import")


def _check_mdu_numbers(fm: Any, index: IniIndex, sources: Sources) -> None:
    """Numbers of the MDU that the import uses: finite, and of a sensible sign."""
    checks = (("time", "tstart", None), ("time", "tstop", None), ("time", "dtuser", "positive"),
              ("time", "dtmax", "positive"), ("time", "tzone", None), ("geometry", "waterlevini", "level"),
              ("physics", "uniffrictcoef", None), ("physics", "uniffrictcoef1d", None))
    problems = []
    for section, name, rule in checks:
        value = getattr(getattr(fm, section, None), name, None)
        if not isinstance(value, int | float):
            continue
        bad = not math.isfinite(value) or (rule == "positive" and value <= 0) or (rule == "level" and abs(value) > 1e4)
        if bad:
            problems.append(_mdu_key(index, section, name, value, "not a finite number" if not math.isfinite(value)
                                     else "must be positive" if rule == "positive" else "not a plausible level"))
    his = getattr(fm.output, "hisinterval", None)
    if his and isinstance(his[0], int | float) and (not math.isfinite(his[0]) or his[0] < 0):
        problems.append(_mdu_key(index, "output", "hisinterval", his[0], "must be a finite, non-negative interval"))
    if problems:
        raise CaseError("; ".join(problems), file=str(index.path))


def _mdu_key(index: IniIndex, section: str, name: str, value: Any, problem: str) -> str:
    sec = next((s for s in index.sections if _header_key(s.header) == section), None)
    raw = None
    if sec is not None:
        raw = next((r for lines in sec.keys.values() for r in lines if _field_key(r.key) == name), None)
    if raw is None:
        return f"[{_SECTION_NAMES.get(section, section)}] {name} = {value}: {problem}"
    return f"line {raw.line}, [{sec.header}] {raw.key} = {raw.value}: {problem}"


def mdu_line(index: IniIndex, section: str, name: str) -> str:
    """``line N, [Time] RefDate = value`` of an MDU key, for a message (the key's name when absent)."""
    sec = next((s for s in index.sections if _header_key(s.header) == section), None)
    raw = None
    if sec is not None:
        raw = next((r for lines in sec.keys.values() for r in lines if _field_key(r.key) == name), None)
    return f"line {raw.line}, [{sec.header}] {raw.key} = {raw.value}" if raw else f"[{section}] {name}"


def _file_models(fm: Any, index: IniIndex, sources: Sources, section: str, key: str) -> list[Any]:
    """The file models of an MDU key: hydrolib-core's objects, or the paths written when it could not take them."""
    if (section, key) in sources.dropped:
        return _dropped_paths(index, section, key)
    value = getattr(getattr(fm, section), key, None)
    if value is None or (isinstance(value, list) and not value):
        return []
    return value if isinstance(value, list) else [value]


def _dropped_paths(index: IniIndex, section: str, key: str) -> list[Path]:
    sec = next((s for s in index.sections if _header_key(s.header) == section), None)
    raw = next((r for lines in (sec.keys.values() if sec else []) for r in lines if _field_key(r.key) == key), None)
    if raw is None or not raw.value:
        return []
    return [Path(p.strip()) for p in raw.value.replace(",", ";").split(";") if p.strip()]


def _network(fm: Any, mdu: Path, index: IniIndex, sources: Sources) -> tuple[Path | None, Any]:
    net = fm.geometry.netfile
    path = getattr(net, "filepath", None)
    if ("geometry", "netfile") in sources.dropped or path is None:
        paths = _dropped_paths(index, "geometry", "netfile")
        path = paths[0] if paths else None
    full = None if path is None else (path if Path(path).is_absolute() else mdu.parent / path)
    if type(net).__name__ == "NetworkModel" and getattr(net, "network", None) is not None and full is not None \
            and is_file(full) and sources.inside(full):
        return full, net.network
    if path is None:
        raise CaseError("the model names no network file (NetFile)", file=str(mdu), field=mdu_line(index, "geometry",
                                                                                                       "netfile"))
    access = next((a for a in reversed(sources.access) if full is not None and a.path == Path(full)
                   and a.status != "read"), None)
    reason = access.reason if access else "hydrolib-core could not read it as a UGRID network"
    if access is None and full is not None and not sources.inside(full):
        reason = f"it lies outside the model folder {sources.root}; the import reads no file outside it"
    elif access is None and full is not None and not is_file(full):
        reason = "the file does not exist"
    raise CaseError(f"the network file {path}: {reason}", file=str(mdu), field=mdu_line(index, "geometry", "netfile"))


def _check_lines(index: IniIndex, sources: Sources, ledger: Ledger, what: str) -> None:
    """Lines hydrolib-core's parser would skip silently are errors: a key there would be lost without a word."""
    for line, text in index.stray[:20]:
        ledger.error(f"{sources.rel(index.path)}, line {line}", f"{text[:60]!r} is not INI text (a [section], "
                     f"'key = value' or a comment) in this {what} file; hydrolib-core would skip it silently")
    if len(index.stray) > 20:
        ledger.error(f"{sources.rel(index.path)}", f"{len(index.stray) - 20} more lines that are not INI text")


# -- the files an MDU names ------------------------------------------------------------------------------


class _Reader:
    """Reads the files of a model into blocks, refusing files that are missing, outside, unreadable or not INI."""

    def __init__(self, sources: Sources, ledger: Ledger, base: Path, relative_to_parent: bool):
        self.sources = sources
        self.ledger = ledger
        self.base = base
        self.relative_to_parent = relative_to_parent
        self.forcing: dict[Path, Any] = {}

    def full(self, path: Path | str, folder: Path | None = None) -> Path:
        """A file name as D-Flow FM resolves it: relative to the MDU's folder (or its own file's folder)."""
        path = Path(path)
        return path if path.is_absolute() else (folder if folder is not None and self.relative_to_parent
                                                else self.base) / path

    def refuse_file(self, path: Path, what: str, reason: str, hydraulic: bool) -> None:
        effect = (f"the {what} it holds are missing, which changes the hydraulics" if hydraulic
                  else f"the {what} it holds are not stations of the case")
        self.ledger.refused("file", self.sources.rel(path), f"{reason}; {effect}", hydraulic=hydraulic)

    def check(self, full: Path, what: str, hydraulic: bool) -> bool:
        """Whether a file may and can be read; a refusal of it when not."""
        if not self.sources.inside(full):
            self.refuse_file(full, what, f"it lies outside the model folder {self.sources.root} (the import reads no "
                             "file outside it: copy it into the model folder)", hydraulic)
            return False
        if not is_file(full):
            self.refuse_file(full, what, "the file does not exist or is not a readable file", hydraulic)
            return False
        try:
            self.sources.ini(full)
        except OSError as exc:
            self.refuse_file(full, what, f"the file cannot be read ({exc.strerror or exc})", hydraulic)
            return False
        return True

    def blocks(self, models: list[Any], what: str, headers: str | tuple[str, ...],
               kind_of: Callable[[dict], tuple[str, Any] | None]) -> list[FileBlocks]:
        """The blocks of the files an MDU key names (hydrolib-core's objects, or read block by block)."""
        headers = (headers,) if isinstance(headers, str) else headers
        hydraulic = what not in ("observation points", "observation cross-sections")
        out = []
        for model in models:
            path = Path(getattr(model, "filepath", None) or model)
            full = self.full(path)
            name = type(model).__name__
            if name in ("DiskOnlyFileModel", "PolyFile", "XYNModel") or isinstance(model, Path | str):
                if name == "XYNModel":
                    self.refuse_file(full, what, "an .xyn points file (x, y, name) is not read", hydraulic)
                    continue
                if not self.check(full, what, hydraulic):
                    continue
                found = self._parse_blocks(full, what, headers, kind_of)
            else:
                if not self.check(full, what, hydraulic):
                    continue
                found = FileBlocks(full, _objects_of(model))
                self._locate(found, headers)
                self._warn_unknown_keys(full, what, kind_of)
            if self._not_ini(found, what, headers, hydraulic):
                continue
            out.append(found)
        return out

    def _not_ini(self, found: FileBlocks, what: str, headers: tuple[str, ...], hydraulic: bool) -> bool:
        """A file without any block of its kind and with text that is not INI: not a file of its kind, refused."""
        index = self.sources.ini(found.path)
        ours = [s for s in index.sections if s.header.lower() in {h.lower() for h in headers}]
        if not ours and (index.stray or not index.sections or found.objects == []) and not found.failed:
            if index.stray or not index.sections:
                first = f"; line {index.stray[0][0]} reads {index.stray[0][1][:40]!r}" if index.stray else ""
                self.refuse_file(found.path, what, f"not a D-Flow FM {what} file (no [{headers[0]}] block"
                                 f"{first})", hydraulic)
                return True
        _check_lines(index, self.sources, self.ledger, what)
        for s in index.sections:
            if s.header.lower() not in {h.lower() for h in (*headers, "General")}:
                self.ledger.warn(f"{self.sources.rel(found.path)}, line {s.line}: a [{s.header}] block in a {what} "
                                 "file is not read")
        return False

    def _locate(self, found: FileBlocks, headers: tuple[str, ...]) -> None:
        """Tie each object of a file hydrolib-core parsed as a whole to its section (same order per header)."""
        index = self.sources.ini(found.path)
        by_header: dict[str, list[RawSection]] = {h.lower(): index.of(h) for h in headers}
        position: dict[str, int] = {}
        for obj in found.objects:
            header = _header_of(obj) or headers[0]
            sections = by_header.get(header.lower(), [])
            k = position.get(header.lower(), 0)
            position[header.lower()] = k + 1
            if k < len(sections):
                self.sources.locate(obj, found.path, sections[k])

    def _warn_unknown_keys(self, path: Path, what: str, kind_of: Callable[[dict], tuple[str, Any] | None]) -> None:
        """Warn about the keys of each block that its hydrolib-core model does not know (some models ignore them)."""
        index = self.sources.ini(path)
        found_by_keys: dict[tuple[str, tuple[str, ...]], list[str]] = {}
        for section in index.sections:
            if section.header.lower() == "general":
                continue
            for _, lines in [(s, lines) for s, lines in index.duplicates() if s is section]:
                _warn_duplicate(self.sources, self.ledger, path, section, lines)
            data = {k: (v[0].value if v else None) for k, v in section.keys.items()}
            found = kind_of({**data, "_header": section.header})
            if found is None:
                continue
            kind, cls = found
            known = {n.lower() for n in cls.model_fields} | {
                f.alias.lower() for f in cls.model_fields.values() if f.alias} | {"_header", "datablock", "comments"}
            unknown = tuple(sorted(section.keys[k][0].key for k in data if k not in known))
            if unknown:
                found_by_keys.setdefault((kind, unknown), []).append(f"{section.block_id!r} (line {section.line})")
        for (kind, keys), ids in found_by_keys.items():
            shown = ", ".join(ids[:5]) + (f" and {len(ids) - 5} more" if len(ids) > 5 else "")
            self.ledger.warn(f"{what} file {self.sources.rel(path)}: unknown keyword(s) {', '.join(keys)} read past in "
                             f"{kind} {shown}")

    def _parse_blocks(self, path: Path, what: str, headers: tuple[str, ...],
                      kind_of: Callable[[dict], tuple[str, Any] | None]) -> FileBlocks:
        from hydrolib.core.dflowfm.ini.parser import Parser

        self.ledger.warn(f"{what} file {self.sources.rel(path)}: hydrolib-core could not validate the file as a whole "
                         "(it kept it unparsed); read block by block instead, each block with its own model, and the "
                         "blocks that fail are refused by name")
        doc = Parser.parse(path)
        index = self.sources.ini(path)
        out = FileBlocks(path)
        for k, section in enumerate(doc.sections):
            raw = index.sections[k] if k < len(index.sections) else None
            data = {key.lower(): v for key, v in section.flatten(duplicate_key_as_list=False,
                                                                 with_comments=False).items()}
            if raw is not None:  # a key given twice: its first value, as D-Flow FM reads it
                for lines in raw.keys.values():
                    if len(lines) > 1:
                        data[_field_key(lines[0].key)] = lines[0].value
                        _warn_duplicate(self.sources, self.ledger, path, raw, lines)
            if section.header.lower() == "general" or section.header.lower() not in {h.lower() for h in headers}:
                continue
            found = kind_of({**data, "_header": section.header})
            block_id = _block_name(raw, self.sources, path)
            if found is None:
                out.failed.append((section.header, block_id, f"[{section.header}] block of type "
                                   f"{data.get('type')!r} is not known to hydrolib-core"))
                continue
            kind, cls = found
            for block_type, test, drop, why in REPAIRS:
                if kind == block_type and test(data):
                    data = {key: v for key, v in data.items() if key not in drop}
                    self.ledger.warn(f"{what} file {self.sources.rel(path)}, {kind} {block_id!r}: {why}")
            unknown: list[tuple[str, list[str]]] = []
            data = self._with_forcing(data, path, kind, block_id)
            try:
                with reading(self.sources, unknown), _relative_to(self._anchor(path)):
                    obj = cls.model_validate(data)
            except ValidationError as exc:
                self._block_failure(out, exc, raw, kind, block_id)
                continue
            out.objects.append(obj)
            if raw is not None:
                self.sources.locate(obj, path, raw)
            for _, keys in unknown:
                self.ledger.warn(f"{what} file {self.sources.rel(path)}, {kind} {block_id!r} (line "
                                 f"{raw.line if raw else '?'}): unknown keyword(s) read past: {', '.join(keys)}")
        return out

    def _anchor(self, path: Path) -> Path:
        return path.parent if self.relative_to_parent else self.base

    def _block_failure(self, out: FileBlocks, exc: ValidationError, raw: RawSection | None, kind: str,
                       block_id: str) -> None:
        """A block hydrolib-core rejects: a missing key or file refuses it; a bad value is an error with its line."""
        errors = exc.errors(include_url=False)
        values = [e for e in errors if e.get("type") != "missing" and "not found" not in str(e.get("msg", ""))
                  and "no such file" not in str(e.get("msg", "")) and "outside the model folder" not in
                  str(e.get("msg", ""))]
        reason = _first_error(exc)
        if values and raw is not None:
            err = values[0]
            key = next((str(x) for x in err.get("loc", ()) if raw.first(str(x)) is not None), None)
            line = raw.first(key) if key else None
            where = f"{self.sources.rel(out.path)}, line {line.line if line else raw.line}"
            what = f"{kind} {block_id!r}" + (f", {line.key} = {line.value}" if line else "")
            self.ledger.error(where, f"{what}: {' '.join(str(err.get('msg', '')).split())}")
            out.failed.append((kind, block_id, f"an unusable value (see the errors): {reason}"))
            return
        for access in self.sources.access:
            if access.status != "read" and access.path.name in reason:
                reason = f"its file {self.sources.rel(access.path)}: {access.reason}"
                break
        out.failed.append((kind, block_id, reason))

    def _with_forcing(self, data: dict, path: Path, kind: str, block_id: str) -> dict:
        """Block values that name a ``.bc`` file, read by the import itself (a NaN there is an error with its line)."""
        out = dict(data)
        for key, value in data.items():
            if not isinstance(value, str) or not value.strip().lower().endswith(".bc"):
                continue
            full = self.full(value.strip(), path.parent)
            model = self.forcing_model(full)
            if model is not None:
                out[key] = model
        return out

    def forcing_model(self, full: Path) -> Any:
        """A ``.bc`` file as a ForcingModel of its good blocks (None when it cannot be read); bad blocks recorded."""
        from hydrolib.core.dflowfm.bc.models import ForcingModel
        from hydrolib.core.dflowfm.ini.parser import Parser, ParserConfig

        key = Path(full)
        if key in self.forcing:
            return self.forcing[key]
        self.forcing[key] = None
        if not self.sources.inside(full) or not is_file(full):
            return None
        try:
            index = self.sources.ini(full, datablocks=True)
            doc = Parser.parse(full, ParserConfig(parse_datablocks=True))
        except OSError:
            return None
        good = []
        forcing = [s for s in index.sections if s.header.lower() == "forcing"]
        failures: dict[str, str] = {}
        parsed = [s for s in doc.sections if s.header.lower() == "forcing"]
        for raw, section in zip(forcing, parsed, strict=False):
            data = section.flatten()
            try:
                block = ForcingModel(forcing=[data]).forcing[0]
            except ValidationError as exc:
                reason = _first_error(exc)
                bad = next((line for line, text in raw.rows if not all(_finite_text(t) for t in text.split())), None)
                if bad is not None:
                    self.ledger.error(f"{self.sources.rel(full)}, line {bad}",
                                      f"forcing {raw.block_id!r}: a value that is not a finite number in its table")
                    reason = f"a value that is not a finite number at line {bad} (see the errors)"
                failures[raw.block_id] = reason
                continue
            good.append(block)
            self.sources.locate(block, full, raw)
        model = ForcingModel(forcing=good)
        model.filepath = Path(self.sources.rel(full))
        self.forcing[key] = model
        self.sources.forcing_failures[key] = failures
        return model

    def ext(self, model: Any) -> ExtBlocks | None:
        """The external forcing file: hydrolib-core's ExtModel, or read block by block when it could not take it."""
        path = Path(getattr(model, "filepath", None) or model)
        full = self.full(path)
        what = "boundaries and laterals"
        if not self.check(full, what, True):
            return None
        index = self.sources.ini(full)
        name = type(model).__name__
        out = ExtBlocks(full)
        if name == "ExtModel":
            out.boundary, out.lateral = list(model.boundary), list(model.lateral)
            out.meteo = list(getattr(model, "meteo", None) or [])
            out.sourcesink = list(getattr(model, "sourcesink", None) or [])
            for header, objects in (("Boundary", out.boundary), ("Lateral", out.lateral)):
                for obj, raw in zip(objects, index.of(header), strict=False):
                    self.sources.locate(obj, full, raw)
            for section, lines in index.duplicates():
                _warn_duplicate(self.sources, self.ledger, full, section, lines)
        else:
            self._ext_blocks(out, index)
        _check_lines(index, self.sources, self.ledger, "external forcing")
        return out

    def _ext_blocks(self, out: ExtBlocks, index: IniIndex) -> None:
        from hydrolib.core.dflowfm.ext.models import Boundary, Lateral, Meteo
        from hydrolib.core.dflowfm.ini.parser import Parser

        self.ledger.warn(f"external forcing file {self.sources.rel(out.path)}: hydrolib-core could not validate the "
                         "file as a whole; read block by block instead, each block with its own model")
        doc = Parser.parse(out.path)
        classes = {"boundary": (Boundary, out.boundary), "lateral": (Lateral, out.lateral),
                   "meteo": (Meteo, out.meteo)}
        for k, section in enumerate(doc.sections):
            raw = index.sections[k] if k < len(index.sections) else None
            header = section.header.lower()
            if header == "general":
                continue
            block_id = _block_name(raw, self.sources, out.path)
            if header not in classes:
                out.failed.append((section.header, block_id, f"[{section.header}] block is not read"))
                continue
            cls, target = classes[header]
            data = {key.lower(): v for key, v in section.flatten(duplicate_key_as_list=False,
                                                                 with_comments=False).items()}
            if raw is not None:
                for lines in raw.keys.values():
                    if len(lines) > 1:
                        data[_field_key(lines[0].key)] = lines[0].value
                        _warn_duplicate(self.sources, self.ledger, out.path, raw, lines)
            for key in ("forcingfile", "discharge"):
                value = data.get(key)
                if isinstance(value, str) and not _finite_text(value) and value.strip().lower() != "realtime":
                    full = self.full(value.strip(), out.path.parent)
                    if not self.sources.inside(full):
                        out.failed.append((header, block_id, f"its forcing file {value.strip()} lies outside the model "
                                                             f"folder {self.sources.root} (not read)"))
                        data = None
                        break
                    if not is_file(full):
                        out.failed.append((header, block_id, f"its forcing file {value.strip()} does not exist"))
                        data = None
                        break
                    model = self.forcing_model(full)
                    if model is None:
                        out.failed.append((header, block_id, f"its forcing file {value.strip()} cannot be read"))
                        data = None
                        break
                    data[key] = model
            if data is None:
                continue
            try:
                with reading(self.sources, []), _relative_to(self._anchor(out.path)):
                    obj = cls.model_validate(data)
            except ValidationError as exc:
                fake = FileBlocks(out.path)
                self._block_failure(fake, exc, raw, header, block_id)
                out.failed.extend(fake.failed)
                continue
            target.append(obj)
            if raw is not None:
                self.sources.locate(obj, out.path, raw)


def _block_name(raw: RawSection | None, sources: Sources, path: Path) -> str:
    """The id of a block for the ledger; a block without one is named by its file and line."""
    if raw is not None and raw.block_id:
        return raw.block_id
    return f"(no id) {sources.rel(path)}, line {raw.line}" if raw is not None else f"(no id) {sources.rel(path)}"


def _header_of(obj: Any) -> str | None:
    header = getattr(type(obj), "model_fields", {}).get("_header")
    if header is not None:
        return str(header.default)
    private = getattr(obj, "_header", None)
    if isinstance(private, str):
        return private
    return getattr(private, "default", None)


def _finite_text(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _objects_of(model: Any) -> list[Any]:
    """The block objects of a parsed hydrolib-core INI model (definitions, structures, ...)."""
    name = type(model).__name__
    if name == "CrossDefModel":
        return list(model.definition)
    if name == "CrossLocModel":
        return list(model.crosssection)
    if name == "StructureModel":
        return list(model.structure)
    if name == "FrictionModel":
        return [*model.global_, *model.branch]
    if name == "StorageNodeModel":
        return list(model.storagenode)
    if name == "ObservationPointModel":
        return list(model.observationpoint)
    if name == "ObservationCrossSectionModel":
        return list(model.observationcrosssection)
    raise TypeError(name)


def _first_error(exc: ValidationError) -> str:
    err = exc.errors(include_url=False)[0]
    loc = ".".join(str(x) for x in err.get("loc", ()) if not str(x).startswith("`"))
    return f"{loc}: {' '.join(str(err.get('msg', '')).split())}"


# -- values -----------------------------------------------------------------------------------------------

#: Fields whose values are levels (m AD): within ±10 km.
_LEVEL_WORDS = ("level", "shift", "zcoordinates", "zvalues", "levels")
#: Fields whose values cannot be negative: widths, lengths, areas, coefficients, capacities, friction values.
_NON_NEGATIVE = ("width", "widths", "diameter", "height", "length", "area", "storagearea", "coeff", "capacity",
                 "frictionvalue", "frictionvalues", "friction", "bedfriction", "chainage", "dischargecoeff",
                 "corrcoeff")
_LIMIT = 1.0e4


def _screen(obj: Any, sources: Sources, ledger: Ledger) -> bool:
    """Whether every number of a block is usable; an error with file, line and key for each that is not."""
    fields = getattr(type(obj), "model_fields", {})
    ok = True
    for name in fields:
        if name in ("comments", "datablock", "filepath"):
            continue
        value = getattr(obj, name, None)
        numbers = value if isinstance(value, list) else [value]
        numbers = [v for v in numbers if isinstance(v, int | float) and not isinstance(v, bool)]
        if not numbers:
            continue
        problem = None
        lower = name.lower()
        if not all(math.isfinite(float(v)) for v in numbers):
            problem = "not a finite number"
        elif any(w in lower for w in _LEVEL_WORDS) and any(abs(float(v)) > _LIMIT for v in numbers):
            problem = "not a plausible level (beyond ±10,000 m)"
        elif lower.endswith(_NON_NEGATIVE) and any(float(v) < 0 for v in numbers) and not _may_be_negative(obj, lower):
            problem = "cannot be negative"
        elif lower in ("frictionvalue", "frictionvalues") and any(float(v) <= 0 for v in numbers):
            problem = "must be positive"
        if problem is None:
            continue
        ok = False
        key = sources.key_of(obj, name)
        found = sources.section_of(obj)
        raw = found[1].first(key) if found else None
        shown = raw.value if raw is not None else value
        block = found[1] if found else None
        what = f"[{block.header}] {block.block_id!r}" if block else type(obj).__name__
        ledger.error(sources.where(obj, key) or "?", f"{what}, {key} = {shown}: {problem}")
    return ok


def _may_be_negative(obj: Any, name: str) -> bool:
    """Fields whose name matches a rule but that may be negative (a lateral's discharge, a pump's capacity sign)."""
    return name in ("discharge",)


# -- block kinds ------------------------------------------------------------------------------------------

#: Known inconsistencies between the files of some tools and hydrolib-core's validation, and their repair:
#: (block type, test on the block's keys, keys to drop, why).
REPAIRS: tuple[tuple[str, Callable[[dict], bool], tuple[str, ...], str], ...] = (
    ("pump", lambda d: _number(d.get("numreductionlevels")) == 0 and ("head" in d or "reductionfactor" in d),
     ("head", "reductionfactor"),
     "numReductionLevels = 0 with a head/reductionFactor table: D-Flow FM reads no reduction table when "
     "numReductionLevels is 0, so the table was ignored"),
)


def _number(text: Any) -> float | None:
    try:
        return float(str(text).split()[0])
    except (ValueError, IndexError):
        return None


@contextlib.contextmanager
def _relative_to(folder: Path) -> Iterator[None]:
    """Within the block, hydrolib-core resolves the file names that blocks name (``.bc``, ``.tim``) from ``folder``."""
    from hydrolib.core.base.file_manager import ResolveRelativeMode, file_load_context

    with file_load_context() as context:
        context.push_new_parent(folder, ResolveRelativeMode.ToAnchor)
        try:
            yield
        finally:
            context.pop_last_parent()


def _crossdef_kind(data: dict) -> tuple[str, Any] | None:
    from hydrolib.core.dflowfm.crosssection import models as m

    classes = {"circle": m.CircleCrsDef, "rectangle": m.RectangleCrsDef, "zwriver": m.ZWRiverCrsDef,
               "zw": m.ZWCrsDef, "yz": m.YZCrsDef, "xyz": m.XYZCrsDef}
    cls = classes.get(str(data.get("type", "")).lower())
    return ("cross-section definition", cls) if cls else None


def _structure_kind(data: dict) -> tuple[str, Any] | None:
    from hydrolib.core.dflowfm.structure import models as m

    classes = {"weir": m.Weir, "universalweir": m.UniversalWeir, "culvert": m.Culvert, "pump": m.Pump,
               "compound": m.Compound, "orifice": m.Orifice, "gate": m.Gate, "generalstructure": m.GeneralStructure,
               "bridge": m.Bridge, "dambreak": m.Dambreak, "longculvert": m.LongCulvert}
    name = str(data.get("type", "")).lower()
    cls = classes.get(name)
    return (name, cls) if cls else None


def _friction_kind(data: dict) -> tuple[str, Any] | None:
    from hydrolib.core.dflowfm.friction import models as m

    header = str(data.get("_header", "")).lower()
    if header == "global":
        return ("friction group", m.FrictGlobal)
    if header == "branch":
        return ("friction on a branch", m.FrictBranch)
    return None


def _crossloc_model() -> Any:
    from hydrolib.core.dflowfm.crosssection.models import CrossSection

    return CrossSection


def _storage_model() -> Any:
    from hydrolib.core.dflowfm.storagenode.models import StorageNode

    return StorageNode


def _obs_model() -> Any:
    from hydrolib.core.dflowfm.obs.models import ObservationPoint

    return ObservationPoint


def _obscrs_model() -> Any:
    from hydrolib.core.dflowfm.obscrosssection.models import ObservationCrossSection

    return ObservationCrossSection
