"""What ``rivercal online`` says it updated: true for any --cycle, not only the default day."""

from __future__ import annotations

from rivercal.cli.online import updated_words


def test_the_parameters_are_said_to_be_updated_every_cycle_not_daily() -> None:
    # an imported sewer model of two hours runs cycles of 1 h: 'parameters (daily)' contradicted --cycle 1h
    assert updated_words("both") == "Updated: states (hourly, ensemble Kalman filter) and parameters (every cycle)."
    assert "daily" not in updated_words("both")
    assert updated_words("parameters") == "Updated: parameters only."


def test_a_failed_state_updating_is_said_beside_what_was_updated() -> None:
    # the SOBEK 3 Waal with --assimilate both: every member diverged, the cycle issued the parameters' forecast;
    # 'Updated: states ... and parameters' alone hid that
    text = updated_words("both", [0], 1)
    assert text.startswith("Updated: states (hourly, ensemble Kalman filter) and parameters (every cycle). ")
    assert "The state updating failed in 1 of 1 cycles (0: every member of the ensemble failed" in text
    assert "their updated forecast is the parameters' own" in text
    assert "failed in 6 of 9 cycles (0, 1, 2, 3, 4 …:" in updated_words("both", [0, 1, 2, 3, 4, 8], 9)
    assert updated_words("both", [], 3) == updated_words("both")


def test_options_that_differ_from_the_stored_runs_are_bad_input_naming_run(tmp_path) -> None:
    # a second 'rivercal online' into the same store with another --cycle: exit status 2 (the user's options),
    # not 1 (a problem that is not the input's fault), and the message names --run; nothing is run
    from typer.testing import CliRunner

    from rivercal.cli.main import app
    from rivercal.store import Store

    db = tmp_path / "s.sqlite"
    with Store(db) as store:
        store.ensure_run("PI-0", "dommel", {"period": "1h"})
    run = CliRunner().invoke(app, ["online", "dommel", "--scenario", "PI-0", "--assimilate", "parameters", "--db",
                                   str(db), "--from", "2010-10-18", "--to", "2010-10-18", "--workers", "1", "-q"])
    assert run.exit_code == 2, run.output
    assert "--run PI-0: " in run.stderr and "was created with another configuration (keys differ:" in run.stderr
