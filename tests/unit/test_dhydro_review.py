"""The D-HYDRO import on the variants a reviewer made of real models: each defect found, fixed at its root.

Each test edits the small test model (tests/dhydro_models.py) the way the reviewer edited the shared models
(/work/probe-dhydro: a boundary given twice, a gate series that starts closed, a Tzone, block-to interpolation,
...) and checks that the import converts the feature right, records it in the ledger, or stops with an error that
names the file and line — never an internal error, never a silent change.
"""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

import pytest

from rivercal.errors import CaseError
from rivercal.io.dhydro import ImportOptions, import_dhydro
from tests.dhydro_models import write_model


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    return write_model(tmp_path_factory.mktemp("dhydro") / "model").parent


def _model(base: Path, tmp_path: Path) -> Path:
    shutil.copytree(base, tmp_path / "model")
    return tmp_path / "model"


def _append(path: Path, text: str) -> int:
    """Append text to a file; returns the 1-based line of its first non-blank line."""
    old = path.read_text(encoding="utf-8")
    if not old.endswith("\n"):
        old += "\n"
    path.write_text(old + text, encoding="utf-8")
    return old.count("\n") + 1 + (len(text) - len(text.lstrip("\n")))


def _line_of(path: Path, pattern: str, nth: int = 0) -> int:
    text = path.read_text(encoding="utf-8")
    matches = list(re.finditer(pattern, text, flags=re.I | re.M))
    assert len(matches) > nth, f"{pattern!r} not in {path.name}"
    return text[:matches[nth].start()].count("\n") + 1


def _import(model: Path, tmp_path: Path, **options):
    return import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(realtime_lateral=0.01, **options))


def _error(model: Path, tmp_path: Path, **options) -> str:
    with pytest.raises(CaseError) as info:
        _import(model, tmp_path, **options)
    message = str(info.value)
    assert "bug" not in message and "internal" not in message
    assert not (tmp_path / "case" / "case.toml").exists()
    return message


def _case(tmp_path: Path) -> dict:
    return tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))


def _entry(result, kind: str, ident: str):
    return next(e for e in result.ledger.entries if e.kind == kind and e.id == ident)


# -- 1. a boundary node or a lateral id given twice ----------------------------------------------------------


def test_two_boundaries_on_one_node_are_an_error_naming_both_blocks(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    ext = model / "forcing.ext"
    first = _line_of(ext, r"^\[Boundary\]", 1)
    second = _append(ext, "\n[Boundary]\nquantity = waterlevelbnd\nnodeId = D\nforcingFile = boundaries.bc\n")
    message = _error(model, tmp_path)
    assert f"forcing.ext, line {second}" in message and f"forcing.ext, line {first}" in message
    assert "'D'" in message


def test_two_laterals_with_one_id_are_an_error_naming_both_blocks(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    ext = model / "forcing.ext"
    first = _line_of(ext, r"^\[Lateral\]", 0)
    second = _append(ext, "\n[Lateral]\nid = lat_const\nbranchId = b2\nchainage = 100.0\ndischarge = 0.5\n")
    message = _error(model, tmp_path, allow_partial=True)
    assert f"forcing.ext, line {second}" in message and f"forcing.ext, line {first}" in message
    assert "'lat_const'" in message
