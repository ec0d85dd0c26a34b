"""docs/case-format.md and the case schema cannot drift apart."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rivercal.case import CaseFile, EngineSettings, InitialConditions, load_case
from rivercal.engine import Simulator

DOC = Path(__file__).resolve().parents[2] / "docs" / "case-format.md"


def _schema_names() -> tuple[set[str], set[str]]:
    """Every property name and every enum value in the JSON Schema of case.toml (through $defs)."""
    properties: set[str] = set()
    enums: set[str] = set()

    def walk(node) -> None:
        if isinstance(node, dict):
            if isinstance(node.get("properties"), dict):
                properties.update(node["properties"])
            for key in ("enum", "const"):
                values = node.get(key)
                if values is not None:
                    enums.update(str(v) for v in (values if isinstance(values, list) else [values]))
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(CaseFile.model_json_schema())
    return properties, enums


def _code_tokens(text: str) -> set[str]:
    """Words that appear inside `inline code` or fenced code blocks of the document."""
    spans = re.findall(r"```.*?```", text, flags=re.S) + re.findall(r"`([^`\n]+)`", text)
    return {word for span in spans for word in re.findall(r"[A-Za-z_][A-Za-z0-9_]*(?:-[A-Za-z0-9_]+)*", span)}


def _fenced(text: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def test_every_schema_property_is_documented() -> None:
    properties, _ = _schema_names()
    assert len(properties) > 60  # the walk really reached the nested tables
    tokens = _code_tokens(DOC.read_text(encoding="utf-8"))
    missing = sorted(properties - tokens)
    assert not missing, f"fields of the case schema not documented in {DOC.name}: {missing}"


def test_every_allowed_value_is_documented() -> None:
    _, enums = _schema_names()
    assert {"strickler", "zw", "rating", "h_up", "negative"} <= enums
    tokens = _code_tokens(DOC.read_text(encoding="utf-8"))
    missing = sorted(enums - tokens)
    assert not missing, f"allowed values not documented in {DOC.name}: {missing}"


def test_every_table_has_a_section() -> None:
    text = DOC.read_text(encoding="utf-8")
    top = CaseFile.model_json_schema()["properties"]
    for name, spec in top.items():
        is_list = spec.get("type") == "array" or any(s.get("type") == "array" for s in spec.get("anyOf", []))
        heading = f"## `[[{name}]]`" if is_list else f"## `[{name}]`"
        assert heading in text, f"no section {heading!r} in {DOC.name}"


def _section_defaults(text: str, heading: str) -> dict[str, str]:
    section = text.split(heading, 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `(\w+)` \| [^|]+ \| [^|]+ \| ([^|]+) \|", section, flags=re.M)
    return {name: default.strip() for name, default in rows}


@pytest.mark.parametrize(
    ("heading", "model"), [("## `[engine]`", EngineSettings), ("## `[initial]`", InitialConditions)]
)
def test_documented_defaults_match_the_schema(heading: str, model) -> None:
    documented = _section_defaults(DOC.read_text(encoding="utf-8"), heading)
    assert set(documented) == set(model.model_fields)
    for name, value in model().model_dump().items():
        if value is None:
            assert documented[name] == "none", name
        elif isinstance(value, str):
            assert documented[name] == f'`"{value}"`', name
        else:
            assert float(documented[name]) == pytest.approx(value), name


def test_the_documented_example_loads_and_runs(tmp_path: Path) -> None:
    text = DOC.read_text(encoding="utf-8")
    tomls, csvs = _fenced(text, "toml"), _fenced(text, "csv")
    assert len(tomls) == 1, "the document has one complete example"
    (tmp_path / "case.toml").write_text(tomls[0], encoding="utf-8")
    (tmp_path / "forcing.csv").write_text(csvs[-1], encoding="utf-8")
    case = load_case(tmp_path)
    sim = Simulator(case)
    result, _ = sim.simulate()
    listed = re.search(r"Its simulated series are (.*?)\.\n", text, flags=re.S)
    assert listed is not None
    assert list(result.series.columns) == re.findall(r"`([^`]+)`", listed.group(1))
    assert result.series.notna().all().all()


@pytest.mark.parametrize("line", [
    line for line in DOC.read_text(encoding="utf-8").splitlines() if line.startswith("mycase/")
])
def test_the_documented_messages_are_one_line_with_file_and_field(line: str) -> None:
    file, field, problem = line.split(": ", 2)
    assert file.endswith((".toml", ".csv")) and field and problem
