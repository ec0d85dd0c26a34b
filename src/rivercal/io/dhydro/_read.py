"""Reading a D-Flow FM model with hydrolib-core, checking what it returns.

Real models are written by many tools and versions, so two things are handled here rather than
left to fail or to pass silently:

- **Unknown keywords.** hydrolib-core rejects an MDU or INI file whose sections carry keywords its
  schema does not know (an older or newer format, another tool's extras). The model is read with
  that check turned into a record: every unknown keyword becomes a warning in ``import.md``.
- **Silent fall-backs.** Where a file fails hydrolib-core's validation, :class:`FMModel` keeps it as an
  opaque ``DiskOnlyFileModel`` without an error. Every file model is type-checked here; a file that
  fell back is read again block by block (hydrolib-core's INI parser, then the block's own model),
  so that one bad block costs that block, named, and not the file. A few known inconsistencies
  between tools are repaired with a warning (:data:`REPAIRS`).
"""

from __future__ import annotations

import contextlib
import threading
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from rivercal.errors import CaseError
from rivercal.io.dhydro._ledger import Ledger

__all__ = ["FileBlocks", "LoadedModel", "load_fm_model"]

_LOCK = threading.Lock()
#: The folder that file names inside a file's blocks are relative to, by the file's folder (the MDU's folder
#: unless the MDU says PathsRelativeToParent = 1).
_BASE: dict[Path, Path] = {}


@dataclass
class FileBlocks:
    """The blocks of one file: the parsed objects and the blocks that failed (id, reason)."""

    path: Path
    objects: list[Any] = field(default_factory=list)
    failed: list[tuple[str, str, str]] = field(default_factory=list)  # (kind, id, reason)


@dataclass
class LoadedModel:
    """A D-Flow FM model as hydrolib-core objects, each file checked for its type.

    Attributes
    ----------
    mdu
        Path of the MDU file.
    fm
        The ``FMModel``.
    network
        The ``Network`` of the net file (mesh1d).
    crossdefs, crosslocs, structures, frictions, storage_nodes, observations
        Blocks of those files (a file that hydrolib-core could not validate as a whole is read
        block by block).
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
    ext: Any


@contextlib.contextmanager
def _recording_unknown_keywords(found: list[tuple[str, list[str]]]) -> Iterator[None]:
    """Within the block, hydrolib-core records unknown INI/MDU keywords in ``found`` instead of raising."""
    from hydrolib.core.dflowfm.ini import util

    manager = util.UnknownKeywordErrorManager
    original = manager.raise_error_for_unknown_keywords

    def record(self, data, section_header, fields, excluded_fields):
        unknown = self._get_all_unknown_keywords(data, fields, excluded_fields)
        if unknown:
            header = getattr(section_header, "default", section_header)
            found.append((str(header), list(unknown)))

    with _LOCK:
        manager.raise_error_for_unknown_keywords = record
        try:
            yield
        finally:
            manager.raise_error_for_unknown_keywords = original


def load_fm_model(mdu: Path, ledger: Ledger) -> LoadedModel:
    """Read an MDU and the files it refers to with hydrolib-core.

    Raises
    ------
    CaseError
        When the MDU or its network file cannot be read at all.
    """
    from hydrolib.core.dflowfm.mdu.models import FMModel

    mdu = Path(mdu)
    if not mdu.is_file():
        raise CaseError("the D-Flow FM model file does not exist", file=str(mdu))
    unknown: list[tuple[str, list[str]]] = []
    try:
        with _recording_unknown_keywords(unknown), warnings.catch_warnings():
            # hydrolib-core warns that [Initial] blocks of initial-field files are deprecated in newer D-Flow FM
            # versions; real models still carry them, and the import reads them as they are
            warnings.filterwarnings("ignore", category=DeprecationWarning, module="pydantic")
            fm = FMModel(filepath=mdu)
    except ValidationError as exc:
        raise CaseError(f"hydrolib-core cannot read the model: {_first_error(exc)}", file=str(mdu)) from None
    except (OSError, ValueError) as exc:
        raise CaseError(f"hydrolib-core cannot read the model: {' '.join(str(exc).split())}", file=str(mdu)) from None
    for section, keys in unknown:
        ledger.warn(f"unknown keyword(s) in section [{section}] read past (not known to hydrolib-core's schema, "
                    f"ignored by the import): {', '.join(keys)}")
    geometry = fm.geometry
    net = geometry.netfile
    if type(net).__name__ != "NetworkModel" or getattr(net, "network", None) is None:
        raise CaseError(f"the network file {getattr(net, 'filepath', None)} could not be read as a UGRID network "
                        f"(hydrolib-core returned {type(net).__name__})", file=str(mdu), field="geometry.NetFile")
    base = mdu.parent
    relative_to_parent = bool(getattr(fm.general, "pathsrelativetoparent", False))
    for f in _as_list(geometry.structurefile) + _as_list(geometry.crossdeffile):
        path = Path(getattr(f, "filepath", None) or "")
        folder = (path if path.is_absolute() else base / path).parent
        _BASE[folder] = folder if relative_to_parent else base
    crossdefs = _blocks(geometry.crossdeffile, "CrossDefModel", base, ledger, "cross-section definitions",
                        _crossdef_kind)
    crosslocs = _blocks(geometry.crosslocfile, "CrossLocModel", base, ledger, "cross-section locations",
                        lambda _: ("cross-section location", _crossloc_model()))
    structures = [_blocks(f, "StructureModel", base, ledger, "structures", _structure_kind)
                  for f in _as_list(geometry.structurefile)]
    frictions = [_blocks(f, "FrictionModel", base, ledger, "roughness", _friction_kind)
                 for f in _as_list(geometry.frictfile)]
    storage = None
    if geometry.storagenodefile is not None:
        storage = _blocks(geometry.storagenodefile, "StorageNodeModel", base, ledger, "storage nodes",
                          lambda _: ("storage node", _storage_model()))
    observations = [_blocks(f, "ObservationPointModel", base, ledger, "observation points",
                            lambda _: ("observation point", _obs_model()))
                    for f in _as_list(fm.output.obsfile)]
    ext = fm.external_forcing.extforcefilenew
    if ext is not None and type(ext).__name__ != "ExtModel":
        ledger.warn(f"the external forcing file {getattr(ext, 'filepath', None)} could not be validated by "
                    f"hydrolib-core (it returned {type(ext).__name__}); its boundaries and laterals are missing")
        ext = None
    return LoadedModel(mdu=mdu, fm=fm, network=net.network, crossdefs=crossdefs or FileBlocks(Path("")),
                       crosslocs=crosslocs or FileBlocks(Path("")), structures=[s for s in structures if s],
                       frictions=[f for f in frictions if f], storage_nodes=storage,
                       observations=[o for o in observations if o], ext=ext)


def _as_list(value: Any) -> list[Any]:
    if value is None:
        return []
    return list(value) if isinstance(value, list) else [value]


def _first_error(exc: ValidationError) -> str:
    err = exc.errors(include_url=False)[0]
    loc = ".".join(str(x) for x in err.get("loc", ()))
    return f"{loc}: {' '.join(str(err.get('msg', '')).split())}"


# -- block-by-block reading of a file that hydrolib-core kept as an opaque DiskOnlyFileModel ---------------


def _blocks(model: Any, expected: str, base: Path, ledger: Ledger, what: str,
            kind_of: Callable[[dict], tuple[str, Any] | None]) -> FileBlocks | None:
    """The blocks of a file model: as hydrolib-core parsed them, or parsed block by block after a fall-back."""
    if model is None:
        return None
    path = Path(getattr(model, "filepath", None) or "")
    full = path if path.is_absolute() else base / path
    name = type(model).__name__
    if name == expected:
        if full.is_file():
            _warn_unknown_keys(full, ledger, what, kind_of)
        return FileBlocks(full, _objects_of(model))
    if name != "DiskOnlyFileModel":
        ledger.warn(f"{what} file {path}: hydrolib-core returned a {name}, not a {expected}; read block by block")
    else:
        ledger.warn(f"{what} file {path}: hydrolib-core could not validate the file as a whole and kept it unparsed "
                    "(a DiskOnlyFileModel); read block by block instead, each block with its own model, and the "
                    "blocks that fail are refused by name")
    if not full.is_file():
        ledger.warn(f"{what} file {path} does not exist")
        return FileBlocks(full)
    return _parse_blocks(full, ledger, what, kind_of)


def _warn_unknown_keys(path: Path, ledger: Ledger, what: str,
                       kind_of: Callable[[dict], tuple[str, Any] | None]) -> None:
    """Warn about the keys of each block that its hydrolib-core model does not know (some models ignore them)."""
    from hydrolib.core.dflowfm.ini.parser import Parser

    found_by_keys: dict[tuple[str, tuple[str, ...]], list[str]] = {}
    for section in Parser.parse(path).sections:
        if section.header.lower() == "general":
            continue
        data = {k.lower(): v for k, v in section.flatten(duplicate_key_as_list=False, with_comments=False).items()}
        found = kind_of({**data, "_header": section.header})
        if found is None:
            continue
        kind, cls = found
        known = {n.lower() for n in cls.model_fields} | {
            f.alias.lower() for f in cls.model_fields.values() if f.alias} | {"_header", "datablock", "comments"}
        unknown = tuple(sorted(k for k in data if k not in known))
        if unknown:
            block_id = str(data.get("id") or data.get("frictionid") or data.get("branchid") or data.get("name") or "?")
            found_by_keys.setdefault((kind, unknown), []).append(block_id)
    for (kind, keys), ids in found_by_keys.items():
        shown = ", ".join(repr(i) for i in ids[:5]) + (f" and {len(ids) - 5} more" if len(ids) > 5 else "")
        ledger.warn(f"{what} file {path.name}: unknown keyword(s) {', '.join(keys)} read past in {kind} {shown}")


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
    raise TypeError(name)


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


def _parse_blocks(path: Path, ledger: Ledger, what: str,
                  kind_of: Callable[[dict], tuple[str, Any] | None]) -> FileBlocks:
    from hydrolib.core.dflowfm.ini.parser import Parser

    doc = Parser.parse(path)
    out = FileBlocks(path)
    for section in doc.sections:
        data = {k.lower(): v for k, v in section.flatten(duplicate_key_as_list=False, with_comments=False).items()}
        if section.header.lower() == "general":
            continue
        found = kind_of({**data, "_header": section.header})
        block_id = str(data.get("id") or data.get("frictionid") or data.get("branchid") or data.get("name") or "?")
        if found is None:
            out.failed.append((section.header, block_id, f"[{section.header}] block of type "
                                                        f"{data.get('type')!r} is not known to hydrolib-core"))
            continue
        kind, cls = found
        for block_type, test, drop, why in REPAIRS:
            if kind == block_type and test(data):
                data = {k: v for k, v in data.items() if k not in drop}
                ledger.warn(f"{what} file {path.name}, {kind} {block_id!r}: {why}")
        unknown: list[tuple[str, list[str]]] = []
        try:
            with _recording_unknown_keywords(unknown), _relative_to(_BASE.get(path.parent)):
                out.objects.append(cls.model_validate(data))
        except ValidationError as exc:
            out.failed.append((kind, block_id, _first_error(exc)))
            continue
        for _, keys in unknown:
            ledger.warn(f"{what} file {path.name}, {kind} {block_id!r}: unknown keyword(s) read past: "
                        f"{', '.join(keys)}")
    return out


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
