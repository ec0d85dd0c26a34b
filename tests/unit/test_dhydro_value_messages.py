"""A value that the case's own rules refuse is named as the D-Flow FM user wrote it: key, value and its line.

The importer screens the numbers of every block (finite, signs, magnitudes); what passes that and still breaks
a rule of the case (a weir of no width) used to be reported with the case's field name (``crest_width``) at the
line of the block's header. The user wrote ``crestWidth`` on another line: the message must say that.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from rivercal.errors import CaseError
from rivercal.io.dhydro import ImportOptions, import_dhydro
from tests.dhydro_models import write_model


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    return write_model(tmp_path_factory.mktemp("dhydro") / "model").parent


def _set(path: Path, key: str, old: str, new: str) -> int:
    """Replace the first ``key = old`` of a file by ``key = new``; returns its 1-based line."""
    text = path.read_text(encoding="utf-8")
    m = re.search(rf"^(\s*{key}\s*=\s*){re.escape(old)}", text, flags=re.M)
    assert m, f"{key} = {old} not in {path.name}"
    path.write_text(text[:m.start()] + m.group(1) + new + text[m.end():], encoding="utf-8")
    return text[:m.start()].count("\n") + 1


@pytest.mark.parametrize(("key", "old", "new", "why"), [
    ("crestWidth", "4.0", "0.0", "greater than or equal to 0.001"),
    ("allowedFlowDir", "both", "sideways", "sideways"),
])
def test_a_value_the_case_refuses_is_named_by_its_key_and_line(base, tmp_path, key, old, new, why) -> None:
    model = tmp_path / "model"
    shutil.copytree(base, model)
    line = _set(model / "structures.ini", key, old, new)
    with pytest.raises(CaseError) as info:
        import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(realtime_lateral=0.01))
    message = str(info.value)
    assert f"structures.ini, line {line}: weir " in message
    assert f"{key} = {new}: " in message and why in message
    assert "crest_width" not in message and "allowed_flow" not in message
    assert not (tmp_path / "case" / "case.toml").exists()
