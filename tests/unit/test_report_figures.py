"""The chapter-5 figures: values on the network map, two maps on one scale, levels around a transition."""

import io

import numpy as np
import pandas as pd
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.text import Text

from rivercal._figure import subplots
from rivercal.case import load_case
from rivercal.engine.compile import compile_network
from rivercal.report.figures import plot_network_pair, plot_network_values, plot_transition_levels


@pytest.fixture(scope="module")
def case():
    return load_case("dommel")


@pytest.fixture(scope="module")
def labels(case):
    return pd.Index(compile_network(case.network, case.spec.engine).hp_label)


def _texts(ax):
    return {t.get_text() for t in ax.texts}


def test_every_calculation_point_is_coloured_on_a_symmetric_scale(case, labels, tmp_path):
    values = pd.Series(np.linspace(-0.05, 0.2, labels.size), index=labels)
    fig = plot_network_values(case, values, title="PI-Fg: DSS", label="Δŷ_avg (m)")
    assert isinstance(fig, Figure)
    ax, cbar = fig.axes
    assert ax.get_title() == "PI-Fg: DSS" and cbar.get_ylabel() == "Δŷ_avg (m)"
    (points,) = ax.collections
    np.testing.assert_allclose(points.get_array(), values.to_numpy())
    assert points.get_offsets().shape == (labels.size, 2)
    assert (points.norm.vmin, points.norm.vmax) == (-0.2, 0.2)  # symmetric about 0, zero is white
    # the five stations are marked, the adjustable weirs carry their parameter names
    assert {"0028", "0040", "0029", "0030", "0031"} <= _texts(ax)
    assert {"W4 ZL1-5930", "W9 ZL25-8463"} <= _texts(ax)
    # map positions follow the case geometry: the upstream node of ZL1 sits at (0, 0)
    xy = dict(zip(values.index, map(tuple, points.get_offsets()), strict=True))
    assert xy["node:ZL1_up"] == (0.0, 0.0)
    fig.savefig(tmp_path / "map.png")
    assert (tmp_path / "map.png").stat().st_size > 10_000


def test_all_zero_values_give_a_valid_white_map_and_nan_points_are_grey(case, labels):
    zero = pd.Series(0.0, index=labels)
    fig = plot_network_values(case, zero, title="DSS before the transition", label="Δŷ_avg (m)")
    (points,) = fig.axes[0].collections
    assert points.norm.vmax > 0 and points.norm.vmin == -points.norm.vmax
    assert np.allclose(points.to_rgba(points.get_array())[:, :3], 0.97, atol=0.03)  # the middle of RdBu_r
    partial = zero.copy()
    partial.iloc[:10] = np.nan
    fig = plot_network_values(case, partial, title="", label="m", vmax=0.1)
    grey, coloured = fig.axes[0].collections
    assert len(grey.get_offsets()) == 10 and len(coloured.get_offsets()) == labels.size - 10
    assert coloured.norm.vmax == 0.1


def test_map_draws_into_a_given_axes_and_rejects_unknown_points(case, labels):
    fig = Figure()
    ax = fig.add_subplot()
    assert plot_network_values(case.network, pd.Series(0.01, index=labels), title="t", label="m", ax=ax) is fig
    with pytest.raises(ValueError, match=r"calculation point 'Nowhere@12\.0' is neither"):
        plot_network_values(case, pd.Series([0.1], index=["Nowhere@12.0"]), title="t", label="m")
    with pytest.raises(ValueError, match="vmax must be positive, got 0"):
        plot_network_values(case, pd.Series(0.01, index=labels), title="t", label="m", vmax=0)


def test_pair_shares_one_colour_scale(case, labels):
    dss = pd.Series(0.30, index=labels)
    ours = pd.Series(-0.05, index=labels)
    fig = plot_network_pair(case, dss, ours, label="Δŷ_avg (m)", suptitle="PI-Fg after the transition")
    left, right, cbar = fig.axes
    assert (left.get_title(), right.get_title()) == ("DSS", "rivercal")
    assert cbar.get_ylabel() == "Δŷ_avg (m)"
    norms = [(ax.collections[0].norm.vmin, ax.collections[0].norm.vmax) for ax in (left, right)]
    assert norms == [(-0.30, 0.30), (-0.30, 0.30)]
    assert fig.get_suptitle() == "PI-Fg after the transition"


def test_transition_figure_has_observations_dss_rivercal_and_the_change(tmp_path):
    times = pd.date_range("2010-10-18", "2010-11-15", freq="h", tz="UTC")
    base = pd.DataFrame({"0028.h_up": 10.5 + 0.1 * np.sin(np.arange(times.size) / 30),
                         "0029.Q": 1.0 + 0.5 * np.cos(np.arange(times.size) / 40)}, index=times)
    change = pd.Timestamp("2010-11-01", tz="UTC")
    fig = plot_transition_levels(base + 0.01, base + 0.1, base, series=["0028.h_up", "0029.Q"], change_time=change,
                                 title="PI-Fg at 0028")
    ax_h, ax_q = fig.axes
    assert fig.get_suptitle() == "PI-Fg at 0028"
    assert ax_h.get_ylabel() == "level (m AD)" and ax_q.get_ylabel() == "Q (m³/s)"
    assert ax_q.get_xlabel() == "time (UTC)"
    observed, dss, ours, vline = ax_h.lines
    assert observed.get_marker() == "o" and observed.get_linestyle() == "None"
    assert to_rgba(dss.get_color())[0] > 0.7 and to_rgba(ours.get_color())[2] > 0.6  # red DSS, blue rivercal
    assert vline.get_linestyle() == "--" and vline.get_color() == "black"
    assert [t.get_text() for t in ax_h.get_legend().get_texts()] == ["observed", "DSS", "rivercal", "transition"]
    fig.savefig(tmp_path / "transition.png")
    assert (tmp_path / "transition.png").stat().st_size > 10_000


def test_transition_figure_names_a_missing_series():
    frame = pd.DataFrame({"a.h": [1.0]}, index=pd.DatetimeIndex(["2010-11-01"], tz="UTC"))
    with pytest.raises(KeyError, match=r"series 'b\.h' is not a column of dss"):
        plot_transition_levels(frame.assign(**{"b.h": 1.0}), frame, frame, series=["b.h"], change_time="2010-11-01",
                               title="t")
    with pytest.raises(ValueError, match="series is empty"):
        plot_transition_levels(frame, frame, frame, series=[], change_time="2010-11-01", title="t")


def test_iteration_axes_tick_whole_iterations_only():
    from rivercal._figure import iteration_axis, subplots

    fig, ax = subplots(figsize=(7, 3))
    ax.plot(range(5), [1e4, 16.0, 0.4, 5e-3, 1e-6], "o-")  # five iterations: matplotlib alone ticks 0.5, 1.5 …
    iteration_axis(ax)
    fig.canvas.draw()
    lo, hi = ax.get_xlim()
    ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
    assert len(ticks) >= 3 and all(float(t).is_integer() for t in ticks), ticks
    assert ax.get_xlabel() == "iteration"


def test_schematic_labels_are_placed_apart_inside_the_frame_with_leaders_when_far():
    """Labels of points that lie together (a station at its weir, a branch's middle near both) are placed so that
    no two overlap and none leaves the frame; one placed in the outer ring is joined to its point by a line."""
    from rivercal.report.figures import _place_labels

    _, ax = subplots(figsize=(6, 4))
    ax.plot([0, 1000], [0, 500], lw=2)
    ax.set_xlim(-100, 1100)
    ax.set_ylim(-100, 600)
    names = ["ZL1_0030_3990", "W2 ZL1-3014", "W5 ZL12-4536", "ZL1-4018", "0028", "0040"]  # as at dommel's 0040
    labels = [(400.0 + 60 * (k % 2), 200.0 + 30 * (k % 2), name, {"fontsize": 9}) for k, name in enumerate(names)]
    _place_labels(ax, labels, np.array([[0.0, 0.0], [1000.0, 500.0]]))
    assert [t.get_text() for t in ax.texts] == names
    ax.get_figure().savefig(io.BytesIO(), format="png")  # drawn as written: the labels' positions are final
    boxes = [Text.get_window_extent(t) for t in ax.texts]  # the texts' (not their leaders'), in pixels
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert not a.overlaps(b), (a, b)
    frame = ax.get_window_extent()
    assert all(frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1 for b in boxes)
    far = [t for t in ax.texts if max(abs(v) for v in t.xyann) > 10]
    assert far and all(t.arrow_patch is not None for t in far)
    assert all(t.arrow_patch is None for t in ax.texts if t not in far)


def test_schematic_labels_beyond_the_limit_keep_fixed_offsets():
    """Many labels (a board-size network) are written at fixed offsets, at once, not moved apart."""
    from rivercal.report.figures import MAX_PLACED_LABELS, _place_labels

    _, ax = subplots()
    n = MAX_PLACED_LABELS + 1
    _place_labels(ax, [(float(k), 0.0, f"L{k}", {}) for k in range(n)], np.empty((0, 2)))
    offsets = {t.xyann for t in ax.texts}
    assert len(ax.texts) == n and offsets == {(5, 7), (5, -12)}


def test_a_dense_schematic_leaves_out_branch_names_then_structure_names_but_never_station_names():
    from rivercal.report.figures import MAX_PLACED_LABELS, _fewer_labels

    def labels(branches: int, structures: int, stations: int) -> list[str]:
        return [f"B{k}" for k in range(branches)] + [f"W{k}" for k in range(structures)] + \
            [f"S{k}" for k in range(stations)]

    few = labels(10, 20, 5)
    assert _fewer_labels(few, 10, 5) == few
    room = MAX_PLACED_LABELS - 5
    assert _fewer_labels(labels(50, room, 5), 50, 5) == labels(0, room, 5)
    assert _fewer_labels(labels(50, room + 1, 5), 50, 5) == labels(0, 0, 5)
    assert _fewer_labels(labels(0, 10, MAX_PLACED_LABELS + 1), 0, MAX_PLACED_LABELS + 1) == \
        labels(0, 0, MAX_PLACED_LABELS + 1)  # then all at fixed offsets (see _place_labels)
