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
  repaired with a warning (:data:`._files.REPAIRS`).
- **Values.** Every number of every block is screened (:func:`_screen`): a value that is not a
  finite number, a negative width, length or coefficient, a level beyond ±10 km or a negative
  chainage is an error naming the file, the line and the key. Errors never pass with
  ``--allow-partial``: the file has to be corrected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rivercal.errors import CaseError
from rivercal.io.dhydro._files import ExtBlocks, FileBlocks, _Reader
from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._mdu import _check_lines, _file_models, _load_mdu, _network
from rivercal.io.dhydro._source import Sources, is_file

__all__ = ["ExtBlocks", "FileBlocks", "LoadedModel", "load_fm_model"]


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
