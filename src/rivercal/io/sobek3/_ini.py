"""The INI files of a SOBEK 3 model, read line by line so that every value keeps its file and line.

SOBEK 3 writes its model files (``Flow1D.md1d``, ``NetworkDefinition.ini``, the cross-section, roughness,
boundary and structure files) as INI text: ``[Section]`` headers, ``key = value`` lines with a ``#`` comment
that may follow the value without a space, and, in the ``.bc`` files, data rows after the keys. hydrolib-core's
INI parser reads the same syntax but keeps no line numbers, and an error must name the file, the line and the
key, so this is a small parser of its own. Keys are matched without regard to case, as SOBEK 3 does.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from rivercal.errors import CaseError

__all__ = ["Item", "Section", "read_ini"]

_MISSING = object()
_HEADER = re.compile(r"^\s*\[\s*([^\]]*?)\s*\]\s*(?:[#;].*)?$")


@dataclass(frozen=True)
class Item:
    """One ``key = value`` line.

    Attributes
    ----------
    key
        The key as written.
    value
        The value without its comment, stripped.
    line
        Line number (1 = the first line of the file).
    """

    key: str
    value: str
    line: int


@dataclass
class Section:
    """One ``[name]`` block of a file: its items and its data rows (``.bc`` files).

    Attributes
    ----------
    name
        The section name as written (``Branch``, ``Definition``, ...).
    line
        Line number of the header.
    file
        The file it was read from.
    items
        The ``key = value`` lines, in order.
    rows
        Lines without ``=`` (data rows), with their line numbers.
    """

    name: str
    line: int
    file: Path
    items: list[Item] = field(default_factory=list)
    rows: list[tuple[int, str]] = field(default_factory=list)

    @property
    def kind(self) -> str:
        """The section name in lower case."""
        return self.name.lower()

    def where(self, item: Item | None = None) -> str:
        """``file:line`` of an item (or of the header)."""
        return f"{self.file}:{item.line if item is not None else self.line}"

    def error(self, key: str | None, message: str, item: Item | None = None) -> CaseError:
        """A :class:`CaseError` that names the file, the line and the key (the first line of the key)."""
        if item is None and key is not None:
            found = self.all(key)
            item = found[0] if found else None
        return CaseError(message, file=self.where(item), field=key)

    def error_at(self, line: int, message: str, key: str | None = None) -> CaseError:
        """A :class:`CaseError` at a line of this section (a data row)."""
        return CaseError(message, file=f"{self.file}:{line}", field=key)

    def all(self, key: str) -> list[Item]:
        """Every item with this key (keys compared without case)."""
        low = key.lower()
        return [it for it in self.items if it.key.lower() == low]

    def find(self, *keys: str) -> Item | None:
        """The item of the first of ``keys`` present; an error when one is given twice."""
        for key in keys:
            found = self.all(key)
            if len(found) > 1:
                raise CaseError(f"{key!r} is given {len(found)} times in this [{self.name}] section (lines "
                                f"{', '.join(str(i.line) for i in found)}); give it once",
                                file=self.where(found[1]), field=key)
            if found:
                return found[0]
        return None

    def has(self, *keys: str) -> bool:
        """Whether one of ``keys`` is present with a value."""
        item = self.find(*keys)
        return item is not None and item.value != ""

    def text(self, *keys: str, default=_MISSING) -> str:
        """The value of the first of ``keys`` present, as text."""
        item = self.find(*keys)
        if item is None or item.value == "":
            if default is _MISSING:
                raise self.error(keys[0], f"[{self.name}] has no {keys[0]!r}" + (
                    f" (nor {', '.join(repr(k) for k in keys[1:])})" if len(keys) > 1 else ""))
            return default
        return item.value

    def number(self, *keys: str, default=_MISSING) -> float:
        """The value as a number (Fortran exponents such as ``1.5d-3`` accepted)."""
        item = self.find(*keys)
        if item is None or item.value == "":
            if default is _MISSING:
                raise self.error(keys[0], f"[{self.name}] has no {keys[0]!r}")
            return default
        return _to_number(item.value, self, item)

    def integer(self, *keys: str, default=_MISSING) -> int:
        """The value as a whole number."""
        value = self.number(*keys, default=default)
        if value is default:
            return value
        if value != int(value):
            item = self.find(*keys)
            raise self.error(item.key, f"{item.value!r} is not a whole number", item)
        return int(value)

    def numbers(self, *keys: str, count: int | None = None, default=_MISSING) -> list[float]:
        """The value as a list of numbers (separated by blanks, ``;`` or ``,``), ``count`` of them if given."""
        item = self.find(*keys)
        if item is None or item.value == "":
            if default is _MISSING:
                raise self.error(keys[0], f"[{self.name}] has no {keys[0]!r}")
            return default
        values = [_to_number(v, self, item) for v in re.split(r"[\s;,]+", item.value.strip()) if v]
        if count is not None and len(values) != count:
            raise self.error(item.key, f"{len(values)} value(s) given but {count} expected", item)
        return values

    def words(self, *keys: str, default=_MISSING) -> list[str]:
        """The value as a list of words separated by ``;`` (or blanks when there is no ``;``)."""
        value = self.text(*keys, default=default)
        if value is default:
            return value
        parts = value.split(";") if ";" in value else value.split()
        return [p.strip() for p in parts if p.strip()]

    def flag(self, *keys: str, default=_MISSING) -> bool:
        """The value as a truth value (``1``/``0``, ``true``/``false``, ``-1`` for true as SOBEK writes it)."""
        item = self.find(*keys)
        if item is None or item.value == "":
            if default is _MISSING:
                raise self.error(keys[0], f"[{self.name}] has no {keys[0]!r}")
            return default
        low = item.value.strip().lower()
        if low in ("1", "-1", "true", "yes", "on", "t"):
            return True
        if low in ("0", "false", "no", "off", "f"):
            return False
        raise self.error(item.key, f"{item.value!r} is neither true nor false (1 or 0)", item)


def _to_number(text: str, section: Section, item: Item) -> float:
    try:
        value = float(text.replace("d", "e").replace("D", "e"))
    except ValueError:
        raise section.error(item.key, f"{text!r} is not a number", item) from None
    if value != value or value in (float("inf"), float("-inf")):
        raise section.error(item.key, f"{text!r} is not a finite number", item)
    return value


def _strip_comment(value: str) -> str:
    """The value of a ``key = value`` line without its comment.

    A value may be delimited by ``#...#`` (one with blanks, as D-Flow FM writes ids): ``#with blanks# rest``. A
    ``#`` followed by a blank, or one without a closing ``#``, begins a comment instead, so that an empty value
    followed by a comment (``file = # Name and location of the file``, as DeltaShell writes it) stays empty.
    """
    value = value.strip()
    if value.startswith("#"):
        end = value.find("#", 1)
        if end > 1 and not value[1].isspace():
            return value[1:end].strip()
        return ""
    cut = value.find("#")
    return (value[:cut] if cut >= 0 else value).strip()


def read_ini(path: Path) -> list[Section]:
    """The sections of an INI file of a SOBEK 3 model.

    Raises
    ------
    CaseError
        When the file cannot be read, is not text, or has a line outside every section (the message names the
        file and the line).
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise CaseError(f"cannot read the file: {exc.strerror or exc}", file=str(path)) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    if "\x00" in text:
        raise CaseError("this is not a text file (it holds NUL bytes)", file=str(path))
    sections: list[Section] = []
    current: Section | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped[0] in "#;*":
            continue
        header = _HEADER.match(line)
        if header:
            current = Section(header.group(1), number, path)
            sections.append(current)
            continue
        if current is None:
            raise CaseError(f"line {number} lies before the first [section] header: {stripped[:60]!r}",
                            file=f"{path}:{number}")
        if "=" in stripped:
            key, value = stripped.split("=", 1)
            if not key.strip() or re.search(r"\s", key.strip()):
                raise CaseError(f"{stripped[:60]!r} is neither a 'key = value' line nor a data row",
                                file=f"{path}:{number}")
            current.items.append(Item(key.strip(), _strip_comment(value), number))
        else:
            current.rows.append((number, _strip_comment(stripped)))
    return sections
