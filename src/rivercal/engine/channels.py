"""The channel geometry of a grid: which table each point stores with and each link conveys with, and its friction.

Three ways to place the cross-sections on the grid (``engine.cross_sections``):

- ``nearest``: each calculation point takes the profile of the nearest cross-section at the bed level
  interpolated there; a channel link conveys with the profile of its upwind point;
- ``interpolated`` (D-Flow FM's way): each link takes the cross-section interpolated between the two around
  its middle (table by table at equal depth, :func:`rivercal.engine.sections.interpolate_tables`), at the bed
  level there, and conveys with it at the upwind level; each point stores the water of its half-links. A branch
  with a positive ``order`` continues its cross-sections across a connection node into the next branch of the
  same order (:func:`extended_cross_sections`), as D-Flow FM 1D does with its branch orders;
- ``points`` (Mascaret's way, its planimetry of each computational section): each calculation point takes the
  cross-section interpolated at it, at the bed level there; a half-link stores with the table of its end point
  and a link conveys with its upwind point's table (at the link's friction slot). A point's storage and the flow
  area of the links it feeds then come from one table, which a steep torrent whose profiles change from pool to
  riffle needs: with ``interpolated`` the Oriège's supercritical reaches never settled (levels swinging by a
  metre at any step down to 0.5 s), with ``points`` they are steady at every step.

A profile of a plain shape (open rectangular, trapezoidal, zw without sections or summer dike) whose friction is
the link's own coefficient is tabulated as before (:func:`rivercal.engine.geometry.zw_of`); every other link
conveys with a table of :mod:`rivercal.engine.sections` whose conveyance K(h) holds the friction of each section
— its own law, a value along the branch, a value that depends on the water level — relative to the link's
friction slot (:func:`rivercal.engine.sections.kernel_columns`).

Friction *slots*: the kernels read each link's friction value from ``fric[lk_fric[link]]``. The slots are
the branches (their own friction, or the global one), then the friction groups, each followed by its constant
values on particular branches (in their own law when they have one). A link whose profile names friction groups
takes the slot of the first section's group on its branch: the group's constant value there, or the group's own
value when the group has none there or varies along the branch or with the level (that variation is held in the
link's table relative to the group's value, so ``friction:group:<id>`` scales it); a link whose profile names none
takes its branch's slot.

Summer dikes: a link or point whose cross-section has a summer dike stores the water behind it in a storage
contribution of its own (:func:`rivercal.engine.sections.dike_storage`) from the dike's base, whose table the time
loop switches between the rising and the falling curve (``sd_*`` arrays of :class:`Channels`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rivercal.engine.geometry import ProfileTables, build_tables, flow_records, storage_zw, zw_of
from rivercal.engine.kernels.codes import (
    FRICTION_CHEZY,
    FRICTION_MANNING,
    FRICTION_STRICKLER,
    FRICTION_WHITE_COLEBROOK,
)
from rivercal.engine.sections import (
    DikeShape,
    SectionTable,
    dike_storage,
    flow_view,
    interpolate_tables,
    kernel_columns,
    section_table,
)
from rivercal.network import RectangularProfile, TrapezoidalProfile, ZWProfile, profile_sections
from rivercal.network.grid import Grid

__all__ = ["FRICTION_CODES", "Channels", "channel_geometry", "extended_cross_sections", "initial_levels"]

#: Friction type names of the case → codes of the kernel arrays.
FRICTION_CODES = {"strickler": FRICTION_STRICKLER, "manning": FRICTION_MANNING, "chezy": FRICTION_CHEZY,
                  "white-colebrook": FRICTION_WHITE_COLEBROOK}
#: Steps of the interpolation weight between two cross-sections (a link between them gets the table of
#: the nearest step: at most 1/(2 STEPS) off in weight, so that a branch does not need a table per link). A
#: link whose friction varies with the level has a table of its own, at its exact weight.
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
    mixed_groups
        Friction group id → the id of a profile whose sections name it beside another group. Such a profile's
        links convey with the sections' coefficients relative to their first section's group (their friction
        slot): a change of the first group's value alone scales the whole profile's conveyance, and a change of
        another group's value does not reach it. Such a group is not a calibration target
        (:meth:`rivercal.engine.Simulator.parameter_arrays` refuses it).

    The storage arrays also hold the summer dikes' storage contributions that change curve: ``sd_sc`` (their index
    among the contributions, whose table ``sc_prof`` is the rising curve), ``sd_hp`` (their h-point), ``sd_alt``
    (the table of the falling curve), ``sd_full`` and ``sd_base`` (the levels, m AD, at or above which the falling
    curve and at or below which the rising curve takes over).
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
    mixed_groups: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class _Friction:
    """The friction of one section of a profile at one place: a law and a constant or level-dependent coefficient.

    ``levels`` (m AD) and ``values`` give the coefficient as a function of the water level (linear between the
    levels, constant beyond them); otherwise ``value`` holds it.
    """

    law: str
    value: float | None = None
    levels: np.ndarray | None = field(default=None, compare=False)
    values: np.ndarray | None = field(default=None, compare=False)

    @property
    def constant(self) -> bool:
        return self.levels is None

    def on(self, depth: np.ndarray, bed: float):
        """The coefficient at the water levels ``bed + depth`` (a number when constant)."""
        if self.levels is None:
            return self.value
        return np.interp(bed + depth, self.levels, self.values)


def _plain(profile) -> bool:
    if isinstance(profile, RectangularProfile):
        return not profile.closed
    if isinstance(profile, TrapezoidalProfile):
        return True
    return (isinstance(profile, ZWProfile) and not profile.closed and profile.section_widths is None
            and profile.summer_dike is None)


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
        self.mixed: dict[str, str] = {}  # friction group → a profile that names it beside another group
        for g in network.friction_groups:
            self._slot(("group", g.id), g.type, g.value)
            for bf in g.branches:
                if not bf.varies:
                    self._slot(("group", g.id, bf.branch), bf.type or g.type, bf.value)

    def _slot(self, key: tuple, kind: str, value: float) -> int:
        if key not in self.slot_of:
            self.slot_of[key] = len(self.slot_key)
            self.slot_key.append(key)
            self.slot_type.append(FRICTION_CODES[kind])
            self.slot_value.append(value)
        return self.slot_of[key]

    def slot_law(self, slot: int) -> tuple[str, float]:
        """Friction law and coefficient of a slot."""
        names = {code: name for name, code in FRICTION_CODES.items()}
        return names[self.slot_type[slot]], self.slot_value[slot]

    def friction(self, p: int, branch, chainage: float) -> tuple[list[_Friction], int]:
        """The friction of each section of profile ``p`` on ``branch`` at ``chainage`` (m), and the link's slot."""
        profile = self.network.profiles[p]
        n = profile_sections(profile)
        if not profile.friction:
            own = branch.friction or self.network.friction
            return [_Friction(own.type, own.value)] * n, self.slot_of[("branch", branch.id)]
        if len(set(profile.friction)) > 1:
            for gid in profile.friction:
                self.mixed.setdefault(gid, profile.id)
        out = []
        for gid in profile.friction:
            group = self.groups[gid]
            entry = group.entry(branch.id)
            if entry is None:
                out.append(_Friction(group.type, group.value))
                continue
            law = entry.type or group.type
            levels, values = entry.coefficient_at(chainage)
            out.append(_Friction(law, float(values[0])) if levels is None
                       else _Friction(law, levels=levels, values=values))
        first = self.groups[profile.friction[0]].entry(branch.id)
        key = ("group", profile.friction[0], branch.id)
        slot = self.slot_of[key] if first is not None and not first.varies else self.slot_of[("group",
                                                                                             profile.friction[0])]
        return out, slot

    def section(self, geometry: tuple) -> SectionTable:
        """The section table of ``("profile", p)`` or ``("between", pa, pb, weight)``."""
        if geometry not in self.sections:
            if geometry[0] == "profile":
                table = section_table(self.network.profiles[geometry[1]])
            else:
                _, pa, pb, weight = geometry
                table = interpolate_tables(self.section(("profile", pa)), self.section(("profile", pb)), weight)
            self.sections[geometry] = table
        return self.sections[geometry]

    def table(self, geometry: tuple, frictions: list[_Friction], slot: int, bed: float) -> int:
        """The kernel table of a geometry conveying with ``frictions`` relative to ``slot``, at bed ``bed`` (m AD)."""
        law, value = self.slot_law(slot)
        if geometry[0] == "profile" and _plain(self.network.profiles[geometry[1]]) and len(frictions) == 1 \
                and frictions[0] == _Friction(law, value):
            key: tuple = ("plain", geometry[1])
            if key not in self.index:
                self._add(key, zw_of(self.network.profiles[geometry[1]]))
            return self.index[key]
        level_dependent = not all(f.constant for f in frictions)
        key = ("section", geometry, tuple(frictions), law, value, bed if level_dependent else None)
        if key not in self.index or level_dependent:
            t = flow_view(self.section(geometry))
            n = t.sections
            frictions = (frictions + [frictions[-1]] * n)[:n]
            conveyance = t.conveyance([f.law for f in frictions], [f.on(t.depth, bed) for f in frictions])
            plain_wc = law == "white-colebrook" and all(f == _Friction(law, value) for f in frictions)
            self._add(key, kernel_columns(t, conveyance, law, value, plain_white_colebrook=plain_wc))
        return self.index[key]

    def storage_table(self, p: int) -> int:
        """A table of profile ``p`` for storage only (its flow columns are never read)."""
        profile = self.network.profiles[p]
        if _plain(profile):
            key: tuple = ("plain", p)
            if key not in self.index:
                self._add(key, zw_of(profile))
            return self.index[key]
        key = ("storage", p)
        if key not in self.index:
            t = self.section(("profile", p))
            self._add(key, kernel_columns(t, t.s23, "strickler", 1.0))
        return self.index[key]

    def dike_tables(self, dike: DikeShape) -> tuple[int, int]:
        """The tables of a summer dike's storage: rising curve and falling curve (-1 without one), from its base."""
        key: tuple = ("dike", dike)
        if key not in self.index:
            rising, falling = dike_storage(dike)
            self._add(key, rising)
            if falling is not None:
                self._add(("dike-falling", dike), falling)
        return self.index[key], self.index.get(("dike-falling", dike), -1)

    def _add(self, key: tuple, entry) -> None:
        self.index[key] = len(self.entries)
        self.entries.append(entry)


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
    dikes: list[list[tuple[DikeShape, float, float]]] = [[] for _ in range(grid.n_points)]
    for k, p in enumerate(network.profiles):  # plain profiles first, in their order (the tables of before)
        if _plain(p):
            b._add(("plain", k), zw_of(p))
    if mode == "interpolated":
        extended = extended_cross_sections(network)
        for li in range(n_l):
            br = branches[grid.link_branch_id[li]]
            table, bed, slot, dike = _interpolated(b, br, float(grid.link_chainage[li]), extended[br.id])
            link_p1[li] = link_p2[li] = table
            link_b1[li] = link_b2[li] = bed
            link_slot[li] = slot
            half = 0.5 * float(grid.link_length[li])
            contributions[int(grid.link_k1[li])].append((table, bed, half))
            contributions[int(grid.link_k2[li])].append((table, bed, half))
            if dike is not None and dike.total_area > 0:
                dikes[int(grid.link_k1[li])].append((dike, bed, half))
                dikes[int(grid.link_k2[li])].append((dike, bed, half))
    elif mode == "points":
        extended = extended_cross_sections(network)
        for li in range(n_l):
            br = branches[grid.link_branch_id[li]]
            middle, half = float(grid.link_chainage[li]), 0.5 * float(grid.link_length[li])
            slot = _slot_at(b, br, middle, extended[br.id])
            link_slot[li] = slot
            for end, chainage, k in ((1, middle - half, int(grid.link_k1[li])), (2, middle + half,
                                                                                 int(grid.link_k2[li]))):
                table, bed, _, dike = _interpolated(b, br, chainage, extended[br.id], slot)
                if end == 1:
                    link_p1[li], link_b1[li] = table, bed
                else:
                    link_p2[li], link_b2[li] = table, bed
                contributions[k].append((table, bed, half))
                if dike is not None and dike.total_area > 0:
                    dikes[k].append((dike, bed, half))
    else:
        for li in range(n_l):
            br = branches[grid.link_branch_id[li]]
            chainage = float(grid.link_chainage[li])
            p1, p2 = int(grid.link_p1[li]), int(grid.link_p2[li])
            owner = p1 if network.profiles[p1].friction else p2
            _, slot = b.friction(owner, br, chainage)
            link_slot[li] = slot
            for p, bed, out in ((p1, link_b1[li], link_p1), (p2, link_b2[li], link_p2)):
                frictions, _ = b.friction(p, br, chainage)
                out[li] = b.table(("profile", p), frictions, slot, float(bed))
        point_branch = _point_branches(grid)
        for i, sections in enumerate(grid.sections):
            for (p, bed, half), _bid in zip(sections, point_branch[i], strict=True):
                contributions[i].append((b.storage_table(p), bed, half))
                dike = b.section(("profile", p)).dike if not _plain(network.profiles[p]) else None
                if dike is not None and dike.total_area > 0:
                    dikes[i].append((dike, float(bed), half))
    profile_table = {}
    barrels = {c.profile for c in [*network.culverts, *network.bridges] if getattr(c, "profile", None)}
    for k, p in enumerate(network.profiles):
        if p.id not in barrels:
            continue
        key = ("barrel", k)
        if _plain(p):
            b._add(key, zw_of(p))
        else:
            t = flow_view(b.section(("profile", k)))
            b._add(key, kernel_columns(t, t.s23, "strickler", 1.0))
        profile_table[p.id] = b.index[key]
    storage = _storage(network, grid, b, contributions, dikes, min_storage_area)
    return Channels(storage=storage, link_p1=link_p1, link_b1=link_b1, link_p2=link_p2, link_b2=link_b2,
                    link_slot=link_slot, slot_type=np.asarray(b.slot_type, dtype=np.int64),
                    slot_value=np.asarray(b.slot_value, dtype=float), slot_key=b.slot_key,
                    profile_table=profile_table, mixed_groups=dict(b.mixed))


def _point_branches(grid: Grid) -> list[list[str]]:
    """Per h-point, the branch of each of its channel sections (in the order of ``grid.sections``)."""
    out: list[list[str]] = [[] for _ in range(grid.n_points)]
    for bid, (_, ids) in grid.branch_points.items():
        for i in ids:
            out[i].append(bid)
    return out


def extended_cross_sections(network) -> dict[str, list[tuple[float, int, float]]]:
    """Per branch, its cross-sections as (chainage m, profile index, bed level m AD), with those borrowed across nodes.

    D-Flow FM 1D's rule for branch orders (Deltares, D-Flow FM 1D, ``useBranchOrdersCrs`` in the flow1d library's
    CrossSections.f90, read in the Delft3D 4 source tree): the first and the last cross-section of every branch of a
    positive order is copied onto the first other branch of the same order (in the network's order) that meets it
    at that end node, at the chainage it has seen from that branch — before its start (a negative chainage) or
    beyond its end (more than its length). A branch without cross-sections of its own passes it on, with its length
    added, to the next branch of the same order at its other end. A link between a branch's last cross-section and
    the node is then interpolated towards the cross-section beyond the node instead of holding the last one.
    Branches without an order (or of order 0 or below) keep their own cross-sections only.
    """
    profiles = {p.id: k for k, p in enumerate(network.profiles)}
    own = {br.id: [(cs.chainage, profiles[cs.profile], cs.bed_level) for cs in br.cross_sections]
           for br in network.branches}
    out = {bid: list(items) for bid, items in own.items()}
    ordered = [br for br in network.branches if br.order is not None and br.order > 0]
    at_node: dict[str, list] = {}  # node → the ordered branches that end there, in the network's order
    for br in ordered:
        at_node.setdefault(br.from_node, []).append(br)
        if br.to_node != br.from_node:
            at_node.setdefault(br.to_node, []).append(br)

    def push(branch, item: tuple[float, int, float], distance: float, at_start: bool, seen: set[str]) -> None:
        node = branch.from_node if at_start else branch.to_node
        for other in at_node.get(node, []):
            if other.id == branch.id or other.order != branch.order:
                continue
            if other.to_node == node:
                chainage, further_at_start = other.length + distance, True
            elif other.from_node == node:
                chainage, further_at_start = -distance, False
            else:
                continue
            out[other.id].append((chainage, item[1], item[2]))
            if not own[other.id] and other.id not in seen:  # no cross-section of its own: pass it on
                push(other, item, distance + other.length, further_at_start, seen | {other.id})
            return

    for br in ordered:
        items = own[br.id]
        if not items:
            continue
        push(br, items[0], items[0][0], True, {br.id})
        push(br, items[-1], br.length - items[-1][0], False, {br.id})
    return {bid: sorted(items, key=lambda c: c[0]) for bid, items in out.items()}


def _interpolated(b: _Builder, branch, chainage: float, sections: list[tuple[float, int, float]],
                  slot: int | None = None) -> tuple[int, float, int, DikeShape | None]:
    """Table, bed level (m AD), friction slot and summer dike of the cross-section at ``chainage`` of ``branch``.

    With ``slot`` the table's conveyance is relative to that friction slot (a link's), not to the one of the
    cross-section's own friction there.
    """
    ch = np.array([c[0] for c in sections])
    bed = float(np.interp(chainage, ch, [c[2] for c in sections]))
    j = int(np.clip(np.searchsorted(ch, chainage, side="right") - 1, 0, ch.size - 1))
    if j == ch.size - 1 or chainage <= ch[0]:
        p = sections[0 if chainage <= ch[0] else -1][1]
        frictions, own = b.friction(p, branch, chainage)
        slot = own if slot is None else slot
        return b.table(("profile", p), frictions, slot, bed), bed, slot, _dike(b, ("profile", p))
    pa, pb = sections[j][1], sections[j + 1][1]
    exact = (chainage - ch[j]) / (ch[j + 1] - ch[j])
    near = pa if exact < 0.5 else pb
    frictions, own = b.friction(near, branch, chainage)
    if not all(f.constant for f in frictions):
        weight = exact  # a table of its own anyway
    else:
        weight = round(exact * STEPS) / STEPS
    if pa == pb or weight in (0.0, 1.0) or _same_shape(b.network.profiles[pa], b.network.profiles[pb]):
        p = pa if weight < 0.5 else pb
        frictions, own = b.friction(p, branch, chainage)
        slot = own if slot is None else slot
        return b.table(("profile", p), frictions, slot, bed), bed, slot, _dike(b, ("profile", p))
    slot = own if slot is None else slot
    geometry = ("between", pa, pb, weight)
    return b.table(geometry, frictions, slot, bed), bed, slot, _dike(b, geometry)


def _slot_at(b: _Builder, branch, chainage: float, sections: list[tuple[float, int, float]]) -> int:
    """The friction slot of the cross-section at ``chainage`` of ``branch`` (as :func:`_interpolated` takes it)."""
    ch = np.array([c[0] for c in sections])
    j = int(np.clip(np.searchsorted(ch, chainage, side="right") - 1, 0, ch.size - 1))
    if j == ch.size - 1 or chainage <= ch[0]:
        return b.friction(sections[0 if chainage <= ch[0] else -1][1], branch, chainage)[1]
    pa, pb = sections[j][1], sections[j + 1][1]
    exact = (chainage - ch[j]) / (ch[j + 1] - ch[j])
    frictions, slot = b.friction(pa if exact < 0.5 else pb, branch, chainage)
    weight = exact if not all(f.constant for f in frictions) else round(exact * STEPS) / STEPS
    if pa == pb or weight in (0.0, 1.0) or _same_shape(b.network.profiles[pa], b.network.profiles[pb]):
        return b.friction(pa if weight < 0.5 else pb, branch, chainage)[1]
    return slot


def _dike(b: _Builder, geometry: tuple) -> DikeShape | None:
    """The summer dike of a geometry (None for a plain profile, which has none)."""
    if geometry[0] == "profile" and _plain(b.network.profiles[geometry[1]]):
        return None
    return b.section(geometry).dike


def _same_shape(a, c) -> bool:
    """Whether two profiles are the same shape with the same friction (ids aside)."""
    return a.model_dump(exclude={"id"}) == c.model_dump(exclude={"id"})


def initial_levels(network, hp_label: list[str], hp_branch: list[str], hp_chainage: np.ndarray) -> np.ndarray:
    """The initial water level (m AD) of every h-point that a branch's ``initial_levels`` covers, NaN elsewhere.

    A calculation point takes the level of its branch at its chainage; a node the mean of the levels of the
    branches that end at it and have initial levels.
    """
    by_id = {br.id: br for br in network.branches}
    out = np.full(len(hp_label), np.nan)
    for i, (bid, chainage) in enumerate(zip(hp_branch, hp_chainage, strict=True)):
        if bid and by_id[bid].initial_levels is not None:
            out[i] = float(by_id[bid].initial_levels.level_at(chainage))
    at_node: dict[str, list[float]] = {}
    for br in network.branches:
        if br.initial_levels is None:
            continue
        at_node.setdefault(br.from_node, []).append(float(br.initial_levels.level_at(0.0)))
        at_node.setdefault(br.to_node, []).append(float(br.initial_levels.level_at(br.length)))
    for i, label in enumerate(hp_label):
        if label.startswith("node:") and label[5:] in at_node:
            out[i] = float(np.mean(at_node[label[5:]]))
    return out


def _storage(network, grid: Grid, b: _Builder, contributions, dikes, min_storage_area: float) -> dict[str, np.ndarray]:
    """The ``hp_*``, ``sc_*``, ``sd_*`` and ``tab_*`` arrays (node storage as tables of length 1 m).

    ``dikes`` holds per point the summer dikes of its channel (shape, bed level m AD of its cross-section, length
    m); each becomes a storage contribution from the dike's base, after the point's other contributions.
    """
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
    switching: list[tuple[int, int, int, int, float, float]] = []  # point, position, rising, falling, full, base
    for i, items in enumerate(dikes):
        for dike, bed, length in items:
            rising, falling = b.dike_tables(dike)
            if falling >= 0:
                switching.append((i, len(contributions[i]), rising, falling, bed + dike.full, bed + dike.base))
            contributions[i].append((rising, bed + dike.base, length))
    tables: ProfileTables = build_tables(b.entries)
    sc_ptr = np.zeros(n_hp + 1, dtype=np.int64)
    sc_ptr[1:] = np.cumsum([len(c) for c in contributions])
    flat = [entry for c in contributions for entry in c]
    return dict(
        sd_sc=np.array([sc_ptr[i] + k for i, k, *_ in switching], dtype=np.int64),
        sd_hp=np.array([i for i, *_ in switching], dtype=np.int64),
        sd_alt=np.array([s[3] for s in switching], dtype=np.int64),
        sd_full=np.array([s[4] for s in switching], dtype=float),
        sd_base=np.array([s[5] for s in switching], dtype=float),
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
