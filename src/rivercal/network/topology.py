"""The whole network and the rules that need all of it.

Ids are unique, every reference names an object that exists, structures lie within their branch
and above its bed, boundaries sit at end nodes. The branches may form several disconnected parts
(a D-Flow FM model may hold separate channels); :meth:`Network.parts` lists them.
"""

from __future__ import annotations

import difflib
from collections import defaultdict, deque

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import NetworkModel, num
from rivercal.network.branches import Branch
from rivercal.network.forcing import Boundary, Lateral
from rivercal.network.friction import Friction, FrictionGroup
from rivercal.network.nodes import Node
from rivercal.network.profiles import Profile
from rivercal.network.stations import Station
from rivercal.network.structures import Bridge, Culvert, Orifice, Pump, UniversalWeir, Weir

#: The structure tables of a network, in the order of the engine's layout: (table, kind of object).
STRUCTURE_TABLES = (
    ("weirs", "weir"),
    ("culverts", "culvert"),
    ("pumps", "pump"),
    ("orifices", "orifice"),
    ("universal_weirs", "universal weir"),
    ("bridges", "bridge"),
)

__all__ = ["STRUCTURE_TABLES", "Network"]


class Network(NetworkModel):
    """A complete river network.

    Attributes
    ----------
    friction
        Global friction, inherited by every branch without its own (``friction:global``).
    friction_groups
        Named friction groups that profiles refer to per section (``friction:group:<id>``).
    profiles, nodes, branches
        Geometry and topology.
    weirs, culverts, pumps, orifices, universal_weirs, bridges
        Structures on branches.
    boundaries, laterals
        Forcing locations.
    stations
        Observation stations.
    """

    friction: Friction = Field(
        default=Friction(type="strickler", value=30.0),
        description="global friction, used by every branch without its own (default Strickler 30 m^(1/3)/s)",
    )
    friction_groups: list[FrictionGroup] = Field(
        default=[], description="named friction groups that profiles refer to, section by section"
    )
    profiles: list[Profile] = Field(min_length=1, description="cross-section shapes, referenced by id")
    nodes: list[Node] = Field(min_length=2, description="connection nodes (branch ends)")
    branches: list[Branch] = Field(min_length=1, description="channel reaches between two nodes")
    weirs: list[Weir] = Field(default=[], description="weirs on branches")
    culverts: list[Culvert] = Field(default=[], description="culverts on branches")
    pumps: list[Pump] = Field(default=[], description="pumps on branches")
    orifices: list[Orifice] = Field(default=[], description="orifices (gated weirs) on branches")
    universal_weirs: list[UniversalWeir] = Field(default=[], description="weirs with a crest of any shape")
    bridges: list[Bridge] = Field(default=[], description="bridges on branches")
    boundaries: list[Boundary] = Field(default=[], description="boundary conditions at end nodes")
    laterals: list[Lateral] = Field(default=[], description="point inflows and extractions")
    stations: list[Station] = Field(default=[], description="observation stations")

    @model_validator(mode="after")
    def _check_topology(self) -> Network:
        _unique(self.friction_groups, "friction_groups", "friction group")
        _unique(self.profiles, "profiles", "profile")
        _unique(self.nodes, "nodes", "node")
        _unique(self.branches, "branches", "branch")
        _unique_structures(self)
        _unique(self.boundaries, "boundaries", "boundary")
        _unique(self.laterals, "laterals", "lateral")
        _unique(self.stations, "stations", "station")
        nodes = {n.id for n in self.nodes}
        profiles = {p.id for p in self.profiles}
        branches = {b.id: b for b in self.branches}
        degree: dict[str, int] = defaultdict(int)
        for i, b in enumerate(self.branches):
            for end in ("from_node", "to_node"):
                node = getattr(b, end)
                if node not in nodes:
                    raise FieldProblem(f"branches[{i}].{end}", f"branch {b.id!r} refers to unknown node {node!r}"
                                       f"{_known(nodes, node)}")
                degree[node] += 1
            for j, cs in enumerate(b.cross_sections):
                if cs.profile not in profiles:
                    raise FieldProblem(
                        f"branches[{i}].cross_sections[{j}].profile",
                        f"branch {b.id!r} refers to unknown profile {cs.profile!r}{_known(profiles, cs.profile)}",
                    )
        for i, n in enumerate(self.nodes):
            if degree[n.id] == 0:
                raise FieldProblem(
                    f"nodes[{i}].id", f"node {n.id!r} is not the end of any branch; remove it or connect a branch to it"
                )
        self._check_friction_groups(branches)
        self._check_structures(branches)
        boundary_at: dict[str, Boundary] = {}
        for i, bd in enumerate(self.boundaries):
            if bd.node not in nodes:
                raise FieldProblem(f"boundaries[{i}].node", f"boundary {bd.id!r} refers to unknown node {bd.node!r}"
                                   f"{_known(nodes, bd.node)}")
            if degree[bd.node] != 1:
                raise FieldProblem(
                    f"boundaries[{i}].node",
                    f"boundary {bd.id!r} is at node {bd.node!r}, which joins {degree[bd.node]} branches; "
                    "boundaries must sit at end nodes (nodes with exactly one branch)",
                )
            if bd.node in boundary_at:
                raise FieldProblem(
                    f"boundaries[{i}].node",
                    f"node {bd.node!r} already has boundary {boundary_at[bd.node].id!r}; a node takes one boundary",
                )
            boundary_at[bd.node] = bd
        for i, lat in enumerate(self.laterals):
            where = f"laterals[{i}]"
            if lat.node is not None:
                if lat.node not in nodes:
                    raise FieldProblem(f"{where}.node", f"lateral {lat.id!r} refers to unknown node {lat.node!r}"
                                       f"{_known(nodes, lat.node)}")
                bd = boundary_at.get(lat.node)
                if bd is not None and bd.type == "level":
                    raise FieldProblem(
                        f"{where}.node",
                        f"lateral {lat.id!r} is at node {lat.node!r}, which has level boundary {bd.id!r}: the level "
                        "there is imposed, so the inflow would be lost; move the lateral onto the branch",
                    )
            else:
                self._check_on_branch(lat, where, "lateral", branches)
        structures = {s.id for s in self.structures}
        for i, st in enumerate(self.stations):
            if st.structure is not None and st.structure not in structures:
                raise FieldProblem(
                    f"stations[{i}].structure",
                    f"station {st.id!r} refers to unknown structure {st.structure!r} (no structure "
                    f"has that id){_known(structures, st.structure)}",
                )
            if st.branch is not None:
                self._check_on_branch(st, f"stations[{i}]", "station", branches)
        return self

    def _check_on_branch(self, item: Lateral | Station, where: str, what: str, branches: dict[str, Branch]) -> None:
        if item.branch not in branches:
            raise FieldProblem(f"{where}.branch", f"{what} {item.id!r} refers to unknown branch {item.branch!r}"
                               f"{_known(branches, item.branch)}")
        length = branches[item.branch].length
        if item.chainage is not None and item.chainage > length:
            raise FieldProblem(
                f"{where}.chainage",
                f"{what} {item.id!r} at chainage {num(item.chainage)} m lies beyond the end of branch "
                f"{item.branch!r} ({num(length)} m long)",
            )

    def parts(self) -> list[list[str]]:
        """The connected parts of the network: lists of node ids, the part of the first node first."""
        adjacency: dict[str, set[str]] = defaultdict(set)
        for b in self.branches:
            adjacency[b.from_node].add(b.to_node)
            adjacency[b.to_node].add(b.from_node)
        seen: set[str] = set()
        parts: list[list[str]] = []
        for n in self.nodes:
            if n.id in seen:
                continue
            part = [n.id]
            seen.add(n.id)
            queue = deque([n.id])
            while queue:
                for nb in sorted(adjacency[queue.popleft()]):
                    if nb not in seen:
                        seen.add(nb)
                        part.append(nb)
                        queue.append(nb)
            parts.append(part)
        return parts

    def _check_friction_groups(self, branches: dict[str, Branch]) -> None:
        groups = {g.id for g in self.friction_groups}
        for i, g in enumerate(self.friction_groups):
            for j, bf in enumerate(g.branches):
                if bf.branch not in branches:
                    raise FieldProblem(f"friction_groups[{i}].branches[{j}].branch",
                                       f"friction group {g.id!r} refers to unknown branch {bf.branch!r}"
                                       f"{_known(branches, bf.branch)}")
        for i, p in enumerate(self.profiles):
            for j, gid in enumerate(p.friction or []):
                if gid not in groups:
                    raise FieldProblem(f"profiles[{i}].friction[{j}]",
                                       f"profile {p.id!r} refers to unknown friction group {gid!r}"
                                       f"{_known(groups, gid)}")

    def _check_structures(self, branches: dict[str, Branch]) -> None:
        profiles = {p.id for p in self.profiles}
        for table, what in STRUCTURE_TABLES:
            for i, s in enumerate(getattr(self, table)):
                where = f"{table}[{i}]"
                if s.branch not in branches:
                    raise FieldProblem(f"{where}.branch", f"{what} {s.id!r} refers to unknown branch {s.branch!r}"
                                       f"{_known(branches, s.branch)}")
                br = branches[s.branch]
                if s.chainage > br.length:
                    raise FieldProblem(
                        f"{where}.chainage",
                        f"{what} {s.id!r} at chainage {num(s.chainage)} m lies beyond the end of branch {br.id!r} "
                        f"({num(br.length)} m long)",
                    )
                bed = br.bed_level_at(s.chainage)
                at = f"({bed:.3f} m AD at chainage {num(s.chainage)} m of branch {br.id!r})"
                if isinstance(s, Weir | Orifice | UniversalWeir) and s.crest_level < bed:
                    raise FieldProblem(
                        f"{where}.crest_level",
                        f"the crest of {what} {s.id!r} ({num(s.crest_level)} m AD) lies below the bed {at}",
                    )
                if isinstance(s, Culvert):
                    if s.invert_level_end is None and s.invert_level < bed - 1e-9:
                        raise FieldProblem(
                            f"{where}.invert_level",
                            f"the invert of culvert {s.id!r} ({num(s.invert_level)} m AD) lies below the bed {at}; "
                            "a siphon or sloping culvert gives both inverts (invert_level and invert_level_end)",
                        )
                    if s.profile is not None and s.profile not in profiles:
                        raise FieldProblem(f"{where}.profile", f"culvert {s.id!r} refers to unknown profile "
                                                               f"{s.profile!r}{_known(profiles, s.profile)}")
                if isinstance(s, Bridge) and s.profile not in profiles:
                    raise FieldProblem(f"{where}.profile", f"bridge {s.id!r} refers to unknown profile "
                                                           f"{s.profile!r}{_known(profiles, s.profile)}")

    # -- convenience look-ups -------------------------------------------------------------

    def branch(self, branch_id: str) -> Branch:
        """The branch with this id."""
        for b in self.branches:
            if b.id == branch_id:
                return b
        raise KeyError(branch_id)

    def profile(self, profile_id: str) -> Profile:
        """The profile with this id."""
        for p in self.profiles:
            if p.id == profile_id:
                return p
        raise KeyError(profile_id)

    @property
    def structures(self) -> list[Weir | Culvert | Pump | Orifice | UniversalWeir | Bridge]:
        """Every structure, in the order of :data:`STRUCTURE_TABLES`."""
        return [s for table, _ in STRUCTURE_TABLES for s in getattr(self, table)]

    def structure(self, structure_id: str) -> Weir | Culvert | Pump | Orifice | UniversalWeir | Bridge:
        """The structure with this id."""
        for s in self.structures:
            if s.id == structure_id:
                return s
        raise KeyError(structure_id)

    def friction_group(self, group_id: str) -> FrictionGroup:
        """The friction group with this id."""
        for g in self.friction_groups:
            if g.id == group_id:
                return g
        raise KeyError(group_id)

    @property
    def observables(self) -> list[str]:
        """All simulated series names ``"<station>.<quantity>"``, in station order."""
        return [name for st in self.stations for name in st.observables]


def _known(ids, name: str) -> str:
    """A suggestion, or a short list of the ids that do exist, for an 'unknown id' message."""
    names = sorted(ids)
    if not names:
        return " (there are none)"
    lower = {n.lower(): n for n in names}
    close = difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=0.6)
    if close:
        hint = " (ids are case-sensitive)" if close[0] == name.lower() else ""
        return f"; did you mean {lower[close[0]]!r}?{hint}"
    shown = ", ".join(repr(n) for n in names[:8])
    return f" (known: {shown}{', ...' if len(names) > 8 else ''})"


def _unique(items: list, table: str, what: str) -> None:
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        if item.id in first:
            raise FieldProblem(
                f"{table}[{i}].id", f"{what} id {item.id!r} is used twice (also by {table}[{first[item.id]}])"
            )
        first[item.id] = i


def _unique_structures(network: Network) -> None:
    first: dict[str, str] = {}
    for table, _ in STRUCTURE_TABLES:
        for i, s in enumerate(getattr(network, table)):
            where = f"{table}[{i}]"
            if s.id in first:
                raise FieldProblem(
                    f"{where}.id",
                    f"structure id {s.id!r} is used twice (also by {first[s.id]}); all structures share one set "
                    "of ids",
                )
            first[s.id] = where
