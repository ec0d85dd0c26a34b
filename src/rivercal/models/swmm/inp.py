"""Reading and editing an EPA SWMM 5 input file (``.inp``) by section, object and column.

An ``.inp`` file is a sequence of ``[SECTION]`` blocks of whitespace-separated rows; ``;`` starts a
comment (SWMM 5 user's manual, appendix D). :class:`InpFile` keeps the text of every row, so a file
written back differs from the original only in the values that were set, and knows just enough of the
format to read the objects a calibration needs: node inverts, conduits with their roughness, weirs
with their crest heights, orifices, ``[TAGS]`` groups and the ``[OPTIONS]`` dates and steps.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

__all__ = ["InpFile", "InpRow", "seconds", "swmm_date", "swmm_step"]

#: Sections whose rows start with a node id and have its invert elevation in the second column.
NODE_SECTIONS = ("JUNCTIONS", "OUTFALLS", "STORAGE", "DIVIDERS")


@dataclass
class InpRow:
    """One data row: its tokens and the comment that followed them (kept when the row is written)."""

    tokens: list[str]
    comment: str = ""

    def text(self) -> str:
        """The row as a line of the file."""
        body = " ".join(_quote(t) for t in self.tokens)
        return f"{body} {self.comment}".rstrip() if self.comment else body


class InpFile:
    """An ``.inp`` file as ordered sections (module docstring).

    Rows are parsed when a section is first read; sections that were never edited are written back
    exactly as they were read (a long ``[TIMESERIES]`` costs nothing per run).

    Parameters
    ----------
    text
        The file's contents.
    source
        Where it came from, for messages.

    Raises
    ------
    ValueError
        For rows before the first section header, naming the line.
    """

    def __init__(self, text: str, source: str = "<inp>"):
        self.source = source
        self._raw: dict[str, list[str]] = {}
        self._first_line: dict[str, int] = {}
        self._parsed: dict[str, list[InpRow | str]] = {}
        current: list[str] | None = None
        for no, line in enumerate(text.splitlines(), 1):
            stripped = line.strip()
            header = re.fullmatch(r"\[([A-Za-z_]+)\]", stripped)
            if header:
                name = header.group(1).upper()
                current = self._raw.setdefault(name, [])
                self._first_line.setdefault(name, no + 1)
                continue
            if current is None:
                if stripped and not stripped.startswith(";"):
                    raise ValueError(f"{source}: line {no}: data before the first [SECTION] header")
                continue
            current.append(line)
        while any(lines and not lines[-1].strip() for lines in self._raw.values()):
            for lines in self._raw.values():
                while lines and not lines[-1].strip():
                    lines.pop()

    @classmethod
    def read(cls, path: str | Path) -> InpFile:
        """Read a file (UTF-8, falling back to Latin-1 as SWMM files often are)."""
        raw = Path(path).read_bytes()
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            text = raw.decode("latin-1")
        return cls(text, source=str(path))

    # -- reading ------------------------------------------------------------------------------------

    def _section(self, section: str) -> list[InpRow | str]:
        name = section.upper()
        if name not in self._parsed:
            out: list[InpRow | str] = []
            for k, line in enumerate(self._raw.get(name, [])):
                stripped = line.strip()
                if not stripped or stripped.startswith(";"):
                    out.append(line)
                    continue
                body, sep, comment = line.partition(";")
                try:
                    tokens = shlex.split(body, posix=True) if '"' in body or "'" in body else body.split()
                except ValueError as exc:
                    raise ValueError(f"{self.source}: line {self._first_line[name] + k}: {exc}") from None
                out.append(InpRow(tokens, sep + comment if sep else ""))
            self._parsed[name] = out
        return self._parsed[name]

    def has(self, section: str) -> bool:
        """Whether the file has this section."""
        return section.upper() in self._raw

    def sections(self) -> list[str]:
        """The file's sections in the order they come (upper case): SWMM numbers its objects in that order."""
        return list(self._raw)

    def raw_lines(self, section: str) -> list[str]:
        """The lines of a section as read (comments and blank lines included; empty when absent)."""
        return list(self._raw.get(section.upper(), []))

    def rows(self, section: str) -> list[InpRow]:
        """The data rows of a section (empty when the file has none)."""
        return [r for r in self._section(section) if isinstance(r, InpRow)]

    def table(self, section: str) -> dict[str, InpRow]:
        """Rows of a section by their first token (the object id)."""
        return {r.tokens[0]: r for r in self.rows(section) if r.tokens}

    def option(self, key: str) -> str | None:
        """The value of an ``[OPTIONS]`` key (None when absent)."""
        for r in self.rows("OPTIONS"):
            if r.tokens and r.tokens[0].upper() == key.upper():
                return " ".join(r.tokens[1:])
        return None

    def node_inverts(self) -> dict[str, float]:
        """Invert elevation of every node, m."""
        out = {}
        for section in NODE_SECTIONS:
            for r in self.rows(section):
                out[r.tokens[0]] = float(r.tokens[1])
        return out

    def tags(self, kind: str = "Link") -> dict[str, list[str]]:
        """Object ids by tag for one kind of object (``Link``, ``Node``, ``Subcatch``)."""
        out: dict[str, list[str]] = {}
        for r in self.rows("TAGS"):
            if len(r.tokens) >= 3 and r.tokens[0].lower() == kind.lower():
                out.setdefault(r.tokens[2], []).append(r.tokens[1])
        return out

    # -- editing ------------------------------------------------------------------------------------

    def set_option(self, key: str, value: str) -> None:
        """Set an ``[OPTIONS]`` key (added when absent)."""
        rows = self._section("OPTIONS")
        self._raw.setdefault("OPTIONS", [])
        for r in rows:
            if isinstance(r, InpRow) and r.tokens and r.tokens[0].upper() == key.upper():
                r.tokens = [r.tokens[0], value]
                return
        rows.append(InpRow([key, value]))

    def set_value(self, section: str, ident: str, column: int, value: str) -> None:
        """Set column ``column`` (0 = the id) of object ``ident`` in ``section``.

        Raises
        ------
        KeyError
            When the section has no such object or the row is too short.
        """
        row = self.table(section).get(ident)
        if row is None:
            raise KeyError(f"{self.source}: [{section.upper()}] has no object {ident!r}")
        if column >= len(row.tokens):
            raise KeyError(f"{self.source}: [{section.upper()}] {ident}: no column {column}")
        row.tokens[column] = value

    def replace_section(self, section: str, lines: list[str]) -> None:
        """Replace a whole section by these lines, written as they are (added at the end when absent)."""
        name = section.upper()
        self._raw.setdefault(name, [])
        self._parsed[name] = [str(line) for line in lines]

    def copy(self) -> InpFile:
        """An independent copy (edits of one do not reach the other)."""
        other = InpFile.__new__(InpFile)
        other.source = self.source
        other._raw = self._raw
        other._first_line = self._first_line
        other._parsed = {k: [InpRow(list(r.tokens), r.comment) if isinstance(r, InpRow) else r for r in v]
                         for k, v in self._parsed.items()}
        return other

    def text(self) -> str:
        """The file's contents."""
        out: list[str] = []
        for name, raw in self._raw.items():
            out.append(f"[{name}]")
            if name in self._parsed:
                out.extend(r.text() if isinstance(r, InpRow) else r for r in self._parsed[name])
            else:
                out.extend(raw)
            out.append("")
        return "\n".join(out) + "\n"


def seconds(text: str | None, default: float) -> float:
    """A step of an ``[OPTIONS]`` value, ``HH:MM:SS`` or seconds, in s (``default`` when absent)."""
    if text is None:
        return default
    if ":" in text:
        parts = [float(p) for p in text.split(":")]
        while len(parts) < 3:
            parts.append(0.0)
        return parts[0] * 3600 + parts[1] * 60 + parts[2]
    return float(text)


def swmm_date(t: pd.Timestamp) -> tuple[str, str]:
    """A time as SWMM's ``MM/DD/YYYY`` and ``HH:MM:SS`` (SWMM has no time zones: UTC clock time)."""
    return t.strftime("%m/%d/%Y"), t.strftime("%H:%M:%S")


def swmm_step(seconds: float) -> str:
    """A step as SWMM's ``HH:MM:SS`` (whole seconds)."""
    s = round(seconds)
    return f"{s // 3600:02d}:{s % 3600 // 60:02d}:{s % 60:02d}"


def _quote(token: str) -> str:
    return f'"{token}"' if (not token or any(c.isspace() for c in token)) else token
