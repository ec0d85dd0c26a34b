"""The SOBEK 3 import on variants of the small model (tests/sobek3_models.py) that once went wrong: a closed gate,
ids used twice, sub-second time steps, block-wise and periodic series, a universal weir whose crest is not its
lowest z value, comments where a value is empty, and renamed ids that took a valid one's name."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from rivercal.io.sobek3 import ImportOptions, import_sobek3
from tests.sobek3_models import write_model


def _import(tmp_path: Path, **replace: tuple[str, str]) -> tuple[dict, str, Path]:
    """Import the model with the replacements (partially: the model has refused objects); the case and import.md."""
    md1d = write_model(tmp_path / "model", **replace)
    import_sobek3(md1d, tmp_path / "case", ImportOptions(allow_partial=True))
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    return data, (tmp_path / "case" / "import.md").read_text(encoding="utf-8"), tmp_path / "case"


def _by_id(items: list[dict]) -> dict[str, dict]:
    return {i["id"]: i for i in items}


# -- a closed orifice --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("open_level", ["-1.2", "-1.5"])  # at the crest, below it
def test_a_closed_orifice_lets_no_water_through(tmp_path, open_level) -> None:
    data, md, _ = _import(tmp_path, Structures_ini=("openLevel             = -0.5",
                                                    f"openLevel             = {open_level}"))
    orifice = _by_id(data["orifices"])["orifice1"]
    assert orifice["allowed_flow"] == "none"
    assert orifice["gate_lower_edge_level"] > orifice["crest_level"] == -1.2
    row = next(line for line in md.splitlines() if "`orifice1`" in line)
    assert "closed" in row and "no water" in row
