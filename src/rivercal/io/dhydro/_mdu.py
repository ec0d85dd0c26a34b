"""The MDU of a D-Flow FM model: read with hydrolib-core, its keys and numbers checked.

hydrolib-core's ``FMModel`` is built again and again, each round leaving out the file keys (and unknown
sections) it rejects, which are then read block by block (:mod:`._files`); keywords unknown to its schema
and keys given twice are warnings with their lines, a number the import uses that is not usable an error.
Also the helpers shared with the reading of the referenced files: a key given twice, lines that are not INI.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from rivercal.errors import CaseError
from rivercal.io.dhydro._ledger import Ledger
from rivercal.io.dhydro._source import IniIndex, RawSection, Sources, is_file, reading

__all__ = ["FILE_KEYS", "mdu_line"]

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
