"""Where the values of a D-Flow FM model come from (file, line, key), and which files an import may read.

hydrolib-core parses a model into objects that no longer know their file or line. An import that
reports "a NaN somewhere in the structures" helps nobody, so every INI file the import reads is
also indexed here line by line (:class:`IniIndex`): its sections, the line of every key, its data
rows, and the lines that hydrolib-core's parser skips without a word (text that is neither a
section, a comment, ``key = value`` nor a data row). Each object hydrolib-core returns is tied to
its section (:meth:`Sources.locate`), so that a message can say ``structures.ini, line 42, weir
'W1', crestLevel``.

The same place decides which files are read at all (:func:`reading`): only files inside the
model's folder (the MDU's folder and its subfolders). A file named by an absolute path or by
``..`` that leaves that folder is not opened; the import refuses it by name. A model folder is
what a modeller hands over; a reference out of it points at a file on somebody else's disk (an
absolute Windows path left by a tool) or at a file the user did not choose to import,
and its content would end up in the case. Reading it and saying so would still put an unchosen
file into the case, and the user gives the exchange files of a coupled run by name anyway
(``--realtime``). A symbolic link inside the folder is followed: placing it there is the user's
own choice.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["FileAccess", "IniIndex", "RawKey", "RawSection", "Sources", "is_file", "reading"]

_LOCK = threading.RLock()  # reentrant: a block read inside a file read takes it again
#: UTF-8 with or without a byte order mark (Windows tools write one; hydrolib-core reads past it), else Latin-1.
_ENCODINGS = ("utf-8-sig", "latin-1")
#: Comment lines of D-Flow FM's INI files: ``#``, and ``*`` as D-Flow FM's GUI writes under an MDU's header.
_COMMENT = ("#", "*")


@dataclass(frozen=True)
class RawKey:
    """One ``key = value`` line: its 1-based line number, the key as written and the value (None when empty)."""

    line: int
    key: str
    value: str | None


@dataclass
class RawSection:
    """One ``[header]`` block of an INI file as written.

    Attributes
    ----------
    header
        The header as written (``Structure``).
    line
        1-based line of the header.
    keys
        ``key = value`` lines by lower-case key, in file order (a key given twice has two entries).
    rows
        Data rows (``.bc`` files): (line, text).
    """

    header: str
    line: int
    keys: dict[str, list[RawKey]] = field(default_factory=dict)
    rows: list[tuple[int, str]] = field(default_factory=list)

    def first(self, key: str) -> RawKey | None:
        """The first line of a key (D-Flow FM reads the first of a key given twice), or None."""
        found = self.keys.get(key.lower())
        return found[0] if found else None

    def value(self, key: str) -> str | None:
        """The value of the first line of a key, without ``#...#`` delimiters, or None."""
        raw = self.first(key)
        if raw is None or raw.value is None:
            return None
        text = raw.value.strip()
        if len(text) >= 2 and text.startswith("#") and text.endswith("#"):
            text = text[1:-1].strip()
        return text

    @property
    def block_id(self) -> str:
        """The id by which the block is known (``id``, ``name``, ``frictionId``, ``branchId``, ``nodeId``, ...)."""
        for key in ("id", "name", "frictionid", "branchid", "nodeid", "quantity"):
            value = self.value(key)
            if value:
                return value
        return ""


@dataclass
class IniIndex:
    """An INI file of D-Flow FM, indexed by line.

    Attributes
    ----------
    path
        The file.
    sections
        Its ``[header]`` blocks in file order.
    stray
        Lines that are not INI (neither blank, comment, header, ``key = value`` nor, in a file with data
        blocks, a data row): (line, text). hydrolib-core's parser skips them without a word.
    """

    path: Path
    sections: list[RawSection]
    stray: list[tuple[int, str]]

    @classmethod
    def read(cls, path: Path, *, datablocks: bool = False) -> IniIndex:
        """Index a file the way hydrolib-core's INI parser reads it.

        Raises
        ------
        OSError
            When the file cannot be read.
        """
        text = read_text(path)
        sections: list[RawSection] = []
        stray: list[tuple[int, str]] = []
        current: RawSection | None = None
        in_rows = False
        for number, line in enumerate(text.splitlines(), start=1):
            stripped = line.strip()
            if not stripped:
                continue
            if stripped.startswith("[") and stripped.endswith("]"):
                current = RawSection(stripped[1:-1].strip(), number)
                sections.append(current)
                in_rows = False
                continue
            if stripped.startswith(_COMMENT):
                continue
            if current is None:
                stray.append((number, stripped))
                continue
            if in_rows:
                current.rows.append((number, stripped))
                continue
            if "=" in stripped:
                key, _, value = stripped.partition("=")
                value = _strip_comment(value.strip())
                current.keys.setdefault(key.strip().lower(), []).append(RawKey(number, key.strip(), value or None))
                continue
            if datablocks:
                current.rows.append((number, stripped))
                in_rows = True
                continue
            stray.append((number, stripped))
        return cls(Path(path), sections, stray)

    def of(self, header: str) -> list[RawSection]:
        """The sections with a header (case-insensitive), in file order."""
        return [s for s in self.sections if s.header.lower() == header.lower()]

    def duplicates(self) -> list[tuple[RawSection, list[RawKey]]]:
        """Keys given more than once in one section: (section, their lines)."""
        return [(s, lines) for s in self.sections for lines in s.keys.values() if len(lines) > 1]


def _strip_comment(value: str) -> str:
    """The value part of ``value # comment`` (a value may be delimited as ``#a value#``)."""
    if "#" not in value:
        return value
    if value.startswith("#"):
        parts = value.split("#")
        return "#".join(parts[:3]) if len(parts) >= 3 else ""  # ``key = # a comment`` has no value
    return value.split("#", 1)[0].strip()


def is_file(path: Path | str) -> bool:
    """Whether a path names a readable regular file (False for a name too long or a path the system refuses)."""
    try:
        return Path(path).is_file()
    except (OSError, ValueError):
        return False


def read_text(path: Path) -> str:
    """A file's text, UTF-8 or else Latin-1 (as hydrolib-core reads it).

    Raises
    ------
    OSError
        When the file cannot be read.
    """
    data = Path(path).read_bytes()
    for encoding in _ENCODINGS:
        try:
            return data.decode(encoding)
        except UnicodeDecodeError:
            continue
    return data.decode("latin-1", errors="replace")  # pragma: no cover - latin-1 decodes any byte


@dataclass(frozen=True)
class FileAccess:
    """A file hydrolib-core was asked to read.

    The path, the model class, and what happened (``read``, ``outside``, ``missing``, ``unreadable``) with the reason.
    """

    path: Path
    model: str
    status: str
    reason: str = ""


@dataclass
class Sources:
    """The files of one import: which may be read, their line indexes, and the section of each block object.

    Attributes
    ----------
    root
        The model folder (the MDU's folder); only files inside it are read.
    access
        Every file hydrolib-core was asked to read, in order.
    dropped
        MDU keys (section, key) whose files hydrolib-core could not take as a whole; the import reads
        those files block by block itself.
    forcing_failures
        Per ``.bc`` file read block by block: the blocks that failed, by name, and why.
    """

    root: Path
    access: list[FileAccess] = field(default_factory=list)
    dropped: set[tuple[str, str]] = field(default_factory=set)
    forcing_failures: dict[Path, dict[str, str]] = field(default_factory=dict)
    _index: dict[tuple[Path, bool], IniIndex] = field(default_factory=dict)
    _located: dict[int, tuple[Any, Path, RawSection]] = field(default_factory=dict)

    def inside(self, path: Path) -> bool:
        """Whether a path lies in the model folder (by its name: ``..`` resolved, symbolic links not)."""
        full = os.path.normpath(os.path.abspath(path))
        root = os.path.normpath(os.path.abspath(self.root))
        return full == root or full.startswith(root + os.sep)

    def rel(self, path: Path | str | None) -> str:
        """A path as a message shows it: relative to the model folder when inside it."""
        if path is None:
            return "?"
        full = Path(os.path.normpath(os.path.abspath(path)))
        try:
            return str(full.relative_to(os.path.normpath(os.path.abspath(self.root))))
        except ValueError:
            return str(path)

    def ini(self, path: Path, *, datablocks: bool = False) -> IniIndex:
        """The line index of an INI file (read once).

        Raises
        ------
        OSError
            When the file cannot be read.
        """
        key = (Path(os.path.normpath(os.path.abspath(path))), datablocks)
        if key not in self._index:
            self._index[key] = IniIndex.read(key[0], datablocks=datablocks)
        return self._index[key]

    def find_block(self, block_id: str, headers: tuple[str, ...] | None = None) -> str:
        """``file, line N`` of the first block read with this id, or "".

        ``headers`` (lower case) limits the search to blocks of those kinds: a sewer model names a lateral after
        its storage node, and the lateral's block is the one wanted.
        """
        for (path, _), index in self._index.items():
            for section in index.sections:
                header = section.header.lower()
                if header != "general" and (headers is None or header in headers) and section.block_id == block_id:
                    return f"{self.rel(path)}, line {section.line}"
        return ""

    def locate(self, obj: Any, path: Path, section: RawSection) -> None:
        """Tie a hydrolib-core block object to the section it was read from."""
        self._located[id(obj)] = (obj, path, section)

    def section_of(self, obj: Any) -> tuple[Path, RawSection] | None:
        """The file and section a block object was read from, or None."""
        found = self._located.get(id(obj))
        return (found[1], found[2]) if found is not None and found[0] is obj else None

    def where(self, obj: Any, key: str | None = None) -> str:
        """``file, line N`` of a block object (of its key when given and present), for a message."""
        found = self.section_of(obj)
        if found is None:
            return ""
        path, section = found
        raw = section.first(key) if key else None
        line = raw.line if raw is not None else section.line
        return f"{self.rel(path)}, line {line}"

    def key_of(self, obj: Any, field_name: str) -> str:
        """The key of a field as written in the block (its alias when the block does not have it)."""
        cls = type(obj)
        info = getattr(cls, "model_fields", {}).get(field_name)
        alias = (info.alias if info is not None and info.alias else field_name)
        found = self.section_of(obj)
        if found is not None:
            raw = found[1].first(alias) or found[1].first(field_name)
            if raw is not None:
                return raw.key
        return alias


@contextlib.contextmanager
def reading(sources: Sources, unknown: list[tuple[str, list[str]]]) -> Iterator[None]:
    """Within the block, hydrolib-core reads only files inside the model folder, and records instead of raising.

    - A file outside ``sources.root``, missing, or unreadable is not read: hydrolib-core gets a
      ``ValueError`` (so it keeps the file as unparsed or fails the object that names it) and
      ``sources.access`` says why.
    - A key given twice in a section of an INI file is taken once, its first value, as D-Flow FM's
      INI reader does (it looks a key up as the first child of that name: Deltares, delft3d,
      ``utils_lgpl/deltares_common/.../tree_structures.f90``, ``tree_get_node_by_name``).
    - Unknown keywords are recorded in ``unknown`` (section, keys) instead of failing the file.
    - MDU keys listed in ``sources.dropped`` are left out of the MDU's data.
    """
    from hydrolib.core.base.models import ParsableFileModel
    from hydrolib.core.dflowfm.ini import util
    from hydrolib.core.dflowfm.ini.models import INIModel
    from hydrolib.core.dflowfm.net.models import Network

    manager = util.UnknownKeywordErrorManager
    original_unknown = manager.raise_error_for_unknown_keywords
    original_load = ParsableFileModel.__dict__["_load"]
    original_network_attr = Network.__dict__["from_file"]
    original_network = original_network_attr.__func__

    def record(self, data, section_header, fields, excluded_fields):
        found = self._get_all_unknown_keywords(data, fields, excluded_fields)
        if found:
            header = getattr(section_header, "default", section_header)
            unknown.append((str(header), list(found)))

    def load(self, filepath):
        path = Path(filepath)
        name = type(self).__name__
        if not sources.inside(path):
            sources.access.append(FileAccess(path, name, "outside", "it lies outside the model folder "
                                             f"{sources.root}; the import reads no file outside it"))
            raise ValueError(f"{path}: outside the model folder, not read")
        if not is_file(path):
            sources.access.append(FileAccess(path, name, "missing", "the file does not exist"))
            raise ValueError(f"{path}: no such file")
        if isinstance(self, INIModel):
            try:
                index = sources.ini(path, datablocks=name == "ForcingModel")
            except OSError as exc:
                sources.access.append(FileAccess(path, name, "unreadable", f"cannot be read ({exc.strerror or exc})"))
                raise ValueError(f"{path}: unreadable") from None
        try:
            data = original_load(self, path)
        except (OSError, UnicodeError) as exc:
            sources.access.append(FileAccess(path, name, "unreadable", f"cannot be read ({exc})"))
            raise ValueError(f"{path}: unreadable") from None
        if isinstance(self, INIModel) and name != "ForcingModel":  # a .bc block repeats quantity/unit on purpose
            _first_of_duplicates(data, index)
        if name == "FMModel":
            for section, key in sources.dropped:
                if not key:
                    data.pop(section, None)
                    continue
                part = data.get(section)
                if isinstance(part, dict):
                    part.pop(key, None)
        sources.access.append(FileAccess(path, name, "read"))
        return data

    def network_from_file(cls, file_path, *args, **kwargs):
        problem = check_ugrid(Path(file_path))
        if problem:
            sources.access.append(FileAccess(Path(file_path), "NetworkModel", "unreadable",
                                             f"not a readable UGRID network ({problem})"))
            raise ValueError(f"{file_path}: not a readable network")
        try:
            return original_network(cls, file_path, *args, **kwargs)
        except Exception as exc:  # a damaged NetCDF file fails in netCDF4, xarray or meshkernel in many ways
            reason = " ".join(f"{type(exc).__name__}: {exc}".split())[:300]
            sources.access.append(FileAccess(Path(file_path), "NetworkModel", "unreadable",
                                             f"not a readable UGRID network ({reason})"))
            raise ValueError(f"{file_path}: not a readable network") from None

    with _LOCK:
        manager.raise_error_for_unknown_keywords = record
        type.__setattr__(ParsableFileModel, "_load", load)
        type.__setattr__(Network, "from_file", classmethod(network_from_file))
        try:
            yield
        finally:
            manager.raise_error_for_unknown_keywords = original_unknown
            type.__setattr__(ParsableFileModel, "_load", original_load)
            type.__setattr__(Network, "from_file", original_network_attr)


def check_ugrid(path: Path) -> str:
    """What makes a UGRID net file unusable before hydrolib-core hands its arrays to meshkernel, or "".

    meshkernel (C++) trusts the connectivity it is given; a damaged file with a node index out of range
    crashes the process. Every mesh topology's node coordinates must be finite numbers of one length, and
    every connectivity must index those nodes (after its ``start_index``, fill values aside).
    """
    import netCDF4

    try:
        with netCDF4.Dataset(path) as ds:
            ds.set_auto_mask(False)
            topologies = [v for v in ds.variables.values() if getattr(v, "cf_role", "") == "mesh_topology"]
            if not topologies:
                return "no mesh topology (cf_role = mesh_topology)"
            for topo in topologies:
                names = str(getattr(topo, "node_coordinates", "")).split()
                coords = [np.asarray(ds.variables[n][:], dtype=float).ravel() for n in names if n in ds.variables]
                if len(coords) < 2 or len(coords) != len(names):
                    return f"{topo.name}: node coordinates {names} missing"
                n = coords[0].size
                if any(c.size != n or not np.all(np.isfinite(c)) for c in coords):
                    return f"{topo.name}: node coordinates of unequal length or not finite"
                for attr in ("edge_node_connectivity", "face_node_connectivity"):
                    name = getattr(topo, attr, None)
                    if name is None:
                        continue
                    if name not in ds.variables:
                        return f"{topo.name}: {attr} {name} missing"
                    var = ds.variables[name]
                    values = np.asarray(var[:])
                    if values.dtype.kind not in "iu":
                        return f"{name}: node indices that are not integers"
                    fill = getattr(var, "_FillValue", None)
                    start = int(getattr(var, "start_index", 0))
                    used = values[values != fill] if fill is not None else values.ravel()
                    if used.size and (used.min() - start < 0 or used.max() - start >= n):
                        return f"{name}: node indices outside the {n} nodes"
    except (OSError, RuntimeError, ValueError, KeyError, IndexError, TypeError, AttributeError, OverflowError,
            MemoryError) as exc:
        return " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
    return ""


def _first_of_duplicates(data: dict, index: IniIndex) -> None:
    """In hydrolib-core's parsed data of an INI file, keep the first value of every key given twice."""
    from hydrolib.core.base.utils import to_key

    seen: dict[str, int] = {}
    for section in index.sections:
        header = to_key(section.header)
        position = seen.get(header, 0)
        seen[header] = position + 1
        dups = [lines for lines in section.keys.values() if len(lines) > 1]
        if not dups:
            continue
        part = data.get(header)
        if isinstance(part, list):
            part = part[position] if position < len(part) else None
        if not isinstance(part, dict):
            continue
        for lines in dups:
            key = to_key(lines[0].key)
            for holder in (part, part.get("comments")):
                if isinstance(holder, dict) and isinstance(holder.get(key), list):
                    holder[key] = holder[key][0]


def finite(value: Any) -> bool:
    """Whether a number is finite (True for what is not a number)."""
    return not isinstance(value, float) or math.isfinite(value)
