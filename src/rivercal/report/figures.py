"""Figures: the network schematic and station hydrographs (PNG, matplotlib Agg backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.network.schema import Network

__all__ = ["plot_network", "plot_series"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _branch_xy(network: Network) -> dict[str, np.ndarray]:
    nodes = {n.id: n for n in network.nodes}
    out = {}
    for b in network.branches:
        if b.geometry:
            out[b.id] = np.asarray(b.geometry, dtype=float)
        else:
            a, c = nodes[b.from_node], nodes[b.to_node]
            out[b.id] = np.array([[a.x, a.y], [c.x, c.y]], dtype=float)
    return out


def _at(xy: np.ndarray, frac: float) -> tuple[float, float]:
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    t = frac * s[-1]
    return float(np.interp(t, s, xy[:, 0])), float(np.interp(t, s, xy[:, 1]))


def plot_network(network: Network, path: str | Path, *, title: str = "", label_weirs: bool = True,
                 weir_labels: dict[str, str] | None = None) -> Path:
    """Draw branches, nodes, weirs (labelled), culverts, pumps, stations and laterals.

    Needs node coordinates (``x``, ``y`` in m) or branch polylines. Returns the written path.
    """
    missing = [n.id for n in network.nodes if n.x is None or n.y is None]
    if missing:
        raise ValueError(f"node {missing[0]!r} has no x/y coordinates; the schematic needs them for every node")
    plt = _pyplot()
    xy = _branch_xy(network)
    lengths = {b.id: b.length for b in network.branches}
    fig, ax = plt.subplots(figsize=(11, 7.5))
    for bid, pts in xy.items():
        ax.plot(pts[:, 0], pts[:, 1], color="#2b6cb0", lw=2.2, zorder=1)
        mx, my = _at(pts, 0.5)
        ax.annotate(bid, (mx, my), xytext=(4, 4), textcoords="offset points", color="#2b6cb0", fontsize=8,
                    style="italic")
    for n in network.nodes:
        ax.plot(n.x, n.y, "o", color="white", mec="#1a365d", ms=5, zorder=3)
    bnd_nodes = {b.node: b.type for b in network.boundaries}
    for n in network.nodes:
        if n.id in bnd_nodes:
            marker = {"discharge": ">", "level": "s", "rating": "D"}[bnd_nodes[n.id]]
            ax.plot(n.x, n.y, marker, color="#2f855a", ms=9, zorder=4)
    struct_xy = {}
    flip = 0
    for kind, items, marker, colour in (("weir", network.weirs, "|", "#c53030"),
                                        ("culvert", network.culverts, "s", "#805ad5"),
                                        ("pump", network.pumps, "^", "#dd6b20")):
        for s in items:
            px, py = _at(xy[s.branch], s.chainage / lengths[s.branch])
            struct_xy[s.id] = (px, py)
            ax.plot(px, py, marker, color=colour, ms=12 if kind == "weir" else 7, mew=3, zorder=5)
            if label_weirs or kind != "weir":
                label = (weir_labels or {}).get(s.id, s.id)
                flip += 1  # alternate below/above so that neighbouring labels do not overlap
                ax.annotate(label, (px, py), xytext=(5, -12 if flip % 2 else 7), textcoords="offset points",
                            fontsize=7, color=colour)
    for st in network.stations:
        if st.structure is not None:
            px, py = struct_xy[st.structure]
        else:
            px, py = _at(xy[st.branch], st.chainage / lengths[st.branch])
        ax.plot(px, py, "o", mfc="none", mec="black", ms=15, mew=1.6, zorder=6)
        ax.annotate(st.id, (px, py), xytext=(6, 8), textcoords="offset points", fontsize=9, weight="bold")
    node_xy = {n.id: (n.x, n.y) for n in network.nodes}
    for lat in network.laterals:
        if lat.node is not None:
            px, py = node_xy[lat.node]
        else:
            px, py = _at(xy[lat.branch], lat.chainage / lengths[lat.branch])
        ax.plot(px, py, "v", color="#38a169", ms=6, zorder=4)
    handles = [
        plt.Line2D([], [], color="#2b6cb0", lw=2.2, label="branch"),
        plt.Line2D([], [], ls="", marker="|", color="#c53030", ms=12, mew=3, label="weir"),
        plt.Line2D([], [], ls="", marker="o", mfc="none", mec="black", ms=12, label="station"),
        plt.Line2D([], [], ls="", marker="v", color="#38a169", label="lateral inflow"),
        plt.Line2D([], [], ls="", marker=">", color="#2f855a", label="Q boundary"),
        plt.Line2D([], [], ls="", marker="D", color="#2f855a", label="Q(h) / level boundary"),
    ]
    if network.culverts:
        handles.append(plt.Line2D([], [], ls="", marker="s", color="#805ad5", label="culvert"))
    ax.legend(handles=handles, loc="best", fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title or "network")
    ax.grid(alpha=0.25)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def plot_series(series: pd.DataFrame, path: str | Path, *, title: str = "") -> Path:
    """Station hydrographs: levels (m AD) on the left panels, discharges (m³/s) on the right."""
    plt = _pyplot()
    stations = sorted({c.split(".")[0] for c in series.columns})
    fig, axes = plt.subplots(len(stations), 2, figsize=(12, 1.9 * len(stations) + 0.8), sharex=True, squeeze=False)
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
    plt.close(fig)
    return path



def plot_convergence(history: list[dict], names: list[str], path: str | Path, *, truth: dict | None = None,
                     units: dict | None = None, title: str = "") -> Path:
    """Parameter values per iteration (thesis Fig. 4-8), with the true values dashed when known."""
    plt = _pyplot()
    fig, axes = plt.subplots(len(names), 1, figsize=(7, 2.2 * len(names) + 0.6), sharex=True, squeeze=False)
    it = [h["iteration"] for h in history]
    for ax, name in zip(axes[:, 0], names, strict=True):
        ax.plot(it, [h[name] for h in history], "o-", color="#2b6cb0")
        if truth and name in truth:
            ax.axhline(truth[name], ls="--", color="#c53030", label="true value")
            ax.legend(fontsize=8)
        ax.set_ylabel(f"{name} ({(units or {}).get(name, '')})".replace(" ()", ""))
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("iteration")
    fig.suptitle(title or "parameter convergence")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_cost(history: list[dict], path: str | Path, *, title: str = "") -> Path:
    """Cost per iteration on a log scale (thesis Fig. 4-9), with the linearised cost where the method has one."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 3.6))
    it = [h["iteration"] for h in history]
    ax.semilogy(it, [max(h["cost"], 1e-16) for h in history], "o-", color="#2b6cb0", label="cost S")
    lin = [h.get("linear_cost", np.nan) for h in history]
    if np.isfinite(lin).any():
        ax.semilogy(it, [max(v, 1e-16) if np.isfinite(v) else np.nan for v in lin], "x--", color="#dd6b20",
                    label="linearised cost")
    ax.set_xlabel("iteration")
    ax.set_ylabel("cost (Eq. 2-3, -)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title or "cost per iteration")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
