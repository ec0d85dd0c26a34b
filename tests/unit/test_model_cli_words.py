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
