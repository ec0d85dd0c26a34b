"""Structures on a branch: weirs, universal weirs, orifices, culverts, bridges and pumps.

A setting that an operator or a controller changes (a weir's crest, an orifice's gate, a pump's
capacity) may be given as a time series instead of a constant.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import (
    MIN_SIZE,
    Discharge,
    FlowDirection,
    Identifier,
    Level,
    NetworkModel,
    Real,
    Size,
    non_decreasing,
    num,
    same_length,
)
from rivercal.network.forcing import SeriesRef
from rivercal.network.friction import Friction

__all__ = ["Bridge", "Culvert", "Orifice", "Pump", "UniversalWeir", "Weir"]

_DIRECTION = "flow directions let through: 'both', 'positive', 'negative' or 'none'"



class _OnBranch(NetworkModel):
    id: Identifier = Field(description="structure id, unique among all structures")
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
    crest_series
        A time series of the crest level (m AD) set by an operator or a controller; the crest
        follows it and ``crest_level`` is only its value for checks.
    """

    crest_level: Level = Field(description="crest level, m AD (not below the bed at the weir)")
    crest_width: Size = Field(ge=MIN_SIZE, description="crest width, m")
    discharge_coefficient: Real = Field(default=1.0, gt=0, le=2.0, description="discharge coefficient c_e, -")
    lateral_contraction: Real = Field(default=1.0, gt=0, le=1.0, description="lateral contraction coefficient c_w, -")
    allowed_flow: FlowDirection = Field(default="both", description=_DIRECTION)
    crest_series: SeriesRef | None = Field(
        default=None, description="time series of the crest level, m AD (instead of the constant crest_level)"
    )


class Culvert(_OnBranch):
    """A culvert: a closed conduit with entrance, friction and exit losses.

    Attributes
    ----------
    shape
        ``rectangular`` (``width`` x ``height``), ``circular`` (``diameter``) or ``profile`` (the
        closed or open profile ``profile``).
    width, height, diameter
        Conduit dimensions, m.
    profile
        Id of a profile that gives the conduit's shape (``shape = "profile"``).
    invert_level
        Level of the conduit's bottom at its from-node end, m AD; not below the bed.
    invert_level_end
        Level of the conduit's bottom at its to-node end, m AD (default: ``invert_level``); a
        siphon or a sloping culvert has two inverts.
    length
        Conduit length, m.
    inlet_loss, outlet_loss
        Entrance and exit loss coefficients, dimensionless.
    friction
        Wall friction (default Manning n = 0.015 s/m^(1/3), concrete).
    bend_loss
        Loss coefficient of bends (a siphon), dimensionless.
    outlet_expansion
        Whether the exit loss is ``outlet_loss (1 - A/A_2)²``, A the culvert's flow area and A_2 the channel's
        downstream (a Borda-Carnot expansion loss, D-Flow FM's culvert), instead of ``outlet_loss``.
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    """

    shape: Literal["rectangular", "circular", "profile"] = Field(
        description="'rectangular' (width x height), 'circular' (diameter) or 'profile' (a profile's shape)"
    )
    profile: Identifier | None = Field(default=None, description="id of the profile of a culvert of shape 'profile'")
    width: Size | None = Field(default=None, ge=MIN_SIZE, description="inside width of a rectangular culvert, m")
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="inside height of a rectangular culvert, m")
    diameter: Size | None = Field(default=None, ge=MIN_SIZE, description="inside diameter of a circular culvert, m")
    invert_level: Level = Field(description="level of the conduit's bottom at its from-node end, m AD")
    invert_level_end: Level | None = Field(
        default=None, description="level of the conduit's bottom at its to-node end, m AD (default: invert_level)"
    )
    length: Size = Field(ge=MIN_SIZE, description="length of the conduit, m")
    inlet_loss: Real = Field(default=0.5, ge=0, description="entrance loss coefficient, -")
    outlet_loss: Real = Field(default=1.0, ge=0, description="exit loss coefficient, -")
    bend_loss: Real = Field(default=0.0, ge=0, description="loss coefficient of bends (a siphon), -")
    outlet_expansion: bool = Field(
        default=False,
        description="exit loss outlet_loss (1 - A/A_2)² with A_2 the channel's flow area downstream (Borda-Carnot, "
        "as D-Flow FM) instead of the constant outlet_loss",
    )
    friction: Friction = Field(
        default=Friction(type="manning", value=0.015), description="wall friction (default Manning n = 0.015)"
    )
    allowed_flow: FlowDirection = Field(default="both", description=_DIRECTION)

    @model_validator(mode="after")
    def _dimensions(self) -> Culvert:
        if self.shape == "profile":
            if self.profile is None:
                raise FieldProblem("profile", "a culvert of shape 'profile' needs the id of its profile")
            for name in ("width", "height", "diameter"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a culvert of shape 'profile' takes its {name} from the profile")
            return self
        if self.profile is not None:
            raise FieldProblem("profile", f"a {self.shape} culvert has its own dimensions; use shape = 'profile'")
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
        """Height of the conduit, m (nan for a culvert of shape 'profile': see its profile)."""
        if self.shape == "profile":
            return float("nan")
        return float(self.diameter if self.shape == "circular" else self.height)  # type: ignore[arg-type]

    @property
    def inverts(self) -> tuple[float, float]:
        """Invert levels at the from-node and the to-node end, m AD."""
        end = self.invert_level if self.invert_level_end is None else self.invert_level_end
        return self.invert_level, end


class Pump(_OnBranch):
    """A pump with a fixed capacity and level switches on its suction side.

    Attributes
    ----------
    capacity
        Discharge when running, m³/s.
    start_level, stop_level
        Suction-side levels at which the pump switches on and off, m AD (start > stop). A pump cannot draw water
        that is not there: whatever its stop level (one at or below the bed is allowed, as in D-Flow FM), it stops
        when its suction point holds less than 1 cm of water and starts again at 2 cm at the earliest.
    direction
        ``positive`` pumps in the branch direction, ``negative`` against it.
    capacity_series
        A time series of the capacity (m³/s, not negative) set by an operator or a controller;
        the pump delivers it while it runs, and ``capacity`` is only its nominal value.
    """

    capacity: Discharge = Field(gt=0, description="discharge when running, m³/s")
    start_level: Level = Field(description="suction-side level at which the pump starts, m AD")
    stop_level: Level = Field(description="suction-side level at which the pump stops, m AD (below start_level)")
    direction: Literal["positive", "negative"] = Field(
        default="positive", description="'positive' pumps in the branch direction, 'negative' against it"
    )
    capacity_series: SeriesRef | None = Field(
        default=None, description="time series of the capacity, m³/s (instead of the constant capacity)"
    )

    @model_validator(mode="after")
    def _levels(self) -> Pump:
        if not self.start_level > self.stop_level:
            raise FieldProblem(
                "stop_level",
                f"stop_level {num(self.stop_level)} m AD must be below start_level {num(self.start_level)} m AD",
            )
        return self


class Orifice(_OnBranch):
    """An orifice: a weir crest under a gate (D-Flow FM "orifice").

    Free weir flow while the water stays below the gate's lower edge; gate flow below it.

    Attributes
    ----------
    crest_level
        Crest (sill) level, m AD; not below the bed.
    crest_width
        Width of the opening, m.
    gate_lower_edge_level
        Level of the gate's lower edge, m AD (above the crest).
    gate_series
        A time series of the gate's lower edge, m AD (instead of the constant).
    discharge_coefficient
        Contraction/discharge coefficient μ, dimensionless.
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    max_flow_positive, max_flow_negative
        Largest discharge let through in each direction, m³/s (none: no limit).
    """

    crest_level: Level = Field(description="crest (sill) level, m AD (not below the bed)")
    crest_width: Size = Field(ge=MIN_SIZE, description="width of the opening, m")
    gate_lower_edge_level: Level = Field(description="level of the gate's lower edge, m AD (above the crest)")
    gate_series: SeriesRef | None = Field(
        default=None, description="time series of the gate's lower edge, m AD (instead of the constant)"
    )
    discharge_coefficient: Real = Field(default=0.63, gt=0, le=2.0, description="discharge coefficient, -")
    allowed_flow: FlowDirection = Field(default="both", description=_DIRECTION)
    max_flow_positive: Discharge | None = Field(
        default=None, ge=0, description="largest discharge in the branch direction, m³/s (default: no limit)"
    )
    max_flow_negative: Discharge | None = Field(
        default=None, ge=0, description="largest discharge against the branch direction, m³/s (default: no limit)"
    )

    @model_validator(mode="after")
    def _gate(self) -> Orifice:
        if not self.gate_lower_edge_level > self.crest_level:
            raise FieldProblem(
                "gate_lower_edge_level",
                f"the gate's lower edge {num(self.gate_lower_edge_level)} m AD must be above the crest "
                f"{num(self.crest_level)} m AD (a closed orifice: use allowed_flow = 'none')",
            )
        return self


class UniversalWeir(_OnBranch):
    """A weir with a crest of any shape (D-Flow FM "universalWeir").

    The crest is a y-z polyline; the weir discharges as a sum of broad-crested weirs over each
    piece of the crest.

    Attributes
    ----------
    y
        Horizontal positions across the crest, m, non-decreasing.
    z
        Height of the crest above ``crest_level`` at each position, m (the lowest is 0).
    crest_level
        Level of the lowest point of the crest, m AD; not below the bed.
    discharge_coefficient
        Discharge coefficient c_e, dimensionless.
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    """

    y: list[Real] = Field(min_length=2, description="horizontal positions across the crest, m, non-decreasing")
    z: list[Size] = Field(min_length=2, description="height of the crest above crest_level at each y, m")
    crest_level: Level = Field(description="level of the lowest point of the crest, m AD (not below the bed)")
    discharge_coefficient: Real = Field(default=1.0, gt=0, le=2.0, description="discharge coefficient c_e, -")
    allowed_flow: FlowDirection = Field(default="both", description=_DIRECTION)

    @model_validator(mode="after")
    def _shape(self) -> UniversalWeir:
        same_length(self.y, "y", self.z, "z")
        non_decreasing(self.y, "y", "m", "positions run from one side of the crest to the other")
        if min(self.z) != 0.0:
            raise FieldProblem("z", f"heights are measured from the crest level, so the lowest must be 0, got "
                                    f"{num(min(self.z))} m")
        if self.y[-1] - self.y[0] < MIN_SIZE:
            raise FieldProblem("y", "the crest has no width: the first and last y are the same")
        return self


class Bridge(_OnBranch):
    """A bridge: flow through the opening between its abutments, with entrance, friction and exit losses.

    Discharged like a short culvert of the bridge's open profile (D-Flow FM "bridge").

    Attributes
    ----------
    profile
        Id of the profile of the opening.
    bed_level
        Level of the lowest point of the opening's profile, m AD.
    length
        Length of the bridge in the flow direction, m.
    inlet_loss, outlet_loss
        Entrance and exit loss coefficients, dimensionless.
    friction
        Friction of the opening's bed and walls.
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    """

    profile: Identifier = Field(description="id of the profile of the opening")
    bed_level: Level = Field(description="level of the lowest point of the opening, m AD")
    length: Size = Field(ge=MIN_SIZE, description="length of the bridge in the flow direction, m")
    inlet_loss: Real = Field(default=0.5, ge=0, description="entrance loss coefficient, -")
    outlet_loss: Real = Field(default=1.0, ge=0, description="exit loss coefficient, -")
    friction: Friction = Field(
        default=Friction(type="manning", value=0.015), description="friction of the opening (default Manning 0.015)"
    )
    allowed_flow: FlowDirection = Field(default="both", description=_DIRECTION)
