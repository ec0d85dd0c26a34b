"""The diagnostics line of an estimate: its value, σ and unit, and no unit after a dimensionless factor."""

from __future__ import annotations

from types import SimpleNamespace

import pandas as pd

from rivercal.fews.adapter import _report_cycle
from rivercal.fews.pi import Diagnostics


def test_an_estimate_is_said_with_its_unit_and_a_dimensionless_one_without() -> None:
    # an imported SOBEK 3 model's friction factor F_scale has unit "-" ("1.2 ± 0.00617 - (accepted)" before)
    service = SimpleNamespace(parameters=[SimpleNamespace(name="F_scale", unit="-"),
                                          SimpleNamespace(name="FA", unit="m^(1/3)/s")])
    outcome = SimpleNamespace(cycle=0, issue_time=pd.Timestamp("2001-01-22", tz="UTC"), status="done", model_runs=7,
                              wall_s=2.2, hot_start=True, accepted={"F_scale": 1.2, "FA": 16.0},
                              estimates={"F_scale": 1.2, "FA": 25.0}, std={"F_scale": 0.00617, "FA": 3.0},
                              held={"FA": "the window cannot see FA"}, message="", alerts=[])
    diag = Diagnostics()
    _report_cycle(outcome, service, diag)
    texts = [line.text for line in diag.lines]
    assert "F_scale = 1.2 ± 0.00617 (accepted)" in texts
    assert "FA: estimate 25 ± 3 m^(1/3)/s held; the forecast uses 16 m^(1/3)/s: the window cannot see FA" in texts
