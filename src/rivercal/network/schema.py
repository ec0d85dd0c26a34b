"""The river network as validated data: nodes, branches, profiles, structures, boundaries, stations.

These pydantic models are both the in-memory network description and the schema of the network
part of ``case.toml`` (see ``docs/case-format.md``). Field-level rules (positive widths, monotone
tables, finite numbers) are checked by the models themselves; rules that need the whole network
(unknown ids, connectivity, a crest below the bed) are checked by :meth:`Network._check_topology`.
Nothing here does numerics beyond evaluating the bed level along a branch.

Every rule that fails raises :class:`FieldProblem`, a ``ValueError`` that carries the path of the
offending field relative to the model that raised it (``cross_sections[1].chainage``), so that
the case loader can report the full path (``branches[2].cross_sections[1].chainage``).

Conventions
-----------
Levels are in m above the vertical datum (m AD); depths, widths, lengths and chainages in m;
discharges in m³/s; areas in m². The positive flow direction of a branch runs from its
``from_node`` (chainage 0) to its ``to_node`` (chainage = ``length``). Numbers must be finite
(``nan`` and ``inf`` are rejected) and written as numbers, not as quoted text.
"""

from __future__ import annotations

import difflib
import itertools
from collections import defaultdict, deque
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "FRICTION_RANGES",
    "MAX_DISCHARGE",
    "MAX_LEVEL",
    "MAX_POINTS_PER_BRANCH",
    "MAX_SIZE",
    "MIN_SIZE",
    "Boundary",
    "Branch",
    "CrossSection",
    "Culvert",
    "Discharge",
    "FieldProblem",
    "Friction",
    "Lateral",
    "Level",
    "Network",
    "Node",
    "Profile",
    "Pump",
    "RatingTable",
    "Real",
    "RectangularProfile",
    "SeriesRef",
    "Size",
    "Station",
    "StorageTable",
    "TrapezoidalProfile",
    "Weir",
    "ZWProfile",
]

#: Most calculation points one branch may get (length / dx); more is a unit mistake, not a model.
MAX_POINTS_PER_BRANCH = 100_000

#: Plausible range of each friction coefficient; values outside are almost always a unit or type
#: mix-up (a Manning n given as a Strickler k_s, or the reverse).
FRICTION_RANGES: dict[str, tuple[float, float, str]] = {
    "strickler": (1.0, 200.0, "m^(1/3)/s"),
    "manning": (0.005, 1.0, "s/m^(1/3)"),
    "chezy": (1.0, 300.0, "m^(1/2)/s"),
}

Identifier = Annotated[
    str,
    Field(
        min_length=1,
        max_length=64,
        pattern=r"^[A-Za-z0-9_.\-]+$",
        description="identifier: 1-64 letters, digits, '_', '-' or '.'",
    ),
]
#: Levels must lie within ±MAX_LEVEL m AD.
MAX_LEVEL = 1.0e4
#: Discharges (boundaries, laterals, pumps, ratings) must lie within ±MAX_DISCHARGE m³/s.
MAX_DISCHARGE = 1.0e6
#: Widths, heights and diameters that must be positive are at least MIN_SIZE m (1 mm) ...
MIN_SIZE = 1.0e-3
#: ... and at most MAX_SIZE m.
MAX_SIZE = 1.0e5

#: A finite number written as a number (an int is accepted; text, booleans, nan and inf are not).
Real = Annotated[float, Field(strict=True)]
#: A water or bed level, m AD.
Level = Annotated[float, Field(strict=True, ge=-MAX_LEVEL, le=MAX_LEVEL)]
#: A discharge, m³/s.
Discharge = Annotated[float, Field(strict=True, ge=-MAX_DISCHARGE, le=MAX_DISCHARGE)]
#: A width, height or diameter, m.
Size = Annotated[float, Field(strict=True, le=MAX_SIZE)]
FlowDirection = Literal["both", "positive", "negative", "none"]


class FieldProblem(ValueError):
    """A rule broken by one field.

    Parameters
    ----------
    path
        Path of the field relative to the model that raises the problem, e.g.
        ``cross_sections[1].chainage``; empty for the model as a whole.
    reason
        What is wrong, in words.
    """

    def __init__(self, path: str, reason: str):
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}" if path else reason)


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True, allow_inf_nan=False)


def _num(value: float) -> str:
    """A number as a user wrote it: no trailing zeros, no exponent for ordinary values."""
    return f"{value:g}"


def _nums(values: list[float]) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def _strictly_increasing(values: list[float], name: str, unit: str) -> None:
    for i, (a, b) in enumerate(itertools.pairwise(values), start=1):
        if not b > a:
            raise FieldProblem(
                f"{name}[{i}]",
                f"{name} must increase strictly, but {_num(b)} {unit} (position {i}) is not above "
                f"{_num(a)} {unit} (position {i - 1}) in {_nums(values)}",
            )


def _non_decreasing(values: list[float], name: str, unit: str, why: str) -> None:
    for i, (a, b) in enumerate(itertools.pairwise(values), start=1):
        if b < a:
            raise FieldProblem(
                f"{name}[{i}]",
                f"{name} must not decrease, but {_num(b)} {unit} (position {i}) is below {_num(a)} {unit} "
                f"(position {i - 1}) in {_nums(values)}; {why}",
            )


def _non_negative(values: list[float], name: str, unit: str) -> None:
    for i, v in enumerate(values):
        if v < 0:
            raise FieldProblem(f"{name}[{i}]", f"{name} must not be negative, got {_num(v)} {unit} at position {i}")


def _tiny(value: float, unit: str, least: float) -> str:
    return f"{_num(value)} {unit} is neither 0 nor at least {_num(least)} {unit}; values are in metres"


def _same_length(a: list, a_name: str, b: list, b_name: str) -> None:
    if len(a) != len(b):
        raise FieldProblem(
            b_name, f"{b_name} has {len(b)} values but {a_name} has {len(a)}; give one per {a_name.removesuffix('s')}"
        )


class Friction(_Model):
    """Bed friction law and coefficient.

    Attributes
    ----------
    type
        ``strickler`` (k_s in m^(1/3)/s, C = k_s R^(1/6), thesis Eq. 3-3), ``manning`` (n in
        s/m^(1/3), C = R^(1/6)/n) or ``chezy`` (C in m^(1/2)/s).
    value
        The coefficient, in the unit of its type; it must lie in the plausible range of
        :data:`FRICTION_RANGES` (this catches a Manning n given as a Strickler k_s).
    """

    type: Literal["strickler", "manning", "chezy"] = Field(
        default="strickler",
        description="friction law: 'strickler' (k_s, m^(1/3)/s), 'manning' (n, s/m^(1/3)) or 'chezy' (C, m^(1/2)/s)",
    )
    value: Real = Field(
        gt=0,
        description="friction coefficient in the unit of its type (Strickler k_s 1-200 m^(1/3)/s, "
        "Manning n 0.005-1 s/m^(1/3), Chezy C 1-300 m^(1/2)/s)",
    )

    @model_validator(mode="after")
    def _plausible(self) -> Friction:
        low, high, unit = FRICTION_RANGES[self.type]
        if not low <= self.value <= high:
            hint = ""
            if self.type == "strickler" and self.value < low:
                hint = '; is it a Manning n? then write type = "manning"'
            elif self.type == "manning" and self.value > high:
                hint = '; is it a Strickler k_s? then write type = "strickler"'
            raise FieldProblem(
                "value",
                f"{self.type} coefficient {_num(self.value)} {unit} is outside the plausible range "
                f"{_num(low)}-{_num(high)} {unit}{hint}",
            )
        return self


class SeriesRef(_Model):
    """A column of a CSV time series file in the case folder.

    Attributes
    ----------
    file
        Path of the CSV file relative to the case folder.
    column
        Name of the value column (the first column holds the UTC times).
    """

    file: str = Field(min_length=1, description="CSV file, relative to the case folder")
    column: str = Field(min_length=1, description="name of the value column in that file")


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
    type: Literal["rectangular"] = Field(description="profile type 'rectangular'")
    width: Size = Field(ge=MIN_SIZE, description="width of the channel, m")
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional)")


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
    type: Literal["trapezoidal"] = Field(description="profile type 'trapezoidal'")
    bottom_width: Size = Field(ge=0, description="width of the bed, m (0 for a V-shaped channel)")
    side_slope: Real = Field(
        ge=0, le=1000, description="horizontal run per metre rise of each bank, m/m (1.5 means 1:1.5; 0 = vertical)"
    )
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional)")

    @model_validator(mode="after")
    def _not_degenerate(self) -> TrapezoidalProfile:
        if self.bottom_width == 0 and self.side_slope == 0:
            raise FieldProblem("bottom_width", "bottom_width and side_slope are both 0: the profile has no width")
        if 0 < self.bottom_width < MIN_SIZE:
            raise FieldProblem("bottom_width", _tiny(self.bottom_width, "m", MIN_SIZE))
        if 0 < self.side_slope < MIN_SIZE:
            raise FieldProblem(
                "side_slope", f"{_num(self.side_slope)} m/m is neither 0 (vertical banks) nor at least {_num(MIN_SIZE)}"
            )
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
    height
        Bank height above the bed, m (optional): the top of the main channel, above which water
        spreads over the floodplain part of the table.
    """

    id: Identifier
    type: Literal["zw"] = Field(description="profile type 'zw' (tabulated heights and widths)")
    heights: list[Size] = Field(
        min_length=2, description="heights above the lowest point of the profile, m; start at 0, strictly increasing"
    )
    flow_widths: list[Size] = Field(
        min_length=2, description="width that conveys flow at each height, m; non-negative, non-decreasing"
    )
    total_widths: list[Size] | None = Field(
        default=None,
        description="width that stores water at each height, m (default: flow_widths); not below the flow width",
    )
    height: Size | None = Field(
        default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional; top of the main channel)"
    )

    @model_validator(mode="after")
    def _check_table(self) -> ZWProfile:
        _same_length(self.heights, "heights", self.flow_widths, "flow_widths")
        if self.total_widths is not None:
            _same_length(self.heights, "heights", self.total_widths, "total_widths")
        if self.heights[0] != 0.0:
            raise FieldProblem(
                "heights[0]",
                f"heights are measured from the lowest point of the profile and must start at 0, got "
                f"{_num(self.heights[0])} m (the level of that point is the cross-section's bed_level)",
            )
        _strictly_increasing(self.heights, "heights", "m")
        for name, widths in (("flow_widths", self.flow_widths), ("total_widths", self.total_widths)):
            if widths is None:
                continue
            _non_negative(widths, name, "m")
            for i, w in enumerate(widths):
                if 0 < w < MIN_SIZE:
                    raise FieldProblem(f"{name}[{i}]", _tiny(w, "m", MIN_SIZE))
            _non_decreasing(widths, name, "m", "a profile cannot narrow upward")
        if self.flow_widths[-1] <= 0:
            raise FieldProblem(
                f"flow_widths[{len(self.flow_widths) - 1}]",
                "the top flow width must be positive, otherwise the profile cannot convey flow",
            )
        if self.total_widths is not None:
            for i, (t, f) in enumerate(zip(self.total_widths, self.flow_widths, strict=True)):
                if t < f:
                    raise FieldProblem(
                        f"total_widths[{i}]",
                        f"total (storage) width {_num(t)} m is smaller than the flow width {_num(f)} m at height "
                        f"{_num(self.heights[i])} m",
                    )
        return self

    @property
    def storage_widths(self) -> list[float]:
        """Total (storage) widths, m."""
        return list(self.total_widths if self.total_widths is not None else self.flow_widths)


Profile = Annotated[RectangularProfile | TrapezoidalProfile | ZWProfile, Field(discriminator="type")]


class StorageTable(_Model):
    """Storage area of a connection node as a function of level.

    Attributes
    ----------
    levels
        Water levels, m AD, strictly increasing.
    areas
        Horizontal storage area at each level, m², non-negative and non-decreasing. Linear in
        between; constant above the last level; zero below the first.
    """

    levels: list[Level] = Field(min_length=2, description="water levels, m AD, strictly increasing")
    areas: list[Real] = Field(
        min_length=2, description="horizontal storage area at each level, m²; non-negative, non-decreasing"
    )

    @model_validator(mode="after")
    def _check(self) -> StorageTable:
        _same_length(self.levels, "levels", self.areas, "areas")
        _strictly_increasing(self.levels, "levels", "m AD")
        _non_negative(self.areas, "areas", "m²")
        _non_decreasing(self.areas, "areas", "m²", "the storage area cannot shrink as the water rises")
        if self.areas[-1] <= 0:
            raise FieldProblem(f"areas[{len(self.areas) - 1}]", "all storage areas are 0: the table stores no water")
        return self


class Node(_Model):
    """A connection node: the end of one or more branches.

    Attributes
    ----------
    x, y
        Map coordinates, m (optional, both or neither; used for plots).
    storage_area
        Extra horizontal storage area at the node, m² (a pond or a manhole), from the lowest bed
        level of the attached branches upward.
    storage_table
        Extra storage as a level-area table (alternative to ``storage_area``).
    """

    id: Identifier
    x: Real | None = Field(default=None, description="map x coordinate, m (optional)")
    y: Real | None = Field(default=None, description="map y coordinate, m (optional)")
    storage_area: Real = Field(
        default=0.0, ge=0, description="extra storage area at the node, m² (a pond), from the lowest bed level up"
    )
    storage_table: StorageTable | None = Field(
        default=None, description="extra storage as a level-area table (instead of storage_area)"
    )

    @model_validator(mode="after")
    def _one_storage(self) -> Node:
        if self.storage_table is not None and self.storage_area > 0:
            raise FieldProblem("storage_table", "give either storage_area or storage_table, not both")
        if (self.x is None) != (self.y is None):
            raise FieldProblem("x" if self.x is None else "y", "give both map coordinates x and y, or neither")
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

    chainage: Real = Field(ge=0, description="distance from the start of the branch, m")
    profile: Identifier = Field(description="id of a profile in [[profiles]]")
    bed_level: Level = Field(description="level of the lowest point of the profile, m AD")


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

    id: Identifier = Field(description="branch id (its own friction is the parameter friction:branch:<id>)")
    from_node: Identifier = Field(description="node at chainage 0 (positive flow runs from here)")
    to_node: Identifier = Field(description="node at the end of the branch (chainage = length)")
    length: Real = Field(ge=0.1, le=1.0e7, description="length along the channel axis, m")
    dx: Real = Field(default=100.0, gt=0, description="target spacing of calculation points, m")
    friction: Friction | None = Field(
        default=None, description="friction of this branch (default: the global friction)"
    )
    cross_sections: list[CrossSection] = Field(
        min_length=1, description="cross-sections ordered by chainage (at least one)"
    )
    geometry: list[tuple[Real, Real]] | None = Field(
        default=None, min_length=2, description="polyline [[x, y], ...] of the channel axis, m (optional, for plots)"
    )

    @model_validator(mode="after")
    def _check_sections(self) -> Branch:
        if self.from_node == self.to_node:
            raise FieldProblem(
                "to_node", f"from_node and to_node are the same node {self.from_node!r}; a branch joins two nodes"
            )
        chainages = [cs.chainage for cs in self.cross_sections]
        for i, (a, b) in enumerate(itertools.pairwise(chainages), start=1):
            if not b > a:
                raise FieldProblem(
                    f"cross_sections[{i}].chainage",
                    f"cross-sections must be ordered by increasing chainage, but {_num(b)} m follows {_num(a)} m",
                )
        if chainages[-1] > self.length:
            raise FieldProblem(
                f"cross_sections[{len(chainages) - 1}].chainage",
                f"cross-section at chainage {_num(chainages[-1])} m lies beyond the end of the branch "
                f"({_num(self.length)} m long)",
            )
        points = self.length / self.dx
        if points > MAX_POINTS_PER_BRANCH:
            raise FieldProblem(
                "dx",
                f"dx = {_num(self.dx)} m on a branch of {_num(self.length)} m gives {points:,.0f} calculation points "
                f"(at most {MAX_POINTS_PER_BRANCH:,}); dx and length are in metres",
            )
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
    id: Identifier = Field(description="structure id, unique among weirs, culverts and pumps")
    branch: Identifier = Field(description="id of the branch the structure sits on")
    chainage: Real = Field(ge=0, description="distance from the start of the branch, m")


class Weir(_OnBranch):
    """A broad-crested weir (thesis Eq. 3-4, free/submerged switch at h1 - zs = 1.5 (h2 - zs)).

    Attributes
    ----------
    crest_level
        Crest level z_s, m AD (a calibration target: ``weir:<id>.crest_level``); not below the bed.
    crest_width
        Crest width W_s, m.
    discharge_coefficient
        c_e, dimensionless.
    lateral_contraction
        c_w, dimensionless.
    allowed_flow
        ``both``, ``positive`` (branch direction only), ``negative`` or ``none``.
    """

    crest_level: Level = Field(description="crest level, m AD (not below the bed at the weir)")
    crest_width: Size = Field(ge=MIN_SIZE, description="crest width, m")
    discharge_coefficient: Real = Field(default=1.0, gt=0, le=2.0, description="discharge coefficient c_e, -")
    lateral_contraction: Real = Field(default=1.0, gt=0, le=1.0, description="lateral contraction coefficient c_w, -")
    allowed_flow: FlowDirection = Field(
        default="both", description="flow directions let through: 'both', 'positive', 'negative' or 'none'"
    )


class Culvert(_OnBranch):
    """A culvert: a closed conduit with entrance, friction and exit losses.

    Attributes
    ----------
    shape
        ``rectangular`` (``width`` x ``height``) or ``circular`` (``diameter``).
    width, height, diameter
        Conduit dimensions, m.
    invert_level
        Level of the conduit's bottom, m AD; not below the bed.
    length
        Conduit length, m.
    inlet_loss, outlet_loss
        Entrance and exit loss coefficients, dimensionless.
    friction
        Wall friction (default Manning n = 0.015 s/m^(1/3), concrete).
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    """

    shape: Literal["rectangular", "circular"] = Field(description="'rectangular' (width x height) or 'circular'")
    width: Size | None = Field(default=None, ge=MIN_SIZE, description="inside width of a rectangular culvert, m")
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="inside height of a rectangular culvert, m")
    diameter: Size | None = Field(default=None, ge=MIN_SIZE, description="inside diameter of a circular culvert, m")
    invert_level: Level = Field(description="level of the conduit's bottom, m AD (not below the bed)")
    length: Size = Field(ge=MIN_SIZE, description="length of the conduit, m")
    inlet_loss: Real = Field(default=0.5, ge=0, description="entrance loss coefficient, -")
    outlet_loss: Real = Field(default=1.0, ge=0, description="exit loss coefficient, -")
    friction: Friction = Field(
        default=Friction(type="manning", value=0.015), description="wall friction (default Manning n = 0.015)"
    )
    allowed_flow: FlowDirection = Field(
        default="both", description="flow directions let through: 'both', 'positive', 'negative' or 'none'"
    )

    @model_validator(mode="after")
    def _dimensions(self) -> Culvert:
        if self.shape == "rectangular":
            for name in ("width", "height"):
                if getattr(self, name) is None:
                    raise FieldProblem(name, f"a rectangular culvert needs {name} (m)")
            if self.diameter is not None:
                raise FieldProblem("diameter", "a rectangular culvert has width and height, not a diameter")
        else:
            if self.diameter is None:
                raise FieldProblem("diameter", "a circular culvert needs diameter (m)")
            for name in ("width", "height"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a circular culvert has a diameter, not a {name}")
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
        Suction-side levels at which the pump switches on and off, m AD (start > stop > bed).
    direction
        ``positive`` pumps in the branch direction, ``negative`` against it.
    """

    capacity: Discharge = Field(gt=0, description="discharge when running, m³/s")
    start_level: Level = Field(description="suction-side level at which the pump starts, m AD")
    stop_level: Level = Field(description="suction-side level at which the pump stops, m AD (below start_level)")
    direction: Literal["positive", "negative"] = Field(
        default="positive", description="'positive' pumps in the branch direction, 'negative' against it"
    )

    @model_validator(mode="after")
    def _levels(self) -> Pump:
        if not self.start_level > self.stop_level:
            raise FieldProblem(
                "stop_level",
                f"stop_level {_num(self.stop_level)} m AD must be below start_level {_num(self.start_level)} m AD",
            )
        return self


class RatingTable(_Model):
    """Outflow discharge as a function of level at a boundary node (a Q(h) relation).

    Attributes
    ----------
    levels
        Levels, m AD, strictly increasing.
    discharges
        Outflow at each level, m³/s: starting at 0 (the level at which outflow stops; below the
        table the engine keeps the first value) and non-decreasing. Above the table the last
        slope is extrapolated.
    """

    levels: list[Level] = Field(min_length=2, description="water levels, m AD, strictly increasing")
    discharges: list[Discharge] = Field(
        min_length=2, description="outflow at each level, m³/s; starts at 0, non-decreasing"
    )

    @model_validator(mode="after")
    def _check(self) -> RatingTable:
        _same_length(self.levels, "levels", self.discharges, "discharges")
        _strictly_increasing(self.levels, "levels", "m AD")
        _non_negative(self.discharges, "discharges", "m³/s")
        _non_decreasing(self.discharges, "discharges", "m³/s", "the outflow cannot fall as the level rises")
        if self.discharges[0] != 0:
            raise FieldProblem(
                "discharges[0]",
                f"the first discharge must be 0 m³/s (the level at which outflow stops), got "
                f"{_num(self.discharges[0])} m³/s; below the table the outflow stays at the first value, which "
                "would drain the node even when it is dry",
            )
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
    catchment
        Id of a sub-catchment (``[[catchments]]`` of the case) whose runoff is the inflow (for
        ``discharge``).
    rating
        The Q(h) table (for ``rating``).
    """

    id: Identifier
    node: Identifier = Field(description="id of an end node (a node with exactly one branch)")
    type: Literal["discharge", "level", "rating"] = Field(
        description="'discharge' (inflow, m³/s), 'level' (water level, m AD) or 'rating' (outflow from a Q(h) table)"
    )
    series: SeriesRef | None = Field(default=None, description="time series of the value (discharge or level)")
    value: Discharge | None = Field(default=None, description="constant value instead of a series: m³/s or m AD")
    catchment: Identifier | None = Field(
        default=None, description="sub-catchment whose runoff (m³/s) is the inflow of a 'discharge' boundary"
    )
    rating: RatingTable | None = Field(default=None, description="the Q(h) table of a 'rating' boundary")

    @model_validator(mode="after")
    def _one_source(self) -> Boundary:
        if self.type == "rating":
            if self.rating is None:
                raise FieldProblem("rating", "a rating boundary needs a rating table (levels and discharges)")
            for name in ("series", "value", "catchment"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a rating boundary takes its outflow from the rating table, not a {name}")
        else:
            if self.rating is not None:
                raise FieldProblem("rating", f"a {self.type} boundary takes a series or a value, not a rating table")
            if self.type == "level" and self.catchment is not None:
                raise FieldProblem("catchment", "a level boundary cannot take its level from a catchment's runoff")
            given = [name for name in ("series", "value", "catchment") if getattr(self, name) is not None]
            if not given:
                raise FieldProblem("series", f"a {self.type} boundary needs a series, a constant value or a catchment")
            if len(given) > 1:
                raise FieldProblem(given[1], f"a {self.type} boundary takes one of series, value or catchment, "
                                             f"not {' and '.join(given)}")
            if self.type == "level" and self.value is not None and abs(self.value) > MAX_LEVEL:
                raise FieldProblem(
                    "value", f"level {_num(self.value)} m AD lies outside ±{_num(MAX_LEVEL)} m AD (levels are in m AD)"
                )
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
    catchment
        Or the id of a sub-catchment (``[[catchments]]`` of the case) whose runoff is the inflow.
    """

    id: Identifier
    node: Identifier | None = Field(
        default=None, description="node that receives the inflow (or give branch and chainage)"
    )
    branch: Identifier | None = Field(default=None, description="branch that receives the inflow")
    chainage: Real | None = Field(default=None, ge=0, description="location on the branch, m from its start")
    series: SeriesRef | None = Field(default=None, description="time series of the inflow, m³/s (negative: extraction)")
    value: Discharge | None = Field(default=None, description="constant inflow instead of a series, m³/s")
    catchment: Identifier | None = Field(default=None, description="sub-catchment whose runoff (m³/s) is the inflow")

    @model_validator(mode="after")
    def _location_and_source(self) -> Lateral:
        _one_location(self.node, "node", self.branch, self.chainage, "a lateral")
        given = [name for name in ("series", "value", "catchment") if getattr(self, name) is not None]
        if not given:
            raise FieldProblem("series", "a lateral needs a series, a constant value (m³/s) or a catchment")
        if len(given) > 1:
            raise FieldProblem(given[1],
                               f"a lateral takes one of series, value or catchment, not {' and '.join(given)}")
        return self


def _one_location(point: str | None, point_name: str, branch: str | None, chainage: float | None, what: str) -> None:
    if branch is not None and chainage is None:
        raise FieldProblem("chainage", f"{what} on a branch needs a chainage (m from the start of the branch)")
    if chainage is not None and branch is None:
        raise FieldProblem("branch", f"{what} with a chainage needs the branch it lies on")
    if point is not None and branch is not None:
        raise FieldProblem(point_name, f"give either {point_name}, or branch and chainage, not both")
    if point is None and branch is None:
        raise FieldProblem(point_name, f"{what} needs a location: {point_name}, or branch and chainage")


StationQuantity = Literal["h", "h_up", "h_down", "Q"]
QUANTITIES_AT_STRUCTURE = ("h_up", "h_down", "Q")
QUANTITIES_ON_BRANCH = ("h", "Q")


class Station(_Model):
    """An observation station.

    A station either sits at a structure (quantities ``h_up``, ``h_down``, ``Q``) or at a
    chainage on a branch (quantities ``h``, ``Q``). Its simulated series are named
    ``"<id>.<quantity>"``, so a station id must not contain a dot.

    Attributes
    ----------
    structure
        Id of a weir, culvert or pump.
    branch, chainage
        A location on a branch, m.
    quantities
        Observed quantities (default ``h_up, h_down`` at a structure, ``h`` on a branch).
    """

    id: Identifier = Field(description="station id, the prefix of its series names '<id>.<quantity>' (no '.')")
    structure: Identifier | None = Field(default=None, description="id of a weir, culvert or pump")
    branch: Identifier | None = Field(default=None, description="branch of a station that is not at a structure")
    chainage: Real | None = Field(default=None, ge=0, description="location on the branch, m from its start")
    quantities: list[StationQuantity] | None = Field(
        default=None,
        min_length=1,
        description="observed quantities: 'h_up', 'h_down', 'Q' at a structure (default h_up, h_down); "
        "'h', 'Q' on a branch (default h). Levels in m AD, discharges in m³/s",
    )

    @model_validator(mode="after")
    def _location(self) -> Station:
        if "." in self.id:
            raise FieldProblem(
                "id", f"station id {self.id!r} contains a '.'; series are named '<station>.<quantity>', so it cannot"
            )
        _one_location(self.structure, "structure", self.branch, self.chainage, "a station")
        allowed = QUANTITIES_AT_STRUCTURE if self.structure is not None else QUANTITIES_ON_BRANCH
        seen: set[str] = set()
        for i, q in enumerate(self.quantities or []):
            if q not in allowed:
                if self.structure is not None:
                    reason = (f"quantity {q!r} does not exist at a structure; use 'h_up' and 'h_down' for the levels "
                              "either side of it, or 'Q'")
                else:
                    reason = (f"quantity {q!r} exists only at a structure; a station on a branch measures 'h' or "
                              "'Q' (use structure = <id> for levels either side of a structure)")
                raise FieldProblem(f"quantities[{i}]", reason)
            if q in seen:
                raise FieldProblem(f"quantities[{i}]", f"quantity {q!r} is listed twice")
            seen.add(q)
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

    friction: Friction = Field(
        default=Friction(type="strickler", value=30.0),
        description="global friction, used by every branch without its own (default Strickler 30 m^(1/3)/s)",
    )
    profiles: list[Profile] = Field(min_length=1, description="cross-section shapes, referenced by id")
    nodes: list[Node] = Field(min_length=2, description="connection nodes (branch ends)")
    branches: list[Branch] = Field(min_length=1, description="channel reaches between two nodes")
    weirs: list[Weir] = Field(default=[], description="weirs on branches")
    culverts: list[Culvert] = Field(default=[], description="culverts on branches")
    pumps: list[Pump] = Field(default=[], description="pumps on branches")
    boundaries: list[Boundary] = Field(default=[], description="boundary conditions at end nodes")
    laterals: list[Lateral] = Field(default=[], description="point inflows and extractions")
    stations: list[Station] = Field(default=[], description="observation stations")

    @model_validator(mode="after")
    def _check_topology(self) -> Network:
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
        self._check_connected()
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
        structures = {s.id for s in [*self.weirs, *self.culverts, *self.pumps]}
        for i, st in enumerate(self.stations):
            if st.structure is not None and st.structure not in structures:
                raise FieldProblem(
                    f"stations[{i}].structure",
                    f"station {st.id!r} refers to unknown structure {st.structure!r} (no weir, culvert or pump "
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
                f"{what} {item.id!r} at chainage {_num(item.chainage)} m lies beyond the end of branch "
                f"{item.branch!r} ({_num(length)} m long)",
            )

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
        missing = [(i, n.id) for i, n in enumerate(self.nodes) if n.id not in seen]
        if missing:
            i, node = missing[0]
            others = ", ".join(repr(m) for _, m in missing[:5]) + (", ..." if len(missing) > 5 else "")
            raise FieldProblem(
                f"nodes[{i}].id",
                f"the network is disconnected: no chain of branches leads from node {start!r} to node {node!r} "
                f"(unreachable: {others}); every node must be connected to the rest of the network",
            )

    def _check_structures(self, branches: dict[str, Branch]) -> None:
        groups = (("weirs", "weir", self.weirs), ("culverts", "culvert", self.culverts), ("pumps", "pump", self.pumps))
        for table, what, items in groups:
            for i, s in enumerate(items):
                where = f"{table}[{i}]"
                if s.branch not in branches:
                    raise FieldProblem(f"{where}.branch", f"{what} {s.id!r} refers to unknown branch {s.branch!r}"
                                       f"{_known(branches, s.branch)}")
                br = branches[s.branch]
                if s.chainage > br.length:
                    raise FieldProblem(
                        f"{where}.chainage",
                        f"{what} {s.id!r} at chainage {_num(s.chainage)} m lies beyond the end of branch {br.id!r} "
                        f"({_num(br.length)} m long)",
                    )
                bed = br.bed_level_at(s.chainage)
                if isinstance(s, Weir) and s.crest_level < bed:
                    raise FieldProblem(
                        f"{where}.crest_level",
                        f"the crest of weir {s.id!r} ({_num(s.crest_level)} m AD) lies below the bed "
                        f"({bed:.3f} m AD at chainage {_num(s.chainage)} m of branch {br.id!r})",
                    )
                if isinstance(s, Culvert) and s.invert_level < bed - 1e-9:
                    raise FieldProblem(
                        f"{where}.invert_level",
                        f"the invert of culvert {s.id!r} ({_num(s.invert_level)} m AD) lies below the bed "
                        f"({bed:.3f} m AD at chainage {_num(s.chainage)} m of branch {br.id!r})",
                    )
                if isinstance(s, Pump) and s.stop_level <= bed:
                    raise FieldProblem(
                        f"{where}.stop_level",
                        f"pump {s.id!r} would run the suction side dry: its stop level {_num(s.stop_level)} m AD is "
                        f"not above the bed ({bed:.3f} m AD at chainage {_num(s.chainage)} m of branch {br.id!r})",
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
    for table, items in (("weirs", network.weirs), ("culverts", network.culverts), ("pumps", network.pumps)):
        for i, s in enumerate(items):
            where = f"{table}[{i}]"
            if s.id in first:
                raise FieldProblem(
                    f"{where}.id",
                    f"structure id {s.id!r} is used twice (also by {first[s.id]}); weirs, culverts and pumps "
                    "share one set of ids",
                )
            first[s.id] = where
