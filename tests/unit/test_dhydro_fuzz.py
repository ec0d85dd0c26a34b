"""Fuzz test of the D-HYDRO import: damaged copies of real models end in a case or a clean error.

Three models are damaged one file at a time (tests/dhydro_fuzz.py: values replaced by nonsense, keys
renamed, removed or given twice, headers lost, files truncated, deleted or overwritten with bytes): the
test model written by hydrolib-core (every profile and structure type), the model with every friction and
cross-section feature (roughness tables, branch orders, a levee, initial levels along a branch) and the packaged
case ``synthetic`` as rivercal's export writes it. Every import must end with a case that loads, or with a
:class:`~rivercal.errors.CaseError` whose message names a file of the model — never another exception —
and must write nothing outside its case folder. The seeds are fixed, so a failure reproduces; a longer
search runs with ``python -m tests.dhydro_fuzz N SEED MODEL.mdu ...``.
"""

from __future__ import annotations

import random
import shutil
from pathlib import Path

import pytest

from rivercal.case import load_case
from rivercal.io.dhydro import export_dhydro
from tests.dhydro_fuzz import mutate, names_a_file, run_case, snapshot
from tests.dhydro_models import write_feature_model, write_model

CASES = 24


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("fuzz-bases")
    test_model = write_model(root / "test")
    exported = export_dhydro(load_case("synthetic"), root / "synthetic").mdu
    return [test_model, write_feature_model(root / "features"), exported]


@pytest.mark.parametrize("seed", range(CASES))
def test_a_damaged_model_gives_a_case_or_a_clean_error(models, tmp_path, seed) -> None:
    rng = random.Random(seed)
    base = models[seed % len(models)]
    model = tmp_path / "model"
    shutil.copytree(base.parent, model)
    names = {p.name for p in model.rglob("*")}
    what = mutate(model, rng)
    before = snapshot(tmp_path, tmp_path / "case")
    outcome = run_case(model / base.name, tmp_path / "case", allow_partial=seed % 3 == 0, realtime_lateral=0.01)
    assert outcome.kind != "crash", f"{what}: {outcome.message}"
    if outcome.kind == "error":
        assert names_a_file(outcome.message, names, model / base.name), f"{what}: {outcome.message}"
        assert "bug" not in outcome.message, f"{what}: {outcome.message}"
    assert snapshot(tmp_path, tmp_path / "case") == before, f"{what}: a file outside the case folder changed"
