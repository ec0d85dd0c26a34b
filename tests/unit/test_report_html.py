"""rivercal.report.html: escaping, tables from DataFrames, relative figure links, page structure."""

from __future__ import annotations

import logging
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.report.html import Page, bullets, figure, paragraph, table


class _Collect(HTMLParser):
    """Start tags with their attributes, and the text of every <td>/<th> cell, in order."""

    def __init__(self):
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.cells: list[str] = []
        self._cell: list[str] | None = None
        self.open: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag in ("td", "th"):
            self._cell = []
        if tag not in ("meta", "img", "br", "link"):
            self.open.append(tag)

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.cells.append("".join(self._cell))
            self._cell = None
        assert self.open and self.open[-1] == tag, f"</{tag}> closes <{self.open[-1] if self.open else None}>"
        self.open.pop()

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _parse(markup: str) -> _Collect:
    parser = _Collect()
    parser.feed(markup)
    parser.close()
    assert parser.open == [], f"unclosed tags {parser.open}"
    return parser


def _png(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n")
    return path


def test_text_is_escaped_everywhere() -> None:
    evil = '<script>alert("x")</script> & \'q\''
    page = Page(f"title {evil}").intro(evil).section(f"head {evil}", paragraph(evil), evil, bullets([evil]))
    markup = page.render()
    assert "<script>" not in markup
    assert markup.count("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &#x27;q&#x27;") == 7
    _parse(markup)  # and the page is well-formed


def test_table_cells_formats_and_escaping() -> None:
    df = pd.DataFrame({"name <b>": ["a<b>", "ok"], "value": [1.23456789, np.nan], "n": [3, 4],
                       "flag": [True, False], "none": [None, "x"]}, index=pd.Index(["r&1", "r2"], name="row"))
    markup = table(df, 'caption "q"', float_format=".3g").render(None)
    parsed = _parse(markup)
    assert parsed.cells == ["row", "name <b>", "value", "n", "flag", "none",
                            "r&1", "a<b>", "1.23", "3", "yes", "–",
                            "r2", "ok", "–", "4", "no", "x"]
    assert "<caption>caption &quot;q&quot;</caption>" in markup
    assert "a&lt;b&gt;" in markup and "<b>" not in markup.replace("<body>", "")
    # numbers are right-aligned cells, text is not
    assert '<td class="num">1.23</td>' in markup and '<td class="num">3</td>' in markup
    assert "<td>a&lt;b&gt;</td>" in markup


def test_table_shows_times_to_the_minute_in_utc() -> None:
    df = pd.DataFrame({"issue_time": [pd.Timestamp("2010-10-18T00:00Z"), pd.Timestamp("2010-10-18T02:00+01:00")],
                       "seen": [pd.Timestamp("2010-10-18 06:30:15"), pd.NaT]})
    parsed = _parse(table(df, index=False).render(None))
    assert parsed.cells == ["issue_time", "seen", "2010-10-18 00:00", "2010-10-18 06:30:15", "2010-10-18 01:00", "–"]


def test_table_without_index_and_with_multiindex_columns() -> None:
    df = pd.DataFrame([[1.5, 2.5]], columns=pd.MultiIndex.from_tuples([("FA", "ours"), ("FA", "thesis")]))
    parsed = _parse(table(df, index=False).render(None))
    assert parsed.cells == ["FA / ours", "FA / thesis", "1.5", "2.5"]


def test_table_needs_a_dataframe() -> None:
    with pytest.raises(TypeError, match="needs a pandas DataFrame, got list"):
        table([[1, 2]])


def test_figure_links_are_relative_to_the_page(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "report"
    inside = _png(out / "cost.png")
    other = _png(tmp_path / "elsewhere" / "levels.png")
    _png(out / "fig" / "bias.png")
    monkeypatch.chdir(tmp_path)
    page = Page("Figures").section(
        "All",
        figure(inside, "absolute path inside the report folder"),
        figure(other, "absolute path elsewhere"),
        figure("fig/bias.png", "relative to the page"),
        figure(Path("report") / "cost.png", "relative to the working directory"),
    )
    written = page.write(out / "index.html")
    assert written == out / "index.html"
    tags = _parse(written.read_text(encoding="utf-8")).tags
    srcs = [a["src"] for t, a in tags if t == "img"]
    assert srcs == ["cost.png", "../elsewhere/levels.png", "fig/bias.png", "cost.png"]
    for src in srcs:  # every link resolves to an existing file from the page's folder
        assert (out / src).resolve().exists(), src
    hrefs = [a["href"] for t, a in tags if t == "a" and not a["href"].startswith("#")]
    assert hrefs == srcs  # each image links to itself
    alts = [a["alt"] for t, a in tags if t == "img"]
    assert alts[0] == "absolute path inside the report folder"


def test_missing_figure_is_shown_as_missing_and_logged(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    page = Page("Figures").section("One", figure(tmp_path / "nope.png", "a caption <x>"))
    with caplog.at_level(logging.WARNING, logger="rivercal.report.html"):
        markup = page.write(tmp_path / "index.html").read_text(encoding="utf-8")
    assert "<img" not in markup
    assert 'class="missing">missing figure: ' in markup and "a caption &lt;x&gt;" in markup
    assert any("nope.png" in r.getMessage() for r in caplog.records)


def test_sections_get_unique_anchors_and_a_table_of_contents() -> None:
    page = Page("P").section("Results", "a").section("Results", "b").section("σ & more", "c")
    markup = page.render()
    anchors = re.findall(r'<h2 id="([^"]+)">', markup)
    assert anchors == ["results", "results-2", "more"]
    toc = re.findall(r'<li><a href="#([^"]+)">', markup)
    assert toc == anchors


def test_single_section_has_no_table_of_contents_and_strings_are_paragraphs() -> None:
    markup = Page("P").section("Only", "plain text").render()
    assert "<nav>" not in markup
    assert "<p>plain text</p>" in markup


def test_bad_input_is_refused_with_a_message() -> None:
    with pytest.raises(ValueError, match="non-empty title"):
        Page("  ")
    with pytest.raises(ValueError, match="non-empty heading"):
        Page("P").section("")
    with pytest.raises(TypeError, match="blocks or strings, got int"):
        Page("P").section("S", 3)


def test_page_is_self_contained_utf8(tmp_path: Path) -> None:
    path = Page("Kosten σ²").section("S", "k_s = 16 m^(1/3)/s").write(tmp_path / "deep" / "er" / "index.html")
    text = path.read_bytes().decode("utf-8")
    assert '<meta charset="utf-8">' in text and "Kosten σ²" in text
    assert "<script" not in text and "http://" not in text and "https://" not in text
    assert "<style>" in text
