"""``rivercal report`` of a run whose model the store knows by its name only (an imported model in a folder)."""

from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rivercal.cli.main import app
from rivercal.store import Store


def _imported_like(folder: Path) -> Path:
    """The packaged case synthetic copied to ``folder`` and named 'test_compound', as an import names a model."""
    shutil.copytree(Path(str(resources.files("rivercal.cases") / "synthetic")), folder)
    toml = folder / "case.toml"
    text = toml.read_text(encoding="utf-8")
    assert 'name = "synthetic"' in text
    toml.write_text(text.replace('name = "synthetic"', 'name = "test_compound"', 1), encoding="utf-8")
    return folder


def test_a_run_of_a_model_in_a_folder_of_its_own_takes_the_folder_with_case(tmp_path: Path,
                                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # an imported model is a folder ('comp/') whose case is named by the model ('test_compound'); the store keeps
    # the name, so 'rivercal report' cannot find the model from the store alone and asks for --case
    monkeypatch.chdir(tmp_path)
    _imported_like(tmp_path / "comp")
    with Store(tmp_path / "s.sqlite") as store:
        store.ensure_run("online", "test_compound", {})
    base = ["report", "--db", "s.sqlite", "--out", "report"]
    run = CliRunner().invoke(app, base)
    assert run.exit_code == 2, run.output
    assert ("run 'online' serves the model 'test_compound', which is neither a folder here nor a packaged case"
            in run.stderr and "with --case" in run.stderr)
    run = CliRunner().invoke(app, [*base, "--case", "synthetic"])   # another model
    assert run.exit_code == 2, run.output
    assert ("--case synthetic: that is the model 'synthetic'; run 'online' of s.sqlite serves 'test_compound'"
            in run.stderr)
    run = CliRunner().invoke(app, [*base, "--case", "comp"])
    assert run.exit_code == 0, run.output
    assert (tmp_path / "report" / "index.html").is_file()


def test_a_run_that_recorded_its_models_folder_is_reported_without_case(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    # 'rivercal online comp …' records where the model lay (model_source); report and dashboard open it from there,
    # and a run whose folder moved resumes (the location is not part of what a resumed run must match)
    from rivercal.dashboard.facts import model_facts

    monkeypatch.chdir(tmp_path)
    case = _imported_like(tmp_path / "comp")
    with Store(tmp_path / "s.sqlite") as store:
        store.ensure_run("online", "test_compound", {"window": "2D", "model_source": str(case)})
    facts = model_facts("test_compound", str(case))
    assert facts.problem == "" and facts.network is not None
    assert "cannot be loaded" in model_facts("test_compound", str(tmp_path / "elsewhere")).problem
    model_facts.cache_clear()
    base = ["report", "--db", "s.sqlite", "--out", "report"]
    run = CliRunner().invoke(app, base)
    assert run.exit_code == 0, run.output
    assert (tmp_path / "report" / "index.html").is_file()
    moved = case.rename(tmp_path / "moved")
    run = CliRunner().invoke(app, [*base[:-1], "report2"])
    assert run.exit_code == 2, run.output
    assert f"(it lay at {case} when the run was created)" in " ".join(run.stderr.split())
    # another model in the recorded folder now: said as such, not as a --case the user never gave
    shutil.copytree(Path(str(resources.files("rivercal.cases") / "synthetic")), case)
    run = CliRunner().invoke(app, [*base[:-1], "report3"])
    assert run.exit_code == 2, run.output
    assert f"{case} (the folder run 'online' recorded): that is the model 'synthetic'" in " ".join(run.stderr.split())
    shutil.rmtree(case)
    with Store(tmp_path / "s.sqlite") as store:  # the same run, its model now elsewhere: it resumes
        resumed = store.ensure_run("online", "test_compound", {"window": "2D", "model_source": str(moved)})
    assert resumed.name == "online"
