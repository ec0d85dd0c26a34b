"""The files an MDU names, read into blocks, each file and block checked.

A file that is missing, outside the model folder, unreadable or not an INI file of its kind is refused by name; a
file hydrolib-core could not validate as a whole is read block by block, each block with its own model (a few
known inconsistencies between tools repaired, :data:`REPAIRS`); the ``.bc`` files blocks name are read by the
import itself, so that a value that is not a finite number is an error with its line.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._mdu import _check_lines, _field_key, _warn_duplicate
from rivercal.io.dhydro._source import IniIndex, RawSection, Sources, is_file, reading

__all__ = ["REPAIRS", "ExtBlocks", "FileBlocks"]


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
