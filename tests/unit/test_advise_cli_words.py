"""What ``rivercal advise gauges`` prints when the present stations need no gauge: words, not an empty table."""

from __future__ import annotations

from rivercal.cli.advise import _print
from rivercal.cli.common import out_console


def _summary(steps: list[dict], enough: int | None) -> dict:
    verdict = {"verdict": {"F_scale": "identifiable"}, "posterior_std": {"F_scale": 0.0027}, "identifiable": 1,
               "smallest_singular_value": 555.0}
    return {"case": "test_compound", "parameters": ["F_scale"], "window": ["2001-01-20T00:00:00+00:00",
            "2001-01-22T00:00:00+00:00"], "candidates": {"count": 2}, "jacobian_runs": 2, "wall_s": 0.6,
            "stations": ["Channel1_middle"], "before": verdict, "after": verdict, "forecasts": [], "steps": steps,
            "units": {"F_scale": "-"}, "enough": enough, "files": {"advice": "out/advice.json"}}


def test_no_gauge_to_add_is_said_in_words_with_the_window_in_utc() -> None:
    # the imported SOBEK 3 compound channel: its one station sees F_scale; the table of advised gauges was empty
    with out_console.capture() as captured:
        _print(_summary([], 0))
    text = " ".join(captured.get().split())
    assert "over 2001-01-20 00:00 .. 2001-01-22 00:00 UTC (2 candidates" in text
    assert "no gauge advised: the present stations make every parameter identifiable already" in text
    assert "the advised gauges, one at a time" not in text and "with 0 added gauges" not in text
    assert "every parameter is identifiable with the present stations" in text
    step = {"step": 1, "name": "bridge A", "series": ["bridge_A.h"], "worth": 0.366, "identifiable": 1,
            "smallest_singular_value": 697.0}
    with out_console.capture() as captured:
        _print(_summary([step], 1))
    text = " ".join(captured.get().split())
    assert "the advised gauges, one at a time" in text and "bridge A" in text
    assert "every parameter is identifiable with 1 added gauge" in text
