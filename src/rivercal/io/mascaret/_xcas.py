"""The Mascaret case file (``.xcas``): an XML tree whose every element knows its line, and typed reads of its values.

A ``.xcas`` file (the XML form of Mascaret's keyword file, written by FUDAA-Mascaret and the TELEMAC-Mascaret
test suite) holds ``<fichierCas><parametresCas>`` with one element per group of settings
(``parametresGeometrieReseau``, ``parametresTemporels``, ``parametresCalage``, ...). Values are element
texts: numbers, ``true``/``false``, space-separated lists (one value per reach, per zone, ...), and lists of
names as ``<string>`` children. Mascaret itself finds an element by its path below ``parametresCas``; the
reader here does the same, letting a path skip levels (``parametresCalage/coefLitMin`` finds
``parametresCalage/frottement/coefLitMin``), as Mascaret's own reader does.

Every bad value is a :class:`~rivercal.errors.CaseError` that names the file, the line and the element.
The file is parsed with defusedxml (no entity expansion, no external document is fetched).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from rivercal.errors import CaseError

__all__ = ["Element", "Xcas", "read_xcas"]


@dataclass
class Element:
    """One XML element: its tag, text, line (1-based) and children."""

    tag: str
    line: int
    text: str = ""
    children: list[Element] = field(default_factory=list)

    def child(self, tag: str) -> Element | None:
        """The first child with this tag, or None."""
        return next((c for c in self.children if c.tag == tag), None)

    def all(self, tag: str) -> list[Element]:
        """The children with this tag."""
        return [c for c in self.children if c.tag == tag]

    def descendants(self, tag: str) -> list[Element]:
        """Every element below this one with this tag, in document order."""
        out = []
        for c in self.children:
            if c.tag == tag:
                out.append(c)
            out.extend(c.descendants(tag))
        return out


class _Builder:
    """An ElementTree parser target that builds :class:`Element` trees with their line numbers."""

    def __init__(self) -> None:
        self.expat = None
        self.stack: list[Element] = []
        self.root: Element | None = None
        self.parts: list[list[str]] = []

    def start(self, tag: str, attrib: dict) -> None:
        line = int(self.expat.CurrentLineNumber) if self.expat is not None else 0
        element = Element(tag=tag, line=line)
        if self.stack:
            self.stack[-1].children.append(element)
        else:
            self.root = element
        self.stack.append(element)
        self.parts.append([])

    def data(self, text: str) -> None:
        if self.parts:
            self.parts[-1].append(text)

    def end(self, tag: str) -> None:
        element = self.stack.pop()
        element.text = "".join(self.parts.pop()).strip()

    def close(self) -> Element | None:
        return self.root


def read_xcas(path: Path | str) -> Xcas:
    """Parse a ``.xcas`` file.

    Raises
    ------
    CaseError
        When the file cannot be read or is not well-formed XML of a Mascaret case (``fichierCas`` /
        ``parametresCas``); the message names the file and the line.
    """
    from defusedxml.common import DefusedXmlException
    from defusedxml.ElementTree import DefusedXMLParser, ParseError

    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CaseError(f"cannot read the Mascaret case file: {exc.strerror or exc}", file=str(path)) from None
    builder = _Builder()
    parser = DefusedXMLParser(target=builder)
    builder.expat = parser.parser
    try:
        parser.feed(data)
        root = parser.close()
    except ParseError as exc:
        line = exc.position[0] if getattr(exc, "position", None) else None
        raise CaseError(f"not well-formed XML: {exc.msg if hasattr(exc, 'msg') else exc}", file=str(path),
                        field=f"line {line}" if line else None) from None
    except DefusedXmlException as exc:
        raise CaseError(f"the XML uses a construct that is refused for safety ({type(exc).__name__}: {exc})",
                        file=str(path)) from None
    if root is None or root.tag != "fichierCas":
        raise CaseError(f"not a Mascaret case file: the root element is <{root.tag if root else ''}>, expected "
                        "<fichierCas>", file=str(path), field=f"line {root.line}" if root else None)
    cas = root.child("parametresCas")
    if cas is None:
        raise CaseError("not a Mascaret case file: <fichierCas> has no <parametresCas>", file=str(path),
                        field=f"line {root.line}")
    return Xcas(path, cas)


class Xcas:
    """Typed access to the values of a ``.xcas`` file (see the module docstring).

    Parameters
    ----------
    path
        The file (for messages and to resolve the files it names).
    root
        Its ``<parametresCas>`` element.
    """

    def __init__(self, path: Path, root: Element):
        self.path = Path(path)
        self.root = root

    @property
    def folder(self) -> Path:
        """The folder of the case file (the files it names are relative to it)."""
        return self.path.parent

    # -- finding --------------------------------------------------------------------------------------

    def find(self, path: str, within: Element | None = None) -> Element | None:
        """The first element at ``path`` (``a/b/c``; each step may skip levels) below ``within`` or the root."""
        found = [within or self.root]
        for step in path.split("/"):
            nxt: list[Element] = []
            for e in found:
                direct = e.all(step)
                nxt.extend(direct if direct else e.descendants(step))
            if not nxt:
                return None
            found = nxt
        return found[0]

    def where(self, element: Element | None, path: str) -> str:
        """``line N, <path>`` for messages."""
        return f"line {element.line}, <{path}>" if element is not None else f"<{path}>"

    def error(self, element: Element | None, path: str, message: str) -> CaseError:
        """A :class:`CaseError` naming the file, the line and the element."""
        return CaseError(message, file=str(self.path), field=self.where(element, path))

    # -- values ---------------------------------------------------------------------------------------

    def text(self, path: str, default: str | None = None, *, within: Element | None = None) -> str:
        """The text of an element; ``default`` when it is absent (an error when no default is given)."""
        e = self.find(path, within)
        if e is None:
            if default is None:
                raise self.error(within, path, "the element is missing")
            return default
        return e.text

    def number(self, path: str, default: float | None = None, *, within: Element | None = None) -> float:
        """A finite number (Fortran ``1.5D+02`` is read too)."""
        e = self.find(path, within)
        if e is None or not e.text:
            if default is None:
                raise self.error(e or within, path, "the element is missing" if e is None else "no value")
            return default
        values = self._numbers(e, path)
        if len(values) != 1:
            raise self.error(e, path, f"expected one number, got {len(values)} ({e.text!r})")
        return values[0]

    def integer(self, path: str, default: int | None = None, *, within: Element | None = None) -> int:
        """A whole number."""
        value = self.number(path, None if default is None else float(default), within=within)
        if value != int(value):
            raise self.error(self.find(path, within), path, f"{value:g} is not a whole number")
        return int(value)

    def boolean(self, path: str, default: bool | None = None, *, within: Element | None = None) -> bool:
        """``true`` or ``false``."""
        e = self.find(path, within)
        if e is None or not e.text:
            if default is None:
                raise self.error(e or within, path, "the element is missing" if e is None else "no value")
            return default
        word = e.text.strip().strip(".").lower()
        if word in ("true", "vrai", "1", "t"):
            return True
        if word in ("false", "faux", "0", "f"):
            return False
        raise self.error(e, path, f"{e.text!r} is not true or false")

    def numbers(self, path: str, count: int | None = None, *, within: Element | None = None,
                default: list[float] | None = None) -> list[float]:
        """A space-separated list of finite numbers; with ``count``, exactly that many are required."""
        e = self.find(path, within)
        if e is None:
            if default is None:
                raise self.error(within, path, "the element is missing")
            return list(default)
        values = self._numbers(e, path) if e.text else []
        if count is not None and len(values) < count:
            raise self.error(e, path, f"expected {count} value(s), got {len(values)}")
        return values[:count] if count is not None else values

    def integers(self, path: str, count: int | None = None, *, within: Element | None = None,
                 default: list[int] | None = None) -> list[int]:
        """A space-separated list of whole numbers."""
        values = self.numbers(path, count, within=within, default=None if default is None else [float(v) for v in
                                                                                              default])
        bad = [v for v in values if v != int(v)]
        if bad:
            raise self.error(self.find(path, within), path, f"{bad[0]:g} is not a whole number")
        return [int(v) for v in values]

    def strings(self, path: str, *, within: Element | None = None) -> list[str]:
        """The texts of the ``<string>`` children of an element (an empty list when it is absent)."""
        e = self.find(path, within)
        if e is None:
            return []
        return [s.text for s in e.all("string")]

    def _numbers(self, e: Element, path: str) -> list[float]:
        out = []
        for word in e.text.replace(",", " ").split():
            try:
                value = float(word.replace("D", "e").replace("d", "e"))
            except ValueError:
                raise self.error(e, path, f"{word!r} is not a number") from None
            if not math.isfinite(value):
                raise self.error(e, path, f"{word!r} is not a finite number")
            out.append(value)
        return out
