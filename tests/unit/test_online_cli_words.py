"""What ``rivercal online`` says it updated: true for any --cycle, not only the default day."""

from __future__ import annotations

from rivercal.cli.online import updated_words


def test_the_parameters_are_said_to_be_updated_every_cycle_not_daily() -> None:
    # an imported sewer model of two hours runs cycles of 1 h: 'parameters (daily)' contradicted --cycle 1h
    assert updated_words("both") == "Updated: states (hourly, ensemble Kalman filter) and parameters (every cycle)."
    assert "daily" not in updated_words("both")
    assert updated_words("parameters") == "Updated: parameters only."
