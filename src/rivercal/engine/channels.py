"""The channel geometry of a grid: which table each point stores with and each link conveys with, and its friction.

Two ways to place the cross-sections on the grid (``engine.cross_sections``):

- ``nearest``: each calculation point takes the profile of the nearest cross-section at the bed level
  interpolated there; a channel link conveys with the profile of its upwind point;
- ``interpolated`` (D-Flow FM's way): each link takes the cross-section interpolated between the two around
  its middle (table by table at equal depth, :func:`rivercal.engine.sections.interpolate_tables`), at the bed
  level there, and conveys with it at the upwind level; each point stores the water of its half-links.

A profile of a plain shape (open rectangular, trapezoidal, zw without sections) is tabulated as before
(:func:`rivercal.engine.geometry.zw_of`); the others (yz, circular, closed, zw with sections) through
:mod:`rivercal.engine.sections`, whose conveyance shapes enter the kernels' R^(4/3) (Strickler, Manning)
and perimeter (Chézy) columns.

Friction *slots*: the kernels read each link's friction value from ``fric[lk_fric[link]]``. The slots are
the branches (their own friction, or the global one), then the friction groups, then the groups' values
on particular branches. A link whose profile names friction groups takes the slot of the profile's first
section (the other sections' coefficients enter its table relative to it); otherwise its branch's slot.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rivercal.engine.geometry import CELLS, MIN_TOP, ProfileTables, build_tables, storage_zw, zw_of
from rivercal.engine.kernels.codes import (
    FRICTION_CHEZY,
    FRICTION_MANNING,
    FRICTION_STRICKLER,
    FRICTION_WHITE_COLEBROOK,
)
from rivercal.engine.sections import SectionTable, interpolate_tables, section_table
from rivercal.network import RectangularProfile, TrapezoidalProfile, ZWProfile
from rivercal.network.grid import Grid

__all__ = ["FRICTION_CODES", "Channels", "channel_geometry"]

#: Friction type names of the case → codes of the kernel arrays.
FRICTION_CODES = {"strickler": FRICTION_STRICKLER, "manning": FRICTION_MANNING, "chezy": FRICTION_CHEZY,
                  "white-colebrook": FRICTION_WHITE_COLEBROOK}
#: Steps of the interpolation weight between two cross-sections (a link between them gets the table of
#: the nearest step: at most 1/(2 STEPS) off in weight, so that a branch does not need a table per link).
STEPS = 20


@dataclass
class Channels:
    """The storage and conveyance geometry of a grid, and its friction slots.

    Attributes
    ----------
    storage
        The ``hp_*``, ``sc_*`` and ``tab_*`` arrays of :class:`~rivercal.engine.compile.NetArrays`.
    link_p1, link_b1, link_p2, link_b2
        Per link: the table and bed level (m AD) it conveys with at its k1 and k2 end.
    link_slot
        Per link: its friction slot.
    slot_type, slot_value
        Per slot: friction law code and coefficient (unit of the law).
    slot_key
        Per slot: ``("branch", id)``, ``("group", id)`` or ``("group", id, branch)``.
    profile_table
        Table index of each profile id that a culvert or bridge barrel takes its shape from.
    """

    storage: dict[str, np.ndarray]
    link_p1: np.ndarray
    link_b1: np.ndarray
    link_p2: np.ndarray
    link_b2: np.ndarray
    link_slot: np.ndarray
    slot_type: np.ndarray
    slot_value: np.ndarray
    slot_key: list[tuple]
    profile_table: dict[str, int] = field(default_factory=dict)


def _k_coefficient(kind: str, value: float) -> float:
    """The coefficient that the conveyance is proportional to: k_s, 1/n or C (1 for White-Colebrook)."""
    return {"strickler": value, "manning": 1.0 / value, "chezy": value}.get(kind, 1.0)


def _plain(profile) -> bool:
    if isinstance(profile, RectangularProfile):
        return not profile.closed
    if isinstance(profile, TrapezoidalProfile):
        return True
    return isinstance(profile, ZWProfile) and not profile.closed and profile.section_widths is None


class _Builder:
    """Tables by key, built once; friction slots by key."""

    def __init__(self, network):
        self.network = network
        self.groups = {g.id: g for g in network.friction_groups}
        self.entries: list = []
        self.index: dict[tuple, int] = {}
        self.sections: dict[tuple, SectionTable] = {}
        self.slot_key: list[tuple] = [("branch", b.id) for b in network.branches]
        self.slot_type: list[int] = [FRICTION_CODES[(b.friction or network.friction).type] for b in network.branches]
        self.slot_value: list[float] = [(b.friction or network.friction).value for b in network.branches]
        self.slot_of = {key: i for i, key in enumerate(self.slot_key)}
        for g in network.friction_groups:
            self._slot(("group", g.id), g.type, g.value)
            for bf in g.branches:
                self._slot(("group", g.id, bf.branch), g.type, bf.value)

    def _slot(self, key: tuple, kind: str, value: float) -> int:
        if key not in self.slot_of:
            self.slot_of[key] = len(self.slot_key)
            self.slot_key.append(key)
            self.slot_type.append(FRICTION_CODES[kind])
            self.slot_value.append(value)
        return self.slot_of[key]

    def context(self, p: int, branch) -> tuple[str, tuple[float, ...] | None, int]:
        """Friction law, section weights and slot of profile index ``p`` on ``branch``."""
        profile = self.network.profiles[p]
        if not profile.friction:
            law = (branch.friction or self.network.friction).type
            return law, None, self.slot_of[("branch", branch.id)]
        first = self.groups[profile.friction[0]]
        base = _k_coefficient(first.type, first.value_on(branch.id))
        weights = tuple(_k_coefficient(self.groups[g].type, self.groups[g].value_on(branch.id)) / base
                        if self.groups[g].type == first.type else 1.0 for g in profile.friction)
        key = ("group", first.id, branch.id) if ("group", first.id, branch.id) in self.slot_of else ("group", first.id)
        return first.type, weights, self.slot_of[key]

    def section(self, p: int, weights) -> SectionTable:
        key = (p, weights)
        if key not in self.sections:
            self.sections[key] = section_table(self.network.profiles[p], list(weights) if weights else None)
        return self.sections[key]

    def table(self, p: int, branch) -> int:
        """The table of profile ``p`` on ``branch`` (plain shapes share one table whatever the law)."""
        law, weights, _ = self.context(p, branch)
        if _plain(self.network.profiles[p]):
            key: tuple = ("plain", p)
            if key not in self.index:
                self._add(key, zw_of(self.network.profiles[p]))
            return self.index[key]
        key = ("section", p, law, weights)
        if key not in self.index:
            self._add(key, _kernel_columns(self.section(p, weights), law))
        return self.index[key]

    def between(self, pa: int, pb: int, weight: float, branch) -> int:
        """The table of the cross-section ``weight`` of the way from profile ``pa`` to ``pb`` on ``branch``."""
        near = pa if weight < 0.5 else pb
        law, _, _ = self.context(near, branch)
        _, wa, _ = self.context(pa, branch)
        _, wb, _ = self.context(pb, branch)
        key = ("between", pa, pb, weight, law, wa, wb)
        if key not in self.index:
            mixed = interpolate_tables(self.section(pa, wa), self.section(pb, wb), weight)
            self._add(key, _kernel_columns(mixed, law))
        return self.index[key]

    def _add(self, key: tuple, entry) -> None:
        self.index[key] = len(self.entries)
        self.entries.append(entry)


def _kernel_columns(t: SectionTable, law: str) -> tuple:
    """A section table as the kernels' columns (af, pf, at, r43, flow width above, total width above, top).

    Strickler and Manning read R^(4/3) = (S23/A)²; Chézy reads R = A/pf, so pf = A / (S12/A)²;
    White-Colebrook reads the plain R = A/P.
    """
    area = t.area
    pf = t.perimeter.copy()
    if law == "chezy":
        radius = t.radius_chezy()
        pf = np.where(radius > 0, np.divide(area, radius, out=np.zeros_like(area), where=radius > 0), pf)
    r43 = t.r43()
    if law == "white-colebrook":
        radius = np.divide(area, t.perimeter, out=np.zeros_like(area), where=t.perimeter > 0)
        r43 = radius ** (4.0 / 3.0)
    top = t.top
    if t.depth.size != CELLS + 1 or top < MIN_TOP - 1e-9:
        raise ValueError("a section table must have the engine's depth grid")
    return (area, pf, t.total, r43, t.flow_width_top, t.total_width_top, top)


def channel_geometry(network, grid: Grid, mode: str, min_storage_area: float) -> Channels:
    """Tables, storage and friction slots of a laid-out network (see the module docstring)."""
    b = _Builder(network)
    branches = {br.id: br for br in network.branches}
    n_l = grid.n_links
    link_p1 = np.empty(n_l, dtype=np.int64)
    link_p2 = np.empty(n_l, dtype=np.int64)
    link_b1 = grid.link_b1.astype(float).copy()
    link_b2 = grid.link_b2.astype(float).copy()
    link_slot = np.empty(n_l, dtype=np.int64)
    contributions: list[list[tuple[int, float, float]]] = [[] for _ in range(grid.n_points)]
    for k, p in enumerate(network.profiles):  # plain profiles first, in their order (the tables of before)
        if _plain(p):
            b._add(("plain", k), zw_of(p))
    if mode == "interpolated":
        for li in range(n_l):
            br = branches[grid.link_branch_id[li]]
            table, bed, slot = _interpolated(b, br, float(grid.link_chainage[li]))
            link_p1[li] = link_p2[li] = table
            link_b1[li] = link_b2[li] = bed
            link_slot[li] = slot
            half = 0.5 * float(grid.link_length[li])
            contributions[int(grid.link_k1[li])].append((table, bed, half))
            contributions[int(grid.link_k2[li])].append((table, bed, half))
    else:
        for li in range(n_l):
            br = branches[grid.link_branch_id[li]]
            p1, p2 = int(grid.link_p1[li]), int(grid.link_p2[li])
            link_p1[li] = b.table(p1, br)
            link_p2[li] = b.table(p2, br)
            owner = p1 if network.profiles[p1].friction else p2
            link_slot[li] = b.context(owner, br)[2]
        point_branch = _point_branches(grid)
        for i, sections in enumerate(grid.sections):
            for (p, bed, half), bid in zip(sections, point_branch[i], strict=True):
                contributions[i].append((b.table(p, branches[bid]), bed, half))
    profile_table = {}
    barrels = {c.profile for c in [*network.culverts, *network.bridges] if getattr(c, "profile", None)}
    for k, p in enumerate(network.profiles):
        if p.id not in barrels:
            continue
        key = ("barrel", k)
        b._add(key, zw_of(p) if _plain(p) else _kernel_columns(section_table(p), "strickler"))
        profile_table[p.id] = b.index[key]
    storage = _storage(network, grid, b, contributions, min_storage_area)
    return Channels(storage=storage, link_p1=link_p1, link_b1=link_b1, link_p2=link_p2, link_b2=link_b2,
                    link_slot=link_slot, slot_type=np.asarray(b.slot_type, dtype=np.int64),
                    slot_value=np.asarray(b.slot_value, dtype=float), slot_key=b.slot_key,
                    profile_table=profile_table)


def _point_branches(grid: Grid) -> list[list[str]]:
    """Per h-point, the branch of each of its channel sections (in the order of ``grid.sections``)."""
    out: list[list[str]] = [[] for _ in range(grid.n_points)]
    for bid, (_, ids) in grid.branch_points.items():
        for i in ids:
            out[i].append(bid)
    return out


def _interpolated(b: _Builder, branch, chainage: float) -> tuple[int, float, int]:
    """Table, bed level (m AD) and friction slot of the cross-section at ``chainage`` of ``branch``."""
    profiles = {p.id: k for k, p in enumerate(b.network.profiles)}
    ch = np.array([cs.chainage for cs in branch.cross_sections])
    bed = float(np.interp(chainage, ch, [cs.bed_level for cs in branch.cross_sections]))
    j = int(np.clip(np.searchsorted(ch, chainage, side="right") - 1, 0, ch.size - 1))
    if j == ch.size - 1 or chainage <= ch[0]:
        p = profiles[branch.cross_sections[0 if chainage <= ch[0] else -1].profile]
        return b.table(p, branch), bed, b.context(p, branch)[2]
    pa = profiles[branch.cross_sections[j].profile]
    pb = profiles[branch.cross_sections[j + 1].profile]
    weight = round((chainage - ch[j]) / (ch[j + 1] - ch[j]) * STEPS) / STEPS
    if pa == pb or weight in (0.0, 1.0) or _same_shape(b.network.profiles[pa], b.network.profiles[pb]):
        p = pa if weight < 0.5 else pb
        return b.table(p, branch), bed, b.context(p, branch)[2]
    near = pa if weight < 0.5 else pb
    return b.between(pa, pb, weight, branch), bed, b.context(near, branch)[2]


def _same_shape(a, c) -> bool:
    """Whether two profiles are the same shape with the same friction (ids aside)."""
    return a.model_dump(exclude={"id"}) == c.model_dump(exclude={"id"})


def _storage(network, grid: Grid, b: _Builder, contributions, min_storage_area: float) -> dict[str, np.ndarray]:
    """The ``hp_*``, ``sc_*`` and ``tab_*`` arrays (node storage as tables of length 1 m)."""
    n_hp = len(contributions)
    hp_bed = np.array([min(bed for _, bed, _ in c) for c in contributions])
    hp_len = np.array([sum(length for _, _, length in c) for c in contributions])
    for node in network.nodes:
        i = grid.node_index[node.id]
        if node.storage_table is not None:
            h, wf, wt, bottom = storage_zw(node.storage_table)
            b._add(("node", node.id), (h, wf, wt))
            contributions[i].append((b.index[("node", node.id)], bottom, 1.0))
        elif node.storage_area > 0:
            b._add(("node", node.id), (np.array([0.0, 1.0]), np.zeros(2), np.full(2, node.storage_area)))
            contributions[i].append((b.index[("node", node.id)], float(hp_bed[i]), 1.0))
    tables: ProfileTables = build_tables(b.entries)
    from rivercal.engine.geometry import flow_records

    sc_ptr = np.zeros(n_hp + 1, dtype=np.int64)
    sc_ptr[1:] = np.cumsum([len(c) for c in contributions])
    flat = [entry for c in contributions for entry in c]
    return dict(
        hp_bed=hp_bed,
        hp_amin=np.full(n_hp, min_storage_area),
        hp_ilen=np.divide(1.0, hp_len, out=np.zeros(n_hp), where=hp_len > 0),
        sc_ptr=sc_ptr,
        sc_prof=np.array([p for p, _, _ in flat], dtype=np.int64),
        sc_bed=np.array([bed for _, bed, _ in flat], dtype=float),
        sc_len=np.array([length for _, _, length in flat], dtype=float),
        tab_off=tables.off,
        tab_n=tables.n,
        tab_dd=tables.dd,
        tab_idd=1.0 / tables.dd,
        tab_af=tables.af,
        tab_pf=tables.pf,
        tab_at=tables.at,
        tab_wt=tables.wt,
        tab_wf_top=tables.wf_top,
        tab_wt_top=tables.wt_top,
        tab_top=tables.top,
        tab_flow=flow_records(tables),
    )
