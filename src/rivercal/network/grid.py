"""The computational grid of a network: where the calculation points and the links between them lie.

The grid is staggered: levels at *h-points* (the connection nodes, then the calculation points inside
the branches, branch by branch along their length), discharges at *links* between consecutive
h-points of a branch. A structure occupies its own short link of ``structure_length`` metres centred
on its chainage (:func:`branch_layout`), so the h-points at the ends of that link carry the levels
just up- and downstream of it.

This is pure data about where things are; the engine turns it into tables and arrays
(:mod:`rivercal.engine.compile`), and the case checks stations and laterals against the same layout.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from rivercal.errors import StructureOverlap
from rivercal.network import Branch, Bridge, Culvert, Network, Orifice, Pump, UniversalWeir, Weir

__all__ = ["Grid", "Segment", "StructureOverlap", "branch_layout", "chainages", "layout_grid"]

Structure = Weir | Culvert | Pump | Orifice | UniversalWeir | Bridge


@dataclass(frozen=True)
class Segment:
    """A stretch of a branch between two calculation points, m from the start of the branch.

    Attributes
    ----------
    a, b
        Chainages of its ends, m.
    structure
        The structure that occupies it, or ``None`` for open channel.
    """

    a: float
    b: float
    structure: Structure | None = None


def branch_layout(branch: Branch, structures: list[Structure], structure_length: float) -> list[Segment]:
    """Split a branch into channel segments (at most ``dx`` long) and one short segment per structure.

    A branch with explicit calculation points (``points``) is split at them instead, and each structure
    occupies the stretch between the two points around it (two structures in one stretch overlap).

    A structure occupies a segment of ``structure_length`` (at most the branch length) centred on its
    chainage. When the channel piece between that segment and an end of the branch would be shorter
    than half the branch's ``dx`` (or a quarter of the structure length), the structure's segment
    reaches the end node instead: the structure then discharges into (or draws from) the node itself.
    A very short cell beside a structure would hold a few m³ and be emptied and refilled within one
    time step (the velocity Courant number |u|Δt/Δx exceeds 1), which makes the level there flip from
    step to step.

    Parameters
    ----------
    branch
        The branch.
    structures
        The weirs, culverts and pumps on it, in the order weirs, culverts, pumps.
    structure_length
        ``engine.structure_length``, m.

    Returns
    -------
    list of Segment
        Consecutive segments from chainage 0 to the branch length.

    Raises
    ------
    StructureOverlap
        When a structure's segment would overlap the previous one.
    """
    if branch.points is not None:
        return _points_layout(branch, structures, structure_length)
    length = branch.length
    half = 0.5 * min(structure_length, length)
    snap = max(0.5 * half, 0.5 * branch.dx)
    segs: list[Segment] = []
    pos = 0.0
    previous: Structure | None = None
    for s in sorted(structures, key=lambda s: s.chainage):
        a, b = s.chainage - half, s.chainage + half
        if a < snap:
            a, b = 0.0, max(b, min(2 * half, length))
        if b > length - snap:
            b, a = length, min(a, max(length - 2 * half, 0.0))
        if a < pos - 1e-9 and previous is not None:
            raise StructureOverlap(s, previous, branch.id, structure_length)
        if a > pos + 1e-9:
            segs.extend(_fill(pos, a, branch.dx))
        segs.append(Segment(a, b, s))
        pos = b
        previous = s
    if pos < length - 1e-9:
        segs.extend(_fill(pos, length, branch.dx))
    return segs


def _points_layout(branch: Branch, structures: list[Structure], structure_length: float) -> list[Segment]:
    """The layout of a branch with given calculation points: a structure occupies the stretch around it."""
    pts = [0.0, *branch.points[1:-1], branch.length]
    owner: dict[int, Structure] = {}
    for s in sorted(structures, key=lambda s: s.chainage):
        j = int(np.clip(np.searchsorted(pts, s.chainage, side="right") - 1, 0, len(pts) - 2))
        if j in owner:
            raise StructureOverlap(s, owner[j], branch.id, structure_length)
        owner[j] = s
    return [Segment(pts[j], pts[j + 1], owner.get(j)) for j in range(len(pts) - 1)]


def chainages(segments: list[Segment]) -> np.ndarray:
    """Chainages of the calculation points of a laid-out branch (both end nodes included), m."""
    return np.array([segments[0].a] + [s.b for s in segments])


def _fill(a: float, b: float, dx: float) -> list[Segment]:
    n = max(1, int(np.ceil((b - a) / dx - 1e-9)))
    edges = np.linspace(a, b, n + 1)
    return [Segment(float(edges[i]), float(edges[i + 1])) for i in range(n)]


@dataclass(frozen=True)
class Grid:
    """The h-points and links of a network, numbered as the engine's arrays are.

    Attributes
    ----------
    hp_label, hp_branch, hp_chainage, hp_xy
        Per h-point: label (``node:<id>`` or ``<branch>@<chainage>``), branch id ("" for a node),
        chainage (m; nan for a node), map position (m; nan where unknown).
    sections
        Per h-point, the channel it represents: (profile index, bed level m AD, length m) for each
        half-segment of a branch that ends at the point.
    link_k1, link_k2
        Per link: its first and second h-point (in branch direction).
    link_length, link_chainage
        Per link: its length and the chainage of its midpoint, m.
    link_branch, link_branch_id
        Per link: index and id of its branch.
    link_p1, link_b1, link_p2, link_b2
        Per link: profile index and bed level (m AD) at its k1 and k2 end.
    link_structure
        Per link: the structure on it, or ``None`` for a channel link.
    link_label
        Per link: ``<branch>@<chainage>`` or ``<kind>:<structure id>``.
    structure_link
        Link index of each structure id.
    node_index
        h-point index of each node id (the nodes come first, in the network's order).
    branch_points
        Per branch id: the chainages of its h-points (m, end nodes included) and their indices.
    """

    hp_label: list[str]
    hp_branch: list[str]
    hp_chainage: np.ndarray
    hp_xy: np.ndarray
    sections: list[list[tuple[int, float, float]]]
    link_k1: np.ndarray
    link_k2: np.ndarray
    link_length: np.ndarray
    link_chainage: np.ndarray
    link_branch: np.ndarray
    link_branch_id: list[str]
    link_p1: np.ndarray
    link_b1: np.ndarray
    link_p2: np.ndarray
    link_b2: np.ndarray
    link_structure: list[Structure | None]
    link_label: list[str]
    structure_link: dict[str, int]
    node_index: dict[str, int]
    branch_points: dict[str, tuple[np.ndarray, list[int]]]

    @property
    def n_points(self) -> int:
        """Number of h-points."""
        return len(self.hp_label)

    @property
    def n_links(self) -> int:
        """Number of links."""
        return len(self.link_label)

    def nearest_point(self, branch: str, chainage: float) -> int:
        """The h-point of ``branch`` nearest to ``chainage`` (m): an end node or a calculation point."""
        chain, ids = self.branch_points[branch]
        return ids[int(np.argmin(np.abs(chain - chainage)))]

    def interval(self, branch: str, chainage: float) -> tuple[int, int, float]:
        """The two consecutive h-points of ``branch`` around ``chainage`` (m) and the weight of the first.

        The weight interpolates linearly between them (1 at the first point, 0 at the second).
        """
        chain, ids = self.branch_points[branch]
        j = int(np.clip(np.searchsorted(chain, chainage, side="right") - 1, 0, len(chain) - 2))
        frac = (chainage - chain[j]) / (chain[j + 1] - chain[j])
        return ids[j], ids[j + 1], 1.0 - frac

    def link_at(self, branch: str, chainage: float) -> int:
        """The link of ``branch`` whose stretch holds ``chainage`` (m); the nearer midpoint on a tie, -1 if none."""
        best, best_d = -1, np.inf
        for li in range(self.n_links):
            if self.link_branch_id[li] != branch:
                continue
            d = abs(self.link_chainage[li] - chainage)
            if d <= 0.5 * self.link_length[li] + 1e-9 and d < best_d:
                best, best_d = li, d
        return best


def layout_grid(network: Network, structure_length: float) -> Grid:
    """Lay out the grid of a validated network.

    Parameters
    ----------
    network
        The network.
    structure_length
        Length of the segment that holds a structure, m (``engine.structure_length``).

    Returns
    -------
    Grid
        The h-points (the nodes first, then each branch's inner calculation points along it) and the
        links (branch by branch, along each branch).

    Raises
    ------
    StructureOverlap
        When two structures on a branch are too close for each to get its own segment (a case checks
        this at load; a network built in code meets it here).
    """
    profiles = {p.id: i for i, p in enumerate(network.profiles)}
    node_index = {n.id: i for i, n in enumerate(network.nodes)}
    hp_label = [f"node:{n.id}" for n in network.nodes]
    hp_branch = [""] * len(network.nodes)
    hp_chainage = [np.nan] * len(network.nodes)
    hp_xy = [(n.x if n.x is not None else np.nan, n.y if n.y is not None else np.nan) for n in network.nodes]
    sections: dict[int, list[tuple[int, float, float]]] = defaultdict(list)
    on_branch: dict[str, list[Structure]] = defaultdict(list)
    for s in network.structures:
        on_branch[s.branch].append(s)

    k1, k2, length, chainage, branch_index, branch_id = [], [], [], [], [], []
    p1, b1, p2, b2 = [], [], [], []
    structures: list[Structure | None] = []
    branch_points: dict[str, tuple[np.ndarray, list[int]]] = {}
    for bi, br in enumerate(network.branches):
        segs = branch_layout(br, on_branch[br.id], structure_length)
        chain = chainages(segs)
        ids = [node_index[br.from_node]]
        for c in chain[1:-1]:
            ids.append(len(hp_label))
            hp_label.append(f"{br.id}@{c:.1f}")
            hp_branch.append(br.id)
            hp_chainage.append(float(c))
            hp_xy.append(_xy_along(network, br, float(c)))
        ids.append(node_index[br.to_node])
        branch_points[br.id] = (chain, ids)
        seg_len = np.diff(chain)
        prof_at, bed_at = _section_lookup(br, profiles, chain)
        for j in range(chain.size):
            half = 0.5 * ((seg_len[j - 1] if j > 0 else 0.0) + (seg_len[j] if j < len(seg_len) else 0.0))
            sections[ids[j]].append((prof_at[j], bed_at[j], half))
        for j, seg in enumerate(segs):
            k1.append(ids[j])
            k2.append(ids[j + 1])
            length.append(seg.b - seg.a)
            chainage.append(0.5 * (seg.a + seg.b))
            branch_index.append(bi)
            branch_id.append(br.id)
            p1.append(prof_at[j])
            b1.append(bed_at[j])
            p2.append(prof_at[j + 1])
            b2.append(bed_at[j + 1])
            structures.append(seg.structure)

    structure_link: dict[str, int] = {}
    link_label = []
    for li, s in enumerate(structures):
        if s is None:
            link_label.append(f"{branch_id[li]}@{chainage[li]:.1f}")
        else:
            structure_link[s.id] = li
            link_label.append(f"{type(s).__name__.lower()}:{s.id}")
    as_int = lambda v: np.asarray(v, dtype=np.int64)  # noqa: E731
    as_float = lambda v: np.asarray(v, dtype=float)  # noqa: E731
    return Grid(
        hp_label=hp_label,
        hp_branch=hp_branch,
        hp_chainage=as_float(hp_chainage),
        hp_xy=as_float(hp_xy),
        sections=[sections[i] for i in range(len(hp_label))],
        link_k1=as_int(k1),
        link_k2=as_int(k2),
        link_length=as_float(length),
        link_chainage=as_float(chainage),
        link_branch=as_int(branch_index),
        link_branch_id=branch_id,
        link_p1=as_int(p1),
        link_b1=as_float(b1),
        link_p2=as_int(p2),
        link_b2=as_float(b2),
        link_structure=structures,
        link_label=link_label,
        structure_link=structure_link,
        node_index=node_index,
        branch_points=branch_points,
    )


def _section_lookup(branch: Branch, profiles: dict[str, int], chain: np.ndarray) -> tuple[list[int], list[float]]:
    """Profile index (of the nearest cross-section) and bed level (m AD, linear) at each chainage."""
    cs_ch = np.array([cs.chainage for cs in branch.cross_sections])
    cs_bed = np.array([cs.bed_level for cs in branch.cross_sections])
    cs_prof = np.array([profiles[cs.profile] for cs in branch.cross_sections])
    right = np.clip(np.searchsorted(cs_ch, chain), 0, cs_ch.size - 1)
    left = np.clip(right - 1, 0, cs_ch.size - 1)
    nearest = np.where(np.abs(chain - cs_ch[left]) <= np.abs(cs_ch[right] - chain), left, right)
    return [int(p) for p in cs_prof[nearest]], [float(b) for b in np.interp(chain, cs_ch, cs_bed)]


def _xy_along(network: Network, branch: Branch, chainage: float) -> tuple[float, float]:
    """Map position of a chainage, along the branch polyline or the straight line between its nodes."""
    if branch.geometry:
        pts = np.asarray(branch.geometry, dtype=float)
    else:
        a = next(n for n in network.nodes if n.id == branch.from_node)
        b = next(n for n in network.nodes if n.id == branch.to_node)
        if None in (a.x, a.y, b.x, b.y):
            return (np.nan, np.nan)
        pts = np.array([[a.x, a.y], [b.x, b.y]], dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    frac = chainage / branch.length * s[-1]
    return (float(np.interp(frac, s, pts[:, 0])), float(np.interp(frac, s, pts[:, 1])))
