"""Sphinx extension of the rivercal documentation: the generated parts of the reference.

- The API pages (``reference/api/*.rst``, written before the sources are read): one page per package of
  rivercal, documenting every name in the ``__all__`` of the package and of each of its public modules
  exactly once, under the shortest public path that exports it. :func:`public_names` is the definition
  of "public" that ``tests/unit/test_docs.py`` checks against the built site's inventory.
- ``.. rivercal-schema:: case`` (or ``model``): a JSON Schema of rivercal rendered as tables, one per
  object, with links between them; the raw schema is written beside the page for download.
- ``.. rivercal-store-schema::``: the tables of a freshly created store, as SQLite creates them.
- ``.. rivercal-cli::``: every command of the ``rivercal`` program with its usage, help and options, from
  the command tree typer builds (typer ships its own click, which sphinx-click does not read).
- Docstrings use ``|x|`` for absolute values; :func:`escape_bars` keeps reST from reading them as
  substitutions, and ``csv`` code blocks are shown as text.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
import re
import sqlite3
import tempfile
import typing
from pathlib import Path
from typing import Any, ClassVar

import typer
from docutils import nodes
from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

import rivercal
from rivercal.cli.main import app as cli_app

#: The ``rivercal`` command tree (typer's click commands).
CLI = typer.main.get_command(cli_app)

#: Packages and modules documented on their own API page, in the order of the reference's contents, with
#: a title (a module of rivercal that is no package and not listed here is documented with its package).
PAGES = {
    "rivercal": "The main names (``import rivercal``)",
    "rivercal.case": "Cases",
    "rivercal.network": "The network",
    "rivercal.engine": "The engine",
    "rivercal.hydrology": "Rainfall-runoff",
    "rivercal.models": "Models behind the contract",
    "rivercal.model": "rivercal.model (short import path)",
    "rivercal.results": "What a run gives",
    "rivercal.parameters": "Parameters",
    "rivercal.observations": "Observations",
    "rivercal.problem": "The calibration problem",
    "rivercal.evaluate": "Evaluation (parallel runs)",
    "rivercal.optimise": "Optimisers",
    "rivercal.analysis": "Analysis",
    "rivercal.assimilate": "Data assimilation (ensemble filters)",
    "rivercal.twin": "Twin experiments",
    "rivercal.online": "The on-line service",
    "rivercal.store": "The store",
    "rivercal.io": "Readers and writers",
    "rivercal.report": "Reports and figures",
    "rivercal.dashboard": "The dashboard",
    "rivercal.fews": "Delft-FEWS",
    "rivercal.workflows": "Workflows (what the commands do)",
    "rivercal.bench": "Benchmarks",
    "rivercal.errors": "Errors",
}

#: Not in the API reference: the command line has its own reference page (generated from the app).
EXCLUDED = ("rivercal.cli", "rivercal.cases")


def public_modules() -> list[str]:
    """Every importable module of rivercal without a ``_``-prefixed part, outside :data:`EXCLUDED`."""
    out = ["rivercal"]
    for info in pkgutil.walk_packages(rivercal.__path__, "rivercal."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts[1:]) or info.name.startswith(EXCLUDED):
            continue
        out.append(info.name)
    return sorted(out)


def public_names() -> dict[str, list[str]]:
    """Module → the names of its ``__all__`` (the public API; the top level's lazy names included)."""
    out = {}
    for name in public_modules():
        module = importlib.import_module(name)
        out[name] = [n for n in getattr(module, "__all__", []) if not n.startswith("__")]
    return out


def _page_of(module: str) -> str:
    """The API page (a key of :data:`PAGES`) that documents ``module``."""
    best = "rivercal"
    for page in PAGES:
        if (module == page or module.startswith(page + ".")) and len(page) > len(best):
            best = page
    return best


def _kind(obj: Any) -> str:
    """The autodoc directive for an object."""
    import inspect

    if inspect.isclass(obj):
        return "autoclass" if not issubclass(obj, BaseException) else "autoexception"
    if inspect.isfunction(obj) or inspect.isbuiltin(obj) or hasattr(obj, "py_func"):
        return "autofunction"
    return "autodata"


def api_pages() -> dict[str, str]:
    """The reST source of every API page, by page module; each public name once (see module docstring)."""
    names = public_names()
    documented: dict[int, str] = {}  # id(object) -> where it is documented (classes, functions)
    data: dict[str, list[Any]] = {}  # name -> the data objects documented under that name
    entries: dict[str, list[tuple[str, Any]]] = {}
    for module in sorted(names, key=lambda m: (m.count("."), m)):
        if module == "rivercal":
            continue
        mod = importlib.import_module(module)
        entries[module] = []
        for n in names[module]:
            obj = getattr(mod, n)
            if _kind(obj) == "autodata":
                if any(o is obj for o in data.get(n, [])):
                    continue
                data.setdefault(n, []).append(obj)
            elif id(obj) in documented:
                continue
            documented.setdefault(id(obj), f"{module}.{n}")
            entries[module].append((n, obj))
    targets = {f"{m}.{n}" for m, members in entries.items() for n, _ in members}
    pages: dict[str, list[str]] = {page: [] for page in PAGES}
    for module, members in entries.items():
        lines = pages[_page_of(module)]
        if module != _page_of(module):
            title = f"``{module}``"
            lines += ["", title, "-" * len(title), ""]
        lines += [f".. automodule:: {module}"]
        if module in targets:  # a function of the package has the module's name: one target only
            lines += ["   :no-index:"]
        lines += ["", f".. currentmodule:: {module}", ""]
        for n, obj in members:
            directive = _kind(obj)
            if typing.get_origin(obj) is not None and directive == "autodata":
                lines += _alias(module, n, obj)
                continue
            lines += [f".. {directive}:: {n}"]
            if directive in ("autoclass", "autoexception"):
                lines += ["   :members:"]
            lines += [""]
    out = {}
    for page, title in PAGES.items():
        body = _top_level(sorted(names["rivercal"]), documented) if page == "rivercal" else "\n".join(pages[page])
        head = f"{title}\n{'=' * len(title)}\n"
        out[page] = f".. This page is written by docs/_ext/rivercal_docs.py at every build.\n\n{head}\n{body}\n"
    return out


def _alias(module: str, name: str, obj: Any) -> list[str]:
    """A type alias as data: its ``#:`` comment and its definition as a literal (autodoc would parse it as reST)."""
    from sphinx.pycode import ModuleAnalyzer
    from sphinx.util.typing import stringify_annotation

    comment = ModuleAnalyzer.for_module(module).find_attr_docs().get(("", name), [])
    definition = " ".join(stringify_annotation(obj, "fully-qualified-except-typing").split())
    return [f".. py:data:: {name}", "", *[f"   {line}" for line in comment if line.strip()], "",
            f"   A type alias: ``{definition}``", ""]


def _top_level(lazy: list[str], documented: dict[int, str]) -> str:
    """The top-level page: the module docstring and a table of the lazy names with links."""
    rows = []
    for n in lazy:
        obj = getattr(rivercal, n)
        target = documented.get(id(obj))
        role = {"autoclass": "class", "autoexception": "exc", "autofunction": "func"}.get(_kind(obj), "data")
        summary = (getattr(obj, "__doc__", None) or "").strip().split("\n")[0] if role != "data" else ""
        if role == "data" and target is None:
            target = f"rivercal.optimise.{n}"
        rows += [f"   * - :{role}:`rivercal.{n} <{target}>`", f"     - {summary or ' '}"]
    return "\n".join([
        ".. automodule:: rivercal", "",
        "Every name below is imported on first use; each links to its entry in the reference.", "",
        ".. list-table::", "   :header-rows: 1", "   :widths: 30 70", "",
        "   * - name", "     - what it is", *rows, ""])


def write_api_pages(app: Any) -> None:
    """Write the API pages into ``reference/api`` (only files whose text changed, so builds stay incremental)."""
    folder = Path(app.srcdir) / "reference" / "api"
    folder.mkdir(parents=True, exist_ok=True)
    pages = api_pages()
    index = ["API reference", "=============", "",
             "Every public name of rivercal (the ``__all__`` of each package and of its public modules), from "
             "its docstring. Import paths: a name is documented under the shortest path that exports it.", "",
             ".. toctree::", "   :maxdepth: 1", ""]
    for page, text in pages.items():
        _write(folder / f"{page}.rst", text)
        index.append(f"   {page}")
    _write(folder / "index.rst", "\n".join(index) + "\n")
    for old in folder.glob("*.rst"):
        if old.stem not in pages and old.stem != "index":
            old.unlink()


def _write(path: Path, text: str) -> None:
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


# -- JSON Schemas --------------------------------------------------------------------------------------------

def schema_of(kind: str) -> dict[str, Any]:
    """The JSON Schema of ``case.toml`` (``case``) or ``model.toml`` (``model``), as the CLI prints it."""
    if kind == "case":
        from rivercal.case.schema import CaseFile

        return CaseFile.model_json_schema()
    if kind == "model":
        from rivercal.models.config import ModelFile

        return ModelFile.model_json_schema()
    raise ValueError(f"unknown schema {kind!r}: expected 'case' or 'model'")


def _type(spec: dict[str, Any], kind: str) -> str:
    """A short reST text of a property's type, with links to the objects it refers to."""
    if "$ref" in spec:
        name = spec["$ref"].rsplit("/", 1)[-1]
        return f":ref:`{name} <{kind}-schema-{name.lower()}>`"
    for key in ("anyOf", "oneOf"):
        if key in spec:
            parts = [_type(s, kind) for s in spec[key]]
            return " or ".join(dict.fromkeys(parts))
    if "const" in spec:
        return f"``{json.dumps(spec['const'])}``"
    if "enum" in spec:
        return "one of " + ", ".join(f"``{json.dumps(v)}``" for v in spec["enum"])
    t = spec.get("type")
    if t == "array":
        items = spec.get("items")
        inner = _type(items, kind) if isinstance(items, dict) and items else "values"
        if "prefixItems" in spec:
            inner = ", ".join(_type(s, kind) for s in spec["prefixItems"])
            return f"array [{inner}]"
        return f"array of {inner}"
    if t == "object":
        extra = spec.get("additionalProperties")
        return f"table of {_type(extra, kind)}" if isinstance(extra, dict) and extra else "table"
    if t == "null":
        return "none"
    return str(t) if t else "any"


_LIMITS = (("minimum", "≥"), ("exclusiveMinimum", ">"), ("maximum", "≤"), ("exclusiveMaximum", "<"),
           ("minItems", "items ≥"), ("maxItems", "items ≤"), ("minLength", "length ≥"), ("maxLength", "length ≤"))


def _limits(spec: dict[str, Any]) -> str:
    parts = []
    for option in [spec, *spec.get("anyOf", [])]:
        parts += [f"{sign} {option[key]}" for key, sign in _LIMITS if key in option]
        if "pattern" in option:
            parts.append(f"pattern ``{option['pattern']}``")
    return "; ".join(dict.fromkeys(parts))


#: In a schema's description: an option (``--set``) or a token in single quotes without spaces (``'variable@id'``).
_CODE_IN_TEXT = re.compile(r"(?<![\w`])(--?[A-Za-z][\w-]*|'[^'\s]+')(?![\w`])")


def _cell(text: str) -> str:
    """A description as one line of reST.

    Options and quoted tokens become literals (no en dash from ``--``, no mail link from ``a@b``); any other
    ``@`` between letters is escaped.
    """
    line = " ".join(str(text).split())
    if not line:
        return " "
    parts = _CODE_IN_TEXT.split(line)
    out = []
    for k, part in enumerate(parts):
        if k % 2:
            out.append(f"``{part.strip(chr(39))}``")
        else:
            out.append(re.sub(r"(?<=\w)@(?=\w)", r"\\@", part))
    return "".join(out)


def schema_rst(schema: dict[str, Any], kind: str) -> list[str]:
    """The lines of reST: one table per object of the schema (the file itself first)."""
    objects = [(schema.get("title", kind), schema), *sorted(schema.get("$defs", {}).items())]
    lines: list[str] = []
    for i, (name, spec) in enumerate(objects):
        label = f"{kind}-schema-{'file' if i == 0 else name.lower()}"
        title = f"The whole file ({name})" if i == 0 else name
        lines += [f".. _{label}:", "", title, "~" * len(title), ""]
        if spec.get("description"):
            lines += [_cell(spec["description"]), ""]
        props = spec.get("properties", {})
        if not props:
            lines += [f"Type: {_type(spec, kind)}.", ""]
            continue
        required = set(spec.get("required", []))
        lines += [".. list-table::", "   :header-rows: 1", "   :widths: 18 22 16 14 30", "",
                  "   * - field", "     - type", "     - default", "     - limits", "     - description"]
        for field, p in props.items():
            default = "required" if field in required else (
                f"``{json.dumps(p['default'])}``" if "default" in p and len(json.dumps(p["default"])) < 40 else
                "(see description)" if "default" in p else "optional")
            lines += [f"   * - ``{field}``", f"     - {_type(p, kind)}", f"     - {default}",
                      f"     - {_cell(_limits(p))}", f"     - {_cell(p.get('description', ''))}"]
        lines += [""]
    return lines


class SchemaDirective(SphinxDirective):
    """``.. rivercal-schema:: case|model``: the schema as tables, and the raw JSON to download."""

    required_arguments = 1
    option_spec: ClassVar[dict[str, Any]] = {"file": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        """The tables, after writing the raw schema beside the page."""
        kind = self.arguments[0]
        schema = schema_of(kind)
        folder = Path(self.env.srcdir) / "reference" / "generated"
        folder.mkdir(parents=True, exist_ok=True)
        _write(folder / f"{kind}.schema.json", json.dumps(schema, indent=2) + "\n")
        lines = [f"The raw schema: :download:`{kind}.schema.json </reference/generated/{kind}.schema.json>` "
                 f"(the same as ``rivercal {kind} schema`` prints).", "", *schema_rst(schema, kind)]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(lines, source=f"<{kind} schema>"), container)
        return list(container.children)


# -- the store ----------------------------------------------------------------------------------------------

def store_tables() -> list[tuple[str, str, list[tuple[str, str, bool, str]]]]:
    """(table, CREATE statement, [(column, type, not null, primary key)]) of a new store, in creation order."""
    from rivercal.store import Store

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "new.sqlite"
        Store(path).close()
        conn = sqlite3.connect(path)
        try:
            rows = conn.execute("SELECT name, sql FROM sqlite_master WHERE type = 'table' "
                                "AND name NOT LIKE 'sqlite_%' ORDER BY rowid").fetchall()
            out = []
            for name, sql in rows:
                info = conn.execute(f"PRAGMA table_info({name})").fetchall()
                out.append((name, sql, [(c[1], c[2], bool(c[3]), "yes" if c[5] else "") for c in info]))
            return out
        finally:
            conn.close()


class StoreSchemaDirective(SphinxDirective):
    """``.. rivercal-store-schema::``: every table of a new store with its columns and CREATE statement."""

    def run(self) -> list[nodes.Node]:
        """One table and one CREATE statement per table."""
        lines: list[str] = []
        for name, sql, columns in store_tables():
            lines += [f"``{name}``", "~" * (len(name) + 4), "", ".. list-table::", "   :header-rows: 1", "",
                      "   * - column", "     - type", "     - not null", "     - primary key"]
            for column, sql_type, not_null, pk in columns:
                lines += [f"   * - ``{column}``", f"     - {sql_type or ' '}", f"     - {'yes' if not_null else ' '}",
                          f"     - {pk or ' '}"]
            lines += ["", ".. code-block:: sql", ""] + [f"   {line}" for line in sql.splitlines()] + [""]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(lines, source="<store schema>"), container)
        return list(container.children)


# -- the command line ------------------------------------------------------------------------------------

#: In help text: an option (``--verbose``, ``-v``), written as a literal so that it is copied as typed.
_OPTION = re.compile(r"(?<![\w-])(--?[A-Za-z][\w-]*)")


def _inline(text: str) -> nodes.paragraph:
    """One paragraph of help text (never parsed as reST): options as literals, the rest as plain text.

    A literal is left alone by Sphinx's smart quotes, which would turn the ``--`` of ``--verbose`` into an en
    dash in plain text (and break copying it).
    """
    para = nodes.paragraph()
    for k, part in enumerate(_OPTION.split(" ".join(text.split()))):
        if part:
            para += nodes.literal(text=part) if k % 2 else nodes.Text(part)
    return para


def _paragraphs(text: str) -> list[nodes.Node]:
    r"""Help text as paragraphs (literal blocks for click's ``\b`` blocks and indented lines), never parsed as reST."""
    out: list[nodes.Node] = []
    for block in re.split(r"\n\s*\n", text.strip()):
        if not block.strip():
            continue
        if block.lstrip().startswith("\b") or any(line.startswith("  ") for line in block.splitlines()[1:]):
            out.append(nodes.literal_block(text=block.replace("\b", "").strip("\n")))
        else:
            out.append(_inline(block))
    return out


def cli_section(command: Any, ctx: Any, path: str) -> nodes.section:
    """A section for one command: usage, help, arguments and options, then its subcommands."""
    section = nodes.section(ids=[nodes.make_id("cli " + path)])
    section += nodes.title(text=path)
    section += nodes.literal_block(text=command.get_usage(ctx).strip())
    section.extend(_paragraphs(command.help or ""))
    items = nodes.definition_list()
    for param in command.params:
        record = param.get_help_record(ctx)
        if record is None:
            continue
        term = nodes.term()
        term += nodes.literal(text=record[0])
        definition = nodes.definition()
        definition += _inline(record[1] or " ")
        items += nodes.definition_list_item("", term, definition)
    if len(items):
        section += nodes.rubric(text="Arguments and options")
        section += items
    for name, sub in getattr(command, "commands", {}).items():
        if getattr(sub, "hidden", False):
            continue
        sub_ctx = type(ctx)(sub, info_name=name, parent=ctx)
        section += cli_section(sub, sub_ctx, f"{path} {name}")
    return section


class CliDirective(SphinxDirective):
    """``.. rivercal-cli::``: the ``rivercal`` program, every command as a section."""

    def run(self) -> list[nodes.Node]:
        """The command tree from ``rivercal`` down."""
        ctx = CLI.context_class(CLI, info_name="rivercal")
        return [cli_section(CLI, ctx, "rivercal")]


# -- docstrings ----------------------------------------------------------------------------------------------

_LITERAL = re.compile(r"(`+[^`]*`+)")


def escape_bars(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    """Escape ``|`` outside literals, literal blocks, doctests and tables (``|x|`` is an absolute value)."""
    literal_indent: int | None = None
    for i, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if literal_indent is not None:
            if stripped and indent <= literal_indent:
                literal_indent = None
            else:
                continue
        if stripped.rstrip().endswith("::"):
            literal_indent = indent
        if "|" not in line or stripped.startswith(("| ", "+-", "+=", ">>>", "...")) or stripped == "|":
            continue
        parts = _LITERAL.split(line)
        lines[i] = "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def setup(app: Any) -> dict[str, Any]:
    """Register the directives, the docstring filter and the writing of the API pages."""
    from pygments.lexers.special import TextLexer

    app.connect("builder-inited", write_api_pages)
    app.connect("autodoc-process-docstring", escape_bars)
    app.add_lexer("csv", TextLexer)
    app.add_directive("rivercal-cli", CliDirective)
    app.add_directive("rivercal-schema", SchemaDirective)
    app.add_directive("rivercal-store-schema", StoreSchemaDirective)
    return {"version": rivercal.__version__, "parallel_read_safe": True, "parallel_write_safe": True}
