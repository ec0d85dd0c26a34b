"""Figures: the network schematic, station hydrographs, and the maps and transitions of thesis chapter 5.

The older functions write a PNG and return its path; the chapter-5 figures (:func:`plot_network_values`,
:func:`plot_network_pair`, :func:`plot_transition_levels`) take data and return a
``matplotlib.figure.Figure`` made without pyplot (nothing global to close), for the caller to save
with ``fig.savefig(path)`` or to embed in a report. Nothing here computes beyond what it draws.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal._figure import iteration_axis, new_figure, subplots
from rivercal.network import Network
from rivercal.network.coordinates import branch_polylines, point_along, station_coordinates

__all__ = [
    "case_weir_labels",
    "mark_change",
    "plot_convergence",
    "plot_cost",
    "plot_network",
    "plot_network_pair",
    "plot_network_values",
    "plot_series",
    "plot_transition_levels",
]



def plot_network(network: Network, path: str | Path, *, title: str = "", label_weirs: bool = True,
                 weir_labels: dict[str, str] | None = None) -> Path:
    """Draw branches, nodes, weirs (labelled), culverts, pumps, stations and laterals.

    Needs node coordinates (``x``, ``y`` in m) or branch polylines. Returns the written path. Labels are
    placed clear of one another; where there would be more than :data:`MAX_PLACED_LABELS`, the branches'
    names are left out, then the structures'.
    """
    missing = [n.id for n in network.nodes if n.x is None or n.y is None]
    if missing:
        raise ValueError(f"node {missing[0]!r} has no x/y coordinates; the schematic needs them for every node")
    from matplotlib.lines import Line2D

    xy = branch_polylines(network)
    lengths = {b.id: b.length for b in network.branches}
    fig, ax = subplots(figsize=(11, 7.5))
    labels: list[tuple[float, float, str, dict[str, Any]]] = []  # anchor (m), text, style; placed at the end
    for bid, pts in xy.items():
        ax.plot(pts[:, 0], pts[:, 1], color="#2b6cb0", lw=2.2, zorder=1)
        mx, my = point_along(pts, 0.5)
        labels.append((mx, my, bid, {"color": "#2b6cb0", "fontsize": 8, "style": "italic"}))
    for n in network.nodes:
        ax.plot(n.x, n.y, "o", color="white", mec="#1a365d", ms=5, zorder=3)
    bnd_nodes = {b.node: b.type for b in network.boundaries}
    for n in network.nodes:
        if n.id in bnd_nodes:
            marker = {"discharge": ">", "level": "s", "rating": "D", "critical": "v"}[bnd_nodes[n.id]]
            ax.plot(n.x, n.y, marker, color="#2f855a", ms=9, zorder=4)
    struct_xy = {}
    kinds = (("weir", network.weirs, "|", "#c53030"), ("culvert", network.culverts, "s", "#805ad5"),
             ("pump", network.pumps, "^", "#dd6b20"), ("orifice", network.orifices, "|", "#975a16"),
             ("universal weir", network.universal_weirs, "|", "#9b2c2c"), ("bridge", network.bridges, "H", "#4a5568"))
    for kind, items, marker, colour in kinds:
        for s in items:
            px, py = point_along(xy[s.branch], s.chainage / lengths[s.branch])
            struct_xy[s.id] = (px, py)
            ax.plot(px, py, marker, color=colour, ms=12 if kind == "weir" else 7, mew=3, zorder=5)
            if label_weirs or kind != "weir":
                labels.append((px, py, (weir_labels or {}).get(s.id, s.id), {"fontsize": 7, "color": colour}))
    for st in network.stations:
        if st.structure is not None:
            px, py = struct_xy[st.structure]
        else:
            px, py = point_along(xy[st.branch], st.chainage / lengths[st.branch])
        ax.plot(px, py, "o", mfc="none", mec="black", ms=15, mew=1.6, zorder=6)
        labels.append((px, py, st.id, {"fontsize": 9, "weight": "bold"}))
    node_xy = {n.id: (n.x, n.y) for n in network.nodes}
    for lat in network.laterals:
        if lat.node is not None:
            px, py = node_xy[lat.node]
        else:
            px, py = point_along(xy[lat.branch], lat.chainage / lengths[lat.branch])
        ax.plot(px, py, "v", color="#38a169", ms=6, zorder=4)
    handles = [
        Line2D([], [], color="#2b6cb0", lw=2.2, label="branch"),
        Line2D([], [], ls="", marker="|", color="#c53030", ms=12, mew=3, label="weir"),
        Line2D([], [], ls="", marker="o", mfc="none", mec="black", ms=12, label="station"),
        Line2D([], [], ls="", marker="v", color="#38a169", label="lateral inflow"),
        Line2D([], [], ls="", marker=">", color="#2f855a", label="Q boundary"),
        Line2D([], [], ls="", marker="D", color="#2f855a", label="Q(h) / level boundary"),
    ]
    handles += [Line2D([], [], ls="", marker=marker, color=colour, ms=7, mew=2, label=kind)
                for kind, items, marker, colour in kinds[1:] if items]
    ax.margins(0.07)  # room inside the frame for the labels of points at its edges
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title or "network")
    ax.grid(alpha=0.25)
    fig.tight_layout()
    avoid = [pts[np.linspace(0, len(pts) - 1, 12).astype(int)] for pts in xy.values()]  # along the lines
    avoid.append(np.array([(n.x, n.y) for n in network.nodes], dtype=float))
    _place_labels(ax, _fewer_labels(labels, len(xy), len(network.stations)), np.vstack(avoid))
    ax.legend(handles=handles, loc="best", fontsize=8)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    return path


#: Up to this many labels are placed clear of one another; more (a board-size network) are written at fixed
#: offsets, alternately below and above (the search costs the number of labels squared).
MAX_PLACED_LABELS = 300
#: Where a label may go, offset from its point (points) with its alignment, nearest first; the outer two
#: rings get a leader line to the point.
_SPOTS = [((dx * r, dy * r), ha, va, r > 1) for r in (1, 2.6, 4.5) for dx, dy, ha, va in (
    (5, 5, "left", "bottom"), (5, -5, "left", "top"), (-5, 5, "right", "bottom"), (-5, -5, "right", "top"),
    (0, 9, "center", "bottom"), (0, -9, "center", "top"), (9, 0, "left", "center"), (-9, 0, "right", "center"))]


def _fewer_labels(labels: list, branches: int, stations: int) -> list:
    """``labels`` (the branches' first, the stations' last) cut to at most :data:`MAX_PLACED_LABELS` where they can be.

    The branches' names are left out first, then the structures'; the stations' names always stay.
    """
    if len(labels) > MAX_PLACED_LABELS:
        labels = labels[branches:]
    if len(labels) > MAX_PLACED_LABELS and stations:
        labels = labels[-stations:]
    return labels


def _place_labels(ax: Any, labels: list[tuple[float, float, str, dict[str, Any]]], avoid: np.ndarray) -> None:
    """Write each label beside its point where it overlaps no label placed before it and covers no point.

    ``labels`` (anchor in m, text, style) are placed in their order, each at the first free spot of
    :data:`_SPOTS` inside the frame (the outer ones with a leader line), else where it overlaps least. ``avoid`` are
    further points a label should not cover (along the branches, markers; m). Beyond
    :data:`MAX_PLACED_LABELS` the labels keep fixed offsets.
    """
    if len(labels) > MAX_PLACED_LABELS:
        for k, (x, y, text, style) in enumerate(labels):
            ax.annotate(text, (x, y), xytext=(5, -12 if k % 2 else 7), textcoords="offset points", zorder=7, **style)
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Text

    fig = ax.get_figure()
    renderer = FigureCanvasAgg(fig).get_renderer()  # this figure's own canvas: no pyplot, no backend change
    ax.apply_aspect()
    anchors = np.array([(x, y) for x, y, *_ in labels], dtype=float).reshape(-1, 2)
    points = ax.transData.transform(np.vstack([anchors, avoid]))  # pixels
    frame = ax.get_window_extent(renderer)
    placed: list[Any] = []
    for (x, y, text, style), own in zip(labels, points[: len(labels)], strict=True):
        best = None
        for offset, ha, va, leader in _SPOTS:
            label = ax.annotate(text, (x, y), xytext=offset, textcoords="offset points", ha=ha, va=va, zorder=7,
                                arrowprops={"arrowstyle": "-", "color": "#718096", "lw": 0.5} if leader else None,
                                **style)
            label.update_positions(renderer)
            box = Text.get_window_extent(label, renderer).expanded(1.04, 1.1)  # the text's, without its leader
            inside = (points[:, 0] >= box.x0) & (points[:, 0] <= box.x1) & (points[:, 1] >= box.y0) \
                & (points[:, 1] <= box.y1)
            outside = not (frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1)
            clash = (sum(box.overlaps(b) for b in placed) + outside) * 10 + int(inside.sum()) - int(box.contains(*own))
            if best is not None and clash >= best[0]:
                label.remove()
                continue
            if best is not None:
                best[1].remove()
            best = (clash, label, box)
            if clash == 0:
                break
        placed.append(best[2])


def plot_series(series: pd.DataFrame, path: str | Path, *, title: str = "") -> Path:
    """Station hydrographs: levels (m AD) on the left panels, discharges (m³/s) on the right."""
    stations = sorted({c.split(".")[0] for c in series.columns})
    fig, axes = subplots(len(stations), 2, figsize=(12, 1.9 * len(stations) + 0.8), sharex=True, squeeze=False)
    for row, st in enumerate(stations):
        ax_h, ax_q = axes[row]
        for c in series.columns:
            name, qty = c.split(".", 1)
            if name != st:
                continue
            if qty == "Q":
                ax_q.plot(series.index, series[c], color="#2f855a", lw=1.2, label=c)
            else:
                ax_h.plot(series.index, series[c], lw=1.2, label=c)
        ax_h.set_ylabel("level (m AD)")
        ax_q.set_ylabel("Q (m³/s)")
        for ax in (ax_h, ax_q):
            if ax.lines:
                ax.legend(fontsize=7, loc="upper right")
            else:
                ax.set_visible(False)
            ax.grid(alpha=0.3)
    fig.suptitle(title or "station series")
    fig.autofmt_xdate()
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path



def plot_convergence(history: list[dict], names: list[str], path: str | Path, *, truth: dict | None = None,
                     units: dict | None = None, title: str = "") -> Path:
    """Parameter values per iteration (thesis Fig. 4-8), with the true values dashed when known."""
    fig, axes = subplots(len(names), 1, figsize=(7, 2.2 * len(names) + 0.6), sharex=True, squeeze=False)
    it = [h["iteration"] for h in history]
    for ax, name in zip(axes[:, 0], names, strict=True):
        ax.plot(it, [h[name] for h in history], "o-", color="#2b6cb0")
        if truth and name in truth:
            ax.axhline(truth[name], ls="--", color="#c53030", label="true value")
            ax.legend(fontsize=8)
        ax.set_ylabel(f"{name} ({(units or {}).get(name, '')})".replace(" ()", ""))
        ax.grid(alpha=0.3)
    iteration_axis(axes[-1, 0])
    fig.suptitle(title or "parameter convergence")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_cost(history: list[dict], path: str | Path, *, title: str = "") -> Path:
    """Cost per iteration on a log scale (thesis Fig. 4-9), with the linearised cost where the method has one."""
    fig, ax = subplots(figsize=(7, 3.6))
    it = [h["iteration"] for h in history]
    ax.semilogy(it, [max(h["cost"], 1e-16) for h in history], "o-", color="#2b6cb0", label="cost S")
    lin = [h.get("linear_cost", np.nan) for h in history]
    if np.isfinite(lin).any():
        ax.semilogy(it, [max(v, 1e-16) if np.isfinite(v) else np.nan for v in lin], "x--", color="#dd6b20",
                    label="linearised cost")
    iteration_axis(ax)
    ax.set_ylabel("cost (Eq. 2-3, -)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title or "cost per iteration")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


# -- thesis chapter 5: values on the network map, and the levels around a transition ---------------


def _network_of(case: Any) -> Network:
    return case.network if hasattr(case, "network") else case


def case_weir_labels(case: Any) -> dict[str, str]:
    """``"W4 ZL1-5930"`` for a weir that a single-target parameter of the case sets, else nothing."""
    names = {}
    for p in getattr(getattr(case, "spec", None), "parameters", None) or []:
        for target in p.targets:
            if target.startswith("weir:") and target.endswith(".crest_level"):
                names[target[5:-12]] = f"{p.name} {target[5:-12]}"
    return names


def _point_xy(network: Network, labels: pd.Index) -> np.ndarray:
    """Map positions (m) of calculation points labelled ``node:<id>`` or ``<branch>@<chainage>``."""
    xy = branch_polylines(network)
    lengths = {b.id: b.length for b in network.branches}
    nodes = {n.id: n for n in network.nodes}
    out = np.empty((len(labels), 2))
    for i, label in enumerate(map(str, labels)):
        if label.startswith("node:") and label[5:] in nodes:
            n = nodes[label[5:]]
            out[i] = (n.x, n.y)
            continue
        branch, _, chainage = label.rpartition("@")
        try:
            out[i] = point_along(xy[branch], float(chainage) / lengths[branch])
        except (KeyError, ValueError):
            raise ValueError(f"calculation point {label!r} is neither 'node:<id>' nor '<branch>@<chainage>' of a "
                             "branch of this network") from None
    return out


def _draw_values(ax: Any, network: Network, values: pd.Series, norm: Any, cmap: str,
                 weir_labels: dict[str, str]) -> Any:
    """Branches, coloured calculation points, weirs and stations on ``ax``; returns the coloured points."""
    missing = [n.id for n in network.nodes if n.x is None or n.y is None]
    if missing:
        raise ValueError(f"node {missing[0]!r} has no x/y coordinates; the map needs them for every node")
    xy = branch_polylines(network)
    lengths = {b.id: b.length for b in network.branches}
    for pts in xy.values():
        ax.plot(pts[:, 0], pts[:, 1], color="#cbd5e0", lw=5, solid_capstyle="round", zorder=1)
    pts = _point_xy(network, values.index)
    v = values.to_numpy(dtype=float)
    known = np.isfinite(v)
    if (~known).any():
        ax.scatter(pts[~known, 0], pts[~known, 1], s=10, color="#a0aec0", zorder=2)
    points = ax.scatter(pts[known, 0], pts[known, 1], c=v[known], cmap=cmap, norm=norm, s=22, edgecolors="#4a5568",
                        linewidths=0.3, zorder=3)
    at_station = {st.structure for st in network.stations}
    span = max(np.ptp(np.concatenate([p[:, 0] for p in xy.values()])), 1.0)
    below: list[tuple[float, float]] = []
    for w in sorted(network.weirs, key=lambda w: point_along(xy[w.branch], w.chainage / lengths[w.branch])):
        px, py = point_along(xy[w.branch], w.chainage / lengths[w.branch])
        ax.plot(px, py, marker="|", color="#1a202c", ms=11, mew=2.5, zorder=4)
        if w.id in at_station:
            continue  # the station's label names the place
        # label below, unless a label below is already that close (then above)
        crowded = any(np.hypot(px - bx, py - by) < 0.07 * span for bx, by in below)
        if not crowded:
            below.append((px, py))
        ax.annotate(weir_labels.get(w.id, w.id), (px, py), xytext=(4, 6 if crowded else -11),
                    textcoords="offset points", fontsize=6.5, color="#2d3748")
    for sid, (px, py) in station_coordinates(network).items():
        ax.plot(px, py, "o", mfc="none", mec="black", ms=14, mew=1.5, zorder=5)
        ax.annotate(sid, (px, py), xytext=(6, 8), textcoords="offset points", fontsize=8.5, weight="bold")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.2)
    return points


def _symmetric_norm(vmax: float | None, *values: pd.Series) -> Any:
    from matplotlib.colors import Normalize

    if vmax is None:
        finite = [np.abs(v.to_numpy(dtype=float)) for v in values]
        finite = [a[np.isfinite(a)] for a in finite]
        vmax = max((float(a.max()) for a in finite if a.size), default=0.0)
        vmax = vmax if vmax > 0.0 else 1e-3  # all zero (thesis Fig. 5-2): a valid scale, every point white
    elif not vmax > 0.0:
        raise ValueError(f"vmax must be positive, got {vmax}")
    return Normalize(-vmax, vmax)


def plot_network_values(case: Any, values: pd.Series, *, title: str, label: str, ax: Any = None,
                        vmax: float | None = None, cmap: str = "RdBu_r",
                        weir_labels: dict[str, str] | None = None) -> Any:
    """The network map with every calculation point coloured by a value (thesis Figs. 5-2, 5-3, 5-5 …).

    Parameters
    ----------
    case
        A loaded case (or its network); nodes need map coordinates.
    values
        One value per calculation point, indexed by its label (``compiled.hp_label``: ``node:<id>`` or
        ``<branch>@<chainage>``), e.g. the average level error Δŷ_avg in m. Points with NaN are drawn grey.
    title
        Axes title.
    label
        Colour-bar label with units, e.g. ``"Δŷ_avg (m)"``.
    ax
        Axes to draw on (default: a new figure).
    vmax
        Half-width of the symmetric colour scale, in the unit of ``values`` (default max |value|).
    cmap
        A diverging colour map (zero is its middle).
    weir_labels
        Label per weir id (default: ``"W4 ZL1-5930"`` where a case parameter sets that crest, else the id).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        For a label that is not a calculation point of the network, a node without coordinates, or vmax ≤ 0.
    """
    network = _network_of(case)
    labels = case_weir_labels(case) if weir_labels is None else weir_labels
    norm = _symmetric_norm(vmax, values)
    if ax is None:
        fig = new_figure(figsize=(10, 6.5), layout="constrained")
        ax = fig.add_subplot()
    fig = ax.figure
    points = _draw_values(ax, network, values, norm, cmap, labels)
    fig.colorbar(points, ax=ax, label=label, shrink=0.8)
    ax.set_title(title)
    return fig


def plot_network_pair(case: Any, left: pd.Series, right: pd.Series, *, label: str,
                             titles: tuple[str, str] = ("DSS", "rivercal"), suptitle: str = "",
                             vmax: float | None = None, cmap: str = "RdBu_r",
                             weir_labels: dict[str, str] | None = None) -> Any:
    """Two network maps side by side on one colour scale, e.g. Δŷ_avg (m) of the DSS and of rivercal.

    ``left`` and ``right`` are values per calculation point as in :func:`plot_network_values`; the
    symmetric scale spans the larger of both (or ``vmax``), so equal colours mean equal values.

    Returns
    -------
    matplotlib.figure.Figure
    """
    network = _network_of(case)
    labels = case_weir_labels(case) if weir_labels is None else weir_labels
    norm = _symmetric_norm(vmax, left, right)
    fig = new_figure(figsize=(16, 6), layout="constrained")
    axes = fig.subplots(1, 2)
    for ax, values, title in zip(axes, (left, right), titles, strict=True):
        points = _draw_values(ax, network, values, norm, cmap, labels)
        ax.set_title(title)
    fig.colorbar(points, ax=list(axes), label=label, shrink=0.8)
    if suptitle:
        fig.suptitle(suptitle)
    return fig


def _axis_label(series_id: str) -> str:
    return "Q (m³/s)" if series_id.rpartition(".")[2] == "Q" else "level (m AD)"


def plot_transition_levels(observed: pd.DataFrame, dss: pd.DataFrame, updated: pd.DataFrame, *,
                           series: list[str], change_time: Any, title: str, dss_label: str = "DSS",
                           updated_label: str = "rivercal", observed_label: str = "observed") -> Any:
    """Series around a parameter transition (thesis Fig. 5-4): observations, DSS and the updated model.

    Parameters
    ----------
    observed, dss, updated
        Frames indexed by UTC time with one column per series id (``"<station>.<quantity>"``; levels in
        m AD, discharges in m³/s): the observations (grey circles), the fixed-parameter DSS (red line) and
        the model with rivercal's estimates (blue line).
    series
        The series to draw, one panel each, e.g. ``["ZL1-5930.h_up", "ZL1-5930.h_down"]``.
    change_time
        Moment of the transition, drawn as a dashed black vertical line; when it lies outside the
        series' period, named in the time axis's label instead (see :func:`mark_change`).
    title
        Figure title.
    dss_label, updated_label
        Legend entries of the two models.
    observed_label
        Legend entry of the circles (e.g. "truth" when they are a twin's noise-free truth, not observations).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    KeyError
        When a series is missing from one of the frames (named).
    ValueError
        When ``series`` is empty.
    """
    if not series:
        raise ValueError("series is empty: name at least one '<station>.<quantity>' to draw")
    for name, frame in (("observed", observed), ("dss", dss), ("updated", updated)):
        absent = [s for s in series if s not in frame.columns]
        if absent:
            have = ", ".join(map(str, frame.columns))
            raise KeyError(f"series {absent[0]!r} is not a column of {name} (have: {have})")
    from matplotlib.dates import AutoDateLocator, ConciseDateFormatter

    change = pd.Timestamp(change_time)
    shown = [frame.index for frame in (observed, dss, updated) if len(frame.index)]
    fig = new_figure(figsize=(11, 2.6 * len(series) + 0.8), layout="constrained")
    axes = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
    for ax, sid in zip(axes, series, strict=True):
        ax.plot(observed.index, observed[sid], "o", mfc="none", mec="#718096", ms=3.5, mew=0.8, label=observed_label,
                zorder=1)
        ax.plot(dss.index, dss[sid], "-", color="#c53030", lw=1.5, label=dss_label, zorder=2)
        ax.plot(updated.index, updated[sid], "-", color="#2b6cb0", lw=1.5, label=updated_label, zorder=3)
        ax.set_ylabel(_axis_label(sid))
        ax.set_title(sid, fontsize=10, loc="left")
        ax.grid(alpha=0.3)
    mark_change(axes, change, min(i.min() for i in shown), max(i.max() for i in shown), axis_label="time (UTC)",
                label="transition")
    axes[0].legend(fontsize=8, loc="best", ncols=4)
    locator = AutoDateLocator()
    axes[-1].xaxis.set_major_locator(locator)
    axes[-1].xaxis.set_major_formatter(ConciseDateFormatter(locator))
    fig.suptitle(title)
    return fig


def mark_change(axes: Any, change: pd.Timestamp | None, lo: pd.Timestamp, hi: pd.Timestamp, *, axis_label: str,
                label: str | None = None) -> None:
    """Mark a transition at ``change`` on panels that share a time axis from ``lo`` to ``hi`` (UTC times).

    Where it lies in ``lo`` .. ``hi``, a dashed line on every panel of ``axes`` (one Axes or a sequence);
    outside, nothing is drawn and the time axis's label of the last panel, ``axis_label``, names it. A line
    far outside the data would stretch the time axis to it and crowd the data at one edge (a replay that
    begins weeks after the change).
    """
    panels = list(np.atleast_1d(axes))
    note = ""
    if change is not None and lo <= change <= hi:
        for ax in panels:
            ax.axvline(change, ls="--", color="black", lw=1.2, label=label, zorder=4)
    elif change is not None:
        note = f"; transition {change:%Y-%m-%d %H:%M} UTC, {'before' if change < lo else 'after'} this period"
    panels[-1].set_xlabel(axis_label + note)
