"""The on-line report's time axes span the cycles, also when the transition lies far outside them.

A replay that begins weeks after the change used to draw the change's dashed line where it was, which
stretched the time axis back to it and crowded the estimates at the right edge. Now the line is drawn
where it lies inside the period shown; outside, the time axis's label names it.
"""

from __future__ import annotations

import matplotlib.dates as mdates
import pandas as pd
import pytest
from matplotlib.figure import Figure

from rivercal.report.figures import mark_change, plot_transition_levels
from rivercal.report.online import _estimates_plot

CHANGE = pd.Timestamp("2010-11-01", tz="UTC")


def _axes_over(lo: pd.Timestamp, hi: pd.Timestamp, change: pd.Timestamp):
    ax = Figure().subplots()
    ax.plot([lo, hi], [20.0, 21.0], "o")
    mark_change(ax, change, lo, hi, axis_label="time (UTC)", label="transition")
    return ax, ax.get_xlabel().removeprefix("time (UTC)").removeprefix("; ")  # the note, if any


def _limits(ax) -> tuple[pd.Timestamp, pd.Timestamp]:
    a, b = ax.get_xlim()
    return (pd.Timestamp(mdates.num2date(a)), pd.Timestamp(mdates.num2date(b)))


@pytest.mark.parametrize(("lo", "hi", "side"), [("2010-11-23", "2010-12-01", "before"),
                                                ("2010-10-01", "2010-10-08", "after")])
def test_a_transition_outside_the_period_is_named_and_leaves_the_axis_alone(lo: str, hi: str, side: str) -> None:
    lo_t, hi_t = pd.Timestamp(lo, tz="UTC"), pd.Timestamp(hi, tz="UTC")
    ax, note = _axes_over(lo_t, hi_t, CHANGE)
    a, b = _limits(ax)
    span = hi_t - lo_t
    assert lo_t - 0.1 * span <= a and b <= hi_t + 0.1 * span  # matplotlib's margins, no more
    assert not ax.lines[1:]  # no dashed line
    assert note == f"transition 2010-11-01 00:00 UTC, {side} this period"


def test_a_transition_inside_the_period_is_a_dashed_line_at_its_time() -> None:
    ax, note = _axes_over(pd.Timestamp("2010-10-28", tz="UTC"), pd.Timestamp("2010-11-05", tz="UTC"), CHANGE)
    (line,) = ax.lines[1:]
    assert line.get_linestyle() == "--" and line.get_label() == "transition"
    assert pd.Timestamp(line.get_xdata()[0]) == CHANGE  # axvline keeps the time as given
    assert note == ""


@pytest.mark.parametrize(("change", "truth"), [("2010-11-01", [25.0, 25.0]), ("2010-11-30 12:00", [16.0, 25.0, 25.0]),
                                               ("2011-01-15", [16.0, 16.0])])
def test_the_estimates_span_the_axis_and_the_truth_holds_its_value_of_the_time(change: str, truth: list) -> None:
    issue = pd.date_range("2010-11-30", periods=3, freq="D", tz="UTC")
    est = pd.DataFrame({"cycle": [0, 1, 2], "issue_time": issue, "window_start": issue - pd.Timedelta(days=7),
                        "parameter": "FA", "value": [24.0, 24.6, 25.1], "std": [0.4, 0.3, 0.3],
                        "accepted": [True, True, False]})
    fig = _estimates_plot(est, {"FA": "m^(1/3)/s"}, {"FA": (16.0, 25.0)}, {"FA": 16.0}, pd.Timestamp(change, tz="UTC"))
    (ax,) = fig.axes
    a, b = _limits(ax)
    assert pd.Timestamp("2010-11-22", tz="UTC") <= a and b <= pd.Timestamp("2010-12-03", tz="UTC")
    (line,) = [line for line in ax.lines if line.get_label() == "truth"]
    assert list(line.get_ydata()) == truth
    inside = pd.Timestamp("2010-11-23", tz="UTC") <= pd.Timestamp(change, tz="UTC") <= issue[-1]
    assert ("transition" in ax.get_xlabel()) != inside


def test_the_levels_at_a_weir_keep_their_period_when_the_change_lies_weeks_before() -> None:
    times = pd.date_range("2010-11-30", "2010-12-01", freq="h", tz="UTC")
    frame = pd.DataFrame({"W.h_up": 7.3, "W.h_down": 6.5}, index=times)
    fig = plot_transition_levels(frame, frame + 0.05, frame, series=["W.h_up", "W.h_down"], change_time=CHANGE,
                                 title="levels at weir W")
    for ax in fig.axes:
        a, b = _limits(ax)
        assert times[0] - pd.Timedelta(hours=3) <= a and b <= times[-1] + pd.Timedelta(hours=3)
        assert not [line for line in ax.lines if line.get_label() == "transition"]
    assert fig.axes[-1].get_xlabel() == "time (UTC); transition 2010-11-01 00:00 UTC, before this period"
