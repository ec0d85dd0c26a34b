"""The river network as validated data: nodes, branches, profiles, structures, boundaries, stations.

These pydantic models are both the in-memory network description and the schema of the network
part of ``case.toml`` (see ``docs/case-format.md``). Field-level rules (positive widths, monotone
tables) are checked by pydantic; rules that need the whole network (unknown ids, connectivity, a
crest below the bed) are checked by :meth:`Network._check_topology`. Nothing here does numerics
beyond evaluating the bed level along a branch.

Conventions
-----------
Levels are in m above the vertical datum (m AD); depths, widths, lengths and chainages in m;
discharges in m³/s; areas in m². The positive flow direction of a branch runs from its
``from_node`` (chainage 0) to its ``to_node`` (chainage = ``length``).
"""

from __future__ import annotations

import itertools
from collections import defaultdict, deque
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "Boundary",
    "Branch",
    "CrossSection",
    "Culvert",
    "Friction",
    "Lateral",
    "Network",
    "Node",
    "Profile",
    "Pump",
    "RatingTable",
    "RectangularProfile",
    "SeriesRef",
    "Station",
    "StorageTable",
    "TrapezoidalProfile",
    "Weir",
    "ZWProfile",
]

Identifier = Annotated[
    str,
    Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$", description="identifier"),
]
FlowDirection = Literal["both", "positive", "negative", "none"]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)


class Friction(_Model):
    """Bed friction law and coefficient.

    Attributes
    ----------
    type
        ``strickler`` (k_s in m^(1/3)/s, C = k_s R^(1/6), thesis Eq. 3-3), ``manning`` (n in
        s/m^(1/3), C = R^(1/6)/n) or ``chezy`` (C in m^(1/2)/s).
    value
        The coefficient, in the unit of its type.
    """

    type: Literal["strickler", "manning", "chezy"] = "strickler"
    value: float = Field(gt=0, description="friction coefficient in the unit of its type")


class SeriesRef(_Model):
    """A column of a CSV time series file in the case folder.

    Attributes
    ----------
    file
        Path of the CSV file relative to the case folder.
    column
        Name of the value column (the first column holds the UTC times).
    """

    file: str = Field(min_length=1)
    column: str = Field(min_length=1)


def _strictly_increasing(values: list[float], name: str) -> None:
    if any(b <= a for a, b in itertools.pairwise(values)):
        raise ValueError(f"{name} must be strictly increasing, got {values}")


class RectangularProfile(_Model):
    """Rectangular cross-section.

    Attributes
    ----------
    width
        Bottom (= flow) width, m.
    height
        Bank height above the bed, m (optional; used for freeboard checks and plots).
    """

    id: Identifier
    type: Literal["rectangular"]
    width: float = Field(gt=0)
    height: float | None = Field(default=None, gt=0)


class TrapezoidalProfile(_Model):
    """Trapezoidal cross-section.

    Attributes
    ----------
    bottom_width
        Width of the bed, m.
    side_slope
        Horizontal run per unit rise of each bank, m/m (0 gives a rectangle).
    height
        Bank height above the bed, m (optional). The table used by the engine extends the banks
        up to ``max(height, 10 m)`` and continues with vertical walls above.
    """

    id: Identifier
    type: Literal["trapezoidal"]
    bottom_width: float = Field(ge=0)
    side_slope: float = Field(ge=0)
    height: float | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _not_degenerate(self) -> TrapezoidalProfile:
        if self.bottom_width == 0 and self.side_slope == 0:
            raise ValueError("bottom_width and side_slope are both 0: the profile has no width")
        return self


class ZWProfile(_Model):
    """Tabulated level-width ("ZW") cross-section, relative to its own lowest point.

    Attributes
    ----------
    heights
        Heights above the bed, m; start at 0 and strictly increase.
    flow_widths
        Width that conveys flow at each height, m; non-negative and non-decreasing.
    total_widths
        Width that stores water at each height, m (default: the flow widths); not smaller than
        the flow width, non-decreasing.
    """

    id: Identifier
    type: Literal["zw"]
    heights: list[float] = Field(min_length=2)
    flow_widths: list[float] = Field(min_length=2)
    total_widths: list[float] | None = None

    @model_validator(mode="after")
    def _check_table(self) -> ZWProfile:
        n = len(self.heights)
        if len(self.flow_widths) != n:
            raise ValueError(f"flow_widths has {len(self.flow_widths)} values, heights has {n}")
        if self.total_widths is not None and len(self.total_widths) != n:
            raise ValueError(f"total_widths has {len(self.total_widths)} values, heights has {n}")
        if self.heights[0] != 0.0:
            raise ValueError(f"heights must start at 0 (the bed), got {self.heights[0]}")
        _strictly_increasing(self.heights, "heights")
        for name, widths in (("flow_widths", self.flow_widths), ("total_widths", self.total_widths)):
            if widths is None:
                continue
            if any(w < 0 or not np.isfinite(w) for w in widths):
                raise ValueError(f"{name} must be finite and non-negative, got {widths}")
            if any(b < a for a, b in itertools.pairwise(widths)):
                raise ValueError(f"{name} must not decrease with height, got {widths}")
        if self.flow_widths[-1] <= 0:
            raise ValueError("the top flow width must be positive")
        if self.total_widths is not None and any(
            t < f for t, f in zip(self.total_widths, self.flow_widths, strict=True)
        ):
            raise ValueError("total_widths must not be smaller than flow_widths")
        return self

    @property
    def storage_widths(self) -> list[float]:
        """Total (storage) widths, m."""
        return list(self.total_widths if self.total_widths is not None else self.flow_widths)


Profile = Annotated[
    RectangularProfile | TrapezoidalProfile | ZWProfile, Field(discriminator="type")
]


class StorageTable(_Model):
    """Storage area of a connection node as a function of level.

    Attributes
    ----------
    levels
        Water levels, m AD, strictly increasing.
    areas
        Horizontal storage area at each level, m², non-negative. Linear in between; constant
        above the last level; zero below the first.
    """

    levels: list[float] = Field(min_length=2)
    areas: list[float] = Field(min_length=2)

    @model_validator(mode="after")
    def _check(self) -> StorageTable:
        if len(self.levels) != len(self.areas):
            raise ValueError(f"levels has {len(self.levels)} values, areas has {len(self.areas)}")
        _strictly_increasing(self.levels, "levels")
        if any(a < 0 or not np.isfinite(a) for a in self.areas):
            raise ValueError(f"areas must be finite and non-negative, got {self.areas}")
        return self


class Node(_Model):
    """A connection node: the end of one or more branches.

    Attributes
    ----------
    x, y
        Map coordinates, m (optional; used for plots and to derive branch lengths).
    storage_area
        Extra horizontal storage area at the node, m² (a pond or a manhole), from the lowest bed
        level of the attached branches upward.
    storage_table
        Extra storage as a level-area table (alternative to ``storage_area``).
    """

    id: Identifier
    x: float | None = None
    y: float | None = None
    storage_area: float = Field(default=0.0, ge=0)
    storage_table: StorageTable | None = None

    @model_validator(mode="after")
    def _one_storage(self) -> Node:
        if self.storage_table is not None and self.storage_area > 0:
            raise ValueError("give either storage_area or storage_table, not both")
        return self


class CrossSection(_Model):
    """A cross-section placed on a branch.

    Attributes
    ----------
    chainage
        Distance from the start of the branch, m.
    profile
        Id of a profile in ``profiles``.
    bed_level
        Level of the lowest point of the profile, m AD. Bed levels are interpolated linearly
        between cross-sections; each calculation point takes the shape of the nearest one.
    """

    chainage: float = Field(ge=0)
    profile: Identifier
    bed_level: float


class Branch(_Model):
    """A channel reach between two connection nodes.

    Attributes
    ----------
    from_node, to_node
        Node ids at chainage 0 and at the end; positive flow runs from ``from_node`` to ``to_node``.
    length
        Length along the axis, m.
    dx
        Target spacing of calculation points, m (default 100 m).
    friction
        Friction of this branch; when absent the branch inherits the case's global friction.
    cross_sections
        At least one cross-section, ordered by chainage.
    geometry
        Optional polyline ``[[x, y], ...]`` in m for plots.
    """

    id: Identifier
    from_node: Identifier
    to_node: Identifier
    length: float = Field(gt=0)
    dx: float = Field(default=100.0, gt=0)
    friction: Friction | None = None
    cross_sections: list[CrossSection] = Field(min_length=1)
    geometry: list[tuple[float, float]] | None = None

    @model_validator(mode="after")
    def _check_sections(self) -> Branch:
        if self.from_node == self.to_node:
            raise ValueError(f"from_node and to_node are the same node {self.from_node!r}")
        chainages = [cs.chainage for cs in self.cross_sections]
        _strictly_increasing(chainages, "cross_sections chainages")
        if chainages[-1] > self.length:
            raise ValueError(f"cross-section at chainage {chainages[-1]} m lies beyond the length {self.length} m")
        return self

    def bed_level_at(self, chainage: float) -> float:
        """Bed level at a chainage, m AD (linear between cross-sections, constant beyond)."""
        ch = [cs.chainage for cs in self.cross_sections]
        zb = [cs.bed_level for cs in self.cross_sections]
        return float(np.interp(chainage, ch, zb))

    def cross_section_at(self, chainage: float) -> CrossSection:
        """The cross-section nearest to a chainage (its shape is used there)."""
        return min(self.cross_sections, key=lambda cs: abs(cs.chainage - chainage))


class _OnBranch(_Model):
    id: Identifier
    branch: Identifier
    chainage: float = Field(ge=0, description="distance from the start of the branch, m")


class Weir(_OnBranch):
    """A broad-crested weir (thesis Eq. 3-4, free/submerged switch at h1 - zs = 1.5 (h2 - zs)).

    Attributes
    ----------
    crest_level
        Crest level z_s, m AD (a calibration target: ``weir:<id>.crest_level``).
    crest_width
        Crest width W_s, m.
    discharge_coefficient
        c_e, dimensionless.
    lateral_contraction
        c_w, dimensionless.
    allowed_flow
        ``both``, ``positive`` (branch direction only), ``negative`` or ``none``.
    """

    crest_level: float
    crest_width: float = Field(gt=0)
    discharge_coefficient: float = Field(default=1.0, gt=0, le=2.0)
    lateral_contraction: float = Field(default=1.0, gt=0, le=1.0)
    allowed_flow: FlowDirection = "both"


class Culvert(_OnBranch):
    """A culvert: a closed conduit with entrance, friction and exit losses.

    Attributes
    ----------
    shape
        ``rectangular`` (``width`` x ``height``) or ``circular`` (``diameter``).
    width, height, diameter
        Conduit dimensions, m.
    invert_level
        Level of the conduit's bottom, m AD.
    length
        Conduit length, m.
    inlet_loss, outlet_loss
        Entrance and exit loss coefficients, dimensionless.
    friction
        Wall friction (default Manning n = 0.015 s/m^(1/3), concrete).
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    """

    shape: Literal["rectangular", "circular"]
    width: float | None = Field(default=None, gt=0)
    height: float | None = Field(default=None, gt=0)
    diameter: float | None = Field(default=None, gt=0)
    invert_level: float
    length: float = Field(gt=0)
    inlet_loss: float = Field(default=0.5, ge=0)
    outlet_loss: float = Field(default=1.0, ge=0)
    friction: Friction = Friction(type="manning", value=0.015)
    allowed_flow: FlowDirection = "both"

    @model_validator(mode="after")
    def _dimensions(self) -> Culvert:
        if self.shape == "rectangular" and (self.width is None or self.height is None):
            raise ValueError("a rectangular culvert needs width and height")
        if self.shape == "circular" and self.diameter is None:
            raise ValueError("a circular culvert needs diameter")
        return self

    @property
    def opening_height(self) -> float:
        """Height of the conduit, m."""
        return float(self.diameter if self.shape == "circular" else self.height)  # type: ignore[arg-type]


class Pump(_OnBranch):
    """A pump with a fixed capacity and level switches on its suction side.

    Attributes
    ----------
    capacity
        Discharge when running, m³/s.
    start_level, stop_level
        Suction-side levels at which the pump switches on and off, m AD (start > stop).
    direction
        ``positive`` pumps in the branch direction, ``negative`` against it.
    """

    capacity: float = Field(gt=0)
    start_level: float
    stop_level: float
    direction: Literal["positive", "negative"] = "positive"

    @model_validator(mode="after")
    def _levels(self) -> Pump:
        if not self.start_level > self.stop_level:
            raise ValueError(f"start_level {self.start_level} must be above stop_level {self.stop_level}")
        return self


class RatingTable(_Model):
    """Outflow discharge as a function of level at a boundary node (a Q(h) relation).

    Attributes
    ----------
    levels
        Levels, m AD, strictly increasing.
    discharges
        Outflow at each level, m³/s, non-negative and non-decreasing.
    """

    levels: list[float] = Field(min_length=2)
    discharges: list[float] = Field(min_length=2)

    @model_validator(mode="after")
    def _check(self) -> RatingTable:
        if len(self.levels) != len(self.discharges):
            raise ValueError(f"levels has {len(self.levels)} values, discharges has {len(self.discharges)}")
        _strictly_increasing(self.levels, "levels")
        if any(q < 0 or not np.isfinite(q) for q in self.discharges):
            raise ValueError("discharges must be finite and non-negative")
        if any(b < a for a, b in zip(self.discharges, self.discharges[1:], strict=False)):
            raise ValueError("discharges must not decrease with level")
        return self


class Boundary(_Model):
    """A boundary condition at an end node.

    Attributes
    ----------
    node
        Id of an end node (a node with exactly one branch).
    type
        ``discharge`` (inflow Q(t), m³/s, negative for outflow), ``level`` (h(t), m AD) or
        ``rating`` (outflow from a Q(h) table).
    series
        Time series of the value (for ``discharge`` and ``level``).
    value
        Constant value instead of a series.
    rating
        The Q(h) table (for ``rating``).
    """

    id: Identifier
    node: Identifier
    type: Literal["discharge", "level", "rating"]
    series: SeriesRef | None = None
    value: float | None = None
    rating: RatingTable | None = None

    @model_validator(mode="after")
    def _one_source(self) -> Boundary:
        if self.type == "rating":
            if self.rating is None or self.series is not None or self.value is not None:
                raise ValueError("a rating boundary needs a rating table and no series or value")
        elif (self.series is None) == (self.value is None):
            raise ValueError(f"a {self.type} boundary needs exactly one of series or value")
        return self


class Lateral(_Model):
    """A point inflow (m³/s, negative for an extraction) at a node or at a chainage on a branch.

    Attributes
    ----------
    node
        Node id, or
    branch, chainage
        a location on a branch (the inflow goes to the nearest calculation point).
    series, value
        The discharge as a time series, or a constant, m³/s.
    """

    id: Identifier
    node: Identifier | None = None
    branch: Identifier | None = None
    chainage: float | None = Field(default=None, ge=0)
    series: SeriesRef | None = None
    value: float | None = None

    @model_validator(mode="after")
    def _location_and_source(self) -> Lateral:
        on_branch = self.branch is not None and self.chainage is not None
        if (self.node is not None) == on_branch or (self.branch is None) != (self.chainage is None):
            raise ValueError("give either node, or branch and chainage")
        if (self.series is None) == (self.value is None):
            raise ValueError("give exactly one of series or value")
        return self


StationQuantity = Literal["h", "h_up", "h_down", "Q"]


class Station(_Model):
    """An observation station.

    A station either sits at a structure (quantities ``h_up``, ``h_down``, ``Q``) or at a
    chainage on a branch (quantities ``h``, ``Q``). Its simulated series are named
    ``"<id>.<quantity>"``.

    Attributes
    ----------
    structure
        Id of a weir, culvert or pump.
    branch, chainage
        A location on a branch, m.
    quantities
        Observed quantities (default ``h_up, h_down`` at a structure, ``h`` on a branch).
    """

    id: Identifier
    structure: Identifier | None = None
    branch: Identifier | None = None
    chainage: float | None = Field(default=None, ge=0)
    quantities: list[StationQuantity] | None = None

    @model_validator(mode="after")
    def _location(self) -> Station:
        at_branch = self.branch is not None and self.chainage is not None
        if (self.structure is not None) == at_branch or (self.branch is None) != (self.chainage is None):
            raise ValueError("give either structure, or branch and chainage")
        allowed = {"h_up", "h_down", "Q"} if self.structure is not None else {"h", "Q"}
        bad = [q for q in self.quantities or [] if q not in allowed]
        if bad:
            where = "a structure" if self.structure is not None else "a chainage"
            raise ValueError(f"quantities {bad} are not available at {where} (allowed: {sorted(allowed)})")
        if self.quantities is not None and len(set(self.quantities)) != len(self.quantities):
            raise ValueError(f"duplicate quantities {self.quantities}")
        return self

    @property
    def observables(self) -> list[str]:
        """Names ``"<station>.<quantity>"`` of the series this station produces."""
        default = ["h_up", "h_down"] if self.structure is not None else ["h"]
        return [f"{self.id}.{q}" for q in (self.quantities or default)]


class Network(_Model):
    """A complete river network.

    Attributes
    ----------
    friction
        Global friction, inherited by every branch without its own (``friction:global``).
    profiles, nodes, branches
        Geometry and topology.
    weirs, culverts, pumps
        Structures on branches.
    boundaries, laterals
        Forcing locations.
    stations
        Observation stations.
    """

    friction: Friction = Friction(type="strickler", value=30.0)
    profiles: list[Profile] = Field(min_length=1)
    nodes: list[Node] = Field(min_length=2)
    branches: list[Branch] = Field(min_length=1)
    weirs: list[Weir] = []
    culverts: list[Culvert] = []
    pumps: list[Pump] = []
    boundaries: list[Boundary] = []
    laterals: list[Lateral] = []
    stations: list[Station] = []

    @model_validator(mode="after")
    def _check_topology(self) -> Network:
        _unique(self.profiles, "profiles")
        _unique(self.nodes, "nodes")
        _unique(self.branches, "branches")
        _unique([*self.weirs, *self.culverts, *self.pumps], "structures (weirs, culverts and pumps)")
        _unique(self.boundaries, "boundaries")
        _unique(self.laterals, "laterals")
        _unique(self.stations, "stations")
        nodes = {n.id for n in self.nodes}
        profiles = {p.id for p in self.profiles}
        branches = {b.id: b for b in self.branches}
        degree: dict[str, int] = defaultdict(int)
        for i, b in enumerate(self.branches):
            for end in ("from_node", "to_node"):
                if getattr(b, end) not in nodes:
                    raise ValueError(f"branches[{i}].{end}: unknown node {getattr(b, end)!r}")
                degree[getattr(b, end)] += 1
            for j, cs in enumerate(b.cross_sections):
                if cs.profile not in profiles:
                    raise ValueError(f"branches[{i}].cross_sections[{j}].profile: unknown profile {cs.profile!r}")
        unused = sorted(nodes - set(degree))
        if unused:
            raise ValueError(f"nodes: node {unused[0]!r} is not connected to any branch")
        self._check_connected()
        self._check_structures(branches)
        boundary_nodes: set[str] = set()
        for i, bd in enumerate(self.boundaries):
            if bd.node not in nodes:
                raise ValueError(f"boundaries[{i}].node: unknown node {bd.node!r}")
            if degree[bd.node] != 1:
                raise ValueError(
                    f"boundaries[{i}].node: node {bd.node!r} joins {degree[bd.node]} branches; "
                    "boundaries must sit at end nodes"
                )
            if bd.node in boundary_nodes:
                raise ValueError(f"boundaries[{i}].node: node {bd.node!r} already has a boundary")
            boundary_nodes.add(bd.node)
        for i, lat in enumerate(self.laterals):
            self._check_location(lat, f"laterals[{i}]", nodes, branches)
        structures = {s.id for s in [*self.weirs, *self.culverts, *self.pumps]}
        for i, st in enumerate(self.stations):
            if st.structure is not None and st.structure not in structures:
                raise ValueError(f"stations[{i}].structure: unknown structure {st.structure!r}")
            if st.branch is not None:
                self._check_location(st, f"stations[{i}]", nodes, branches)
        return self

    def _check_location(self, item: Lateral | Station, where: str, nodes: set[str], branches: dict) -> None:
        node = getattr(item, "node", None)
        if node is not None and node not in nodes:
            raise ValueError(f"{where}.node: unknown node {node!r}")
        if item.branch is not None:
            if item.branch not in branches:
                raise ValueError(f"{where}.branch: unknown branch {item.branch!r}")
            length = branches[item.branch].length
            if item.chainage is not None and item.chainage > length:
                raise ValueError(f"{where}.chainage: {item.chainage} m is beyond the branch length {length} m")

    def _check_connected(self) -> None:
        adjacency: dict[str, set[str]] = defaultdict(set)
        for b in self.branches:
            adjacency[b.from_node].add(b.to_node)
            adjacency[b.to_node].add(b.from_node)
        start = self.nodes[0].id
        seen = {start}
        queue = deque([start])
        while queue:
            for nb in adjacency[queue.popleft()]:
                if nb not in seen:
                    seen.add(nb)
                    queue.append(nb)
        missing = [n.id for n in self.nodes if n.id not in seen]
        if missing:
            raise ValueError(
                f"the network is disconnected: node {missing[0]!r} cannot be reached from node {start!r}"
            )

    def _check_structures(self, branches: dict[str, Branch]) -> None:
        groups = (("weirs", self.weirs), ("culverts", self.culverts), ("pumps", self.pumps))
        for kind, items in groups:
            for i, s in enumerate(items):
                where = f"{kind}[{i}]"
                if s.branch not in branches:
                    raise ValueError(f"{where}.branch: unknown branch {s.branch!r}")
                br = branches[s.branch]
                if s.chainage > br.length:
                    raise ValueError(f"{where}.chainage: {s.chainage} m is beyond the branch length {br.length} m")
                bed = br.bed_level_at(s.chainage)
                if isinstance(s, Weir) and s.crest_level < bed:
                    raise ValueError(
                        f"{where}.crest_level: crest {s.crest_level} m AD of weir {s.id!r} lies below "
                        f"the bed ({bed:.3f} m AD at chainage {s.chainage} m of branch {s.branch!r})"
                    )
                if isinstance(s, Culvert) and s.invert_level < bed - 1e-9:
                    raise ValueError(
                        f"{where}.invert_level: invert {s.invert_level} m AD of culvert {s.id!r} lies below "
                        f"the bed ({bed:.3f} m AD)"
                    )
                if isinstance(s, Pump) and s.stop_level <= bed:
                    raise ValueError(
                        f"{where}.stop_level: pump {s.id!r} would run the suction side dry: stop level "
                        f"{s.stop_level} m AD is not above the bed ({bed:.3f} m AD)"
                    )

    # -- convenience look-ups -------------------------------------------------------------

    def branch(self, branch_id: str) -> Branch:
        """The branch with this id."""
        for b in self.branches:
            if b.id == branch_id:
                return b
        raise KeyError(branch_id)

    def profile(self, profile_id: str) -> RectangularProfile | TrapezoidalProfile | ZWProfile:
        """The profile with this id."""
        for p in self.profiles:
            if p.id == profile_id:
                return p
        raise KeyError(profile_id)

    def structure(self, structure_id: str) -> Weir | Culvert | Pump:
        """The weir, culvert or pump with this id."""
        for s in [*self.weirs, *self.culverts, *self.pumps]:
            if s.id == structure_id:
                return s
        raise KeyError(structure_id)

    @property
    def observables(self) -> list[str]:
        """All simulated series names ``"<station>.<quantity>"``, in station order."""
        return [name for st in self.stations for name in st.observables]


def _unique(items: list, what: str) -> None:
    seen: set[str] = set()
    for i, item in enumerate(items):
        if item.id in seen:
            raise ValueError(f"{what}: id {item.id!r} is used twice (item {i})")
        seen.add(item.id)
