"""The HTML page builder of rivercal's reports, on the Jinja2 templates of :mod:`rivercal.report.pages`.

One self-contained file per page: a short inline stylesheet, no JavaScript, no external assets, no
network access (the live dashboard extends the same templates). Figures are *linked* (relative paths to
PNG files next to the page), never embedded, so that a report folder can be moved or archived as a whole.
Every piece of text and every table cell is HTML-escaped; there is no way to inject markup through the API.

The API is five names:

- :class:`Page` — ``Page(title)``, ``.section(heading, *blocks)``, ``.render()``, ``.write(path)``;
- :func:`paragraph`, :func:`table`, :func:`figure`, :func:`bullets` — the blocks a section holds (a plain
  string given to ``section`` is a paragraph).

Examples
--------
>>> import pandas as pd
>>> page = Page("Twin experiments")
>>> _ = page.section("Summary", "Robustness 100 % <all>.", table(pd.DataFrame({"x": [1.5]}), "One row"))
>>> "Robustness 100 % &lt;all&gt;." in page.render()
True
"""

from __future__ import annotations

import datetime as _dt
import logging
import numbers
import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from markupsafe import Markup

from rivercal.report.pages import environment

__all__ = ["Block", "Page", "bullets", "figure", "paragraph", "table"]

log = logging.getLogger(__name__)

@dataclass(frozen=True)
class Block:
    """A piece of a section: a function of the page's folder (for relative links) to HTML markup.

    Build blocks with :func:`paragraph`, :func:`table`, :func:`figure` or :func:`bullets`; the markup
    they produce is escaped already.
    """

    render: Callable[[Path | None], str]


def _macro(name: str) -> Callable[..., str]:
    return getattr(environment().get_template("blocks.html").module, name)


def paragraph(text: str) -> Block:
    """A paragraph of plain text (escaped; blank lines do not split it)."""
    markup = _macro("paragraph")(str(text))
    return Block(lambda _base: markup)


def bullets(items: Iterable[str]) -> Block:
    """An unordered list of plain-text items (escaped)."""
    markup = _macro("bullets")([str(i) for i in items])
    return Block(lambda _base: markup)


def _cell(value: Any, float_format: str) -> tuple[str, bool]:
    """Text of a table cell and whether it is a number (right-aligned)."""
    if isinstance(value, bool | np.bool_):
        return ("yes" if value else "no"), False
    if value is None or (not isinstance(value, str) and np.ndim(value) == 0 and pd.isna(value)):
        return "–", False
    if isinstance(value, _dt.datetime):  # pandas Timestamps too
        return _time(value), False
    if isinstance(value, numbers.Integral):
        return str(int(value)), True
    if isinstance(value, numbers.Real):
        return format(float(value), float_format), True
    return str(value), False


def _time(value: _dt.datetime) -> str:
    """A time as a table shows it: in UTC when it has a zone, to the minute (seconds only when there are some)."""
    if value.tzinfo is not None:
        value = value.astimezone(_dt.UTC)
    return value.strftime("%Y-%m-%d %H:%M:%S" if value.second or value.microsecond else "%Y-%m-%d %H:%M")


def _label(value: Any) -> str:
    return " / ".join(map(str, value)) if isinstance(value, tuple) else str(value)


def table(df: pd.DataFrame, caption: str = "", *, index: bool = True, float_format: str = ".4g") -> Block:
    """A table of a pandas DataFrame.

    Parameters
    ----------
    df
        The data; column and index labels become headers (tuples of a MultiIndex joined by " / ").
    caption
        Shown above the table (plain text).
    index
        Whether to show the index as the first column.
    float_format
        Format spec for floats (``format(value, float_format)``); NaN and None show as "–", booleans as
        yes/no, integers as they are, times as ``YYYY-MM-DD HH:MM`` (in UTC when they have a zone: state
        the zone in the caption or the page).

    Raises
    ------
    TypeError
        When ``df`` is not a DataFrame.
    """
    if not isinstance(df, pd.DataFrame):
        raise TypeError(f"table() needs a pandas DataFrame, got {type(df).__name__}")
    head = [(_label(df.index.name) if df.index.name is not None else "")] if index else []
    head += [_label(c) for c in df.columns]
    rows = []
    for label, row in zip(df.index, df.itertuples(index=False, name=None), strict=True):
        cells = [("th", _label(label))] if index else []
        for value in row:
            text, numeric = _cell(value, float_format)
            cells.append(("num" if numeric else "td", text))
        rows.append(cells)
    markup = _macro("table")(head, rows, caption)
    return Block(lambda _base: markup)


def _href(path: Path, base: Path | None) -> str:
    """The URL of ``path`` from the page's folder ``base``: relative, with forward slashes."""
    rel = os.path.relpath(path, base) if base is not None and path.is_absolute() else str(path)
    return Path(rel).as_posix()


def figure(path: str | Path, caption: str, *, alt: str | None = None) -> Block:
    """A figure: an ``<img>`` that links ``path`` relative to the page, with a caption.

    Parameters
    ----------
    path
        The image file. An absolute path is linked relative to the folder the page is written to. A
        relative path is looked up first in the page's folder (``figure("cost.png", ...)`` for a page
        written next to it) and then in the working directory of the call (``figure(out / "cost.png",
        ...)`` with a relative ``out``); the link is made relative to the page either way.
    caption
        Plain-text caption below the image.
    alt
        Alternative text (default: the caption).

    Notes
    -----
    When the file is found in neither place when the page is rendered, the figure shows a visible
    "missing figure" note instead of a broken image, and a warning is logged.
    """
    path = Path(path)
    from_cwd = path if path.is_absolute() else Path.cwd() / path

    def render(base: Path | None) -> str:
        if path.is_absolute() or base is None:
            target, href = from_cwd, _href(from_cwd, base)
        elif (base / path).exists():
            target, href = base / path, path.as_posix()
        else:
            target, href = from_cwd, _href(from_cwd, base)
        if not target.exists():
            log.warning("figure %s does not exist; the page notes it as missing", path)
            return _macro("missing_figure")(path.as_posix(), caption)
        return _macro("figure")(href, caption, alt or caption)

    return Block(render)


def _anchor(heading: str, taken: set[str]) -> str:
    slug = re.sub(r"[^a-z0-9]+", "-", heading.lower()).strip("-") or "section"
    anchor, n = slug, 2
    while anchor in taken:
        anchor, n = f"{slug}-{n}", n + 1
    taken.add(anchor)
    return anchor


class Page:
    """An HTML page: a title, optional intro blocks, and sections with a generated table of contents.

    Parameters
    ----------
    title
        The page title (plain text; shown as ``<h1>`` and in the browser tab).

    Examples
    --------
    >>> page = Page("Report").section("Numbers", paragraph("a < b"))
    >>> '<h2 id="numbers">Numbers</h2>' in page.render()
    True
    """

    def __init__(self, title: str):
        if not str(title).strip():
            raise ValueError("a page needs a non-empty title")
        self.title = str(title)
        self._intro: list[Block] = []
        self._sections: list[tuple[str, str, list[Block]]] = []
        self._anchors: set[str] = set()

    @staticmethod
    def _blocks(blocks: Iterable[Block | str]) -> list[Block]:
        out = []
        for b in blocks:
            if isinstance(b, str):
                out.append(paragraph(b))
            elif isinstance(b, Block):
                out.append(b)
            else:
                raise TypeError(f"a section holds blocks or strings, got {type(b).__name__}")
        return out

    def intro(self, *blocks: Block | str) -> Page:
        """Add blocks shown under the title, before the table of contents; returns the page."""
        self._intro += self._blocks(blocks)
        return self

    def section(self, heading: str, *blocks: Block | str) -> Page:
        """Add a section (``<h2>`` + blocks; a string is a paragraph); returns the page for chaining."""
        if not str(heading).strip():
            raise ValueError("a section needs a non-empty heading")
        self._sections.append((str(heading), _anchor(str(heading), self._anchors), self._blocks(blocks)))
        return self

    def render(self, base: Path | None = None) -> str:
        """The whole page as a string; figure links are made relative to ``base`` (the page's folder)."""
        stamp = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
        sections = [(heading, anchor, [Markup(b.render(base)) for b in blocks])
                    for heading, anchor, blocks in self._sections]
        return environment().get_template("report.html").render(
            title=self.title, intro=[Markup(b.render(base)) for b in self._intro], sections=sections,
            stamp=stamp) + "\n"

    def write(self, path: str | Path) -> Path:
        """Write the page (UTF-8) to ``path``, creating its folder; figure links relative to it."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.render(path.parent.resolve()), encoding="utf-8")
        return path
