"""``rivercal model check`` prints its titles as written: no word of them taken for rich markup."""

from __future__ import annotations

from typer.testing import CliRunner

from rivercal.cli.common import out_console
from rivercal.cli.main import app


def test_the_quantities_title_names_the_parameters_table() -> None:
    # '[[parameters]]' in a rich title is markup: it printed 'what --set and [] targets may name'
    with out_console.capture() as captured:
        run = CliRunner().invoke(app, ["model", "check", "dommel"])
    assert run.exit_code == 0, run.output
    text = " ".join(captured.get().split())
    assert "what --set and [[parameters]] targets may name" in text


def test_an_unknown_case_or_model_lists_the_packaged_models_too(tmp_path, monkeypatch) -> None:
    # 'rivercal simulate dommel_swmm' listed the packaged cases only; dommel-swmm is a packaged model
    import pytest

    from rivercal.errors import CaseError
    from rivercal.models import load_model

    monkeypatch.chdir(tmp_path)
    with pytest.raises(CaseError) as caught:
        load_model("dommel_swmm")
    assert str(caught.value) == ("'dommel_swmm' is neither a case folder nor a packaged case, nor a model.toml or a "
                                 "packaged model (packaged cases: dommel, dommel-controlled, synthetic, westerscheldt; "
                                 "packaged models: dommel-swmm)")
    assert load_model("synthetic").name == "synthetic"
