"""Input templates of a black box: any text file with ``{{NAME}}`` or ``{{NAME:FORMAT}}`` placeholders.

``NAME`` is a quantity of the black box, rendered with ``FORMAT`` (a Python format spec such as ``.3f``;
default the quantity's ``format``). A quantity may carry a linear map, ``{{NAME*A+B:FORMAT}}`` writes
A·value + B (``{{FR*0.0625}}``: a roughness factor times this conduit's Manning n; ``{{Wd+0.87}}``: a
crest shift on this weir's crest height), so one quantity can set many numbers of a file.

Built-in placeholders: ``start``, ``end``, ``run_start`` (times; ``FORMAT`` is a ``strftime`` format,
default ISO 8601; ``run_start`` is ``spinup`` hours before ``start`` for a cold start), ``run_dir`` (the
run folder), ``dt`` and ``output_interval`` (s), ``hot`` and ``cold`` (``1``/``0``; with a ``FORMAT``
the text after the colon when true and nothing otherwise, e.g. ``{{hot:USE HOTSTART "restart.hsf"}}``).

Text outside ``{{…}}`` is copied as it is, so a template can hold braces of its own format. The command
line (argv) takes the same names in single braces, ``{run_dir}``; its items are passed to the program
as they are, never through a shell.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any

import pandas as pd

__all__ = ["PLACEHOLDER", "Template", "render_argv"]

#: ``{{ name }}`` or ``{{ name : format }}``; the name is a quantity or built-in name.
_NUMBER = r"[0-9]+(?:\.[0-9]*)?(?:[eE][+\-]?[0-9]+)?"
PLACEHOLDER = re.compile(r"\{\{\s*([A-Za-z_][A-Za-z0-9_.\-]*?)\s*(?:\*\s*(" + _NUMBER + r"))?\s*(?:([+\-])\s*("
                         + _NUMBER + r"))?\s*(?::([^{}]*?))?\s*\}\}")
_TIMES = ("start", "end", "run_start")


class Template:
    """A parsed template: text pieces and placeholders, rendered per run.

    Parameters
    ----------
    text
        The template's contents.
    source
        Where it came from, for messages.
    """

    def __init__(self, text: str, source: str = "<template>"):
        self.source = source
        self.pieces: list[str | tuple[str, str | None, float, float]] = []
        pos = 0
        for m in PLACEHOLDER.finditer(text):
            self.pieces.append(text[pos:m.start()])
            scale = float(m.group(2)) if m.group(2) else 1.0
            shift = (float(m.group(4)) * (-1.0 if m.group(3) == "-" else 1.0)) if m.group(4) else 0.0
            self.pieces.append((m.group(1), m.group(5), scale, shift))
            pos = m.end()
        self.pieces.append(text[pos:])

    @property
    def names(self) -> set[str]:
        """Names of the placeholders used."""
        return {p[0] for p in self.pieces if isinstance(p, tuple)}

    def check(self, quantities: Iterable[str], builtins: Iterable[str]) -> None:
        """ValueError naming the first placeholder that is neither a quantity nor a built-in (or maps a built-in)."""
        quantities, builtins = set(quantities), set(builtins)
        for p in self.pieces:
            if not isinstance(p, tuple):
                continue
            if p[0] in builtins and (p[2] != 1.0 or p[3] != 0.0):
                raise ValueError(f"{self.source}: the built-in placeholder {p[0]!r} takes no *A+B")
            if p[0] not in quantities | builtins:
                raise ValueError(f"{self.source}: placeholder {{{{{p[0]}}}}} is neither a quantity of the model "
                                 f"({', '.join(sorted(quantities))}) nor a built-in ({', '.join(sorted(builtins))})")

    def render(self, values: Mapping[str, Any], formats: Mapping[str, str]) -> str:
        """The text with every placeholder replaced (module docstring)."""
        out = []
        for p in self.pieces:
            if isinstance(p, str):
                out.append(p)
            else:
                name, spec, scale, shift = p
                value = values[name]
                if scale != 1.0 or shift != 0.0:
                    value = scale * float(value) + shift
                out.append(_format(name, value, spec if spec is not None else formats.get(name)))
        return "".join(out)


def render_argv(argv: Iterable[str], values: Mapping[str, Any], formats: Mapping[str, str]) -> list[str]:
    """The command's items with ``{name}`` / ``{name:format}`` replaced; everything else kept literally.

    Raises
    ------
    KeyError
        For an unknown name in braces.
    """
    pattern = re.compile(r"\{([A-Za-z_][A-Za-z0-9_.\-]*)(?::([^{}]*))?\}")

    def sub(m: re.Match) -> str:
        name = m.group(1)
        if name not in values:
            raise KeyError(f"command item {m.string!r}: {{{name}}} is not a quantity or built-in placeholder")
        return _format(name, values[name], m.group(2) if m.group(2) is not None else formats.get(name))

    return [pattern.sub(sub, item) for item in argv]


#: A width or precision of four digits or more: a number rendered as megabytes of text.
_WIDE = re.compile(r"[0-9]{4,}")


def _format(name: str, value: Any, spec: str | None) -> str:
    if isinstance(value, bool):
        return (spec if value else "") if spec is not None else str(int(value))
    if isinstance(value, pd.Timestamp):
        return value.strftime(spec) if spec else value.isoformat()
    if isinstance(value, float | int) and not isinstance(value, bool):
        if spec and _WIDE.search(spec):
            raise ValueError(f"{name}: the format {spec[:40]!r} asks for a width or precision above 999")
        return format(value, spec) if spec else repr(float(value)) if isinstance(value, float) else str(value)
    return str(value)
