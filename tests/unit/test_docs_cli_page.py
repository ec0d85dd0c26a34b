"""The command-line reference page and the file-format tables of the documentation, as built from the program:
options stay literal (Sphinx's smart quotes make ``--verbose`` an en-dash ``–verbose`` in plain text, which
then cannot be copied), and a token such as ``'variable@id'`` never becomes a mail link."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import pytest
from docutils import nodes
from docutils.core import publish_doctree

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.fixture(scope="module")
def ext():
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        return importlib.import_module("rivercal_docs")
    finally:
        sys.path.remove(str(DOCS / "_ext"))


def _plain_text(node: nodes.Node) -> list[str]:
    """The text of ``node`` outside literals: what smart quotes may rewrite."""
    out = []
    for text in node.findall(nodes.Text):
        if not any(isinstance(a, nodes.literal | nodes.literal_block) for a in _ancestors(text)):
            out.append(str(text))
    return out


def _ancestors(node: nodes.Node):
    while node.parent is not None:
        node = node.parent
        yield node


def test_every_option_in_the_cli_reference_is_a_literal(ext) -> None:
    ctx = ext.CLI.context_class(ext.CLI, info_name="rivercal")
    page = ext.cli_section(ext.CLI, ctx, "rivercal")
    plain = _plain_text(page)
    options = [t for t in plain if re.search(r"(?<![\w-])--?[A-Za-z]", t)]
    assert options == [], options[:5]
    literals = {n.astext().split()[0].rstrip(",") for n in page.findall(nodes.literal) if n.astext().strip()}
    assert {"--verbose", "--alert-k", "--window", "--json"} <= literals
    # the help text's own mentions too, e.g. "--window" in calibrate's help of --window
    mentioned = [n for n in page.findall(nodes.literal) if isinstance(n.parent, nodes.paragraph)
                 and n.astext() == "--dependency"]
    assert mentioned


@pytest.mark.parametrize("kind", ["case", "model"])
def test_no_schema_description_becomes_a_mail_link_or_loses_its_dashes(ext, kind: str) -> None:
    text = "\n".join(ext.schema_rst(ext.schema_of(kind), kind))
    tree = publish_doctree(text, settings_overrides={"report_level": 5, "smart_quotes": True})
    links = [n for n in tree.findall(nodes.reference) if n.get("refuri", "").startswith("mailto:")]
    assert links == []
    assert all("–" not in t or "--" not in t for t in _plain_text(tree))
    if kind == "model":
        assert "variable@id" in {n.astext() for n in tree.findall(nodes.literal)}
